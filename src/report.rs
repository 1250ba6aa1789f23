//! `report.json`: what ran and what was left out, timings and memory per
//! stage, the inputs and their hashes, the options, the adapter, counts, the
//! convergence trace and texel energy per primitive and per atlas, so that
//! CI can check a bake's energy (`bake check`) and a user can see how good
//! and how fast it was.
//!
//! The layout is documented field by field, with units, in
//! `schema/report.schema.json` (JSON Schema draft 2020-12); a test validates
//! a real report against it. `SCHEMA_VERSION` is bumped on any change to the
//! layout, and the schema's `schema_version` constant with it.

use std::io::Read;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::colour::luminance;
use crate::gpu::AdapterDescription;
use crate::probes::ProbeStats;
use crate::scene::PrimitiveKey;
use crate::solve::{BounceStats, ContactStats, Skipped, Solution, direct::DirectStats, punctual::PunctualStats};
use crate::texelize::TexelSet;

/// Version of the report's layout; bumped on any change to it. Version 4
/// added a primitive's `instance` and the scene's `contact`, version 5 the
/// scene's `punctual`, version 6 the direct pass's `rays` in place of its
/// shadow-map size (and the option with it), version 8 the bounce pass's
/// `passes` and the option `time_passes`, version 9 the option
/// `direct_rays`; `bake check` still reads version 3.
pub const SCHEMA_VERSION: u32 = 9;

/// The oldest version `bake check` reads: every later change only added
/// optional fields.
pub const OLDEST_READABLE_VERSION: u32 = 3;

/// The schema `report.json` follows (also in the repository as `schema/report.schema.json`).
pub const SCHEMA: &str = include_str!("../schema/report.schema.json");

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Report {
    pub schema_version: u32,
    pub bake_version: String,
    /// Every file the run read, hashed.
    pub inputs: Vec<InputFile>,
    pub options: OptionsReport,
    pub adapter: AdapterDescription,
    pub environment: Option<EnvironmentReport>,
    pub scenes: Vec<SceneReport>,
    pub total_seconds: f64,
}

/// One input file and its content hash.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct InputFile {
    /// "scene" or "environment".
    pub role: String,
    /// The path as given on the command line.
    pub path: PathBuf,
    pub bytes: u64,
    /// SHA-256 of the file's bytes, lower-case hex.
    pub sha256: String,
}

impl InputFile {
    /// Reads and hashes `path`.
    pub fn hash(role: &str, path: &Path) -> Result<InputFile> {
        let (file, length) =
            crate::files::open(path).with_context(|| format!("{role} '{}': cannot read", path.display()))?;
        let mut file = file.take(length);
        let mut hasher = Sha256::new();
        let mut buffer = vec![0u8; 1 << 16];
        let mut bytes = 0u64;
        loop {
            let n = file.read(&mut buffer).with_context(|| format!("{role} '{}': cannot read", path.display()))?;
            if n == 0 {
                break;
            }
            hasher.update(&buffer[..n]);
            bytes += n as u64;
        }
        let sha256 = hasher.finalize().iter().map(|b| format!("{b:02x}")).collect();
        Ok(InputFile { role: role.to_string(), path: path.to_path_buf(), bytes, sha256 })
    }
}

/// Options that are about the report itself, not the bake.
#[derive(Clone, Debug, Default)]
pub struct ReportOptions {
    /// The command line as given (recorded in the report).
    pub arguments: Vec<String>,
    /// Write `OUT/<name>.convergence.svg` per scene (`--plot`).
    pub plot: bool,
}

