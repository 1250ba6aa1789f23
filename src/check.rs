//! `bake check`: a bake's texel energy against a golden report, and the
//! invariants every bake must keep, for CI.
//!
//! ```text
//! bake check baked/report.json --against golden/report.json --tolerance 2%
//! bake check baked/room.glb --against golden/room.json
//! ```
//! The target is a `report.json`, or a baked `.glb`/`.gltf` whose run's
//! `report.json` lies beside it (then only that scene is checked). Lightmap
//! EXRs found beside the report are re-read and their texels checked too,
//! and each KTX2 lightmap against its EXR.
//!
//! Exit codes: 0 every check passed, 1 a figure moved beyond the tolerance or
//! an invariant does not hold (a readable table on stdout says which), 2 the
//! check could not run (a file is missing or unreadable; one line on stderr).
//!
//! # Compared with the golden report
//! Scenes are matched by name (the input's file stem), primitives by (node,
//! mesh, primitive) index, shown by name. Per primitive: covered texels,
//! mean L_lm, power received, reflected and emitted (each per channel), and
//! the p1, p50 and p99 texel luminance. A figure moved if
//! |now − golden| > tolerance · max(|golden|, floor), where the floor (1e-3 of
//! the largest figure of its group: the three channels, or the luminance
//! percentiles and the mean) keeps a channel or percentile that is almost 0
//! from failing on round-off. A primitive or scene present on one side only
//! is a change too.
//!
//! # Invariants (no golden report needed)
//! See `invariants` and `lightmap_violations`; each is defined in
//! `schema/report.schema.json` under "Invariants" and in the README.

use std::ffi::OsStr;
use std::path::{Component, Path, PathBuf};

use anyhow::{Context, Result, bail};

use crate::colour::luminance;
use crate::progress::printable;
use crate::report::{EnergyStats, OLDEST_READABLE_VERSION, PrimitiveEnergy, Report, SCHEMA_VERSION, SceneReport};

/// Exit code: every check passed.
pub const EXIT_PASS: u8 = 0;
/// Exit code: a figure moved beyond the tolerance or an invariant does not hold.
pub const EXIT_FAIL: u8 = 1;
/// Exit code: the check could not run (bad or missing input).
pub const EXIT_ERROR: u8 = 2;

/// Default relative tolerance of `--tolerance`.
pub const DEFAULT_TOLERANCE: f64 = 0.02;
/// Relative slack of the energy-balance invariant, as a share of the largest
/// bounced power expected (GPU sums are f32, accumulated in varying order).
pub const BALANCE_SLACK: f64 = 0.01;
/// How much more light may land than was shot between surfaces: the form
/// factors' discretisation error (1–6% measured in a closed room with a
/// lamp on lavapipe, most in the first shots from the small bright lamp).
pub const FORM_FACTOR_SLACK: f64 = 0.1;
/// Relative slack of the other invariants (f64 sums of f32 values).
const ROUND_OFF: f64 = 1e-4;

/// What to check.
#[derive(Clone, Debug)]
pub struct CheckOptions {
    /// `report.json`, or a baked `.glb`/`.gltf` with its run's `report.json` beside it.
    pub target: PathBuf,
    /// The golden report to compare with; `None` checks the invariants only.
    pub against: Option<PathBuf>,
    /// Relative tolerance (0.02 = 2%).
    pub tolerance: f64,
}

/// A figure that moved beyond the tolerance, or a scene or primitive present on one side only.
#[derive(Clone, Debug, PartialEq)]
pub struct Change {
    pub scene: String,
    /// The primitive's display name (with its key), or "—" for the scene.
    pub mesh: String,
    pub metric: String,
    pub golden: Option<f64>,
    pub now: Option<f64>,
}

impl Change {
    /// Relative change (now − golden)/|golden|, if both exist and golden ≠ 0.
    pub fn relative(&self) -> Option<f64> {
        match (self.golden, self.now) {
            (Some(g), Some(n)) if g != 0.0 => Some((n - g) / g.abs()),
            _ => None,
        }
    }
}

/// An invariant that does not hold.
#[derive(Clone, Debug, PartialEq)]
pub struct Violation {
    pub scene: String,
    pub message: String,
}

