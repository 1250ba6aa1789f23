//! What the user sees while a bake runs: numbered stages with a progress bar
//! and ETA on a terminal, plain log lines (text or JSON) when stderr is not
//! a terminal, nothing but errors with `--quiet`; at the end a one-screen
//! summary (or one JSON object with `"event": "summary"`).
//!
//! JSON mode writes one object per line on stderr, each with an `event`:
//! `adapter`, `stage` (a stage starts), `progress`, `notice`, `finish` (a
//! stage ended; `message` says what it made), `summary` (the run's figures,
//! see `Summary`) and `error` (the run failed; `message` is the cause).

use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use serde::Serialize;

use crate::colour::luminance;
use crate::report::Report;

/// How progress is shown.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LogMode {
    /// Bars on a terminal, plain lines otherwise.
    Auto,
    /// Plain text lines on stderr.
    Text,
    /// One JSON object per line on stderr, for build systems.
    Json,
    /// Errors only.
    Quiet,
}

/// Receives the pipeline's progress.
pub trait Progress {
    /// A stage starts. `scene` names the input it works on (empty for shared stages).
    fn stage(&mut self, scene: &str, name: &str);
    /// Work units done out of `total` in the current stage.
    fn update(&mut self, done: u64, total: u64);
    /// The current stage finished; `summary` says what it produced.
    fn finish(&mut self, summary: &str);
    /// A one-line notice (something left out, changed or clamped).
    fn notice(&mut self, message: &str);
}

/// Progress that goes nowhere (tests, library use).
pub struct Silent;

impl Progress for Silent {
    fn stage(&mut self, _: &str, _: &str) {}
    fn update(&mut self, _: u64, _: u64) {}
    fn finish(&mut self, _: &str) {}
    fn notice(&mut self, _: &str) {}
}

/// Progress on stderr in the chosen mode.
pub struct Reporter {
    mode: LogMode,
    bar: Option<ProgressBar>,
    scene: String,
    name: String,
    started: Instant,
    count: usize,
    last_line: Instant,
}

impl Reporter {
    pub fn new(mode: LogMode) -> Reporter {
        let mode = match mode {
            LogMode::Auto if std::io::stderr().is_terminal() => LogMode::Auto,
            LogMode::Auto => LogMode::Text,
            other => other,
        };
        Reporter {
            mode,
            bar: None,
            scene: String::new(),
            name: String::new(),
            started: Instant::now(),
            count: 0,
            last_line: Instant::now(),
        }
    }

    /// "scene stage", as the terminal shows it: a scene is named after its file, whose name may hold control characters.
    fn label(&self) -> String {
        printable(&if self.scene.is_empty() { self.name.clone() } else { format!("{} {}", self.scene, self.name) })
    }

    /// A one-line message outside any stage (e.g. which adapter runs), as event `event` in JSON.
    pub fn info(&mut self, event: &str, message: &str) {
        match self.mode {
            LogMode::Quiet => {}
            LogMode::Json => {
                let mut err = std::io::stderr().lock();
                let _ = writeln!(err, "{}", serde_json::json!({ "event": event, "message": message }));
            }
            _ => eprintln!("{message}"),
        }
    }

    /// The final summary: a screen of text, or one JSON object in JSON mode.
    pub fn summary(&mut self, report: &Report, output: &Path) {
        let summary = Summary::of(report, output);
        match self.mode {
            LogMode::Quiet => {}
            LogMode::Json => {
                let mut value = serde_json::to_value(&summary).unwrap_or_default();
                value["event"] = "summary".into();
                let mut err = std::io::stderr().lock();
                let _ = writeln!(err, "{value}");
            }
            _ => eprint!("{}", summary.text()),
        }
    }

    fn line(&self, event: &str, message: &str) {
        let mut err = std::io::stderr().lock();
        let _ = match self.mode {
            LogMode::Json => writeln!(
                err,
                "{}",
                serde_json::json!({ "event": event, "scene": self.scene, "stage": self.name, "message": message })
            ),
            _ => writeln!(err, "{message}"),
        };
    }
}

impl Progress for Reporter {
    fn stage(&mut self, scene: &str, name: &str) {
        self.scene = scene.to_string();
        self.name = name.to_string();
        self.started = Instant::now();
        self.last_line = Instant::now();
        self.count += 1;
        if self.mode == LogMode::Auto {
            let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr());
            bar.set_style(
                ProgressStyle::with_template("{prefix:>4} {msg:32} {spinner} {wide_bar} {pos}/{len} eta {eta}")
                    .unwrap(),
            );
            bar.set_prefix(format!("[{}]", self.count));
            bar.set_message(self.label());
            bar.enable_steady_tick(Duration::from_millis(120));
            self.bar = Some(bar);
        } else if self.mode == LogMode::Json {
            self.line("stage", &self.label());
        }
    }

    fn update(&mut self, done: u64, total: u64) {
        if let Some(bar) = &self.bar {
            bar.set_length(total);
            bar.set_position(done);
        } else if self.mode == LogMode::Text && self.last_line.elapsed() > Duration::from_secs(10) {
            self.last_line = Instant::now();
            self.line("progress", &format!("      {}: {done}/{total}", self.label()));
        }
    }

    fn finish(&mut self, summary: &str) {
        let seconds = self.started.elapsed().as_secs_f64();
        let text = format!("[{}] {}: {summary} ({seconds:.2} s)", self.count, self.label());
        match self.bar.take() {
            Some(bar) => {
                bar.finish_and_clear();
                eprintln!("{text}");
            }
            None if self.mode == LogMode::Quiet => {}
            None => self.line("finish", &text),
        }
    }

    fn notice(&mut self, message: &str) {
        let message = printable(message);
        match &self.bar {
            Some(bar) => bar.println(format!("note: {message}")),
            None if self.mode == LogMode::Quiet => {}
            None => self.line("notice", &format!("note: {message}")),
        }
    }
}

