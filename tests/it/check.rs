//! `bake check` as CI runs it, on real fixture bakes: a report passes against
//! itself; a mesh whose energy moved by 5% fails with the mesh named; a NaN
//! texel (in the report or in the lightmap EXR) fails with the mesh named;
//! broken energy invariants fail; every fixture's bake keeps them; and the
//! exit codes are the documented ones (0 pass, 1 check failed, 2 error).

use std::path::Path;

use crate::common::{self, fixture, run_bake as run};
use serde_json::Value;

fn check(dir: &Path, args: &[&str]) -> (Option<i32>, String) {
    let mut full = vec!["check"];
    full.extend_from_slice(args);
    let output = run(dir, &full);
    let text = format!("{}{}", String::from_utf8_lossy(&output.stdout), String::from_utf8_lossy(&output.stderr));
    eprintln!("$ bake {}\n{text}", full.join(" "));
    (output.status.code(), text)
}

/// A tiny bake of sphere_on_ground (meshes "ground#0" and "sphere#0") into `dir/out`.
fn bake_fixture(dir: &Path) {
    let input = fixture("sphere_on_ground.glb");
    let env = fixture("sky_sun.exr");
    let output = run(
        dir,
        &[
            input.to_str().unwrap(),
            "--env",
            env.to_str().unwrap(),
            "-o",
            "out",
            "--max-atlas-size",
            "64",
            "--lights",
            "64",
            "--max-shots",
            "64",
            "-q",
        ],
    );
    assert!(output.status.success(), "bake failed: {}", String::from_utf8_lossy(&output.stderr));
}

