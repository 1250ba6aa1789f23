//! Light probes (`--probes`): ambient cubes with known answers, against the
//! CPU path tracer, in Bevy's volume layout, and through the CLI.

use std::path::Path;

use bake::environment::{EnvironmentMap, LightMode};
use bake::fixtures::{MeshData, Placement, SceneBuilder, six_wall_room};
use bake::probes::{FACES, ProbeOptions, Probes};
use bake::reference::{Reference, ReferenceOptions, ReferencePoint};
use serde_json::json;

use crate::common;

fn with_probes(atlas: u32, spacing: f64, region: [[f64; 3]; 2]) -> bake::config::BakeOptions {
    let mut options = common::options(atlas);
    options.probes = Some(ProbeOptions { spacing, region: Some(region), rays: 1024 });
    options
}

/// Largest relative difference of any face of any probe from `expected(face)`.
fn worst_face(probes: &Probes, expected: impl Fn(usize) -> f32) -> f32 {
    let mut worst = 0.0f32;
    for faces in &probes.faces {
        for (f, value) in faces.iter().enumerate() {
            for c in value {
                worst = worst.max((c / expected(f) - 1.0).abs());
            }
        }
    }
    worst
}

#[test]
fn probes_over_an_open_field_see_the_sky_above_the_ground_below_and_half_of_each_beside() {
    let gpu = common::gpu();
    let (sky, albedo) = (1.5f32, 0.4f32);
    let mut builder = SceneBuilder::new();
    let grey = [albedo, albedo, albedo, 1.0];
    builder.object("field", &MeshData::plane(400.0, 400.0, 1), grey, [0.0; 3], Placement::default());
    let lights = common::lights(&EnvironmentMap::constant([sky; 3]), LightMode::default());
    let options = with_probes(32, 1.0, [[-1.0, 0.5, -1.0], [1.0, 2.5, 1.0]]);
    let baked = common::bake(&gpu, &builder, &lights, &options);
    let probes = baked.probes.as_ref().expect("probes were asked for");
    assert_eq!(probes.grid.counts, [2, 2, 2]);
    assert!(probes.buried.iter().all(|b| !b), "no probe is inside anything");
    // +Y sees the sky, −Y the field (L_lm = sky, so ρ·sky), the sides half of each.
    let expected = |f: usize| match FACES[f] {
        "+Y" => sky,
        "-Y" => albedo * sky,
        _ => (1.0 + albedo) * sky / 2.0,
    };
    let worst = worst_face(probes, expected);
    eprintln!("open field: worst face {:.3}%", worst * 100.0);
    assert!(worst < 0.01, "a face is {:.2}% off", worst * 100.0);

    // Bevy's layout: probe (x, y, z)'s face along axis a at (x, y + Ry if it
    // looks down the axis, z + a·Rz) of a (Rx, 2Ry, 3Rz) volume.
    let ktx2 = bake::probes::write::encode_ktx2(probes).unwrap();
    let (width, height, depth, texels) = common::read_ktx2(&ktx2);
    assert_eq!((width, height, depth), (2, 4, 6));
    let at = |s: usize, t: usize, p: usize| texels[s + 2 * (t + 4 * p)][0];
    let close = |value: f32, want: f32| (value / want - 1.0).abs() < 0.012;
    for (x, y, z) in [(0, 0, 0), (1, 1, 1), (0, 1, 0)] {
        assert!(close(at(x, y, 2 + z), sky), "+Y of ({x},{y},{z}): {}", at(x, y, 2 + z));
        assert!(close(at(x, y + 2, 2 + z), albedo * sky), "-Y of ({x},{y},{z}): {}", at(x, y + 2, 2 + z));
        assert!(close(at(x, y, z), (1.0 + albedo) * sky / 2.0), "+X of ({x},{y},{z})");
    }
}

