//! The `bake` command: parse, run, print the error chain once, exit with a
//! code that means something (0 ok, 2 error).

use std::process::ExitCode;

use clap::Parser;

use bake::cli::Args;
use bake::gpu::Gpu;
use bake::progress::{LogMode, Reporter};

fn main() -> ExitCode {
    quiet_mesa_runtime_dir_warning();
    let args = Args::parse();
    match run(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("bake: error: {error:#}");
            ExitCode::from(2)
        }
    }
}

fn run(args: Args) -> anyhow::Result<()> {
    let config = args.into_config()?;
    bake::preflight(&config)?;
    let mut progress = Reporter::new(config.log);
    let gpu = Gpu::new(config.adapter.as_deref())?;
    if config.log != LogMode::Quiet {
        eprintln!("adapter: {}", gpu.adapter);
    }
    let report = bake::run(&config, &gpu, &mut progress)?;
    if config.log != LogMode::Quiet {
        eprintln!(
            "baked {} scene(s) in {:.2} s into {}",
            report.scenes.len(),
            report.total_seconds,
            config.output.display()
        );
    }
    Ok(())
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