/// The result of a check.
#[derive(Clone, Debug, Default)]
pub struct Findings {
    /// The golden report compared with, if any.
    pub golden: Option<PathBuf>,
    pub tolerance: f64,
    /// Scenes and primitives checked, figures compared.
    pub scenes: usize,
    pub primitives: usize,
    pub compared: usize,
    /// Lightmap files whose texels were read.
    pub lightmaps: Vec<PathBuf>,
    pub changes: Vec<Change>,
    pub violations: Vec<Violation>,
}

impl Findings {
    pub fn passed(&self) -> bool {
        self.changes.is_empty() && self.violations.is_empty()
    }

    pub fn exit_code(&self) -> u8 {
        if self.passed() { EXIT_PASS } else { EXIT_FAIL }
    }

    /// The readable result: a table of what moved, one line per invariant
    /// violation, and a last line that says PASS or FAIL.
    pub fn render(&self) -> String {
        let mut out = String::new();
        let percent = format_percent(self.tolerance);
        if !self.changes.is_empty() {
            out.push_str(&format!("{} figure(s) moved beyond ±{percent}:\n", self.changes.len()));
            let mut rows = vec![["scene", "mesh", "metric", "golden", "now", "change"].map(String::from)];
            for c in &self.changes {
                let change = match (c.golden, c.now) {
                    (None, _) => "not in golden".to_string(),
                    (_, None) => "missing".to_string(),
                    _ => c.relative().map_or("from 0".to_string(), |r| format!("{:+.2}%", r * 100.0)),
                };
                // Names come from the reports, which may hold control characters.
                rows.push([
                    printable(&c.scene),
                    printable(&c.mesh),
                    c.metric.clone(),
                    c.golden.map_or("—".into(), format_value),
                    c.now.map_or("—".into(), format_value),
                    change,
                ]);
            }
            let widths: Vec<usize> = (0..6).map(|i| rows.iter().map(|r| r[i].chars().count()).max().unwrap()).collect();
            for row in rows {
                let cells: Vec<String> = row
                    .iter()
                    .zip(&widths)
                    .enumerate()
                    .map(|(i, (cell, &w))| {
                        let pad = w - cell.chars().count();
                        if i >= 3 { format!("{}{cell}", " ".repeat(pad)) } else { format!("{cell}{}", " ".repeat(pad)) }
                    })
                    .collect();
                out.push_str(&format!("  {}\n", cells.join("  ").trim_end()));
            }
        }
        for v in &self.violations {
            out.push_str(&format!("invariant: {}: {}\n", printable(&v.scene), printable(&v.message)));
        }
        let against = match &self.golden {
            Some(golden) => {
                let golden = printable(&golden.display().to_string());
                format!(", {} figures compared with {golden} at ±{percent}", self.compared)
            }
            None => ", no golden report given".to_string(),
        };
        let lightmaps = if self.lightmaps.is_empty() {
            String::new()
        } else {
            format!(", {} lightmap file(s) read", self.lightmaps.len())
        };
        out.push_str(&format!(
            "{}: {} scene(s), {} mesh(es){against}{lightmaps}; {} moved, {} invariant violation(s)\n",
            if self.passed() { "PASS" } else { "FAIL" },
            self.scenes,
            self.primitives,
            self.changes.len(),
            self.violations.len()
        ));
        out
    }
}

fn format_value(v: f64) -> String {
    if v == 0.0 || (1e-3..1e6).contains(&v.abs()) { format!("{v:.4}") } else { format!("{v:.4e}") }
}

fn format_percent(fraction: f64) -> String {
    let p = fraction * 100.0;
    if p == p.round() { format!("{p:.0}%") } else { format!("{p}%") }
}

/// Parses a tolerance: "2%" or "0.02". A plain number must be below 1 (write "150%" for more).
pub fn parse_tolerance(text: &str) -> Result<f64, String> {
    let text = text.trim();
    let (number, scale) = match text.strip_suffix('%') {
        Some(number) => (number.trim(), 0.01),
        None => (text, 1.0),
    };
    let value: f64 = number.parse().map_err(|_| format!("'{text}' is not a tolerance: write e.g. 2% or 0.02"))?;
    if !(value.is_finite() && value >= 0.0) {
        return Err(format!("'{text}' is not a tolerance: it must be ≥ 0"));
    }
    if scale == 1.0 && value >= 1.0 {
        return Err(format!("'{text}' is ambiguous: write {text}% for percent, or a fraction below 1"));
    }
    Ok(value * scale)
}

