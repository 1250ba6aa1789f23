//! The `bake` command: parse, run, print the error chain once, exit with a
//! code that means something (0 ok, 1 `bake check` failed, 2 error).

#![warn(clippy::too_many_lines)]

use std::process::ExitCode;

use clap::Parser;

use bake::Gpu;
use bake::check::EXIT_ERROR;
use bake::cli::{Args, CheckArgs, Command};
use bake::progress::{LogMode, Reporter, printable};

fn main() -> ExitCode {
    quiet_mesa_runtime_dir_warning();
    let mut args = match Args::try_parse() {
        Ok(args) => args,
        Err(error) => return usage_error(error),
    };
    bake::remove_staging_on_signals();
    let json_errors = args.log_format == bake::cli::LogFormat::Json && !args.quiet;
    let result = match args.command.take() {
        Some(Command::Check(check)) => run_check(&check),
        None => run(args).map(|()| ExitCode::SUCCESS),
    };
    result.unwrap_or_else(|error| {
        if json_errors {
            eprintln!("{}", serde_json::json!({ "event": "error", "message": format!("{error:#}") }));
        } else {
            eprintln!("bake: error: {}", printable(&format!("{error:#}")));
        }
        ExitCode::from(EXIT_ERROR)
    })
}

/// Help and version as clap prints them; any other command-line error as
/// one line (clap's own takes two to five, with usage and tips).
fn usage_error(error: clap::Error) -> ExitCode {
    use clap::error::ErrorKind;
    if matches!(error.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion) {
        error.exit();
    }
    let text = error.render().to_string();
    let kept = |line: &&str| !(line.is_empty() || ["Usage:", "For more", "tip:"].iter().any(|s| line.starts_with(s)));
    let line = text.lines().map(str::trim).filter(kept).collect::<Vec<_>>().join(" ");
    eprintln!("bake: error: {}", printable(line.strip_prefix("error: ").unwrap_or(&line)));
    ExitCode::from(EXIT_ERROR)
}

fn run(args: Args) -> anyhow::Result<()> {
    let mut config = args.into_config()?;
    config.report.arguments = std::env::args().collect();
    bake::preflight(&config)?;
    let mut progress = Reporter::new(config.log);
    let gpu = Gpu::new(config.adapter.as_deref())?.with_wait_timeout(config.gpu_timeout);
    progress.info("adapter", &format!("adapter: {}", gpu.adapter));
    let report = bake::run(&config, &gpu, &mut progress)?;
    if config.log != LogMode::Quiet {
        progress.summary(&report, &config.output);
    }
    Ok(())
}

/// `bake check`: the table on stdout, exit code 0 (pass) or 1 (failed).
fn run_check(args: &CheckArgs) -> anyhow::Result<ExitCode> {
    let findings = bake::check::run(&args.options())?;
    if !(args.quiet && findings.passed()) {
        print!("{}", findings.render());
    }
    Ok(ExitCode::from(findings.exit_code()))
}

/// Mesa's Vulkan loader complains on stderr when XDG_RUNTIME_DIR is unset
/// (common in CI and containers); give it a private folder so the user sees
/// only bake's own output.
fn quiet_mesa_runtime_dir_warning() {
    if std::env::var_os("XDG_RUNTIME_DIR").is_some() {
        return;
    }
    let user = std::env::var("USER").unwrap_or_else(|_| "user".into());
    let dir = std::env::temp_dir().join(format!("bake-runtime-{user}"));
    if std::fs::create_dir_all(&dir).is_ok() {
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let _ = std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o700));
        }
        // SAFETY: called first thing in main, before any other thread exists.
        unsafe { std::env::set_var("XDG_RUNTIME_DIR", &dir) };
    }
}
