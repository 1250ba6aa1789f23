//! A GPU lost in the middle of a bake (driver reset, unplugged or crashed
//! GPU) ends the run like any other failure: within seconds, exit code 2,
//! one line naming the input, the stage and the adapter, and nothing
//! written: no partial files, no staging folder, earlier outputs untouched.
//!
//! The loss is made by the test hook `BAKE_TEST_LOSE_DEVICE=<stage>`, which
//! destroys the device at that stage's first wait for GPU work (see
//! `Gpu::wait`). A GPU that stops answering without a loss is given up on
//! after `--gpu-timeout` and ends the same way.

use std::path::{Path, PathBuf};
use std::process::Stdio;
use std::time::{Duration, Instant};

use crate::common::{self, fixture};
use bake::fixtures::{MeshData, Placement, SceneBuilder};
use bake::gpu::LOSE_DEVICE_HOOK;

/// Far longer than any of these bakes takes (under 2 s each): past it, the run hangs.
const HANG: Duration = Duration::from_secs(120);

/// What a run left: exit code and stderr.
struct Run {
    code: Option<i32>,
    stderr: String,
}

/// Runs `bake ARGS -o OUT -q` (a small atlas and light budget unless ARGS
/// set them) in `dir`, with the device lost at `lose_at` if given; fails the
/// test if it hangs.
fn bake(dir: &Path, args: &[&str], out: &Path, lose_at: Option<&str>) -> Run {
    let mut command = common::bake_command();
    command.current_dir(dir).args(args).arg("-o").arg(out).arg("-q");
    for default in [["--max-atlas-size", "64"], ["--lights", "32"], ["--max-shots", "256"]] {
        if !args.contains(&default[0]) {
            command.args(default);
        }
    }
    command.env_remove(LOSE_DEVICE_HOOK);
    if let Some(stage) = lose_at {
        command.env(LOSE_DEVICE_HOOK, stage);
    }
    let mut child = command.stdout(Stdio::null()).stderr(Stdio::piped()).spawn().expect("bake runs");
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if start.elapsed() > HANG {
            child.kill().unwrap();
            panic!("bake {args:?} with the device lost at {lose_at:?} still runs after {HANG:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut stderr = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut stderr).unwrap();
    eprintln!("{:?} in {:.2} s: {}", lose_at, start.elapsed().as_secs_f64(), stderr.trim_end());
    Run { code: status.code(), stderr }
}

/// Every file under `dir` with its bytes, sorted by path (empty if `dir` does not exist).
fn contents(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut found = Vec::new();
    let mut pending = vec![dir.to_path_buf()];
    while let Some(folder) = pending.pop() {
        let Ok(entries) = std::fs::read_dir(&folder) else { continue };
        for entry in entries {
            let path = entry.unwrap().path();
            if path.is_dir() {
                found.push((path.clone(), Vec::new()));
                pending.push(path);
            } else {
                found.push((path.clone(), std::fs::read(&path).unwrap()));
            }
        }
    }
    found.sort();
    found
}

/// The run failed as a lost device should: code 2, one line naming the
/// input, the stage and the loss.
fn assert_lost(run: &Run, input: &str, stage: &str) {
    assert_eq!(run.code, Some(2), "{}", run.stderr);
    let lines: Vec<&str> = run.stderr.lines().collect();
    assert_eq!(lines.len(), 1, "one line only: {}", run.stderr);
    let line = lines[0];
    assert!(line.starts_with("bake: error: "), "{line}");
    assert!(line.contains(&format!("input '{input}'")), "the error does not name the input: {line}");
    assert!(line.contains(&format!("{stage}: GPU device lost on ")), "the error does not name the stage: {line}");
}

/// A closed room lit only by an emissive panel: its solve is all bounce passes.
fn lamp_room() -> Vec<u8> {
    let mut scene = SceneBuilder::new();
    scene.object("room", &MeshData::room([4.0, 3.0, 4.0]), [0.7, 0.7, 0.7, 1.0], [0.0; 3], Placement::default());
    let down = glam::Quat::from_rotation_x(std::f32::consts::PI);
    let at = Placement::at(glam::Vec3::new(0.0, 1.45, 0.0)).rotated(down);
    scene.object("lamp", &MeshData::plane(1.0, 1.0, 1), [0.0, 0.0, 0.0, 1.0], [20.0; 3], at);
    scene.to_glb()
}

#[test]
fn a_device_lost_in_any_gpu_stage_ends_the_bake_with_one_line_and_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let sky = fixture("sky_sun.exr");
    let sky = sky.to_str().unwrap();
    std::fs::copy(fixture("sphere_on_ground.glb"), dir.path().join("scene.glb")).unwrap();
    std::fs::write(dir.path().join("lamp.glb"), lamp_room()).unwrap();
    let cases: [(&str, Vec<&str>); 3] = [
        // Rasterizing texels; the direct pass of the solve; the bounce passes of a lamp-lit room.
        ("texelize", vec!["scene.glb", "--env", sky]),
        ("solve", vec!["scene.glb", "--env", sky]),
        ("solve", vec!["lamp.glb"]),
    ];
    for (stage, args) in &cases {
        let before = contents(dir.path());
        let run = bake(dir.path(), args, Path::new("out"), Some(stage));
        assert_lost(&run, args[0], stage);
        assert_eq!(contents(dir.path()), before, "the run left files behind (or changed some)");
    }
}

#[test]
fn a_device_lost_mid_bake_leaves_earlier_outputs_as_they_were() {
    let dir = tempfile::tempdir().unwrap();
    let sky = fixture("sky_sun.exr");
    let args = ["scene.glb", "--env", sky.to_str().unwrap()];
    std::fs::copy(fixture("sphere_on_ground.glb"), dir.path().join("scene.glb")).unwrap();
    let out = dir.path().join("out");
    // The same bake without the hook succeeds: the hook is what fails it below.
    let good = bake(dir.path(), &args, &out, None);
    assert_eq!(good.code, Some(0), "{}", good.stderr);
    let written = contents(&out);
    assert!(written.iter().any(|(p, _)| p.ends_with("scene.glb")), "{written:?}");

    let run = bake(dir.path(), &args, &out, Some("solve"));
    assert_lost(&run, "scene.glb", "solve");
    assert_eq!(contents(&out), written, "the failed run changed the output folder");
}

#[test]
fn a_gpu_that_does_not_answer_within_the_timeout_ends_the_bake_with_one_line_and_no_output() {
    // A hung driver that never reports a lost device would block a build
    // forever; `--gpu-timeout` bounds every wait. One microsecond is shorter
    // than the GPU work of a 1024² atlas, so the first wait (in texelize, or
    // the solve if the driver were that fast) gives up, as a wait on a hung
    // GPU would. (A 64² atlas's work can finish before the first wait.)
    let dir = tempfile::tempdir().unwrap();
    let sky = fixture("sky_sun.exr");
    std::fs::copy(fixture("sphere_on_ground.glb"), dir.path().join("scene.glb")).unwrap();
    let before = contents(dir.path());
    let args = ["scene.glb", "--env", sky.to_str().unwrap(), "--gpu-timeout", "0.000001", "--max-atlas-size", "1024"];
    let run = bake(dir.path(), &args, Path::new("out"), None);
    let stage = if run.stderr.contains("texelize: ") { "texelize" } else { "solve" };
    assert_lost(&run, "scene.glb", stage);
    assert!(run.stderr.contains("within 0.000001 s (--gpu-timeout)"), "the error names the limit: {}", run.stderr);
    assert_eq!(contents(dir.path()), before, "the run left files behind (or changed some)");
}