/// Reads a report, refusing another schema version with a clear message.
/// The file is parsed as it is read, never held whole (as bytes or as a
/// JSON tree): a golden report of 285 MB took 1.2 GB that way; streamed,
/// memory is what the typed report holds.
pub fn read_report(path: &Path) -> Result<Report> {
    let version: SchemaVersion = stream_json(path)?;
    match version.schema_version.as_ref().and_then(serde_json::Value::as_u64) {
        Some(v) if (OLDEST_READABLE_VERSION as u64..=SCHEMA_VERSION as u64).contains(&v) => {}
        Some(v) => bail!(
            "report '{}' has schema version {v}; this bake reads versions {OLDEST_READABLE_VERSION} to \
             {SCHEMA_VERSION}: bake again to refresh it",
            path.display()
        ),
        None => bail!("report '{}': no schema_version: not a bake report", path.display()),
    }
    stream_json(path)
}

/// The one field of a report read before the rest, to refuse another
/// version by name rather than by the first field it lacks.
#[derive(serde::Deserialize)]
struct SchemaVersion {
    schema_version: Option<serde_json::Value>,
}

/// Parses the JSON file `path` into `T` as it is read (up to the length the
/// file had when opened). Errors say whether it is no JSON at all or JSON
/// of another shape.
fn stream_json<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T> {
    use std::io::Read;
    let (file, length) =
        crate::files::open(path).with_context(|| format!("report '{}': cannot read", path.display()))?;
    let reader = std::io::BufReader::with_capacity(1 << 16, file.take(length));
    serde_json::from_reader(reader).map_err(|e| {
        let what = match e.classify() {
            serde_json::error::Category::Data => "does not follow the schema",
            serde_json::error::Category::Io => "cannot read",
            _ => "not JSON (a baked report.json was expected)",
        };
        anyhow::Error::new(e).context(format!("report '{}': {what}", path.display()))
    })
}

/// Runs the whole check. Errors (exit code 2) are inputs that cannot be read.
pub fn run(options: &CheckOptions) -> Result<Findings> {
    let target = &options.target;
    let extension = target.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    let (report_path, only_scene) = match extension.as_str() {
        "glb" | "gltf" => {
            if !target.is_file() {
                bail!("'{}': no such baked file", target.display());
            }
            let dir = target.parent().unwrap_or(Path::new("."));
            let report = dir.join("report.json");
            if !report.is_file() {
                bail!(
                    "'{}': no report.json beside it in '{}' (bake writes one into its output folder)",
                    target.display(),
                    if dir.as_os_str().is_empty() { Path::new(".") } else { dir }.display()
                );
            }
            let stem = target.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
            (report, Some(stem))
        }
        _ => (target.clone(), None),
    };
    let report = read_report(&report_path)?;
    check_scene_names(&report, &report_path)?;
    if let Some(name) = &only_scene
        && !report.scenes.iter().any(|s| &s.name == name)
    {
        bail!("'{}': its report '{}' has no scene named '{name}'", target.display(), report_path.display());
    }
    let golden = options.against.as_deref().map(read_report).transpose()?;
    let selected = |s: &&SceneReport| only_scene.as_ref().is_none_or(|n| &s.name == n);

    let mut findings = Findings { golden: options.against.clone(), tolerance: options.tolerance, ..Default::default() };
    for scene in report.scenes.iter().filter(selected) {
        findings.scenes += 1;
        findings.primitives += scene.energy.len();
        findings.violations.extend(invariants(scene));
        let dir = report_path.parent().unwrap_or(Path::new("."));
        check_lightmap_files(dir, scene, &mut findings)?;
        if let Some(probes) = &scene.probes {
            findings.violations.extend(probe_violations(dir, scene, probes.probes)?);
        }
    }
    if let Some(env) = &report.environment {
        for c in 0..3 {
            let (map, captured) = (env.map_integral[c], env.captured[c]);
            if (map - captured).abs() > 1e-3 * map.abs().max(1e-30) {
                findings.violations.push(Violation {
                    scene: "environment".into(),
                    message: format!(
                        "the lights carry Σ L·Ω = {captured:.6e} in channel {} but the map {map:.6e}: extraction lost or made energy",
                        "rgb".as_bytes()[c] as char
                    ),
                });
            }
        }
    }
    if let Some(golden) = &golden {
        let (changes, compared) = compare(&report, golden, options.tolerance, only_scene.as_deref());
        findings.changes = changes;
        findings.compared = compared;
    }
    Ok(findings)
}

