//! The `bake` binary as a user runs it, each test in a fresh folder: a
//! fixture bakes into a lightmapped GLB that loads with the gltf crate, and
//! bad inputs give one-line errors naming the file, exit code 2, and leave
//! no output behind.

use std::process::Output;

use crate::common::{self, fixture, run_bake as bake, stderr};
use bake::report::Report;

/// The run failed with exit code 2 and exactly one error line mentioning `needle`.
fn assert_one_line_error(output: &Output, needle: &str) {
    let text = stderr(output);
    assert_eq!(output.status.code(), Some(2), "stderr: {text}");
    let errors: Vec<&str> = text.lines().filter(|l| l.starts_with("bake: error:")).collect();
    assert_eq!(errors.len(), 1, "stderr: {text}");
    assert!(errors[0].contains(needle), "'{}' does not name '{needle}'", errors[0]);
    assert_eq!(text.lines().count(), 1, "quiet runs print only the error: {text}");
}

#[test]
fn bakes_a_fixture_into_a_lightmapped_glb() {
    let dir = tempfile::tempdir().unwrap();
    let input = fixture("sphere_on_ground.glb");
    let env = fixture("sky_horizon.hdr");
    let output = bake(
        dir.path(),
        &[
            input.to_str().unwrap(),
            "--env",
            env.to_str().unwrap(),
            "-o",
            "out",
            "--max-atlas-size",
            "96",
            "--lights",
            "cube:8",
            "--quiet",
        ],
    );
    assert!(output.status.success(), "bake failed: {}", stderr(&output));
    let out = dir.path().join("out");

    let glb = std::fs::read(out.join("sphere_on_ground.glb")).unwrap();
    let gltf = gltf::Gltf::from_slice(&glb).expect("the output is valid glTF");
    let mut baked_primitives = 0;
    for mesh in gltf.meshes() {
        for primitive in mesh.primitives() {
            assert!(primitive.get(&gltf::Semantic::TexCoords(1)).is_some(), "mesh {} lacks TEXCOORD_1", mesh.index());
            let material = primitive.material();
            assert!(material.unlit(), "mesh {} is not shown baked", mesh.index());
            let texture = material.pbr_metallic_roughness().base_color_texture().expect("baked texture");
            assert_eq!(texture.tex_coord(), 1);
            match texture.texture().source().expect("an image").source() {
                gltf::image::Source::View { mime_type, .. } => assert_eq!(mime_type, "image/png"),
                gltf::image::Source::Uri { .. } => panic!("the lightmap must be embedded"),
            }
            baked_primitives += 1;
        }
    }
    assert_eq!(baked_primitives, 2);

    let exr = exr::prelude::read_first_rgba_layer_from_file(
        out.join("sphere_on_ground.lightmap0.exr"),
        |size, _| vec![[0f32; 3]; size.width() * size.height()],
        |pixels, position, (r, g, b, _a): (f32, f32, f32, f32)| pixels[position.y() * 96 + position.x()] = [r, g, b],
    );
    assert!(exr.is_ok(), "the EXR lightmap reads back");

    let report: Report = serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report.scenes.len(), 1);
    assert!(report.scenes[0].texels.covered > 0);
    assert!(!report.adapter.name.is_empty());
    assert!(report.scenes[0].energy.iter().all(|e| e.stats.invalid_texels == 0));
    let names: Vec<&str> = report.scenes[0].stages.iter().map(|s| s.stage.as_str()).collect();
    assert_eq!(names, ["import", "unwrap", "texelize", "solve", "export"]);
    assert!(!out.read_dir().unwrap().any(|e| { e.unwrap().file_name().to_string_lossy().starts_with(".bake") }));
}

#[test]
fn missing_input_is_named_and_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let env = fixture("sky_horizon.hdr");
    let output = bake(dir.path(), &["nowhere.glb", "--env", env.to_str().unwrap(), "-o", "out", "-q"]);
    assert_one_line_error(&output, "nowhere.glb");
    assert!(!dir.path().join("out").exists());
}

#[test]
fn a_file_that_is_not_gltf_is_named() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("notes.glb"), "this is not a model").unwrap();
    let env = fixture("sky_horizon.hdr");
    let output = bake(dir.path(), &["notes.glb", "--env", env.to_str().unwrap(), "-o", "out", "-q"]);
    assert_one_line_error(&output, "notes.glb");
    assert!(!dir.path().join("out").exists());
}

#[test]
fn missing_or_unreadable_environment_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let input = fixture("sphere_on_ground.glb");
    let output = bake(dir.path(), &[input.to_str().unwrap(), "--env", "nosky.exr", "-o", "out", "-q"]);
    assert_one_line_error(&output, "nosky.exr");
    std::fs::write(dir.path().join("garbage.exr"), [0u8, 1, 2, 3, 4, 5]).unwrap();
    let output = bake(dir.path(), &[input.to_str().unwrap(), "--env", "garbage.exr", "-o", "out", "-q"]);
    assert_one_line_error(&output, "garbage.exr");
    assert!(!dir.path().join("out").exists());
}

#[test]
fn a_failed_run_keeps_the_previous_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join("sphere_on_ground.glb"), "previous").unwrap();
    let input = fixture("sphere_on_ground.glb");
    let output = bake(dir.path(), &[input.to_str().unwrap(), "--env", "nosky.exr", "-o", "out", "-q"]);
    assert_eq!(output.status.code(), Some(2));
    assert_eq!(std::fs::read_to_string(out.join("sphere_on_ground.glb")).unwrap(), "previous");
    assert_eq!(out.read_dir().unwrap().count(), 1, "nothing else was left in the output folder");
}