/// The options the run used: the command line as given, and every option
/// after defaults were filled in.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct OptionsReport {
    pub arguments: Vec<String>,
    pub texels_per_unit: Option<f32>,
    pub max_atlas_size: u32,
    pub padding: u32,
    pub unwrapper: String,
    pub lights: String,
    pub env_rotation_degrees: f32,
    pub env_intensity: f32,
    pub clamp_nonfinite: bool,
    pub light_batch_size: u32,
    /// `--direct-rays` (absent before version 9).
    #[serde(default)]
    pub direct_rays: Option<u32>,
    pub tolerance: f64,
    pub max_shots: Option<u64>,
    pub max_seconds: Option<f64>,
    pub patches: u32,
    pub shooters_per_batch: u32,
    pub hemicube_size: u32,
    pub exposure: f32,
    pub dilation: u32,
    pub adapter: Option<String>,
    pub plot: bool,
    /// `--time-passes`: each bounce pass's seconds were recorded.
    #[serde(default)]
    pub time_passes: bool,
    /// `--reference`: texels estimated by the CPU reference (0: none).
    pub reference_texels: usize,
    pub reference_samples: u32,
    /// `--probes`: the largest distance between probes, metres (absent before version 7).
    #[serde(default)]
    pub probe_spacing: Option<f64>,
    /// `--probe-box`: min and max corners, world metres.
    #[serde(default)]
    pub probe_box: Option<[[f64; 3]; 2]>,
    #[serde(default)]
    pub probe_rays: u32,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct EnvironmentReport {
    pub path: PathBuf,
    pub width: u32,
    pub height: u32,
    /// The light mode, as given to `--lights`.
    pub mode: String,
    pub lights: usize,
    /// Lights dropped because they carried no energy.
    pub dropped: usize,
    /// Σ L·Ω of the map (after intensity), RGB.
    pub map_integral: [f64; 3],
    /// Σ L·Ω of the light set, RGB (equals `map_integral` up to rounding).
    pub captured: [f64; 3],
    pub rotation_degrees: f32,
    pub intensity: f32,
    pub seconds: f64,
    /// Memory while loading the map and extracting lights.
    pub memory: Option<StageMemory>,
    pub notices: Vec<String>,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct SceneReport {
    /// The output name: the input's file stem (`OUT/<name>.glb`); `bake check` matches scenes by it.
    pub name: String,
    pub input: PathBuf,
    pub outputs: Vec<PathBuf>,
    /// Every stage in pipeline order, with its time and memory.
    pub stages: Vec<StageTime>,
    /// Passes left out and why.
    pub skipped: Vec<Skipped>,
    pub notices: Vec<String>,
    pub primitives: usize,
    pub triangles: usize,
    pub atlas: AtlasReport,
    pub texels: TexelReport,
    pub direct: Option<DirectStats>,
    /// The punctual lights' pass, when the scene has lights and it ran
    /// (absent in version 3 and 4 reports).
    #[serde(default)]
    pub punctual: Option<PunctualStats>,
    /// The bounce pass: shots, why it stopped, unshot energy left and the
    /// ambient term that stands in for it, and the convergence trace.
    pub bounce: Option<BounceStats>,
    /// The contact fix-up, when it ran (absent in version 3 reports).
    #[serde(default)]
    pub contact: Option<ContactStats>,
    /// Texel energy per baked primitive, in scene order.
    pub energy: Vec<PrimitiveEnergy>,
    /// `--reference`: the bake's error against the CPU reference at some texels.
    pub reference: Option<ReferenceReport>,
    /// `--probes`: the irradiance volume's grid and what baking it took (absent before version 7).
    #[serde(default)]
    pub probes: Option<ProbeStats>,
}

/// What `--reference` measured.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct ReferenceReport {
    /// Texels estimated.
    pub texels: usize,
    /// Paths per texel.
    pub samples: u32,
    /// Time the reference took, seconds.
    pub seconds: f64,
    /// The reference's own noise: root mean squared standard error over the
    /// mean reference value (errors below it cannot be resolved).
    pub noise: f64,
    /// Relative RMSE of the final lightmap at those texels.
    pub error: f64,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct StageTime {
    pub stage: String,
    pub seconds: f64,
    /// `None` where memory cannot be measured (not Linux).
    pub memory: Option<StageMemory>,
}

/// Memory of one stage. CPU: the process's resident set (Linux
/// `/proc/self/status` VmRSS, and VmHWM for the peak after resetting it at
/// the stage's start through `/proc/self/clear_refs`). GPU: bytes wgpu's
/// allocator holds for live buffers and textures, sampled whenever the stage
/// waits for the GPU.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct StageMemory {
    pub rss_before_bytes: u64,
    pub rss_after_bytes: u64,
    pub peak_rss_bytes: u64,
    /// "stage" when the high-water mark was reset at the stage's start, so
    /// `peak_rss_bytes` is this stage's peak; "process" when it could not be
    /// reset (the peak since the process started).
    pub peak_rss_scope: String,
    /// Largest GPU allocator total seen at the stage's GPU waits (a lower
    /// bound of its peak); `None` where the backend gives no report.
    pub gpu_peak_bytes: Option<u64>,
    pub gpu_after_bytes: Option<u64>,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct AtlasReport {
    /// Index N of the atlas page (`OUT/<name>.lightmap<N>.exr`).
    pub index: u32,
    pub width: u32,
    pub height: u32,
    pub texels_per_unit: f32,
    pub charts: u32,
    pub utilization: f32,
    pub unwrapper: String,
    /// Texel energy over every covered texel of the page.
    pub energy: EnergyStats,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct TexelReport {
    /// Texels that carry a radiosity element.
    pub covered: usize,
    /// Their total world area, m².
    pub area: f64,
    /// Padding texels filled by dilation.
    pub dilated: usize,
    /// The texel fix-ups in the order they ran, each with the texels it touched
    /// (absent from reports older than the fix-up list).
    #[serde(default)]
    pub fixups: Vec<Fixup>,
    /// The UV seams and how far apart their two sides were before and after stitching.
    #[serde(default)]
    pub seams: crate::export::seams::StitchStats,
}

/// One texel fix-up stage and how many texels it touched.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Fixup {
    pub stage: String,
    pub texels: usize,
    pub what: String,
}

/// Energy statistics of one baked primitive's texels.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct PrimitiveEnergy {
    /// Node, instance, mesh and primitive index: the key `bake check`
    /// matches by. `instance` is the node's EXT_mesh_gpu_instancing instance,
    /// absent for a node without instances (and in version 3 reports).
    pub node: usize,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub instance: Option<usize>,
    pub mesh: usize,
    pub primitive: usize,
    /// For display: the node's (or mesh's) name and the primitive index.
    pub name: String,
    /// Texel rectangle [x0, y0, x1, y1) (x1, y1 exclusive) holding all the
    /// primitive's texels; [0, 0, 0, 0] when it has none.
    pub atlas_bounds: [u32; 4],
    #[serde(flatten)]
    pub stats: EnergyStats,
}