/// Every figure of `now` that moved beyond `tolerance` from `golden`, and
/// how many figures were compared. `only_scene` limits it to one scene.
pub fn compare(now: &Report, golden: &Report, tolerance: f64, only_scene: Option<&str>) -> (Vec<Change>, usize) {
    let mut changes = Vec::new();
    let mut compared = 0;
    let wanted = |name: &str| only_scene.is_none_or(|n| n == name);
    for g in golden.scenes.iter().filter(|s| wanted(&s.name)) {
        let Some(n) = now.scenes.iter().find(|s| s.name == g.name) else {
            changes.push(Change {
                scene: g.name.clone(),
                mesh: "—".into(),
                metric: "scene".into(),
                golden: Some(1.0),
                now: None,
            });
            continue;
        };
        for gp in &g.energy {
            let label = display_name(gp);
            match n.energy.iter().find(|np| key(np) == key(gp)) {
                None => changes.push(Change {
                    scene: g.name.clone(),
                    mesh: label,
                    metric: "mesh".into(),
                    golden: Some(gp.stats.texels as f64),
                    now: None,
                }),
                Some(np) => compared += compare_stats(&g.name, &label, &gp.stats, &np.stats, tolerance, &mut changes),
            }
        }
        for np in n.energy.iter().filter(|np| !g.energy.iter().any(|gp| key(gp) == key(np))) {
            changes.push(Change {
                scene: n.name.clone(),
                mesh: display_name(np),
                metric: "mesh".into(),
                golden: None,
                now: Some(np.stats.texels as f64),
            });
        }
    }
    for n in now.scenes.iter().filter(|s| wanted(&s.name) && !golden.scenes.iter().any(|g| g.name == s.name)) {
        changes.push(Change {
            scene: n.name.clone(),
            mesh: "—".into(),
            metric: "scene".into(),
            golden: None,
            now: Some(1.0),
        });
    }
    (changes, compared)
}

fn key(p: &PrimitiveEnergy) -> (usize, Option<usize>, usize, usize) {
    (p.node, p.instance, p.mesh, p.primitive)
}

fn display_name(p: &PrimitiveEnergy) -> String {
    let instance = p.instance.map(|k| format!(", instance {k}")).unwrap_or_default();
    format!("{} (node {}{instance}, mesh {}, prim {})", p.name, p.node, p.mesh, p.primitive)
}

/// Compares one primitive's figures; returns how many were compared.
fn compare_stats(scene: &str, mesh: &str, g: &EnergyStats, n: &EnergyStats, tol: f64, out: &mut Vec<Change>) -> usize {
    let mut count = 0;
    let mut figure = |metric: String, golden: f64, now: f64, floor: f64| {
        count += 1;
        if (now - golden).abs() > tol * golden.abs().max(floor) + f64::MIN_POSITIVE {
            out.push(Change { scene: scene.into(), mesh: mesh.into(), metric, golden: Some(golden), now: Some(now) });
        }
    };
    figure("texels".into(), g.texels as f64, n.texels as f64, 1.0);
    let channels: [(&str, [f64; 3], [f64; 3]); 4] = [
        ("mean L_lm", g.mean_lightmap, n.mean_lightmap),
        ("power received", g.power_received, n.power_received),
        ("power reflected", g.power_reflected, n.power_reflected),
        ("power emitted", g.power_emitted, n.power_emitted),
    ];
    for (name, golden, now) in channels {
        let floor = 1e-3 * golden.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        if name == "power emitted" && golden == [0.0; 3] && now == [0.0; 3] {
            continue;
        }
        for c in 0..3 {
            figure(format!("{name} {}", ["r", "g", "b"][c]), golden[c], now[c], floor);
        }
    }
    let floor = 1e-3 * luminance(g.mean_lightmap).max(g.p99_luminance);
    for (name, golden, now) in [
        ("p1 luminance", g.p1_luminance, n.p1_luminance),
        ("p50 luminance", g.p50_luminance, n.p50_luminance),
        ("p99 luminance", g.p99_luminance, n.p99_luminance),
    ] {
        figure(name.into(), golden, now, floor);
    }
    count
}

