//! A validated run configuration: one options struct per stage, each with
//! documented defaults. The CLI (`cli.rs`) builds it; tests build it directly.

use std::path::PathBuf;

use crate::environment::LightMode;
use crate::export::ExportOptions;
use crate::import::ImportOptions;
use crate::progress::LogMode;
use crate::report::{OptionsReport, ReportOptions};
use crate::solve::SolveOptions;
use crate::unwrap::UnwrapOptions;

/// How the environment map becomes lights.
#[derive(Clone, Debug)]
pub struct EnvironmentOptions {
    /// Light extraction mode (`--lights`).
    pub lights: LightMode,
    /// Turn the map about +Y, degrees (`--env-rotation`).
    pub rotation_degrees: f32,
    /// Scale its radiance (`--env-intensity`).
    pub intensity: f32,
    /// Replace NaN/infinite texels instead of refusing the map (`--clamp-nonfinite`).
    pub clamp_nonfinite: bool,
}

impl Default for EnvironmentOptions {
    fn default() -> Self {
        EnvironmentOptions {
            lights: LightMode::default(),
            rotation_degrees: 0.0,
            intensity: 1.0,
            clamp_nonfinite: false,
        }
    }
}

/// Options of the per-scene stages.
#[derive(Clone, Debug, Default)]
pub struct BakeOptions {
    pub unwrap: UnwrapOptions,
    /// Bake into the input's TEXCOORD_1 when every primitive has a valid one
    /// (`--keep-uv1`); otherwise unwrap, with a notice naming what failed.
    pub keep_uv1: bool,
    pub solve: SolveOptions,
    pub export: ExportOptions,
    /// `--probes`: bake an irradiance volume too.
    pub probes: Option<crate::probes::ProbeOptions>,
    /// `--reference`: estimate some texels with the CPU reference and trace the error at them.
    pub reference: Option<crate::reference::ReferenceCheck>,
}

/// Everything one `bake` run needs.
#[derive(Clone, Debug)]
pub struct Config {
    /// `.gltf` / `.glb` files; each gets its own outputs.
    pub inputs: Vec<PathBuf>,
    /// Equirectangular environment (EXR or Radiance .hdr); `None` bakes emitters only.
    pub environment: Option<PathBuf>,
    pub environment_options: EnvironmentOptions,
    /// What one input may ask of the run (`--max-triangles`).
    pub import: ImportOptions,
    /// Output folder (created if missing; files in it are replaced only on success).
    pub output: PathBuf,
    /// Substring of the adapter name to use (`--adapter`).
    pub adapter: Option<String>,
    /// Longest wait for one GPU submission (`--gpu-timeout`); `None`: forever.
    pub gpu_timeout: Option<std::time::Duration>,
    pub bake: BakeOptions,
    pub log: LogMode,
    /// What goes into report.json besides the bake, and whether to plot.
    pub report: ReportOptions,
}

/// The report's record of a run's options, written here rather than in
/// report.rs so that the report's layout depends on no `Config`.
impl From<&Config> for OptionsReport {
    fn from(config: &Config) -> OptionsReport {
        let env = &config.environment_options;
        let bake = &config.bake;
        OptionsReport {
            arguments: config.report.arguments.clone(),
            texels_per_unit: bake.unwrap.texels_per_unit,
            max_atlas_size: bake.unwrap.max_atlas_size,
            padding: bake.unwrap.padding,
            unwrapper: bake.unwrap.backend.to_string(),
            lights: env.lights.to_string(),
            env_rotation_degrees: env.rotation_degrees,
            env_intensity: env.intensity,
            clamp_nonfinite: env.clamp_nonfinite,
            light_batch_size: bake.solve.batch_size,
            direct_rays: Some(bake.solve.direct_rays),
            tolerance: bake.solve.bounce.tolerance,
            max_shots: bake.solve.bounce.max_shots,
            max_seconds: bake.solve.bounce.max_seconds,
            patches: bake.solve.bounce.patches,
            shooters_per_batch: bake.solve.bounce.shooters_per_batch,
            hemicube_size: bake.solve.bounce.hemicube_size,
            exposure: bake.export.exposure,
            dilation: bake.export.dilation,
            adapter: config.adapter.clone(),
            plot: config.report.plot,
            time_passes: bake.solve.bounce.time_passes,
            reference_texels: bake.reference.as_ref().map_or(0, |r| r.texels),
            reference_samples: bake.reference.as_ref().map_or(0, |r| r.samples),
            probe_spacing: bake.probes.as_ref().map(|p| p.spacing),
            probe_box: bake.probes.as_ref().and_then(|p| p.region),
            probe_rays: bake.probes.as_ref().map_or(0, |p| p.rays),
        }
    }
}
