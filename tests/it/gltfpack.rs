//! Files as gltfpack writes them for the web, baked through the CLI: with
//! quantized attributes (KHR_mesh_quantization), meshopt-compressed buffer
//! views with filters (EXT_meshopt_compression, `-cc`) and GPU instances
//! (EXT_mesh_gpu_instancing, `-mi`), each primitive bakes to what the same
//! file written plain bakes to. gltfpack is the npm package pinned in
//! pipeline/package-lock.json and installed by pipeline/setup.sh; without
//! it these tests fail, they never skip.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Command;

use bake::fixtures::{MeshData, Placement, SceneBuilder};
use bake::report::Report;
use glam::{Quat, Vec3};

/// Runs gltfpack on `input` with `flags` and returns the written file.
fn gltfpack(input: &Path, dir: &Path, name: &str, flags: &[&str]) -> PathBuf {
    let output = dir.join(format!("{name}.glb"));
    let cli = common::repo("pipeline/node_modules/gltfpack/cli.js");
    let run = Command::new("node")
        .arg(&cli)
        .args(["-i".as_ref(), input.as_os_str(), "-o".as_ref(), output.as_os_str()])
        .args(flags)
        .output()
        .unwrap_or_else(|e| panic!("cannot run node ({e}): gltfpack needs Node.js; run ./pipeline/setup.sh"));
    assert!(
        run.status.success() && output.is_file(),
        "gltfpack {flags:?} failed (run ./pipeline/setup.sh to install it): {}",
        String::from_utf8_lossy(&run.stderr)
    );
    output
}

/// Bakes `input` at 128² under the sun-and-sky fixture, 256 shots of bounced
/// light (the files are compared, not convergence); returns its report.
/// A short bake: the files are compared with each other, not with the
/// converged light (no contact fix-up, which the corner's walls keep busy).
/// `inputs` baked in one run (one start-up), a scene each in the report.
fn bake_all(inputs: &[&Path], out: &Path) -> Report {
    let args = ["--max-atlas-size", "128", "--lights", "128", "--max-shots", "256", "--no-contact-trace", "-q"];
    common::bake_files(inputs, out, &args)
}

/// Each primitive's (texels, mean L_lm) in the scene named `name`, in order.
fn scene_primitives(report: &Report, name: &str) -> Vec<(usize, [f64; 3])> {
    let scene = report.scenes.iter().find(|s| s.name == name).unwrap_or_else(|| panic!("no scene '{name}'"));
    scene.energy.iter().map(|e| (e.stats.texels, e.stats.mean_lightmap)).collect()
}

/// Every primitive's mean within 2 % of the plain file's, and its texels
/// within 5 % (quantized positions move the automatic texel density).
fn assert_bakes_alike(what: &str, packed: &[(usize, [f64; 3])], plain: &[(usize, [f64; 3])]) {
    eprintln!("{what}:\n  packed {packed:.4?}\n  plain  {plain:.4?}");
    assert_eq!(packed.len(), plain.len(), "{what}: primitive count");
    for (p, ((texels_a, mean_a), (texels_b, mean_b))) in packed.iter().zip(plain).enumerate() {
        let texels = *texels_a as f64 / *texels_b as f64;
        assert!((texels - 1.0).abs() < 0.05, "{what}, primitive {p}: {texels_a} texels against {texels_b}");
        for c in 0..3 {
            let ratio = mean_a[c] / mean_b[c];
            assert!((ratio - 1.0).abs() < 0.02, "{what}, primitive {p}: mean {mean_a:?} against {mean_b:?}");
        }
    }
}

#[test]
fn quantized_and_meshopt_compressed_files_bake_as_the_plain_file_does() {
    let dir = tempfile::tempdir().unwrap();
    let input = common::repo("fixtures/corner.glb");
    let plain = gltfpack(&input, dir.path(), "plain", &["-noq"]);
    let quantized = gltfpack(&input, dir.path(), "quantized", &[]);
    let compressed = gltfpack(&input, dir.path(), "compressed", &["-cc"]);
    let json = |file: &Path| -> serde_json::Value {
        let bytes = std::fs::read(file).unwrap();
        serde_json::from_slice(&gltf::binary::Glb::from_slice(&bytes).unwrap().json).unwrap()
    };
    // What the files hold, so that the test tests what it says.
    assert!(json(&plain).get("extensionsUsed").is_none_or(|e| !e.to_string().contains("quantization")));
    assert!(json(&quantized)["extensionsRequired"].to_string().contains("KHR_mesh_quantization"));
    let required = json(&compressed)["extensionsRequired"].to_string();
    assert!(required.contains("EXT_meshopt_compression"), "{required}");
    assert!(json(&compressed).to_string().contains("OCTAHEDRAL"), "-cc filters the normals");

    let report = bake_all(&[&plain, &quantized, &compressed], &dir.path().join("out"));
    let baseline = scene_primitives(&report, "plain");
    assert_bakes_alike("quantized", &scene_primitives(&report, "quantized"), &baseline);
    assert_bakes_alike("compressed", &scene_primitives(&report, "compressed"), &baseline);
    // The output is plain glTF: decoded, the extension gone.
    let output = json(&dir.path().join("out/compressed.glb"));
    assert!(!output.to_string().contains("meshopt_compression"), "the output still names the extension");
}

#[test]
fn gltfpacks_gpu_instances_bake_as_the_nodes_they_replace() {
    // Three boxes drawn by three nodes of one mesh, off the ground (a face
    // flat on the ground is lit by chance, through it).
    let dir = tempfile::tempdir().unwrap();
    let mut scene = SceneBuilder::new();
    scene.object("ground", &MeshData::plane(6.0, 6.0, 1), [0.6, 0.6, 0.6, 1.0], [0.0; 3], Placement::default());
    let grey = scene.material("box", [0.7, 0.7, 0.7, 1.0], [0.0; 3]);
    let cube = scene.mesh("box", &MeshData::cuboid([0.6, 0.6, 0.6]), Some(grey));
    scene.node("box 0", cube, Placement::at(Vec3::new(-1.4, 0.5, 0.0)));
    scene.node("box 1", cube, Placement::at(Vec3::new(0.0, 0.5, 0.6)).rotated(Quat::from_rotation_y(0.8)));
    scene.node("box 2", cube, Placement::at(Vec3::new(1.5, 0.6, -0.2)).scaled(Vec3::splat(1.5)));
    let input = dir.path().join("boxes.glb");
    std::fs::write(&input, scene.to_glb()).unwrap();

    let plain = gltfpack(&input, dir.path(), "plain", &["-noq", "-kn"]);
    let instanced = gltfpack(&input, dir.path(), "instanced", &["-mi", "-cc"]);
    let report = bake_all(&[&instanced, &plain], &dir.path().join("out"));
    let energy = &report.scenes.iter().find(|s| s.name == "instanced").expect("the instanced scene").energy;
    let instances: Vec<_> = energy.iter().filter_map(|e| e.instance).collect();
    assert_eq!(instances, [0, 1, 2], "gltfpack wrote the boxes as three instances of one node");
    // Instances come in the node's order, as the plain nodes do.
    let (packed, baseline) = (scene_primitives(&report, "instanced"), scene_primitives(&report, "plain"));
    assert_bakes_alike("instanced", &packed, &baseline);
}