#[test]
fn help_explains_every_option() {
    let output = common::bake_command().arg("--help").output().unwrap();
    let help = String::from_utf8_lossy(&output.stdout);
    for option in [
        "--env",
        "--output",
        "--texels-per-unit",
        "--max-atlas-size",
        "--padding",
        "--unwrapper",
        "--lights",
        "--env-rotation",
        "--env-intensity",
        "--clamp-nonfinite",
        "--exposure",
        "--adapter",
        "--quiet",
        "--log-format",
        "--format",
        "--keep-uv1",
    ] {
        assert!(help.contains(option), "--help does not mention {option}");
    }
}

#[test]
fn a_scene_lit_only_by_emitters_bakes_without_an_environment() {
    use bake::fixtures::{MeshData, Placement, SceneBuilder};
    let dir = tempfile::tempdir().unwrap();
    let mut scene = SceneBuilder::new();
    scene.object("room", &MeshData::room([4.0, 3.0, 4.0]), [0.7, 0.7, 0.7, 1.0], [0.0; 3], Placement::default());
    scene.object(
        "lamp",
        &MeshData::plane(1.0, 1.0, 1),
        [0.0, 0.0, 0.0, 1.0],
        [20.0, 18.0, 15.0],
        Placement::at(glam::Vec3::new(0.0, 1.45, 0.0)).rotated(glam::Quat::from_rotation_x(std::f32::consts::PI)),
    );
    std::fs::write(dir.path().join("lamp_room.glb"), scene.to_glb()).unwrap();
    let output = bake(dir.path(), &["lamp_room.glb", "-o", "out", "--max-atlas-size", "64", "-q"]);
    assert!(output.status.success(), "{}", stderr(&output));
    let report: Report = serde_json::from_slice(&std::fs::read(dir.path().join("out/report.json")).unwrap()).unwrap();
    let scene = &report.scenes[0];
    assert!(scene.skipped.iter().any(|s| s.pass == "direct"), "the direct pass is reported as left out");
    let bounce = scene.bounce.as_ref().expect("the emitters were shot");
    assert!(bounce.shots > 0 && !bounce.trace.is_empty());
    let room = &scene.energy[0].stats;
    assert!(room.mean_lightmap[0] > 0.1 && room.mean_lightmap[0] > room.mean_lightmap[2], "{:?}", room.mean_lightmap);
}

#[test]
fn nothing_to_light_the_scene_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let input = fixture("sphere_on_ground.glb");
    let output = bake(dir.path(), &[input.to_str().unwrap(), "-o", "out", "-q"]);
    assert_one_line_error(&output, "nothing lights the scene");
    assert!(!dir.path().join("out").exists());
}

#[test]
fn a_scene_lit_by_its_own_lamps_bakes_without_an_environment_and_keeps_its_energy_balance() {
    use bake::fixtures::{MeshData, Placement, SceneBuilder};
    let dir = tempfile::tempdir().unwrap();
    let mut scene = SceneBuilder::new();
    scene.object("ground", &MeshData::plane(4.0, 4.0, 2), [0.6, 0.6, 0.6, 1.0], [0.0; 3], Placement::default());
    let ball = MeshData::sphere(0.4, 24, 12);
    scene.object("ball", &ball, [0.8, 0.3, 0.3, 1.0], [0.0; 3], Placement::at(glam::Vec3::Y * 0.4));
    let lamp = serde_json::json!({ "type": "point", "intensity": 8.0, "color": [1.0, 0.9, 0.7] });
    scene.light("lamp", lamp, Placement::at(glam::Vec3::new(0.5, 1.5, 0.5)));
    std::fs::write(dir.path().join("lamp.glb"), scene.to_glb()).unwrap();
    let args = ["lamp.glb", "-o", "out", "--max-atlas-size", "64", "--max-shots", "200", "-q"];
    let output = bake(dir.path(), &args);
    assert!(output.status.success(), "bake failed: {}", stderr(&output));
    let report: Report = serde_json::from_slice(&std::fs::read(dir.path().join("out/report.json")).unwrap()).unwrap();
    let scene = &report.scenes[0];
    let punctual = scene.punctual.as_ref().expect("the lamp was baked");
    assert_eq!(punctual.lights, 1);
    assert!(punctual.power_received[0] > 0.0 && scene.bounce.is_some());
    assert!(scene.notices.iter().any(|n| n.contains("1 punctual light(s) (KHR_lights_punctual) are baked")));
    // The energy balance counts the lamp's light as direct light.
    let checked = common::bake_command().current_dir(dir.path()).args(["check", "out/report.json"]).output();
    let checked = checked.unwrap();
    assert!(checked.status.success(), "{}", String::from_utf8_lossy(&checked.stdout));

    // Left out, the lamp no longer lights the scene.
    let small = ["--max-atlas-size", "64", "--lights", "64", "--max-shots", "200"];
    let output = bake(dir.path(), &[&["lamp.glb", "-o", "out2", "--no-punctual-lights", "-q"], &small[..]].concat());
    assert_one_line_error(&output, "nothing lights the scene");
    // Under an environment it is kept, and said so.
    let env = fixture("sky_constant.hdr");
    let args = ["lamp.glb", "--env", env.to_str().unwrap(), "-o", "out3", "--no-punctual-lights"];
    let output = bake(dir.path(), &[&args[..], &small[..]].concat());
    assert!(output.status.success(), "bake failed: {}", stderr(&output));
    assert!(stderr(&output).contains("kept in the output but not baked (--no-punctual-lights)"), "{}", stderr(&output));
    let report: Report = serde_json::from_slice(&std::fs::read(dir.path().join("out3/report.json")).unwrap()).unwrap();
    assert!(report.scenes[0].punctual.is_none());
}