fn read(path: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

fn write(path: &Path, value: &Value) {
    std::fs::write(path, serde_json::to_vec_pretty(value).unwrap()).unwrap();
}

/// The index of the primitive named `name` in scene 0.
fn mesh(report: &Value, name: &str) -> usize {
    report["scenes"][0]["energy"].as_array().unwrap().iter().position(|p| p["name"] == name).expect(name)
}

/// Multiplies every energy figure of primitive `p` of scene 0 by `factor`.
fn scale_mesh(report: &mut Value, p: usize, factor: f64) {
    let entry = &mut report["scenes"][0]["energy"][p];
    for key in ["mean_lightmap", "sum_lightmap", "power_received", "power_reflected"] {
        for c in entry[key].as_array_mut().unwrap() {
            *c = (c.as_f64().unwrap() * factor).into();
        }
    }
    for key in ["min_luminance", "p1_luminance", "p50_luminance", "p99_luminance", "max_luminance"] {
        entry[key] = (entry[key].as_f64().unwrap() * factor).into();
    }
}

#[test]
fn a_report_passes_against_itself() {
    let dir = tempfile::tempdir().unwrap();
    bake_fixture(dir.path());
    let (code, text) = check(dir.path(), &["out/report.json", "--against", "out/report.json"]);
    assert_eq!(code, Some(0), "{text}");
    assert!(text.starts_with("PASS: 1 scene(s), 2 mesh(es)"), "{text}");
    assert!(text.contains("2 lightmap file(s) read"), "the EXR and the KTX2 beside the report were checked: {text}");
    // The same through the baked GLB, and with the invariants alone.
    assert_eq!(check(dir.path(), &["out/sphere_on_ground.glb", "--against", "out/report.json"]).0, Some(0));
    assert_eq!(check(dir.path(), &["out/sphere_on_ground.glb"]).0, Some(0));
    let (code, text) = check(dir.path(), &["out/report.json", "--against", "out/report.json", "--quiet"]);
    assert_eq!((code, text.as_str()), (Some(0), ""), "--quiet prints nothing on success");
}

#[test]
fn a_mesh_whose_energy_moved_by_5_percent_fails_with_the_mesh_named() {
    let dir = tempfile::tempdir().unwrap();
    bake_fixture(dir.path());
    let golden = read(&dir.path().join("out/report.json"));
    write(&dir.path().join("golden.json"), &golden);
    let mut moved = golden.clone();
    let sphere = mesh(&moved, "sphere#0");
    scale_mesh(&mut moved, sphere, 1.05);
    write(&dir.path().join("out/report.json"), &moved);

    let (code, text) = check(dir.path(), &["out/report.json", "--against", "golden.json"]);
    assert_eq!(code, Some(1), "{text}");
    assert!(text.starts_with("12 figure(s) moved beyond ±2%:"), "{text}");
    let rows: Vec<&str> = text.lines().skip(2).take_while(|l| l.starts_with("  ")).collect();
    // mean L_lm, power received and reflected (3 channels each), p1, p50, p99 luminance.
    assert_eq!(rows.len(), 12, "{text}");
    assert!(rows.iter().all(|r| r.contains("sphere#0") && r.trim_end().ends_with("+5.00%")), "{text}");
    assert!(!text.contains("ground#0"), "the mesh that did not move is not listed: {text}");
    assert!(text.contains("mean L_lm r") && text.contains("power received g") && text.contains("p50 luminance"));
    assert!(text.lines().last().unwrap().starts_with("FAIL"), "{text}");

    // Within a wider tolerance it passes; 1% passes the default 2%.
    assert_eq!(check(dir.path(), &["out/report.json", "--against", "golden.json", "--tolerance", "6%"]).0, Some(0));
    let mut small = golden.clone();
    scale_mesh(&mut small, sphere, 1.01);
    write(&dir.path().join("out/report.json"), &small);
    assert_eq!(check(dir.path(), &["out/report.json", "--against", "golden.json"]).0, Some(0));
    assert_eq!(check(dir.path(), &["out/report.json", "--against", "golden.json", "--tolerance", "0.005"]).0, Some(1));

    // A mesh that disappeared is named too.
    let mut fewer = golden.clone();
    fewer["scenes"][0]["energy"].as_array_mut().unwrap().remove(sphere);
    write(&dir.path().join("out/report.json"), &fewer);
    let (code, text) = check(dir.path(), &["out/report.json", "--against", "golden.json"]);
    assert_eq!(code, Some(1));
    assert!(text.lines().any(|l| l.contains("sphere#0") && l.contains("missing")), "{text}");
}

#[test]
fn a_nan_texel_fails_with_the_mesh_named() {
    let dir = tempfile::tempdir().unwrap();
    bake_fixture(dir.path());
    let report_path = dir.path().join("out/report.json");
    let report = read(&report_path);
    let sphere = mesh(&report, "sphere#0");

    // In the lightmap EXR: checked through the baked GLB.
    let exr_path = dir.path().join("out/sphere_on_ground.lightmap0.exr");
    let image = exr::prelude::read_first_rgba_layer_from_file(
        &exr_path,
        |size, _| (size.width(), size.height(), vec![[0f32; 3]; size.width() * size.height()]),
        |(w, _, pixels), p, (r, g, b, _a): (f32, f32, f32, f32)| pixels[p.y() * *w + p.x()] = [r, g, b],
    )
    .unwrap();
    let (width, height, mut pixels) = image.layer_data.channel_data.pixels;
    let bounds: Vec<usize> = report["scenes"][0]["energy"][sphere]["atlas_bounds"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap() as usize)
        .collect();
    let (x, y) = ((bounds[0] + bounds[2]) / 2, (bounds[1] + bounds[3]) / 2);
    pixels[y * width + x][1] = f32::NAN;
    exr::prelude::write_rgb_file(&exr_path, width, height, |px, py| {
        let p = pixels[py * width + px];
        (p[0], p[1], p[2])
    })
    .unwrap();
    let (code, text) = check(dir.path(), &["out/sphere_on_ground.glb", "--against", "out/report.json"]);
    assert_eq!(code, Some(1), "{text}");
    let line = text.lines().find(|l| l.contains("NaN")).expect("a line about the NaN texel");
    assert!(line.contains(&format!("texel ({x}, {y})")) && line.contains("sphere#0"), "{line}");
    assert!(line.contains("sphere_on_ground.lightmap0.exr"), "{line}");

    // In the report: a mesh with an invalid texel.
    let mut invalid = report.clone();
    invalid["scenes"][0]["energy"][sphere]["invalid_texels"] = 1.into();
    write(&dir.path().join("invalid.json"), &invalid);
    let (code, text) = check(dir.path(), &["invalid.json"]);
    assert_eq!(code, Some(1), "{text}");
    assert!(text.contains("invariant: sphere_on_ground: mesh sphere#0: 1 of its"), "{text}");
    assert!(text.contains("NaN, infinite or negative"), "{text}");
}

#[test]
fn a_ktx2_lightmap_unlike_its_exr_fails() {
    // The KTX2 holds the EXR's texels packed as E5B9G9R9, bit for bit: one
    // texel changed, the whole map times pi, another size, a damaged or huge
    // file or none at all each fail the check, naming the file.
    let dir = tempfile::tempdir().unwrap();
    bake_fixture(dir.path());
    let ktx2_path = dir.path().join("out/sphere_on_ground.lightmap0.ktx2");
    let original = std::fs::read(&ktx2_path).unwrap();
    let (width, pixels) = common::read_exr(&dir.path().join("out/sphere_on_ground.lightmap0.exr"));
    let height = pixels.len() / width;
    let lit = pixels.iter().position(|p| p[0] > 0.0).expect("a lit texel");
    let mut one_texel = pixels.clone();
    one_texel[lit][0] *= 1.01;
    let times_pi: Vec<[f32; 3]> = pixels.iter().map(|p| p.map(|c| c * std::f32::consts::PI)).collect();
    let encode = |w: usize, h: usize, p: &[[f32; 3]]| bake::export::ktx2::encode(w as u32, h as u32, p).unwrap();
    let cases: [(&str, Option<Vec<u8>>, &str); 6] = [
        ("one texel", Some(encode(width, height, &one_texel)), "1 texels differ from the EXR's"),
        ("times pi", Some(encode(width, height, &times_pi)), "texels differ from the EXR's"),
        ("a row short", Some(encode(width, height - 1, &pixels[width..])), "but the atlas is"),
        ("cut short", Some(original[..original.len() / 2].to_vec()), "sphere_on_ground.lightmap0.ktx2: "),
        ("too large to be its texels", Some(vec![0; 4 * pixels.len() + (65 << 10)]), "bytes, more than"),
        ("gone", None, "is missing"),
    ];
    let (code, text) = check(dir.path(), &["out/report.json"]);
    assert_eq!(code, Some(0), "the bake as written: {text}");
    for (what, bytes, needle) in cases {
        match bytes {
            Some(bytes) => std::fs::write(&ktx2_path, bytes).unwrap(),
            None => std::fs::remove_file(&ktx2_path).unwrap(),
        }
        let (code, text) = check(dir.path(), &["out/report.json"]);
        assert_eq!(code, Some(1), "{what}: {text}");
        let line = text.lines().find(|l| l.contains("lightmap0.ktx2")).unwrap_or_else(|| panic!("{what}: {text}"));
        assert!(line.contains(needle), "{what}: {line}");
    }
}

#[test]
fn broken_energy_invariants_fail() {
    let dir = tempfile::tempdir().unwrap();
    bake_fixture(dir.path());
    let report = read(&dir.path().join("out/report.json"));
    let ground = mesh(&report, "ground#0");
    let cases: [(&str, &str, f64, &str); 4] = [
        ("reflected power above albedo × received", "/scenes/0/energy/G/power_reflected/0", 1.5, "reflected power"),
        ("bounced light lost", "/scenes/0/atlas/energy/power_received/1", 0.9, "emitted power not accounted for"),
        ("a texel lost from the meshes", "/scenes/0/energy/G/texels", 0.5, "covered texels do not add up"),
        ("environment energy lost", "/environment/captured/2", 0.9, "extraction lost or made energy"),
    ];
    for (what, pointer, factor, needle) in cases {
        let mut broken = report.clone();
        let value = broken.pointer_mut(&pointer.replace('G', &ground.to_string())).expect(pointer);
        *value = if value.is_u64() {
            ((value.as_u64().unwrap() as f64 * factor) as u64).into()
        } else {
            (value.as_f64().unwrap() * factor).into()
        };
        write(&dir.path().join("broken.json"), &broken);
        let (code, text) = check(dir.path(), &["broken.json"]);
        assert_eq!(code, Some(1), "{what}: {text}");
        assert!(text.contains(needle), "{what}: {text}");
    }
}

#[test]
fn an_emitter_lit_room_keeps_its_energy_balance() {
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
    let output = run(dir.path(), &["lamp_room.glb", "-o", "out", "--max-atlas-size", "64", "--max-shots", "64", "-q"]);
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let (code, text) = check(dir.path(), &["out/lamp_room.glb"]);
    assert_eq!(code, Some(0), "{text}");

    let typed: bake::report::Report =
        serde_json::from_slice(&std::fs::read(dir.path().join("out/report.json")).unwrap()).unwrap();
    let balance = bake::check::energy_balance(&typed.scenes[0]).unwrap();
    eprintln!("{balance:?}");
    assert!(balance.closure > 0.9, "a closed room catches nearly all the light its lamp sends out");
    // The lamp's light lost on the way: received power without the emitted power that made it.
    let mut lost = read(&dir.path().join("out/report.json"));
    for c in lost.pointer_mut("/scenes/0/atlas/energy/power_emitted").unwrap().as_array_mut().unwrap() {
        *c = (c.as_f64().unwrap() * 2.0).into();
    }
    write(&dir.path().join("lost.json"), &lost);
    let (code, text) = check(dir.path(), &["lost.json"]);
    assert_eq!(code, Some(1), "{text}");
    assert!(text.contains("emitted power not accounted for"), "{text}");
}

#[test]
fn a_lone_quad_under_a_point_light_bounces_nothing_and_passes() {
    // Nothing sees anything. Under an environment, the bounce pass converges
    // before its first shot, and its closure is the scene's coverage (0),
    // not a closed room's 1. Without one, no direct pass measured the
    // coverage: each patch measures its own on its first shot, and the pass
    // converges then. (A white quad shot 64 times a patch, its cap, waiting
    // on light shot ahead that could not land.)
    use bake::fixtures::{MeshData, Placement, SceneBuilder};
    let dir = tempfile::tempdir().unwrap();
    let mut scene = SceneBuilder::new();
    scene.object("quad", &MeshData::plane(4.0, 4.0, 1), [1.0; 4], [0.0; 3], Placement::default());
    scene.light("lamp", serde_json::json!({ "type": "point", "intensity": 20.0 }), Placement::at(glam::Vec3::Y));
    std::fs::write(dir.path().join("quad.glb"), scene.to_glb()).unwrap();
    let env = fixture("sky_constant.hdr");
    for with_env in [true, false] {
        let mut args = vec!["quad.glb", "-o", "out", "--max-atlas-size", "64", "--lights", "16", "-q"];
        if with_env {
            args.extend(["--env", env.to_str().unwrap()]);
        }
        let output = run(dir.path(), &args);
        assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
        let (code, text) = check(dir.path(), &["out/report.json"]);
        assert_eq!(code, Some(0), "{text}");
        let typed: bake::report::Report =
            serde_json::from_slice(&std::fs::read(dir.path().join("out/report.json")).unwrap()).unwrap();
        let bounce = typed.scenes[0].bounce.as_ref().expect("a point light's light may bounce: the pass runs");
        assert_eq!(bounce.stopped_by, bake::solve::StopReason::Converged);
        if with_env {
            assert_eq!(bounce.shots, 0);
        } else {
            assert!(bounce.shots <= 2 * bounce.patches as u64, "{} shots, {} patches", bounce.shots, bounce.patches);
        }
        assert!(bounce.closure < 1e-3 && bounce.shot_closure < 1e-3, "{} {}", bounce.closure, bounce.shot_closure);
    }
}

#[test]
fn a_point_light_on_a_white_box_s_top_face_keeps_the_energy_balance() {
    // The pass converges owing light it shot ahead and never received; the
    // ambient term takes it back (clamped at 0, it stayed in the lightmap
    // and the bounced share came out 1.3 % over the shots').
    use bake::fixtures::{MeshData, Placement, SceneBuilder};
    let dir = tempfile::tempdir().unwrap();
    let mut scene = SceneBuilder::new();
    let white = [1.0; 4];
    scene.object("ground", &MeshData::plane(4.0, 4.0, 1), white, [0.0; 3], Placement::default());
    scene.object("box", &MeshData::cuboid([1.0, 1.0, 1.0]), white, [0.0; 3], Placement::at(glam::Vec3::Y * 0.5));
    scene.light("lamp", serde_json::json!({ "type": "point", "intensity": 100.0 }), Placement::at(glam::Vec3::Y));
    std::fs::write(dir.path().join("lamp.glb"), scene.to_glb()).unwrap();
    let env = fixture("sky_sun.exr");
    let args =
        ["lamp.glb", "--env", env.to_str().unwrap(), "-o", "out", "--max-atlas-size", "64", "--lights", "64", "-q"];
    let output = run(dir.path(), &args);
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let (code, text) = check(dir.path(), &["out/report.json"]);
    assert_eq!(code, Some(0), "{text}");
}

#[test]
fn surfaces_laid_twice_or_just_over_one_another_keep_the_energy_balance() {
    // Where two surfaces coincide each receives the place's light but
    // bounces half of it; a slab 1 mm over the ground hides what is under
    // it. The energy sums weigh texels as the bounce pass does.
    use bake::fixtures::{MeshData, Placement, SceneBuilder};
    let env = fixture("sky_sun.exr");
    for (name, slab) in [("twice", 0.0), ("slab", 0.001)] {
        let dir = tempfile::tempdir().unwrap();
        let mut scene = SceneBuilder::new();
        let grey = [0.7, 0.7, 0.7, 1.0];
        scene.object("ground", &MeshData::plane(4.0, 4.0, 2), grey, [0.0; 3], Placement::default());
        let over = Placement::at(glam::Vec3::Y * slab);
        let size = if slab > 0.0 { 2.0 } else { 4.0 };
        scene.object("over", &MeshData::plane(size, size, 2), grey, [0.0; 3], over);
        let block = Placement::at(glam::Vec3::new(1.0, 0.5, 1.0));
        scene.object("box", &MeshData::cuboid([1.0; 3]), grey, [0.0; 3], block);
        std::fs::write(dir.path().join("scene.glb"), scene.to_glb()).unwrap();
        let args = ["scene.glb", "--env", env.to_str().unwrap(), "-o", "out", "--max-atlas-size", "64", "-q"];
        let output = run(dir.path(), &[&args[..], &["--lights", "64"]].concat());
        assert!(output.status.success(), "{name}: {}", String::from_utf8_lossy(&output.stderr));
        let (code, text) = check(dir.path(), &["out/report.json"]);
        assert_eq!(code, Some(0), "{name}: {text}");
    }
}

#[test]
fn every_fixture_keeps_the_invariants_as_the_ci_example_bakes_it() {
    // pipeline/ci-example.yml's options, the contact fix-up on: the crates
    // and the ball of `everything` and `corner` touch the ground, where the
    // fix-up traces light no shot of the bounce pass carried.
    // One run of all four, as a build step bakes them (and one start-up).
    let dir = tempfile::tempdir().unwrap();
    let env = fixture("sky_sun.exr");
    let scenes = ["corner.glb", "everything.glb", "sphere.glb", "sphere_on_ground.glb"].map(fixture);
    let mut args: Vec<&str> = scenes.iter().map(|s| s.to_str().unwrap()).collect();
    args.extend(["--env", env.to_str().unwrap(), "-o", "out", "-q", "--max-atlas-size", "128", "--lights", "256"]);
    let output = run(dir.path(), &args);
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let (code, text) = check(dir.path(), &["out/report.json"]);
    assert_eq!(code, Some(0), "{text}");
    assert!(text.contains("PASS: 4 scene(s)"), "{text}");
}

#[test]
fn a_report_never_leads_check_to_read_outside_its_folder() {
    // Scene names place the lightmaps check re-reads: one that climbs out
    // ('../leak') or a lightmap linked to a file outside is refused (exit 2),
    // not read.
    let dir = tempfile::tempdir().unwrap();
    bake_fixture(dir.path());
    let d = dir.path();
    for ext in ["exr", "ktx2"] {
        let from = d.join(format!("out/sphere_on_ground.lightmap0.{ext}"));
        std::fs::copy(&from, d.join(format!("leak.lightmap0.{ext}"))).unwrap();
    }
    std::fs::create_dir(d.join("climbs")).unwrap();
    let mut report = read(&d.join("out/report.json"));
    report["scenes"][0]["name"] = "../leak".into();
    write(&d.join("climbs/report.json"), &report);
    let (code, text) = check(d, &["climbs/report.json"]);
    assert_eq!(code, Some(2), "{text}");
    assert!(text.contains("report 'climbs/report.json': scene 0 is named '../leak', which is no file name"), "{text}");

    std::fs::create_dir(d.join("linked")).unwrap();
    std::fs::copy(d.join("out/report.json"), d.join("linked/report.json")).unwrap();
    for ext in ["exr", "ktx2"] {
        let target = d.join(format!("out/sphere_on_ground.lightmap0.{ext}"));
        std::os::unix::fs::symlink(target, d.join(format!("linked/sphere_on_ground.lightmap0.{ext}"))).unwrap();
    }
    let (code, text) = check(d, &["linked/report.json"]);
    assert_eq!(code, Some(2), "{text}");
    assert!(text.contains("resolves outside the report's folder (through a symbolic link): not read"), "{text}");
    assert_eq!(check(d, &["out/report.json"]).0, Some(0), "the bake's own folder passes");
}

#[test]
fn names_a_report_holds_are_printed_with_control_characters_escaped() {
    // A report is input to `bake check`: its names must not split the
    // table's rows or send the terminal an escape sequence (here, clear screen).
    let dir = tempfile::tempdir().unwrap();
    bake_fixture(dir.path());
    let d = dir.path();
    let mut moved = read(&d.join("out/report.json"));
    scale_mesh(&mut moved, 0, 1.2);
    moved["scenes"][0]["energy"][0]["name"] = "ground\u{1b}[2J\nX".into();
    write(&d.join("moved.json"), &moved);
    let (code, text) = check(d, &["out/report.json", "--against", "moved.json"]);
    assert_eq!(code, Some(1), "{text}");
    assert!(!text.contains('\x1b'), "an escape sequence reached the terminal: {text:?}");
    assert!(text.lines().any(|l| l.contains("ground\\u{1b}[2J\\nX (node 0") && l.contains('%')), "{text}");
}

#[test]
fn exit_codes_are_the_documented_ones() {
    let dir = tempfile::tempdir().unwrap();
    bake_fixture(dir.path());
    let d = dir.path();
    assert_eq!(check(d, &["out/report.json", "--against", "out/report.json"]).0, Some(0), "pass");
    let mut moved = read(&d.join("out/report.json"));
    scale_mesh(&mut moved, 0, 1.2);
    write(&d.join("moved.json"), &moved);
    assert_eq!(check(d, &["moved.json", "--against", "out/report.json"]).0, Some(1), "check failed");

    std::fs::write(d.join("notes.json"), "not json").unwrap();
    std::fs::create_dir(d.join("lonely")).unwrap();
    std::fs::copy(d.join("out/sphere_on_ground.glb"), d.join("lonely/sphere_on_ground.glb")).unwrap();
    let mut old = read(&d.join("out/report.json"));
    old["schema_version"] = 1.into();
    write(&d.join("old.json"), &old);
    for (args, needle) in [
        (&["nowhere.json"][..], "nowhere.json"),
        (&["out/report.json", "--against", "nowhere.json"], "nowhere.json"),
        (&["out/report.json", "--against", "notes.json"], "notes.json"),
        (&["lonely/sphere_on_ground.glb"], "no report.json beside it"),
        (&["out/report.json", "--against", "old.json"], "schema version 1"),
        (&["out/report.json", "--tolerance", "two"], "tolerance"),
    ] {
        let (code, text) = check(d, args);
        assert_eq!(code, Some(2), "{args:?}: {text}");
        assert!(text.contains(needle), "{args:?} does not say '{needle}': {text}");
        assert_eq!(text.lines().filter(|l| l.contains("error")).count(), 1, "one error line: {text}");
    }

    let help = String::from_utf8_lossy(&run(d, &["check", "--help"]).stdout).into_owned();
    assert!(help.contains("Exit codes: 0 pass, 1 check failed"), "{help}");
    assert!(help.contains("2 error"), "{help}");
    let readme = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("README.md")).unwrap();
    for code in ["| 0 |", "| 1 |", "| 2 |"] {
        assert!(readme.contains(code), "README's exit-code table lacks {code}");
    }
}