#[test]
fn probes_in_a_room_lit_by_its_ceiling_and_a_lamp_agree_with_the_path_tracer() {
    let gpu = common::gpu();
    // Floor, ceiling (glowing), −X (dark), +X, −Z, +Z: every face of a probe differs.
    let mut builder = six_wall_room([(0.7, 0.0), (0.5, 2.0), (0.2, 0.0), (0.8, 0.0), (0.5, 0.0), (0.6, 0.0)]);
    let lamp = json!({ "type": "point", "intensity": 1.0 });
    builder.light("lamp", lamp, Placement::at(glam::Vec3::new(0.1, 0.2, -0.2)));
    let mut options = with_probes(48, 0.8, [[-0.8, -0.8, -0.8], [0.8, 0.8, 0.8]]);
    options.solve.bounce.patches = 256;
    options.solve.bounce.tolerance = 0.002;
    let scene = common::scene(&builder, "room");
    let baked = bake::bake_scene(&gpu, scene, None, &options, &mut bake::progress::Silent).unwrap();
    let probes = baked.probes.as_ref().unwrap();
    assert_eq!(probes.faces.len(), 8);
    let origin = glam::DVec3::from(baked.scene.origin);
    let axes =
        [[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0]];
    let points: Vec<ReferencePoint> = (0..probes.grid.len())
        .flat_map(|i| {
            let p = (probes.grid.position(i) - origin).as_vec3().to_array();
            axes.map(|normal| ReferencePoint { position: p, normal, face_normal: None })
        })
        .collect();
    let reference = Reference::new(&baked.scene, None, &ReferenceOptions { samples: 8192, ..Default::default() });
    let estimates = reference.estimate(&points);
    let mut worst = 0.0f64;
    for (k, e) in estimates.iter().enumerate() {
        let value = f64::from(probes.faces[k / 6][k % 6][0]);
        let noise = e.std_error[0] / e.lightmap[0];
        assert!(noise < 0.01, "the reference's own noise is {:.2}% at {k}", noise * 100.0);
        worst = worst.max((value / e.lightmap[0] - 1.0).abs());
    }
    eprintln!("room: worst face {:.2}% off the path tracer", worst * 100.0);
    assert!(worst < 0.03, "a probe face is {:.2}% off the path tracer", worst * 100.0);
}

/// Bakes a fixture with `--probes` through the CLI into `out`.
fn cli_bake(out: &Path, extra: &[&str]) -> std::process::Output {
    let input = common::fixture("sphere_on_ground.glb");
    common::tiny_bake(&input, out, extra)
}

