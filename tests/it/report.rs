//! report.json as a user and CI see it: a fixture bake's report validates
//! against the documented JSON Schema (and stops validating when a field is
//! missing or unknown), the schema documents every field, the report records
//! inputs with their hashes, options, memory and energy, the run ends with a
//! summary (text or JSON lines), and `--plot` writes the convergence plot.

use std::path::Path;
use std::process::Output;

use crate::common::{self, fixture, run_bake as bake, stderr};
use bake::report::{Report, SCHEMA_VERSION};
use serde_json::Value;
use sha2::{Digest, Sha256};

/// A tiny bake of sphere_on_ground under the sun sky into `dir/out`, at most 64 shots, with `extra` arguments.
fn bake_fixture(dir: &Path, extra: &[&str]) -> Output {
    bake_small(dir, "sphere_on_ground.glb", &[&["--max-shots", "64"][..], extra].concat())
}

/// A tiny bake (64² atlas, 64 lights) of fixture `name` under the sun sky into `dir/out`, with `extra` arguments.
fn bake_small(dir: &Path, name: &str, extra: &[&str]) -> Output {
    let input = fixture(name);
    let env = fixture("sky_sun.exr");
    let mut args = vec![
        input.to_str().unwrap(),
        "--env",
        env.to_str().unwrap(),
        "-o",
        "out",
        "--max-atlas-size",
        "64",
        "--lights",
        "64",
    ];
    args.extend_from_slice(extra);
    let output = bake(dir, &args);
    assert!(output.status.success(), "bake failed: {}", stderr(&output));
    output
}

const SCHEMA: &str = "schema/report.schema.json";

fn schema() -> Value {
    serde_json::from_slice(&std::fs::read(common::repo(SCHEMA)).unwrap()).expect("the schema is JSON")
}

/// What Ajv (pipeline/schema.mjs) finds wrong in each of `reports` against
/// schema/report.schema.json, in order; the script fails the test if the
/// schema itself is not valid draft 2020-12.
fn schema_errors(reports: &[&Value]) -> Vec<Vec<String>> {
    let dir = tempfile::tempdir().unwrap();
    let files: Vec<_> = (0..reports.len()).map(|i| dir.path().join(format!("report{i}.json"))).collect();
    for (file, report) in files.iter().zip(reports) {
        std::fs::write(file, serde_json::to_vec(report).unwrap()).unwrap();
    }
    let schema = common::repo(SCHEMA);
    let args: Vec<&std::ffi::OsStr> =
        std::iter::once(schema.as_os_str()).chain(files.iter().map(|f| f.as_os_str())).collect();
    let found: serde_json::Map<String, Value> =
        serde_json::from_str(&common::node("pipeline/schema.mjs", &args)).unwrap();
    let messages = |file: &std::path::PathBuf| -> Vec<String> {
        let list = found[file.to_str().unwrap()].as_array().expect("a list per file");
        list.iter().map(|m| m.as_str().unwrap().to_string()).collect()
    };
    files.iter().map(messages).collect()
}

#[test]
fn the_report_of_a_fixture_bake_validates_against_the_schema() {
    let dir = tempfile::tempdir().unwrap();
    bake_fixture(dir.path(), &["-q"]);
    let text = std::fs::read(dir.path().join("out/report.json")).unwrap();
    let report: Value = serde_json::from_slice(&text).unwrap();
    let found = schema_errors(&[&report]).remove(0);
    assert!(found.is_empty(), "the report does not follow the schema:\n{}", found.join("\n"));
    let typed: Report = serde_json::from_slice(&text).unwrap();
    assert_eq!(typed.schema_version, SCHEMA_VERSION);

    // The validation can fail: a missing field anywhere, or one the schema does not document.
    let mut broken = Vec::new();
    for pointer in ["/inputs", "/scenes/0/energy/1/p50_luminance", "/scenes/0/atlas/energy/power_emitted"] {
        let mut missing = report.clone();
        let (parent, key) = pointer.rsplit_once('/').unwrap();
        missing.pointer_mut(parent).unwrap().as_object_mut().unwrap().remove(key).expect(pointer);
        broken.push((format!("without {pointer}"), missing));
    }
    let mut unknown = report.clone();
    unknown.pointer_mut("/scenes/0/energy/0").unwrap()["brightness"] = 1.0.into();
    broken.push(("an undocumented field".into(), unknown));
    let mut wrong_version = report.clone();
    wrong_version["schema_version"] = (SCHEMA_VERSION + 1).into();
    broken.push(("another schema_version".into(), wrong_version));
    let mut negative = report.clone();
    negative.pointer_mut("/scenes/0/energy/0/mean_lightmap").unwrap()[0] = (-1.0).into();
    broken.push(("a negative mean".into(), negative));
    let found = schema_errors(&broken.iter().map(|(_, instance)| instance).collect::<Vec<_>>());
    for ((what, _), found) in broken.iter().zip(found) {
        eprintln!("{what}: {}", found.first().map_or("valid", String::as_str));
        assert!(!found.is_empty(), "a report with {what} validates");
    }
}