/// The invariants one scene's report must keep:
///
/// 1. No texel is NaN, infinite or negative (`invalid_texels` = 0 everywhere).
/// 2. Every covered texel is written and belongs to a primitive: the
///    primitives' texels add up to the atlas's, which equal `texels.covered`.
/// 3. Reflected power lies between received power times the smallest and
///    the largest albedo, per channel, and no albedo exceeds 1.
/// 4. Emitted power is accounted for (`energy_balance`), and the bounce pass
///    lands at most `1 + FORM_FACTOR_SLACK` times the power it shoots.
/// 5. Figures are ordered and finite: min ≤ p1 ≤ p50 ≤ p99 ≤ max luminance;
///    the convergence trace is finite and non-negative.
pub fn invariants(scene: &SceneReport) -> Vec<Violation> {
    let mut out = Vec::new();
    let mut say = |message: String| out.push(Violation { scene: scene.name.clone(), message });
    let groups = scene.energy.iter().map(|p| (format!("mesh {}", p.name), &p.stats));
    let groups = groups.chain(std::iter::once((format!("atlas {}", scene.atlas.index), &scene.atlas.energy)));
    for (what, s) in groups {
        if s.invalid_texels > 0 {
            say(format!("{what}: {} of its {} texels are NaN, infinite or negative", s.invalid_texels, s.texels));
        }
        for c in 0..3 {
            let channel = ["red", "green", "blue"][c];
            let (received, reflected) = (s.power_received[c], s.power_reflected[c]);
            let slack = ROUND_OFF * received.abs() + 1e-12;
            if reflected > s.albedo_max[c] * received + slack || reflected < s.albedo_min[c] * received - slack {
                say(format!(
                    "{what}: reflected power {reflected:.6e} ({channel}) is not between received power {received:.6e} \
                     times the albedo range [{:.4}, {:.4}]",
                    s.albedo_min[c], s.albedo_max[c]
                ));
            }
            if s.albedo_max[c] > 1.0 + 1e-6 {
                say(format!("{what}: albedo {:.4} ({channel}) above 1 creates energy", s.albedo_max[c]));
            }
        }
        let order = [s.min_luminance, s.p1_luminance, s.p50_luminance, s.p99_luminance, s.max_luminance];
        if order.windows(2).any(|w| w[0] > w[1]) || order[0] < 0.0 {
            say(format!("{what}: luminance figures out of order (min, p1, p50, p99, max = {order:?})"));
        }
    }
    let assigned: usize = scene.energy.iter().map(|p| p.stats.texels).sum();
    if assigned != scene.atlas.energy.texels || scene.atlas.energy.texels != scene.texels.covered {
        say(format!(
            "covered texels do not add up: {} covered, {} in the atlas's statistics, {} in the meshes'",
            scene.texels.covered, scene.atlas.energy.texels, assigned
        ));
    }
    if let Some(message) = energy_balance(scene).err() {
        say(message);
    }
    if let Some(bounce) = &scene.bounce
        && bounce.shot_closure > 1.0 + FORM_FACTOR_SLACK
    {
        say(format!(
            "the bounce pass created light: {:.4} times the power shot landed on the scene (at most {:.2} allowed)",
            bounce.shot_closure,
            1.0 + FORM_FACTOR_SLACK
        ));
    }
    if let Some(bounce) = &scene.bounce
        && bounce.trace.iter().any(|t| {
            !(t.seconds.is_finite()
                && t.unshot_fraction >= 0.0
                && t.error_estimate >= 0.0
                && t.error_estimate.is_finite())
        })
    {
        say("the convergence trace has a negative or non-finite point".to_string());
    }
    out
}

/// What the energy balance found: powers in luminance (see `energy_balance`).
#[derive(Clone, Debug, PartialEq)]
pub struct Balance {
    /// Power surfaces received from other surfaces: received − direct.
    pub bounced: f64,
    /// Power surfaces sent out: emitted + reflected.
    pub sent: f64,
    /// bounced / sent.
    pub closure: f64,
    /// The range `closure` must lie in.
    pub expected: (f64, f64),
}

