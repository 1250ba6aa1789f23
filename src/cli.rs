//! Command-line arguments → a validated `Config`. Each option is defined
//! once, here, with its help text and default; the tests at the bottom parse
//! every one of them.

use std::path::PathBuf;

use anyhow::{Result, bail};
use clap::{Parser, Subcommand, ValueEnum};

use crate::check::{self, CheckOptions};
use crate::config::{BakeOptions, Config, EnvironmentOptions};
use crate::environment::LightMode;
use crate::export::{ExportOptions, Format, MaterialDefault};
use crate::import::ImportOptions;
use crate::probes::ProbeOptions;
use crate::progress::LogMode;
use crate::reference::ReferenceCheck;
use crate::report::ReportOptions;
use crate::solve::{BounceOptions, SolveOptions};
use crate::unwrap::{Backend, UnwrapOptions};

/// Bake diffuse global illumination from an HDR environment into glTF lightmaps.
///
/// Each input gets `OUT/<name>.glb` (TEXCOORD_1 plus the baked lighting, shown
/// by any glTF viewer; the input's own material with the lightmap as
/// MOZ_lightmap one KHR_materials_variants variant away, or the other way
/// round with `--material engine`), `OUT/<name>.lightmap0.exr` (the HDR
/// lightmap, L_lm = E/π per texel) and `OUT/<name>.lightmap0.ktx2` (the same
/// as an engine's float texture, E5B9G9R9: Bevy's Lightmap); the run writes
/// `OUT/report.json`.
/// Outputs appear only when the whole run succeeds; inputs are never modified.
/// `bake check` compares a bake's report with a golden one (see `bake check --help`).
///
/// Exit codes: 0 success, 1 `bake check` failed, 2 error (one line on stderr
/// names the file and the problem).
#[derive(Parser, Debug)]
#[command(
    name = "bake",
    version,
    about,
    long_about,
    // `--padding -1` is a value out of range, not an unknown option `-1`.
    allow_negative_numbers = true,
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true
)]
pub struct Args {
    #[command(subcommand)]
    pub command: Option<Command>,

    /// glTF scenes to bake (.gltf or .glb)
    #[arg(required = true, value_name = "INPUT")]
    pub inputs: Vec<PathBuf>,

    /// Equirectangular HDR environment lighting the scene (.exr or .hdr); +Y is up,
    /// the map's centre column looks along +X
    #[arg(long, value_name = "FILE")]
    pub env: Option<PathBuf>,

    /// Output folder (created if missing)
    #[arg(short, long, value_name = "DIR", default_value = "baked")]
    pub output: PathBuf,

    /// Lightmap texel density in texels per metre [default: the highest that fits --max-atlas-size]
    #[arg(long, value_name = "X")]
    pub texels_per_unit: Option<f32>,

    /// Largest lightmap width and height in texels, at most the adapter's largest texture (16384 on lavapipe);
    /// a density that does not fit is lowered, with a notice
    #[arg(long, value_name = "N", default_value_t = 1024, value_parser = clap::value_parser!(u32).range(16..))]
    pub max_atlas_size: u32,

    /// Empty texels kept around each lightmap chart
    #[arg(long, value_name = "N", default_value_t = 2, value_parser = clap::value_parser!(u32).range(0..=64))]
    pub padding: u32,

    /// UV unwrapper for the lightmap UVs
    #[arg(long, value_name = "NAME", default_value_t = Backend::default())]
    pub unwrapper: Backend,

    /// How the environment becomes lights: `cube:N` takes every texel of an N×N cube map
    /// (6·N² lights, the paper's scheme), a plain number K spends K lights where the energy is
    #[arg(long, value_name = "MODE", default_value_t = LightMode::default())]
    pub lights: LightMode,

    /// Turn the environment about +Y by this many degrees
    #[arg(long, value_name = "DEG", default_value_t = 0.0, allow_hyphen_values = true)]
    pub env_rotation: f32,

    /// Scale the environment's radiance
    #[arg(long, value_name = "X", default_value_t = 1.0)]
    pub env_intensity: f32,

    /// Replace NaN or infinite environment texels (with 0, or the largest finite value)
    /// instead of refusing the map
    #[arg(long)]
    pub clamp_nonfinite: bool,

