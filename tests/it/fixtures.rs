//! The committed fixtures are exactly what `cargo run --example
//! make_fixtures` writes: none is a blob that cannot be regenerated.

#[test]
fn committed_fixtures_match_their_generators() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures");
    for (name, bytes) in bake::fixtures::files().unwrap() {
        let committed = std::fs::read(dir.join(&name)).unwrap_or_else(|e| panic!("fixtures/{name}: {e}"));
        assert!(
            committed == bytes,
            "fixtures/{name} differs from its generator: run `cargo run --release --example make_fixtures`"
        );
    }
}

/// The benchmark statues are closed, outward-facing meshes of the advertised size, and the
/// Table 4 scene has about the paper's 9,225 vertices.
#[test]
fn statues_are_closed_outward_meshes() {
    use bake::fixtures::{MeshData, TABLE4_STATUE_FREQUENCY};
    use glam::Vec3;
    for (frequency, variant) in [(1, 0), (4, 1), (TABLE4_STATUE_FREQUENCY, 2)] {
        let mesh = MeshData::statue(frequency, variant);
        let f = frequency as usize;
        assert_eq!(mesh.positions.len(), 10 * f * f + 2);
        assert_eq!(mesh.indices.len(), 3 * 20 * f * f);
        assert_eq!(mesh.normals.len(), mesh.positions.len());
        // Closed and consistently wound: every directed edge once, its reverse once.
        let mut edges = std::collections::HashMap::new();
        for t in mesh.indices.chunks_exact(3) {
            for k in 0..3 {
                *edges.entry((t[k], t[(k + 1) % 3])).or_insert(0) += 1;
            }
        }
        for (&(a, b), &count) in &edges {
            assert_eq!(count, 1, "edge {a}-{b} used {count} times");
            assert_eq!(edges.get(&(b, a)), Some(&1), "edge {a}-{b} has no twin");
        }
        // Outward: positive enclosed volume; standing on y = 0.
        let p = |i: u32| Vec3::from(mesh.positions[i as usize]);
        let volume: f32 = mesh.indices.chunks_exact(3).map(|t| p(t[0]).dot(p(t[1]).cross(p(t[2]))) / 6.0).sum();
        assert!(volume > 0.01, "volume {volume}");
        let lowest = mesh.positions.iter().map(|q| q[1]).fold(f32::INFINITY, f32::min);
        assert_eq!(lowest, 0.0);
    }
    let scene = bake::fixtures::three_statues(TABLE4_STATUE_FREQUENCY);
    let source = bake::asset::SourceAsset::from_bytes(std::path::Path::new("statues.glb"), &scene.to_glb(), None);
    let scene = bake::import::from_asset(source.unwrap()).unwrap();
    let vertices: usize = scene.primitives.iter().map(|p| p.positions.len()).sum();
    assert_eq!((scene.primitives.len(), vertices, scene.triangle_count()), (4, 9252, 18398));
}