#[test]
fn the_schema_documents_every_field_and_matches_the_code() {
    let schema = schema();
    assert_eq!(schema["properties"]["schema_version"]["const"], SCHEMA_VERSION, "bump both together");
    assert_eq!(serde_json::from_str::<Value>(bake::report::SCHEMA).unwrap(), schema, "the built-in copy is stale");
    fn walk(path: &str, node: &Value, undocumented: &mut Vec<String>, fields: &mut usize) {
        if let Some(properties) = node.get("properties").and_then(Value::as_object) {
            for (name, property) in properties {
                *fields += 1;
                let described = property.get("description").and_then(Value::as_str).is_some_and(|d| d.len() > 8);
                if !described {
                    undocumented.push(format!("{path}.{name}"));
                }
                walk(&format!("{path}.{name}"), property, undocumented, fields);
            }
        }
        if let Some(defs) = node.get("$defs").and_then(Value::as_object) {
            for (name, def) in defs {
                if def.get("description").and_then(Value::as_str).is_none() {
                    undocumented.push(format!("$defs.{name}"));
                }
                walk(&format!("$defs.{name}"), def, undocumented, fields);
            }
        }
    }
    let (mut undocumented, mut fields) = (Vec::new(), 0);
    walk("", &schema, &mut undocumented, &mut fields);
    eprintln!("{fields} documented fields");
    assert!(fields > 100, "only {fields} fields");
    assert!(undocumented.is_empty(), "fields without a description: {undocumented:?}");
}