    /// Keep each texel's direct light at its centre even where a shadow edge crosses it
    /// (by default such texels average sub-samples of their footprint)
    #[arg(long)]
    pub no_supersample: bool,

    /// Shadow rays each texel may cast for the environment's light where something may block it, shared out among
    /// the lights by their solid angle and power: fewer bake faster, with noisier penumbrae
    #[arg(long, value_name = "N", default_value_t = crate::solve::direct::DEFAULT_RAYS,
          value_parser = clap::value_parser!(u32).range(1..=1 << 16))]
    pub direct_rays: u32,

    /// Keep the GPU passes' light where another surface comes close to a texel (by default it is traced along rays
    /// on the CPU there: contacts, and the wedge between a ring and the floor under it)
    #[arg(long)]
    pub no_contact_trace: bool,

    /// Leave the scene's punctual lights (KHR_lights_punctual) out of the bake; they stay in the output (by default
    /// they are baked as direct light, with exact shadows, besides the environment and emissive surfaces)
    #[arg(long)]
    pub no_punctual_lights: bool,

    /// Stop bouncing light when the unshot power (and the power shot ahead and still owed), each patch's weighted
    /// by how much of its hemisphere the scene covers, falls below this fraction of the power put in, weighted the
    /// same way; the rest is added as an ambient term and reported
    #[arg(long, value_name = "FRACTION", default_value_t = 0.005)]
    pub tolerance: f64,

    /// Stop bouncing after this many patch shots [default: 64 per patch]
    // Parsed as i64 so that `-1` is refused by its range, not as "invalid digit".
    #[arg(long, value_name = "N", value_parser = clap::builder::RangedI64ValueParser::<u64>::new().range(0..))]
    pub max_shots: Option<u64>,

    /// Stop bouncing after this many seconds (makes the result depend on the machine's speed)
    #[arg(long, value_name = "SECONDS")]
    pub max_time: Option<f64>,

    /// About how many shooter patches to group the lightmap texels into for bounced light
    #[arg(long, value_name = "N", default_value_t = 1024, value_parser = clap::value_parser!(u32).range(1..=1 << 20))]
    pub patches: u32,

    /// Exposure in stops of the 8-bit preview texture viewers show (the EXR is not scaled)
    #[arg(long, value_name = "EV", default_value_t = 0.0, allow_hyphen_values = true)]
    pub exposure: f32,

    /// Output packaging: `glb` (one file, images embedded) or `gltf` (NAME.gltf + NAME.bin + image files)
    #[arg(long, value_name = "FORMAT", default_value_t = Format::default())]
    pub format: Format,

    /// The material baked primitives draw by default: `preview` (unlit with the baked colour, what every glTF
    /// viewer shows exactly) or `engine` (the input's PBR material with the lightmap as MOZ_lightmap, for a
    /// pipeline that feeds an engine); the other form stays a KHR_materials_variants variant
    #[arg(long, value_name = "FORM", default_value_t = MaterialDefault::default())]
    pub material: MaterialDefault,

    /// Bake into the input's own TEXCOORD_1 when every primitive has one inside [0, 1] with no
    /// overlapping triangles; otherwise unwrap as usual, with a notice saying what failed
    #[arg(long)]
    pub keep_uv1: bool,

    /// Also bake light probes for what moves through the scene: an irradiance volume of ambient cubes no more
    /// than this many metres apart over the scene's bounds (or --probe-box), written as OUT/<name>.probes.ktx2
    /// (Bevy's IrradianceVolume) and OUT/<name>.probes.json + .bin
    #[arg(long, value_name = "SPACING")]
    pub probes: Option<f64>,

    /// The box the probes fill, in world coordinates (metres) [default: the scene's bounds]
    #[arg(
        long,
        value_name = "MINX,MINY,MINZ,MAXX,MAXY,MAXZ",
        value_delimiter = ',',
        allow_hyphen_values = true,
        requires = "probes"
    )]
    pub probe_box: Option<Vec<f64>>,

    /// Gather rays per probe (the noise of the surfaces' light in a probe falls as 1/√rays)
    #[arg(long, value_name = "N", default_value_t = crate::probes::DEFAULT_RAYS,
          value_parser = clap::value_parser!(u32).range(16..=1 << 16))]
    pub probe_rays: u32,

    /// Use the GPU adapter whose name contains this text (e.g. "llvmpipe", "NVIDIA")
    #[arg(long, value_name = "NAME")]
    pub adapter: Option<String>,

    /// Give up when one GPU submission (a batch of lights or shots, a read-back) runs longer than
    /// this: a hung driver then ends the bake with an error instead of blocking the build; 0: wait forever
    #[arg(long, value_name = "SECONDS", default_value_t = 600.0)]
    pub gpu_timeout: f64,

    /// Refuse an input that draws more triangles than this, node and GPU instances expanded, before reading them
    /// (unwrapping takes about 0.7 s per 100 000 triangles on 2 cores), or reads more than 3 vertices a triangle,
    /// or draws more than one primitive per 64 triangles of it
    #[arg(long, value_name = "N", default_value_t = crate::limits::DEFAULT_MAX_TRIANGLES,
          value_parser = clap::builder::RangedI64ValueParser::<u64>::new().range(1..))]
    pub max_triangles: u64,

    /// Print nothing but errors
    #[arg(short, long)]
    pub quiet: bool,

    /// Progress format when not quiet: bars on a terminal and text otherwise (auto), or one JSON object per line
    #[arg(long, value_name = "FORMAT", default_value = "auto")]
    pub log_format: LogFormat,

    /// Also write OUT/<name>.convergence.svg: unshot power and error estimate against time (log scale)
    #[arg(long)]
    pub plot: bool,

    /// Wait on the GPU after each pass of the bounce pass's batches and record each pass's seconds in
    /// report.json (scenes[].bounce.passes): slower, for profiling; the lightmaps are the same, unless
    /// --max-time stops the bounce pass earlier
    #[arg(long)]
    pub time_passes: bool,

    /// Estimate N texels with the CPU reference path tracer before solving, and record the bake's
    /// error at them (relative RMSE) at every point of the convergence trace (slow: N × the samples)
    #[arg(long, value_name = "N", value_parser = clap::builder::RangedI64ValueParser::<usize>::new().range(1..=65536))]
    pub reference: Option<usize>,

    /// Paths per texel for --reference (its noise falls as 1/√samples)
    #[arg(long, value_name = "N", default_value_t = 256, value_parser = clap::value_parser!(u32).range(1..=1 << 20))]
    pub reference_samples: u32,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Check a bake's texel energy against a golden report, and the invariants every bake keeps
    ///
    /// TARGET is a bake's report.json, or a baked .glb/.gltf whose run's report.json lies beside
    /// it (then only that scene is checked). Lightmap EXRs beside the report are re-read and
    /// their texels checked too, and each KTX2 against its EXR. Without --against, only the invariants are checked: no NaN,
    /// infinite or negative texel, every covered texel written, reflected power within received
    /// power times albedo, emitted power accounted for.
    ///
    /// Exit codes: 0 pass, 1 check failed (a table on stdout says what moved or which invariant
    /// broke), 2 error (a file is missing or unreadable; one line on stderr).
    Check(CheckArgs),
}

