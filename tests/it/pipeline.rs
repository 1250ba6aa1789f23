//! The build-step example in `pipeline/` as a project would use it: a copy
//! of `pipeline/Makefile` in a fresh folder with two fixture assets bakes
//! both, skips both on a second run, bakes again only the asset that changed,
//! bakes both again when the options change, and its `golden` and `check`
//! targets run `bake check` against the golden reports.

use std::path::Path;
use std::process::{Command, Output};
use std::time::{Duration, SystemTime};

use crate::common::repo;

const OPTIONS: &str = "--max-atlas-size 64 --lights 64 --max-shots 64";

fn make(dir: &Path, options: &str, target: &str) -> Output {
    let output = Command::new("make")
        .current_dir(dir)
        .args(["--no-print-directory", target])
        .arg(format!("BAKE={}", env!("CARGO_BIN_EXE_bake")))
        .arg("ENV=sky.hdr")
        .arg(format!("OPTIONS={options}"))
        .output()
        .expect("make runs (pipeline/setup.sh installs it)");
    eprintln!(
        "$ make {target}\n{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    output
}

/// The assets whose bake ran, by the `-o baked/<name>` of each bake command make printed.
fn baked(output: &Output) -> Vec<String> {
    assert!(output.status.success(), "make failed: {}", String::from_utf8_lossy(&output.stderr));
    let mut names: Vec<String> = String::from_utf8_lossy(&output.stdout)
        .lines()
        .filter_map(|l| l.split(" -o baked/").nth(1))
        .map(|rest| rest.split_whitespace().next().unwrap().to_string())
        .collect();
    names.sort();
    names
}

fn modified(path: &Path) -> SystemTime {
    std::fs::metadata(path).unwrap().modified().unwrap()
}

#[test]
fn the_makefile_bakes_only_what_changed() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::copy(repo("pipeline/Makefile"), d.join("Makefile")).unwrap();
    std::fs::create_dir(d.join("assets")).unwrap();
    for asset in ["sphere.glb", "sphere_on_ground.glb"] {
        std::fs::copy(repo("fixtures").join(asset), d.join("assets").join(asset)).unwrap();
    }
    std::fs::copy(repo("fixtures/sky_sun.hdr"), d.join("sky.hdr")).unwrap();

    assert_eq!(baked(&make(d, OPTIONS, "all")), ["sphere", "sphere_on_ground"]);
    let report = d.join("baked/sphere_on_ground/report.json");
    assert!(d.join("baked/sphere_on_ground/sphere_on_ground.glb").is_file());
    let first = modified(&report);

    assert_eq!(baked(&make(d, OPTIONS, "all")), Vec::<String>::new(), "nothing changed: nothing is baked");
    assert_eq!(modified(&report), first);

    // Coarse file-system clocks: let a second pass before changing inputs.
    std::thread::sleep(Duration::from_millis(1100));
    let asset = d.join("assets/sphere.glb");
    std::fs::write(&asset, std::fs::read(&asset).unwrap()).unwrap();
    assert_eq!(baked(&make(d, OPTIONS, "all")), ["sphere"], "only the changed asset is baked again");
    assert_eq!(modified(&report), first);

    let wider = format!("{OPTIONS} --padding 3");
    assert_eq!(baked(&make(d, &wider, "all")), ["sphere", "sphere_on_ground"], "new options bake everything");
    assert_eq!(baked(&make(d, &wider, "all")), Vec::<String>::new());

    std::thread::sleep(Duration::from_millis(1100));
    std::fs::write(d.join("sky.hdr"), std::fs::read(d.join("sky.hdr")).unwrap()).unwrap();
    assert_eq!(baked(&make(d, &wider, "all")), ["sphere", "sphere_on_ground"], "a new environment bakes everything");

    assert!(make(d, &wider, "golden").status.success());
    assert!(d.join("golden/sphere_on_ground.json").is_file());
    let check = make(d, &wider, "check");
    assert!(check.status.success(), "the bake passes against its own golden reports");
    assert_eq!(String::from_utf8_lossy(&check.stdout).matches("PASS").count(), 2);
    std::fs::remove_file(d.join("golden/sphere.json")).unwrap();
    let missing = make(d, &wider, "check");
    assert!(!missing.status.success(), "a missing golden report fails the check");
    assert!(String::from_utf8_lossy(&missing.stderr).contains("golden/sphere.json"), "and is named");
}

#[test]
fn the_ci_example_runs_the_makefile_and_bake_check() {
    let ci = std::fs::read_to_string(repo("pipeline/ci-example.yml")).unwrap();
    for needle in ["pipeline/setup.sh", "cargo build --release", "-f pipeline/Makefile", " check"] {
        assert!(ci.contains(needle), "ci-example.yml does not run '{needle}'");
    }
    for golden in ["pipeline/golden/sphere_on_ground.json", "pipeline/golden/sphere.json"] {
        let report = bake::check::read_report(&repo(golden)).expect("the committed golden reports read back");
        assert!(!report.scenes.is_empty(), "{golden}");
    }
}