/// Energy statistics of a set of covered texels (one primitive, or an atlas).
/// Powers are Σ over texels of (something)·E·A with E = π·L_lm, in
/// irradiance × m² (W when the environment is in W/(m²·sr)).
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct EnergyStats {
    /// Covered texels.
    pub texels: usize,
    /// Covered texels whose value is NaN, infinite or negative (must be 0);
    /// they are left out of every other figure.
    pub invalid_texels: usize,
    /// Covered texels whose L_lm is exactly 0 in every channel.
    pub zero_texels: usize,
    /// World area, m².
    pub area: f64,
    /// Area-weighted mean lightmap value L_lm = E/π, RGB.
    pub mean_lightmap: [f64; 3],
    /// Σ L_lm over the texels, unweighted, RGB (what the EXR holds in them).
    pub sum_lightmap: [f64; 3],
    /// Texel luminance of L_lm (Rec. 709): smallest, percentiles (nearest
    /// rank over texels, unweighted) and largest.
    pub min_luminance: f64,
    pub p1_luminance: f64,
    pub p50_luminance: f64,
    pub p99_luminance: f64,
    pub max_luminance: f64,
    /// Incident power Σ E·A, RGB. Here and below, A is a texel's area at its
    /// share that bounces light: where two surfaces coincide, each counts for
    /// half (the bounce pass's areas, `solve::overlaps`).
    pub power_received: [f64; 3],
    /// Reflected power Σ ρ·E·A, RGB.
    pub power_reflected: [f64; 3],
    /// Emitted power Σ π·Le·A, RGB.
    pub power_emitted: [f64; 3],
    /// Smallest and largest texel albedo, RGB ([0, 0, 0] without texels).
    pub albedo_min: [f64; 3],
    pub albedo_max: [f64; 3],
}

/// Accumulates `EnergyStats` texel by texel.
#[derive(Default)]
struct Accumulator {
    stats: EnergyStats,
    luminances: Vec<f64>,
    bounds: Option<[u32; 4]>,
}