#[derive(clap::Args, Debug)]
pub struct CheckArgs {
    /// The bake to check: its report.json, or a baked .glb/.gltf with report.json beside it
    #[arg(value_name = "TARGET")]
    pub target: PathBuf,

    /// Golden report.json to compare texel energy per mesh with
    #[arg(long, value_name = "GOLDEN")]
    pub against: Option<PathBuf>,

    /// Largest relative change allowed per figure, as a percentage ("2%") or a fraction ("0.02")
    #[arg(long, value_name = "X", default_value = "2%", value_parser = check::parse_tolerance)]
    pub tolerance: f64,

    /// Print nothing when the check passes
    #[arg(short, long)]
    pub quiet: bool,
}

impl CheckArgs {
    pub fn options(&self) -> CheckOptions {
        CheckOptions { target: self.target.clone(), against: self.against.clone(), tolerance: self.tolerance }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum LogFormat {
    Auto,
    Text,
    Json,
}

impl Args {
    /// Checks ranges and builds the run's configuration.
    pub fn into_config(self) -> Result<Config> {
        self.check_ranges()?;
        let log = match (self.quiet, self.log_format) {
            (true, _) => LogMode::Quiet,
            (false, LogFormat::Auto) => LogMode::Auto,
            (false, LogFormat::Text) => LogMode::Text,
            (false, LogFormat::Json) => LogMode::Json,
        };
        let bake = self.bake_options();
        Ok(Config {
            inputs: self.inputs,
            environment: self.env,
            environment_options: EnvironmentOptions {
                lights: self.lights,
                rotation_degrees: self.env_rotation,
                intensity: self.env_intensity,
                clamp_nonfinite: self.clamp_nonfinite,
            },
            import: ImportOptions { max_triangles: self.max_triangles },
            output: self.output,
            adapter: self.adapter,
            gpu_timeout: (self.gpu_timeout > 0.0).then(|| std::time::Duration::from_secs_f64(self.gpu_timeout)),
            bake,
            log,
            report: ReportOptions { arguments: Vec::new(), plot: self.plot },
        })
    }

    /// Refuses the values clap's parsers let through: floats that are not
    /// finite or out of their range.
    fn check_ranges(&self) -> Result<()> {
        if let Some(t) = self.texels_per_unit
            && !(t.is_finite() && t > 0.0)
        {
            bail!("--texels-per-unit must be a positive number, not {t}");
        }
        // --max-atlas-size's upper limit is the adapter's largest texture, checked once it is open.
        if !(self.env_rotation.is_finite()) {
            bail!("--env-rotation must be a finite angle");
        }
        if !(self.env_intensity.is_finite() && self.env_intensity >= 0.0) {
            bail!("--env-intensity must be a finite number ≥ 0, not {}", self.env_intensity);
        }
        if !(self.tolerance.is_finite() && self.tolerance >= 0.0 && self.tolerance < 1.0) {
            bail!("--tolerance must be a fraction in [0, 1), not {}", self.tolerance);
        }
        // Past about 1.8e19 s a Duration cannot hold it; 1e9 s is 31 years.
        if !(0.0..=1e9).contains(&self.gpu_timeout) {
            bail!(
                "--gpu-timeout must be a number of seconds in [0, 1e9] (0: wait forever), not {}",
                crate::limits::figure(self.gpu_timeout)
            );
        }
        if let Some(seconds) = self.max_time
            && !(seconds.is_finite() && seconds >= 0.0)
        {
            bail!("--max-time must be a number of seconds ≥ 0, not {seconds}");
        }
        if !self.exposure.is_finite() {
            bail!("--exposure must be finite");
        }
        self.check_probe_ranges()
    }

    fn check_probe_ranges(&self) -> Result<()> {
        if let Some(spacing) = self.probes
            && !(spacing.is_finite() && spacing > 0.0)
        {
            bail!("--probes must be a positive distance in metres, not {spacing}");
        }
        if let Some(b) = &self.probe_box {
            let box_ok = b.len() == 6 && b.iter().all(|v| v.is_finite()) && (0..3).all(|k| b[k] <= b[k + 3]);
            if !box_ok {
                bail!("--probe-box must be six finite numbers MINX,MINY,MINZ,MAXX,MAXY,MAXZ with each min ≤ its max");
            }
        }
        Ok(())
    }

    /// What each input's bake takes: unwrap, solve, export and `--reference`.
    fn bake_options(&self) -> BakeOptions {
        BakeOptions {
            unwrap: UnwrapOptions {
                backend: self.unwrapper,
                texels_per_unit: self.texels_per_unit,
                max_atlas_size: self.max_atlas_size,
                padding: self.padding,
            },
            keep_uv1: self.keep_uv1,
            solve: SolveOptions {
                direct_rays: self.direct_rays,
                supersample: !self.no_supersample,
                contact: !self.no_contact_trace,
                punctual: !self.no_punctual_lights,
                bounce: BounceOptions {
                    tolerance: self.tolerance,
                    max_shots: self.max_shots,
                    max_seconds: self.max_time,
                    patches: self.patches,
                    time_passes: self.time_passes,
                    ..BounceOptions::default()
                },
                ..SolveOptions::default()
            },
            export: ExportOptions {
                exposure: self.exposure,
                format: self.format,
                material: self.material,
                ..ExportOptions::default()
            },
            probes: self.probes.map(|spacing| ProbeOptions {
                spacing,
                region: self.probe_box.as_ref().map(|b| [[b[0], b[1], b[2]], [b[3], b[4], b[5]]]),
                rays: self.probe_rays,
            }),
            reference: self.reference.map(|texels| ReferenceCheck {
                texels,
                samples: self.reference_samples,
                environment: None,
                env_rotation_degrees: self.env_rotation,
                env_intensity: self.env_intensity,
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(args: &[&str]) -> Result<Config> {
        let mut full = vec!["bake"];
        full.extend_from_slice(args);
        Args::try_parse_from(full).map_err(|e| anyhow::anyhow!("{e}"))?.into_config()
    }

    #[test]
    fn defaults() {
        let config = parse(&["a.glb"]).unwrap();
        assert_eq!(config.inputs, vec![PathBuf::from("a.glb")]);
        assert_eq!(config.output, PathBuf::from("baked"));
        assert_eq!(config.environment, None);
        assert_eq!(config.bake.unwrap.max_atlas_size, 1024);
        assert_eq!(config.bake.unwrap.padding, 2);
        assert_eq!(config.bake.unwrap.texels_per_unit, None);
        assert_eq!(config.environment_options.lights, LightMode::default());
        assert_eq!(config.environment_options.intensity, 1.0);
        assert_eq!(config.bake.export.exposure, 0.0);
        assert_eq!(config.bake.export.format, Format::Glb);
        assert_eq!(config.bake.export.material, MaterialDefault::Preview);
        assert!(!config.bake.keep_uv1);
        assert_eq!(config.bake.solve.bounce.tolerance, 0.005);
        assert_eq!(config.bake.solve.bounce.max_shots, None);
        assert_eq!(config.bake.solve.bounce.patches, 1024);
        assert_eq!(config.bake.solve.direct_rays, 1024);
        assert_eq!(config.import.max_triangles, crate::limits::DEFAULT_MAX_TRIANGLES);
        assert_eq!(config.log, LogMode::Auto);
    }

    #[test]
    fn every_option_parses() {
        let config = parse(&[
            "a.glb",
            "b.gltf",
            "--env",
            "sky.exr",
            "-o",
            "out",
            "--texels-per-unit",
            "12.5",
            "--max-atlas-size",
            "512",
            "--padding",
            "3",
            "--unwrapper",
            "uvunwrap",
            "--lights",
            "cube:8",
            "--env-rotation",
            "-90",
            "--env-intensity",
            "2",
            "--clamp-nonfinite",
            "--exposure",
            "-1.5",
            "--tolerance",
            "0.05",
            "--max-shots",
            "100",
            "--max-time",
            "2.5",
            "--patches",
            "300",
            "--adapter",
            "llvmpipe",
            "--log-format",
            "json",
            "--plot",
            "--format",
            "gltf",
            "--keep-uv1",
            "--max-triangles",
            "123",
            "--material",
            "engine",
            "--probes",
            "0.5",
            "--probe-box",
            "-1,0,-2.5,1,2,2.5",
            "--probe-rays",
            "256",
        ])
        .unwrap();
        assert_eq!(config.inputs.len(), 2);
        assert_eq!(config.environment, Some(PathBuf::from("sky.exr")));
        assert_eq!(config.output, PathBuf::from("out"));
        assert_eq!(config.bake.unwrap.texels_per_unit, Some(12.5));
        assert_eq!(config.bake.unwrap.max_atlas_size, 512);
        assert_eq!(config.bake.unwrap.padding, 3);
        assert_eq!(config.bake.unwrap.backend, Backend::Uvunwrap);
        assert_eq!(config.environment_options.lights, LightMode::Cube { face_size: 8 });
        assert_eq!(config.environment_options.rotation_degrees, -90.0);
        assert_eq!(config.environment_options.intensity, 2.0);
        assert!(config.environment_options.clamp_nonfinite);
        assert_eq!(config.bake.export.exposure, -1.5);
        assert_eq!(config.bake.solve.bounce.tolerance, 0.05);
        assert_eq!(config.bake.solve.bounce.max_shots, Some(100));
        assert_eq!(config.bake.solve.bounce.max_seconds, Some(2.5));
        assert_eq!(config.bake.solve.bounce.patches, 300);
        assert_eq!(config.adapter.as_deref(), Some("llvmpipe"));
        assert_eq!(config.log, LogMode::Json);
        assert!(config.report.plot);
        assert_eq!(config.bake.export.format, Format::Gltf);
        assert!(config.bake.keep_uv1);
        assert_eq!(config.import.max_triangles, 123);
        assert_eq!(config.bake.export.material, MaterialDefault::Engine);
        let probes = ProbeOptions { spacing: 0.5, region: Some([[-1.0, 0.0, -2.5], [1.0, 2.0, 2.5]]), rays: 256 };
        assert_eq!(config.bake.probes, Some(probes));
        assert_eq!(parse(&["a.glb", "--material", "preview"]).unwrap().bake.export.material, MaterialDefault::Preview);
        assert_eq!(parse(&["a.glb", "-q"]).unwrap().log, LogMode::Quiet);
    }

    fn parse_check(args: &[&str]) -> Result<CheckArgs> {
        let mut full = vec!["bake", "check"];
        full.extend_from_slice(args);
        match Args::try_parse_from(full).map_err(|e| anyhow::anyhow!("{e}"))?.command {
            Some(Command::Check(check)) => Ok(check),
            None => anyhow::bail!("not parsed as `bake check`"),
        }
    }

    #[test]
    fn check_subcommand_parses_and_bake_still_takes_inputs() {
        let check = parse_check(&["out/report.json", "--against", "golden.json", "--tolerance", "5%"]).unwrap();
        assert_eq!(check.target, PathBuf::from("out/report.json"));
        assert_eq!(check.against, Some(PathBuf::from("golden.json")));
        assert!((check.tolerance - 0.05).abs() < 1e-12);
        assert!((parse_check(&["a.glb", "--tolerance", "0.02"]).unwrap().tolerance - 0.02).abs() < 1e-12);
        assert_eq!(parse_check(&["a.glb"]).unwrap().tolerance, check::DEFAULT_TOLERANCE);
        assert_eq!(parse_check(&["a.glb"]).unwrap().against, None);
        for bad in
            [&["a.glb", "--tolerance", "2"][..], &["a.glb", "--tolerance", "-1%"], &["a.glb", "--tolerance", "x"], &[]]
        {
            assert!(parse_check(bad).is_err(), "{bad:?} was accepted");
        }
        // A bake whose second input happens to be called "check" is still a bake.
        let args = Args::try_parse_from(["bake", "a.glb", "check", "--env", "sky.exr"]).unwrap();
        assert!(args.command.is_none());
        assert_eq!(args.inputs, vec![PathBuf::from("a.glb"), PathBuf::from("check")]);
    }

    #[test]
    fn the_direct_pass_ray_budget_parses() {
        let config = parse(&["a.glb", "--direct-rays", "96"]).unwrap();
        assert_eq!(config.bake.solve.direct_rays, 96);
    }

    #[test]
    fn out_of_range_values_are_refused() {
        for bad in [
            &["a.glb", "--texels-per-unit", "0"][..],
            &["a.glb", "--texels-per-unit", "-3"],
            &["a.glb", "--max-atlas-size", "8"],
            &["a.glb", "--padding", "100"],
            &["a.glb", "--env-intensity", "-1"],
            &["a.glb", "--tolerance", "1.5"],
            &["a.glb", "--max-time", "-1"],
            &["a.glb", "--patches", "0"],
            &["a.glb", "--direct-rays", "0"],
            &["a.glb", "--direct-rays", "100000"],
            &["a.glb", "--lights", "sphere:3"],
            &["a.glb", "--unwrapper", "magic"],
            &["a.glb", "--format", "obj"],
            &["a.glb", "--material", "pbr"],
            &["a.glb", "--max-shots", "-1"],
            &["a.glb", "--reference", "0"],
            &["a.glb", "--max-triangles", "0"],
            &["a.glb", "--gpu-timeout", "1e300"],
            &[],
        ] {
            assert!(parse(bad).is_err(), "{bad:?} was accepted");
        }
    }
}