/// "Emitted power accounted for": every watt a surface received that did
/// not come straight from the environment was sent out by a surface, as
/// emission or reflection, and the share of it that landed is what the
/// solver says landed.
///
/// Let P_recv, P_emit, P_refl be the atlas's received, emitted and reflected
/// power (luminance) and P_direct the power the direct pass and the
/// punctual lights' pass delivered (0 without them). Surfaces received P_bounce = P_recv − P_direct from other
/// surfaces, and sent out P_sent = P_emit + P_refl. Progressive refinement
/// shoots part of P_sent, of which the share `shot_closure` landed; the
/// ambient term spreads the unshot rest with `closure` (reflections of it
/// included, by a geometric series). So P_bounce/P_sent is a weighted mean of
/// the two closures and must lie between them (± `BALANCE_SLACK`). Without a
/// bounce pass nothing bounced: P_bounce must be 0. A bounce pass that lost
/// the emitters' light, or created light, breaks it. The contact fix-up
/// replaces the passes' light near contacts by traced light, no share of the
/// shots: P_bounce and P_refl leave out what it changed (`contact`).
pub fn energy_balance(scene: &SceneReport) -> Result<Balance, String> {
    let a = &scene.atlas.energy;
    let received = luminance(a.power_received);
    let direct = scene.direct.as_ref().map_or(0.0, |d| luminance(d.power_received))
        + scene.punctual.as_ref().map_or(0.0, |p| luminance(p.power_received));
    let (received_change, reflected_change) = scene
        .contact
        .as_ref()
        .map_or((0.0, 0.0), |c| (luminance(c.power_received_change), luminance(c.power_reflected_change)));
    let sent = luminance(a.power_emitted) + luminance(a.power_reflected) - reflected_change;
    let bounced = received - direct - received_change;
    let closure = if sent > 0.0 { bounced / sent } else { 0.0 };
    let expected = match &scene.bounce {
        Some(b) => (b.closure.min(b.shot_closure), b.closure.max(b.shot_closure)),
        None => (0.0, 0.0),
    };
    let balance = Balance { bounced, sent, closure, expected };
    let slack = BALANCE_SLACK * expected.1 * sent + ROUND_OFF * received + 1e-12;
    if bounced < expected.0 * sent - slack || bounced > expected.1 * sent + slack {
        let what = if scene.bounce.is_some() {
            format!("between {:.4} and {:.4} of it", expected.0, expected.1)
        } else {
            "none (no bounce pass ran)".to_string()
        };
        return Err(format!(
            "emitted power not accounted for: surfaces sent out {sent:.6e} (emitted + reflected) and received \
             {bounced:.6e} from each other ({:.4} of it); expected {what}",
            closure
        ));
    }
    Ok(balance)
}

/// Refuses a report whose scene names are no plain file names (`../x`,
/// `a/b`, `/x`): each scene's files are read beside the report by its name,
/// and nothing outside the report's folder may be read.
fn check_scene_names(report: &Report, path: &Path) -> Result<()> {
    for (i, scene) in report.scenes.iter().enumerate() {
        let mut parts = Path::new(&scene.name).components();
        let plain = matches!(
            (parts.next(), parts.next()),
            (Some(Component::Normal(part)), None) if part == OsStr::new(&scene.name)
        );
        if !plain {
            bail!(
                "report '{}': scene {i} is named '{}', which is no file name: its lightmap would be read from \
                 outside the report's folder",
                path.display(),
                scene.name
            );
        }
    }
    Ok(())
}

/// `file_name` in the report's folder `dir`, refused where a symbolic link
/// takes it outside that folder.
fn beside_report(dir: &Path, file_name: String) -> Result<PathBuf> {
    let path = dir.join(file_name);
    if !crate::files::resolves_inside(&path, dir) {
        bail!("'{}' resolves outside the report's folder (through a symbolic link): not read", path.display());
    }
    Ok(path)
}

/// Re-reads the scene's lightmap files beside its report, the EXR and the
/// KTX2. A bake writes both for every scene: one that is gone, or is no
/// file, is a failed check, never a pass unchecked.
fn check_lightmap_files(dir: &Path, scene: &SceneReport, findings: &mut Findings) -> Result<()> {
    let path =
        |extension: &str| beside_report(dir, format!("{}.lightmap{}.{extension}", scene.name, scene.atlas.index));
    let unreadable = |path: &Path, e: std::io::Error| Violation {
        scene: scene.name.clone(),
        message: match e.kind() {
            std::io::ErrorKind::NotFound => format!("lightmap '{}' is missing", path.display()),
            _ => format!("lightmap '{}': {e}", path.display()),
        },
    };
    let exr = path("exr")?;
    let (file, length) = match crate::files::open(&exr) {
        Ok(opened) => opened,
        Err(e) => {
            findings.violations.push(unreadable(&exr, e));
            return Ok(());
        }
    };
    let (width, pixels) = read_lightmap_exr(&exr, file, length)?;
    findings.violations.extend(texel_violations(&exr, width, &pixels, scene));
    findings.lightmaps.push(exr);
    let ktx2 = path("ktx2")?;
    match crate::files::open(&ktx2) {
        Ok((file, length)) => {
            findings.violations.extend(ktx2_file_violations(&ktx2, file, length, &pixels, scene)?);
            findings.lightmaps.push(ktx2);
        }
        Err(e) => findings.violations.push(unreadable(&ktx2, e)),
    }
    Ok(())
}