/// The figures a user wants after a run, on one screen.
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    pub seconds: f64,
    pub adapter: String,
    /// Lights from the environment (0 without one).
    pub lights: usize,
    pub environment: Option<PathBuf>,
    pub scenes: Vec<SceneSummary>,
    pub report: PathBuf,
    /// Largest resident set of any stage, bytes (Linux).
    pub peak_rss_bytes: Option<u64>,
}

#[derive(Clone, Debug, Serialize)]
pub struct SceneSummary {
    pub name: String,
    pub seconds: f64,
    pub texels: usize,
    pub atlas: [u32; 2],
    /// Bounce shots and why the pass stopped ("converged", "max shots",
    /// "max time"), or why it was left out.
    pub bounce_shots: u64,
    pub bounce: String,
    /// Unshot power over the power put in, when the bounce pass stopped.
    pub unshot_fraction: f64,
    /// Luminance of the area-weighted mean L_lm.
    pub mean_luminance: f64,
    /// `--reference`: relative RMSE against the CPU reference, its noise, and the texel count.
    pub reference: Option<crate::report::ReferenceReport>,
    pub outputs: Vec<PathBuf>,
}

impl Summary {
    pub fn of(report: &Report, output: &Path) -> Summary {
        let stage_peaks = report.scenes.iter().flat_map(|s| s.stages.iter()).filter_map(|s| s.memory.as_ref());
        let env_peak = report.environment.as_ref().and_then(|e| e.memory.as_ref());
        let peak_rss_bytes = stage_peaks.chain(env_peak).map(|m| m.peak_rss_bytes).max();
        Summary {
            seconds: report.total_seconds,
            adapter: report.adapter.to_string(),
            lights: report.environment.as_ref().map_or(0, |e| e.lights),
            environment: report.environment.as_ref().map(|e| e.path.clone()),
            scenes: report
                .scenes
                .iter()
                .map(|s| SceneSummary {
                    name: s.name.clone(),
                    seconds: s.stages.iter().map(|t| t.seconds).sum(),
                    texels: s.texels.covered,
                    atlas: [s.atlas.width, s.atlas.height],
                    bounce_shots: s.bounce.as_ref().map_or(0, |b| b.shots),
                    bounce: match (&s.bounce, s.skipped.iter().find(|k| k.pass == "bounce")) {
                        (Some(b), _) => b.stopped_by.to_string(),
                        (None, Some(k)) => format!("left out: {}", k.reason),
                        (None, None) => "left out".to_string(),
                    },
                    unshot_fraction: s.bounce.as_ref().map_or(0.0, |b| b.unshot_fraction),
                    mean_luminance: luminance(s.atlas.energy.mean_lightmap),
                    reference: s.reference.clone(),
                    outputs: s.outputs.clone(),
                })
                .collect(),
            report: output.join("report.json"),
            peak_rss_bytes,
        }
    }

    /// The summary as a screen of text.
    pub fn text(&self) -> String {
        let mut out = String::from("── summary ──\n");
        let mut row = |key: &str, value: String| out.push_str(&format!("{key:<10} {value}\n"));
        row("time", format!("{:.2} s", self.seconds));
        row("adapter", self.adapter.clone());
        row(
            "lights",
            match &self.environment {
                Some(env) => format!("{} from {}", self.lights, printable(&env.display().to_string())),
                None => "no environment: the scenes' own emissive materials and punctual lights".to_string(),
            },
        );
        if let Some(peak) = self.peak_rss_bytes {
            row("memory", format!("{:.0} MiB peak resident", peak as f64 / (1u64 << 20) as f64));
        }
        for s in &self.scenes {
            out.push_str(&format!("{}  ({:.2} s)\n", printable(&s.name), s.seconds));
            let mut row = |key: &str, value: String| out.push_str(&format!("  {key:<8} {value}\n"));
            row(
                "texels",
                format!(
                    "{} covered in a {}×{} atlas, mean L_lm {:.4}",
                    s.texels, s.atlas[0], s.atlas[1], s.mean_luminance
                ),
            );
            row(
                "bounce",
                if s.bounce_shots > 0 || !s.bounce.starts_with("left out") {
                    format!(
                        "{} shots, {}, {:.2}% of the power unshot",
                        s.bounce_shots,
                        s.bounce,
                        s.unshot_fraction * 100.0
                    )
                } else {
                    s.bounce.clone()
                },
            );
            if let Some(r) = &s.reference {
                row(
                    "error",
                    format!(
                        "{:.2}% RMSE against the CPU reference at {} texels (its noise {:.2}%)",
                        r.error * 100.0,
                        r.texels,
                        r.noise * 100.0
                    ),
                );
            }
            for (i, path) in s.outputs.iter().enumerate() {
                row(if i == 0 { "wrote" } else { "" }, printable(&path.display().to_string()));
            }
        }
        out.push_str(&format!("{:<10} {}\n", "report", printable(&self.report.display().to_string())));
        out
    }
}

/// `text` with every control character escaped (`\n`, `\0`, `\u{1b}`):
/// names and bytes an input supplies may hold them, and must neither split
/// a one-line message nor drive the user's terminal.
pub fn printable(text: &str) -> String {
    let escape = |c: char| if c.is_control() { c.escape_debug().to_string() } else { c.to_string() };
    text.chars().map(escape).collect()
}