impl Accumulator {
    /// Adds `texel` of lightmap `value`; its powers count `share` of its area.
    fn add(&mut self, texel: &crate::texelize::Texel, value: &[f32; 3], share: f32, width: u32) {
        let s = &mut self.stats;
        s.texels += 1;
        let (x, y) = (texel.x(width.max(1)), texel.y(width.max(1)));
        self.bounds = Some(match self.bounds {
            None => [x, y, x + 1, y + 1],
            Some([x0, y0, x1, y1]) => [x0.min(x), y0.min(y), x1.max(x + 1), y1.max(y + 1)],
        });
        let albedo = texel.albedo.map(|a| a as f64);
        if s.texels == 1 {
            s.albedo_min = albedo;
            s.albedo_max = albedo;
        }
        s.albedo_min = [0, 1, 2].map(|c| s.albedo_min[c].min(albedo[c]));
        s.albedo_max = [0, 1, 2].map(|c| s.albedo_max[c].max(albedo[c]));
        if value.iter().any(|c| !c.is_finite() || *c < 0.0) {
            s.invalid_texels += 1;
            return;
        }
        if value.iter().all(|&c| c == 0.0) {
            s.zero_texels += 1;
        }
        let v = value.map(|c| c as f64);
        let area = texel.area as f64;
        s.area += area;
        self.luminances.push(luminance(v));
        let counted = area * share as f64;
        for c in 0..3 {
            s.mean_lightmap[c] += v[c] * area;
            s.sum_lightmap[c] += v[c];
            let e = v[c] * std::f64::consts::PI * counted;
            s.power_received[c] += e;
            s.power_reflected[c] += e * albedo[c];
            s.power_emitted[c] += std::f64::consts::PI * texel.emission[c] as f64 * counted;
        }
    }

    fn finish(mut self) -> (EnergyStats, [u32; 4]) {
        let s = &mut self.stats;
        if s.area > 0.0 {
            s.mean_lightmap = s.mean_lightmap.map(|m| m / s.area);
        }
        self.luminances.sort_by(f64::total_cmp);
        let rank = |q: f64| -> f64 {
            let n = self.luminances.len();
            if n == 0 { 0.0 } else { self.luminances[((q * n as f64).ceil() as usize).clamp(1, n) - 1] }
        };
        s.min_luminance = rank(0.0);
        s.p1_luminance = rank(0.01);
        s.p50_luminance = rank(0.5);
        s.p99_luminance = rank(0.99);
        s.max_luminance = rank(1.0);
        (self.stats, self.bounds.unwrap_or([0; 4]))
    }
}

/// Texel `i`'s share of its area that bounces light (`Solution::shares`).
fn share(solution: &Solution, i: usize) -> f32 {
    solution.shares.as_ref().map_or(1.0, |s| s[i])
}

/// Energy of every covered texel of `texels` (one atlas page).
pub fn atlas_energy(texels: &TexelSet, solution: &Solution) -> EnergyStats {
    let mut all = Accumulator::default();
    for (i, (texel, value)) in texels.texels.iter().zip(&solution.lightmap).enumerate() {
        all.add(texel, value, share(solution, i), texels.width);
    }
    all.finish().0
}

/// Per-primitive energy of a solution. `keys[p]` and `names[p]` label
/// primitive p.
pub fn primitive_energy(
    texels: &TexelSet,
    solution: &Solution,
    keys: &[PrimitiveKey],
    names: &[String],
) -> Vec<PrimitiveEnergy> {
    let mut accumulators: Vec<Accumulator> = keys.iter().map(|_| Accumulator::default()).collect();
    for (i, (texel, value)) in texels.texels.iter().zip(&solution.lightmap).enumerate() {
        if let Some(entry) = accumulators.get_mut(texel.primitive as usize) {
            entry.add(texel, value, share(solution, i), texels.width);
        }
    }
    keys.iter()
        .zip(names)
        .zip(accumulators)
        .map(|((&PrimitiveKey { node, instance, mesh, primitive }, name), acc)| {
            let (stats, atlas_bounds) = acc.finish();
            PrimitiveEnergy { node, instance, mesh, primitive, name: name.clone(), atlas_bounds, stats }
        })
        .collect()
}