/// Re-reads the scene's probe values (`NAME.probes.bin`, six RGB faces of
/// f32 per probe): there must be `probes` of them, each finite and not
/// negative. A file of another size is refused unread.
fn probe_violations(dir: &Path, scene: &SceneReport, probes: usize) -> Result<Vec<Violation>> {
    use std::io::Read;
    let path = beside_report(dir, format!("{}.probes.bin", scene.name))?;
    let say = |message: String| vec![Violation { scene: scene.name.clone(), message }];
    let (file, length) = match crate::files::open(&path) {
        Ok(opened) => opened,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Ok(say(format!("probes '{}' are missing", path.display())));
        }
        Err(e) => return Ok(say(format!("probes '{}': {e}", path.display()))),
    };
    const FACE_VALUES: usize = 18;
    // In u128: a report's count times 72 must not wrap to the file's length.
    let expected = probes as u128 * (FACE_VALUES * 4) as u128;
    if u128::from(length) != expected {
        return Ok(say(format!("probes '{}' are {length} bytes, not {expected} for {probes} probes", path.display())));
    }
    let mut bytes = Vec::with_capacity(length as usize);
    file.take(length).read_to_end(&mut bytes).with_context(|| format!("probes '{}': cannot read", path.display()))?;
    let values: Vec<f32> = bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
    let bad: Vec<usize> = (0..values.len()).filter(|&i| !(values[i].is_finite() && values[i] >= 0.0)).collect();
    Ok(match bad.first() {
        None => Vec::new(),
        Some(&i) => say(format!(
            "probes '{}': {} values are NaN, infinite or negative, the first probe {} face {} ({})",
            path.display(),
            bad.len(),
            i / FACE_VALUES,
            crate::probes::FACES[i % FACE_VALUES / 3],
            values[i]
        )),
    })
}

/// Reads the KTX2 lightmap opened as `file` (`length` bytes) and checks it
/// against the EXR's texels (`ktx2_violations`). Zstandard stores data that
/// does not shrink as raw blocks, a few bytes over the data; a file larger
/// than that for the EXR's texels is refused unread.
fn ktx2_file_violations(
    path: &Path,
    file: std::fs::File,
    length: u64,
    exr: &[[f32; 3]],
    scene: &SceneReport,
) -> Result<Vec<Violation>> {
    use std::io::Read;
    let most = exr.len() as u64 * 4 + 64 * 1024;
    if length > most {
        let message = format!("lightmap '{}' is {length} bytes, more than {most} for its texels", path.display());
        return Ok(vec![Violation { scene: scene.name.clone(), message }]);
    }
    let mut bytes = Vec::with_capacity(length as usize);
    file.take(length).read_to_end(&mut bytes).with_context(|| format!("lightmap '{}': cannot read", path.display()))?;
    Ok(ktx2_violations(path, &bytes, exr, scene))
}

/// The KTX2 lightmap against the EXR's texels `exr`: the atlas's size, and
/// every texel the EXR's packed as E5B9G9R9, bit for bit (a bake writes both
/// from the same values).
fn ktx2_violations(path: &Path, bytes: &[u8], exr: &[[f32; 3]], scene: &SceneReport) -> Vec<Violation> {
    use crate::export::ktx2::{decode, pack_e5b9g9r9, unpack_e5b9g9r9};
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let say = |message: String| vec![Violation { scene: scene.name.clone(), message: format!("{name}: {message}") }];
    let (width, height, texels) = match decode(bytes, exr.len() as u64) {
        Ok(decoded) => decoded,
        Err(e) => return say(format!("{e:#}")),
    };
    if (width, height) != (scene.atlas.width, scene.atlas.height) || texels.len() != exr.len() {
        return say(format!("{width}×{height} but the atlas is {}×{}", scene.atlas.width, scene.atlas.height));
    }
    let differing: Vec<usize> = (0..exr.len()).filter(|&i| texels[i] != pack_e5b9g9r9(exr[i])).collect();
    match differing.first() {
        None => Vec::new(),
        Some(&i) => say(format!(
            "{} texels differ from the EXR's, the first at ({}, {}): {:?} where the EXR has {:?}",
            differing.len(),
            i as u32 % width,
            i as u32 / width,
            unpack_e5b9g9r9(texels[i]),
            exr[i]
        )),
    }
}

