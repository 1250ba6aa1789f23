//! The same inputs and options give byte-identical output files on the same
//! adapter: the bake (direct light and bounces) and every file export writes.

use crate::common;
use bake::fixtures::{MeshData, Placement, SceneBuilder};
use glam::{Quat, Vec3};
use std::collections::BTreeMap;
use std::path::Path;

fn bake(out: &Path, format: &str) -> BTreeMap<String, Vec<u8>> {
    let output = common::tiny_bake(&common::fixture("everything.glb"), out, &["--format", format]);
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    std::fs::read_dir(out)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.file_name().unwrap() != "report.json") // holds timings
        .map(|p| (p.file_name().unwrap().to_string_lossy().into_owned(), std::fs::read(&p).unwrap()))
        .collect()
}

#[test]
fn baking_twice_gives_identical_files() {
    let dir = tempfile::tempdir().unwrap();
    for format in ["glb", "gltf"] {
        let first = bake(&dir.path().join(format!("{format}-1")), format);
        let second = bake(&dir.path().join(format!("{format}-2")), format);
        assert_eq!(first.keys().collect::<Vec<_>>(), second.keys().collect::<Vec<_>>());
        assert!(first.contains_key("everything.lightmap0.exr") && first.contains_key(&format!("everything.{format}")));
        for (name, bytes) in &first {
            assert!(*bytes == second[name], "{name} differs between two identical bakes");
            eprintln!("{name}: {} bytes, identical", bytes.len());
        }
    }
}

/// A ground under a canopy whose +X half is cut out (alpha MASK): its
/// direct pass needs the pipeline with the alpha test compiled in.
fn cut_out_canopy(path: &Path) {
    let mut b = SceneBuilder::new();
    b.object("ground", &MeshData::plane(4.0, 4.0, 2), [0.5, 0.5, 0.5, 1.0], [0.0; 3], Placement::default());
    let canopy = b.material("canopy", [0.5, 0.5, 0.5, 1.0], [0.0; 3]);
    let texture = b.png_texture(&common::halves([128, 128, 128, 255], [128, 128, 128, 0]), 33071);
    b.base_color_texture(canopy, texture, None);
    b.alpha_mask(canopy, 0.5);
    let mesh = b.mesh("canopy", &MeshData::plane(2.0, 2.0, 2), Some(canopy));
    let over = Placement::at(Vec3::new(0.0, 0.5, 0.0)).rotated(Quat::from_rotation_x(180f32.to_radians()));
    b.node("canopy", mesh, over);
    std::fs::write(path, b.to_glb()).unwrap();
}

/// A run of several scenes builds each pass's pipelines once and reuses them
/// (`gpu::built`; the unit test `a_pipeline_is_built_once_per_device_and_constants`
/// checks their keys): a scene baked after another, whose direct pass needs
/// another pipeline (cut-outs), gets the bytes it gets alone.
#[test]
fn a_scene_baked_after_another_in_one_run_gets_the_files_it_gets_alone() {
    let dir = tempfile::tempdir().unwrap();
    let canopy = dir.path().join("canopy.glb");
    cut_out_canopy(&canopy);
    let files = |out: &Path, inputs: &[&Path]| {
        let output = common::tiny_bake_all(inputs, out, &[]);
        assert!(output.status.success(), "{}", common::stderr(&output));
        ["canopy.glb", "canopy.lightmap0.exr"].map(|name| std::fs::read(out.join(name)).unwrap())
    };
    let alone = files(&dir.path().join("alone"), &[&canopy]);
    let after = files(&dir.path().join("after"), &[&common::fixture("corner.glb"), &canopy]);
    assert!(alone[0] == after[0], "canopy.glb differs when baked after corner.glb");
    assert!(alone[1] == after[1], "its lightmap differs when baked after corner.glb");
}
