//! What the user sees while a bake runs: numbered stages with a progress bar
//! and ETA on a terminal, plain log lines (text or JSON) when stderr is not
//! a terminal, nothing but errors with `--quiet`.

use std::io::{IsTerminal, Write};
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

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

    fn label(&self) -> String {
        if self.scene.is_empty() { self.name.clone() } else { format!("{} {}", self.scene, self.name) }
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
        match &self.bar {
            Some(bar) => bar.println(format!("note: {message}")),
            None if self.mode == LogMode::Quiet => {}
            None => self.line("notice", &format!("note: {message}")),
        }
    }
}