/// Re-reads a lightmap EXR and checks its texels (`texel_violations`).
/// `file` is the lightmap opened, `length` its size in bytes.
pub fn lightmap_violations(
    path: &Path,
    file: std::fs::File,
    length: u64,
    scene: &SceneReport,
) -> Result<Vec<Violation>> {
    let (width, pixels) = read_lightmap_exr(path, file, length)?;
    Ok(texel_violations(path, width, &pixels, scene))
}

/// A lightmap EXR's texels, row by row from the top, with its width.
fn read_lightmap_exr(path: &Path, mut file: std::fs::File, length: u64) -> Result<(usize, Vec<[f32; 3]>)> {
    use exr::prelude::*;
    use std::io::{Seek, SeekFrom};
    let cannot_read = || format!("lightmap '{}': cannot read", path.display());
    crate::environment::check_exr_size(&file, length).map_err(|e| anyhow::anyhow!("{e}")).with_context(cannot_read)?;
    file.seek(SeekFrom::Start(0)).with_context(cannot_read)?;
    let image = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .rgba_channels(
            |size, _| (size.width(), vec![[0f32; 3]; size.width() * size.height()]),
            |(width, pixels), p, (r, g, b, _a): (f32, f32, f32, f32)| pixels[p.y() * *width + p.x()] = [r, g, b],
        )
        .first_valid_layer()
        .all_attributes()
        .from_buffered(std::io::BufReader::new(file))
        .with_context(cannot_read)?;
    Ok(image.layer_data.channel_data.pixels)
}

/// A lightmap's texels checked: none NaN, infinite or negative (each named
/// with the meshes whose texel rectangle holds it), the size the report says,
/// and every covered texel written: at least as many non-zero texels and as
/// much Σ L_lm as the covered texels hold (dilation only adds texels outside
/// the charts).
fn texel_violations(path: &Path, width: usize, pixels: &[[f32; 3]], scene: &SceneReport) -> Vec<Violation> {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let height = pixels.len().checked_div(width).unwrap_or(0);
    let mut out = Vec::new();
    let mut say = |message: String| out.push(Violation { scene: scene.name.clone(), message });
    if (width as u32, height as u32) != (scene.atlas.width, scene.atlas.height) {
        say(format!("{name} is {width}×{height} but the atlas is {}×{}", scene.atlas.width, scene.atlas.height));
        return out;
    }
    let mut bad = Vec::new();
    let mut nonzero = 0usize;
    let mut sum = 0.0f64;
    for (i, p) in pixels.iter().enumerate() {
        if p.iter().any(|c| !c.is_finite() || *c < 0.0) {
            bad.push(i);
            continue;
        }
        if p.iter().any(|&c| c != 0.0) {
            nonzero += 1;
        }
        sum += luminance(p.map(|c| c as f64));
    }
    for &i in bad.iter().take(5) {
        let (x, y) = ((i % width) as u32, (i / width) as u32);
        let meshes: Vec<&str> = scene
            .energy
            .iter()
            .filter(|p| {
                x >= p.atlas_bounds[0] && y >= p.atlas_bounds[1] && x < p.atlas_bounds[2] && y < p.atlas_bounds[3]
            })
            .map(|p| p.name.as_str())
            .collect();
        let owner = if meshes.is_empty() {
            "outside every mesh's texels".to_string()
        } else {
            format!("mesh {}", meshes.join(" or "))
        };
        say(format!("{name}: texel ({x}, {y}) of {owner} is {:?}: NaN, infinite or negative", pixels[i]));
    }
    if bad.len() > 5 {
        say(format!("{name}: {} more texels are NaN, infinite or negative", bad.len() - 5));
    }
    let a = &scene.atlas.energy;
    let lit = a.texels - a.zero_texels - a.invalid_texels;
    if bad.is_empty() && nonzero < lit {
        say(format!(
            "{name}: only {nonzero} texels are non-zero but {lit} covered texels are lit: some were not written"
        ));
    }
    let covered_sum = luminance(a.sum_lightmap);
    if bad.is_empty() && sum < covered_sum * (1.0 - ROUND_OFF) {
        say(format!(
            "{name}: holds Σ L_lm = {sum:.6e} (luminance) but its covered texels {covered_sum:.6e}: some were not written"
        ));
    }
    out
}
