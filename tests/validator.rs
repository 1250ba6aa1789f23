//! Every fixture scene bakes into a file the Khronos glTF validator accepts
//! with zero errors (warnings are allowed, and printed), in both output
//! forms. The validator is the npm package `gltf-validator`, installed by
//! `pipeline/setup.sh` and run through `pipeline/validate.mjs`; without it
//! these tests fail, they never skip.

use std::path::{Path, PathBuf};
use std::process::Command;

use bake::fixtures::{MeshData, Placement, SceneBuilder};

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// Tiny bakes: what is checked here is the file, not the light.
fn bake(input: &Path, out: &Path, extra: &[&str]) {
    let env = repo().join("fixtures/sky_sun.exr");
    let mut args = vec![input.as_os_str(), "--env".as_ref(), env.as_os_str(), "-o".as_ref(), out.as_os_str()];
    for arg in ["--max-atlas-size", "64", "--lights", "64", "--max-shots", "64", "-q"].iter().chain(extra) {
        args.push(arg.as_ref());
    }
    let output = Command::new(env!("CARGO_BIN_EXE_bake")).args(&args).output().expect("bake runs");
    assert!(output.status.success(), "bake {}: {}", input.display(), String::from_utf8_lossy(&output.stderr));
}

/// The validator's report on `file`: (errors, warnings, every message as one line).
fn validate(file: &Path) -> (u64, u64, Vec<String>) {
    let script = repo().join("pipeline/validate.mjs");
    let output =
        Command::new("node").arg(&script).arg(file).output().unwrap_or_else(|e| {
            panic!("cannot run node ({e}): the glTF validator needs Node.js; run ./pipeline/setup.sh")
        });
    let report: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap_or_else(|_| {
        panic!(
            "the glTF validator gave no report on {} (run ./pipeline/setup.sh to install it): {}",
            file.display(),
            String::from_utf8_lossy(&output.stderr)
        )
    });
    let issues = &report["issues"];
    let messages = issues["messages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| {
            format!(
                "{} {} at {}: {}",
                ["error", "warning", "info", "hint"][m["severity"].as_u64().unwrap() as usize],
                m["code"],
                m["pointer"],
                m["message"]
            )
        })
        .collect();
    (issues["numErrors"].as_u64().unwrap(), issues["numWarnings"].as_u64().unwrap(), messages)
}

/// Validates `file`, prints its errors and warnings, and fails on any error.
fn assert_valid(file: &Path) {
    let (errors, warnings, messages) = validate(file);
    let name = file.display();
    eprintln!("{name}: {errors} errors, {warnings} warnings, {} messages", messages.len());
    for message in messages.iter().filter(|m| !m.starts_with("info") && !m.starts_with("hint")) {
        eprintln!("  {message}");
    }
    assert_eq!(errors, 0, "{name} has validation errors:\n{}", messages.join("\n"));
}

fn fixture_scenes() -> Vec<PathBuf> {
    let mut scenes: Vec<PathBuf> = std::fs::read_dir(repo().join("fixtures"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "glb" || e == "gltf"))
        .collect();
    scenes.sort();
    assert!(scenes.len() >= 3, "fixtures/ holds {} scenes", scenes.len());
    scenes
}

#[test]
fn every_fixture_and_its_bake_pass_the_validator() {
    let dir = tempfile::tempdir().unwrap();
    for input in fixture_scenes() {
        assert_valid(&input);
        let stem = input.file_stem().unwrap().to_string_lossy().into_owned();
        let out = dir.path().join(&stem);
        bake(&input, &out, &[]);
        assert_valid(&out.join(format!("{stem}.glb")));
    }
}

#[test]
fn the_gltf_form_passes_the_validator() {
    let dir = tempfile::tempdir().unwrap();
    for input in fixture_scenes() {
        let stem = input.file_stem().unwrap().to_string_lossy().into_owned();
        let out = dir.path().join(&stem);
        bake(&input, &out, &["--format", "gltf"]);
        // The validator reads the .bin and the images through their URIs.
        assert_valid(&out.join(format!("{stem}.gltf")));
    }
}

#[test]
fn a_primitive_without_texcoord_0_gets_a_valid_uv_numbering() {
    // glTF numbers texture coordinate sets from 0 without gaps: TEXCOORD_1 alone is an error.
    let dir = tempfile::tempdir().unwrap();
    let mut sphere = MeshData::sphere(1.0, 12, 6);
    sphere.uv0.clear();
    let mut scene = SceneBuilder::new();
    scene.object("bare", &sphere, [0.8, 0.8, 0.8, 1.0], [0.0; 3], Placement::default());
    let input = dir.path().join("bare.glb");
    std::fs::write(&input, scene.to_glb()).unwrap();
    bake(&input, &dir.path().join("out"), &[]);
    let output = dir.path().join("out/bare.glb");
    assert_valid(&output);
    let gltf = gltf::Gltf::open(&output).unwrap();
    let primitive = gltf.meshes().next().unwrap().primitives().next().unwrap();
    let (uv0, uv1) = (primitive.get(&gltf::Semantic::TexCoords(0)), primitive.get(&gltf::Semantic::TexCoords(1)));
    assert_eq!(uv0.unwrap().index(), uv1.unwrap().index(), "TEXCOORD_0 is the lightmap UVs too");
}

#[test]
fn the_validator_finds_errors() {
    // The check above can fail: a file with a dangling accessor index is an error.
    let dir = tempfile::tempdir().unwrap();
    let broken = dir.path().join("broken.gltf");
    std::fs::write(&broken, r#"{"asset":{"version":"2.0"},"meshes":[{"primitives":[{"attributes":{"POSITION":7}}]}]}"#)
        .unwrap();
    let (errors, _, messages) = validate(&broken);
    assert!(errors > 0, "{messages:?}");
}