#[test]
fn the_cli_writes_the_probe_files_and_check_guards_their_values() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let output = cli_bake(&out, &["--probes", "1.0"]);
    assert!(output.status.success(), "{}", common::stderr(&output));
    for ext in ["ktx2", "json", "bin"] {
        assert!(out.join(format!("sphere_on_ground.probes.{ext}")).is_file(), "no .probes.{ext}");
    }
    let header: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("sphere_on_ground.probes.json")).unwrap()).unwrap();
    let counts: Vec<u64> = header["counts"].as_array().unwrap().iter().map(|c| c.as_u64().unwrap()).collect();
    let probes: u64 = counts.iter().product();
    let buried = header["buried"].as_array().unwrap();
    assert!(!buried.is_empty(), "probes inside the sphere are flagged");
    // ... and hold their neighbours' light, not the black inside the sphere.
    let values = std::fs::read(out.join("sphere_on_ground.probes.bin")).unwrap();
    let value = |k: usize| f32::from_le_bytes(values[4 * k..4 * k + 4].try_into().unwrap());
    for i in buried.iter().map(|b| b.as_u64().unwrap() as usize) {
        assert!((0..18).all(|k| value(18 * i + k) > 0.0), "buried probe {i} is shipped black");
    }
    let schema_check = common::node(
        "pipeline/schema.mjs",
        &[common::repo("schema/report.schema.json").as_os_str(), out.join("report.json").as_os_str()],
    );
    let found: serde_json::Value = serde_json::from_str(&schema_check).unwrap();
    let errors = found.as_object().unwrap().values().flat_map(|v| v.as_array().unwrap()).count();
    assert_eq!(errors, 0, "the report does not follow its schema: {schema_check}");
    let gltf = bake::asset::SourceAsset::load(&out.join("sphere_on_ground.glb")).unwrap().json;
    let record = &gltf["scenes"][0]["extras"]["bake"]["probes"];
    assert_eq!(
        (&record["ktx2"], &record["data"]),
        (&json!("sphere_on_ground.probes.ktx2"), &json!("sphere_on_ground.probes.bin"))
    );
    assert_eq!(record["translation"], header["bevy"]["translation"], "the glTF places the volume as the JSON does");
    let report = bake::check::read_report(&out.join("report.json")).unwrap();
    let stats = report.scenes[0].probes.as_ref().unwrap();
    assert_eq!((stats.probes as u64, stats.buried), (probes, buried.len()));

    // Run to run, the same bytes.
    let again = dir.path().join("again");
    assert!(cli_bake(&again, &["--probes", "1.0"]).status.success());
    for ext in ["ktx2", "bin"] {
        let name = format!("sphere_on_ground.probes.{ext}");
        assert_eq!(std::fs::read(out.join(&name)).unwrap(), std::fs::read(again.join(&name)).unwrap(), "{name}");
    }

    let check = |dir: &Path| common::bake_command().arg("check").arg(dir.join("report.json")).output().unwrap();
    assert_eq!(check(&out).status.code(), Some(0), "{}", String::from_utf8_lossy(&check(&out).stdout));
    // A NaN or a negative face, a short file or none at all fails the check.
    let bin = out.join("sphere_on_ground.probes.bin");
    let good = std::fs::read(&bin).unwrap();
    for (what, bytes) in [
        ("NaN", [&good[..40], &f32::NAN.to_le_bytes(), &good[44..]].concat()),
        ("negative", [&good[..40], &(-1.0f32).to_le_bytes(), &good[44..]].concat()),
        ("short", good[..good.len() - 72].to_vec()),
    ] {
        std::fs::write(&bin, &bytes).unwrap();
        let result = check(&out);
        assert_eq!(result.status.code(), Some(1), "{what}: {}", String::from_utf8_lossy(&result.stdout));
        assert!(String::from_utf8_lossy(&result.stdout).contains("probes"), "{what}");
    }
    // A count whose bytes a 64-bit product would wrap to the file's length (2^62 · 72 to 0).
    let report_path = out.join("report.json");
    let original = std::fs::read(&report_path).unwrap();
    let mut report: serde_json::Value = serde_json::from_slice(&original).unwrap();
    report["scenes"][0]["probes"]["probes"] = json!(1u64 << 62);
    std::fs::write(&report_path, serde_json::to_vec(&report).unwrap()).unwrap();
    std::fs::write(&bin, b"").unwrap();
    assert_eq!(check(&out).status.code(), Some(1), "2^62 probes in an empty file");
    std::fs::write(&report_path, original).unwrap();
    std::fs::remove_file(&bin).unwrap();
    assert_eq!(check(&out).status.code(), Some(1), "a missing probe file");
}

#[test]
fn bad_probe_options_are_refused_with_one_line_and_nothing_written() {
    let dir = tempfile::tempdir().unwrap();
    for args in [
        &["--probes", "0"][..],
        &["--probes", "-1"],
        &["--probes", "nan"],
        &["--probes", "1", "--probe-box", "0,0,0,1,1"],
        &["--probes", "1", "--probe-box", "0,0,0,-1,1,1"],
        &["--probe-box", "0,0,0,1,1,1"],
        &["--probes", "1", "--probe-rays", "0"],
        &["--probes", "0.0001"],
    ] {
        let out = dir.path().join("out");
        let output = cli_bake(&out, args);
        let stderr = common::stderr(&output);
        assert_eq!(output.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains("probe"), "{args:?} names the option: {stderr}");
        assert!(!out.exists(), "{args:?} left {out:?} behind");
    }
}