#[test]
fn the_report_records_inputs_options_memory_and_energy() {
    let dir = tempfile::tempdir().unwrap();
    bake_fixture(dir.path(), &["-q", "--exposure", "1"]);
    let report: Report = serde_json::from_slice(&std::fs::read(dir.path().join("out/report.json")).unwrap()).unwrap();

    let roles: Vec<&str> = report.inputs.iter().map(|i| i.role.as_str()).collect();
    assert_eq!(roles, ["scene", "environment"]);
    for input in &report.inputs {
        let bytes = std::fs::read(&input.path).unwrap();
        let hash: String = Sha256::digest(&bytes).iter().map(|b| format!("{b:02x}")).collect();
        assert_eq!(input.sha256, hash, "{}", input.path.display());
        assert_eq!(input.bytes, bytes.len() as u64);
    }
    assert_eq!(report.options.max_atlas_size, 64);
    assert_eq!(report.options.max_shots, Some(64));
    assert_eq!(report.options.exposure, 1.0);
    assert_eq!(report.options.lights, "64");
    assert!(report.options.arguments.windows(2).any(|w| w == ["--max-atlas-size", "64"]), "{:?}", report.options);

    let scene = &report.scenes[0];
    assert_eq!(scene.name, "sphere_on_ground");
    for stage in &scene.stages {
        let memory = stage.memory.as_ref().expect("memory is measured on Linux");
        eprintln!(
            "{:9} {:6.3} s  rss {:6.1} → {:6.1} MiB, peak {:6.1} MiB ({}), gpu peak {:?} B",
            stage.stage,
            stage.seconds,
            memory.rss_before_bytes as f64 / 1048576.0,
            memory.rss_after_bytes as f64 / 1048576.0,
            memory.peak_rss_bytes as f64 / 1048576.0,
            memory.peak_rss_scope,
            memory.gpu_peak_bytes
        );
        assert!(memory.peak_rss_bytes >= memory.rss_after_bytes.max(1));
    }
    let solve = scene.stages.iter().find(|s| s.stage == "solve").unwrap().memory.clone().unwrap();
    if report.adapter.backend == "Vulkan" {
        assert!(solve.gpu_peak_bytes.unwrap() > 1 << 20, "the solve's buffers and shadow maps take more than 1 MiB");
    }

    let atlas = &scene.atlas.energy;
    assert_eq!(atlas.texels, scene.texels.covered);
    assert_eq!(scene.energy.iter().map(|p| p.stats.texels).sum::<usize>(), atlas.texels);
    for p in &scene.energy {
        let s = &p.stats;
        eprintln!(
            "{}: {} texels in {:?}, L_lm {:?}, luminance p1 {:.4} p50 {:.4} p99 {:.4}",
            p.name, s.texels, p.atlas_bounds, s.mean_lightmap, s.p1_luminance, s.p50_luminance, s.p99_luminance
        );
        assert!(s.min_luminance <= s.p1_luminance && s.p1_luminance <= s.p50_luminance);
        assert!(s.p50_luminance <= s.p99_luminance && s.p99_luminance <= s.max_luminance);
        assert!(s.p1_luminance < s.p99_luminance, "a lit sphere and its shadow are not uniform");
        assert!(p.atlas_bounds[2] > p.atlas_bounds[0] && p.atlas_bounds[2] <= scene.atlas.width);
        assert_eq!(s.power_emitted, [0.0; 3]);
    }
    let direct = scene.direct.as_ref().unwrap();
    assert!(bake::colour::luminance(direct.power_received) < bake::colour::luminance(atlas.power_received));
    let balance = bake::check::energy_balance(scene).expect("the energy balance holds");
    eprintln!("{balance:?}");
}

#[test]
fn a_run_ends_with_a_summary_in_text_or_json_and_quiet_prints_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let text = stderr(&bake_fixture(dir.path(), &["--log-format", "text"]));
    eprintln!("{text}");
    let summary = &text[text.find("── summary ──").expect("a summary")..];
    for needle in ["time", "adapter", "lights     64 from", "texels", "bounce", "shots", "unshot", "report"] {
        assert!(summary.contains(needle), "the summary lacks '{needle}'");
    }
    assert!(summary.contains(&format!("out{}sphere_on_ground.glb", std::path::MAIN_SEPARATOR)), "{summary}");
    assert!(summary.lines().count() <= 24, "the summary takes more than one screen");

    let json = stderr(&bake_fixture(dir.path(), &["--log-format", "json"]));
    let events: Vec<Value> = json
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("not a JSON line ({e}): {l}")))
        .collect();
    let kinds: Vec<&str> = events.iter().map(|e| e["event"].as_str().unwrap()).collect();
    assert_eq!(kinds.first(), Some(&"adapter"));
    assert!(kinds.contains(&"stage") && kinds.contains(&"finish"), "{kinds:?}");
    let last = events.last().unwrap();
    assert_eq!(last["event"], "summary");
    assert_eq!(last["lights"], 64);
    assert!(last["scenes"][0]["texels"].as_u64().unwrap() > 0);
    assert!(last["scenes"][0]["outputs"].as_array().unwrap().len() >= 2);

    let quiet = bake_fixture(dir.path(), &["-q"]);
    assert!(quiet.stderr.is_empty(), "--quiet printed: {}", stderr(&quiet));
    let failed = bake(dir.path(), &["missing.glb", "--log-format", "json"]);
    assert_eq!(failed.status.code(), Some(2));
    let error: Value = serde_json::from_str(stderr(&failed).trim()).expect("the error is one JSON line");
    assert_eq!(error["event"], "error");
    assert!(error["message"].as_str().unwrap().contains("missing.glb"));
}

#[test]
fn plot_writes_a_convergence_svg() {
    let dir = tempfile::tempdir().unwrap();
    bake_fixture(dir.path(), &["-q"]);
    assert!(!dir.path().join("out/sphere_on_ground.convergence.svg").exists(), "no plot unless asked");
    bake_fixture(dir.path(), &["-q", "--plot"]);
    let path = dir.path().join("out/sphere_on_ground.convergence.svg");
    let svg = std::fs::read_to_string(&path).expect("--plot writes OUT/<name>.convergence.svg");
    eprintln!("{} bytes of SVG", svg.len());
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    assert!(svg.contains("unshot power fraction") && svg.contains("error estimate"), "the legend names both curves");
    assert!(svg.matches("<polyline").count() >= 2, "two curves");
    let report: Report = serde_json::from_slice(&std::fs::read(dir.path().join("out/report.json")).unwrap()).unwrap();
    assert!(report.scenes[0].outputs.iter().any(|o| o.ends_with("sphere_on_ground.convergence.svg")));
    assert!(report.options.plot);
}

#[test]
fn plot_of_a_scene_without_a_bounce_pass_says_why() {
    let dir = tempfile::tempdir().unwrap();
    let input = fixture("sphere.glb");
    let env = fixture("sky_constant.hdr");
    let output = bake(
        dir.path(),
        &[
            input.to_str().unwrap(),
            "--env",
            env.to_str().unwrap(),
            "-o",
            "out",
            "--max-atlas-size",
            "32",
            "-q",
            "--plot",
        ],
    );
    assert!(output.status.success(), "{}", stderr(&output));
    let svg = std::fs::read_to_string(dir.path().join("out/sphere.convergence.svg")).unwrap();
    assert!(svg.contains("bounce pass left out"), "{svg}");
}

#[test]
fn reference_traces_the_true_error_and_plots_it() {
    let dir = tempfile::tempdir().unwrap();
    let extra = ["--reference", "24", "--reference-samples", "64", "--plot", "--log-format", "text"];
    let output = bake_small(dir.path(), "sphere_on_ground.glb", &extra);
    assert!(stderr(&output).contains("RMSE against the CPU reference at 24 texels"), "the summary says the error");
    let report: Report = serde_json::from_slice(&std::fs::read(dir.path().join("out/report.json")).unwrap()).unwrap();
    let scene = &report.scenes[0];
    let reference = scene.reference.as_ref().expect("--reference is reported");
    let trace = &scene.bounce.as_ref().unwrap().trace;
    let errors: Vec<f64> = trace.iter().map(|t| t.reference_error.expect("every trace point has it")).collect();
    eprintln!("{reference:?}\nerror against the reference along the trace: {errors:.4?}");
    assert_eq!((reference.texels, reference.samples), (24, 64));
    assert!(errors.iter().all(|e| e.is_finite() && *e >= 0.0));
    assert!(reference.error < errors[0], "bouncing light brings the bake closer to the reference");
    assert!(reference.error < 0.1, "the converged bake is within 10% of the reference: {}", reference.error);
    assert!((reference.error - errors.last().unwrap()).abs() < 0.02, "the final error continues the trace");
    assert_eq!(
        scene.stages.iter().map(|s| s.stage.as_str()).collect::<Vec<_>>(),
        ["import", "unwrap", "texelize", "reference", "solve", "export"]
    );
    let svg = std::fs::read_to_string(dir.path().join("out/sphere_on_ground.convergence.svg")).unwrap();
    assert!(svg.contains("error against the CPU reference") && svg.contains("noise of the reference"));

    let value: Value = serde_json::from_slice(&std::fs::read(dir.path().join("out/report.json")).unwrap()).unwrap();
    let found = schema_errors(&[&value]).remove(0);
    assert!(found.is_empty(), "{found:?}");
}

#[test]
fn the_plotted_trace_ends_at_the_error_the_report_gives_after_the_contact_fix_up() {
    // corner's ball and ring touch its floor: the contact fix-up changes the
    // light the bounce pass left there, after the pass's last trace point
    // (stopped early: how the trace ends is what is tested).
    let dir = tempfile::tempdir().unwrap();
    bake_small(
        dir.path(),
        "corner.glb",
        &["--reference", "64", "--reference-samples", "64", "--plot", "--max-shots", "512"],
    );
    let report: Report = serde_json::from_slice(&std::fs::read(dir.path().join("out/report.json")).unwrap()).unwrap();
    let scene = &report.scenes[0];
    let contact = scene.texels.fixups.iter().find(|f| f.stage == "contact").expect("a contact fix-up entry");
    assert!(contact.texels > 0, "texels near corner's contacts are traced");
    let trace = &scene.bounce.as_ref().unwrap().trace;
    let [.., before, last] = trace.as_slice() else { panic!("a trace of two points or more") };
    let final_error = scene.reference.as_ref().expect("--reference is reported").error;
    eprintln!("trace's last points {before:?}, {last:?}; the report's error {final_error}");
    assert!(last.seconds > before.seconds && last.shots == before.shots, "the last point is the fix-up's");
    assert!((last.reference_error.unwrap() - final_error).abs() < 1e-12, "the trace ends at the report's error");
    let svg = std::fs::read_to_string(dir.path().join("out/corner.convergence.svg")).unwrap();
    assert!(svg.contains("after the contact fix-up"), "the plot says what its last point is");
}

#[test]
fn stop_reasons_are_written_as_the_schema_lists_them() {
    use bake::solve::StopReason;
    let reasons = [StopReason::Converged, StopReason::MaxShots, StopReason::MaxTime];
    let written: Vec<Value> = reasons.iter().map(|r| serde_json::to_value(r).unwrap()).collect();
    let schema = schema();
    let listed = find_key(&schema, "stopped_by").expect("the schema has stopped_by");
    assert_eq!(&Value::from(written.clone()), &listed["enum"]);
    for (reason, value) in reasons.iter().zip(&written) {
        assert_eq!(value.as_str(), Some(reason.to_string().as_str()), "the summary shows what the report says");
        assert_eq!(serde_json::from_value::<StopReason>(value.clone()).unwrap(), *reason);
    }
}

/// The first value under `key` anywhere in `value`.
fn find_key<'v>(value: &'v Value, key: &str) -> Option<&'v Value> {
    match value {
        Value::Object(map) => map.get(key).or_else(|| map.values().find_map(|v| find_key(v, key))),
        Value::Array(items) => items.iter().find_map(|v| find_key(v, key)),
        _ => None,
    }
}

#[test]
fn time_passes_records_each_bounce_pass_and_leaves_the_lightmap_as_it_was() {
    let dir = tempfile::tempdir().unwrap();
    let exr = dir.path().join("out/sphere_on_ground.lightmap0.exr");
    bake_fixture(dir.path(), &["-q"]);
    let plain = std::fs::read(&exr).unwrap();
    let report: Value = serde_json::from_slice(&std::fs::read(dir.path().join("out/report.json")).unwrap()).unwrap();
    assert!(report["scenes"][0]["bounce"].get("passes").is_none(), "no pass times unless asked");

    bake_fixture(dir.path(), &["-q", "--time-passes"]);
    assert!(std::fs::read(&exr).unwrap() == plain, "waiting after each pass changed the lightmap");
    let report: Value = serde_json::from_slice(&std::fs::read(dir.path().join("out/report.json")).unwrap()).unwrap();
    let found = schema_errors(&[&report]).remove(0);
    assert!(found.is_empty(), "the timed report does not follow the schema:\n{}", found.join("\n"));
    assert_eq!(report["options"]["time_passes"], true);
    let bounce = &report["scenes"][0]["bounce"];
    let passes = bounce["passes"].as_array().expect("--time-passes records bounce.passes");
    let names: Vec<&str> = passes.iter().map(|p| p["pass"].as_str().unwrap()).collect();
    eprintln!("{passes:?}");
    let expected = [
        "select",
        "hemicube cull",
        "hemicube render",
        "shooter cull",
        "form-factor measure",
        "far field",
        "near field",
    ];
    assert_eq!(names, expected, "every pass, in the order a batch runs them");
    let timed: f64 = passes.iter().map(|p| p["seconds"].as_f64().unwrap()).sum();
    let total = bounce["seconds"].as_f64().unwrap();
    assert!(timed > 0.0 && timed <= total, "the passes' {timed} s against the bounce pass's {total} s");
}
