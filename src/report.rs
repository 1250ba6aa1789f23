//! `report.json`: what ran and what was left out, timings, the adapter,
//! counts, and per-primitive texel energy, so CI can check a bake's energy
//! and a user can see how good and how fast it was.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::gpu::AdapterDescription;
use crate::solve::{BounceStats, Skipped, Solution, direct::DirectStats};
use crate::texelize::TexelSet;

/// Version of the report's layout; bumped on any incompatible change.
pub const SCHEMA_VERSION: u32 = 1;

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Report {
    pub schema_version: u32,
    pub bake_version: String,
    pub adapter: AdapterDescription,
    pub environment: Option<EnvironmentReport>,
    pub scenes: Vec<SceneReport>,
    pub total_seconds: f64,
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
    pub notices: Vec<String>,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct SceneReport {
    pub input: PathBuf,
    pub outputs: Vec<PathBuf>,
    /// Every stage in pipeline order, with its time.
    pub stages: Vec<StageTime>,
    /// Passes left out and why.
    pub skipped: Vec<Skipped>,
    pub notices: Vec<String>,
    pub primitives: usize,
    pub triangles: usize,
    pub atlas: AtlasReport,
    pub texels: TexelReport,
    pub direct: Option<DirectStats>,
    /// The bounce pass: shots, why it stopped, unshot energy left and the
    /// ambient term that stands in for it, and the convergence trace.
    pub bounce: Option<BounceStats>,
    /// Texel energy per baked primitive, in scene order.
    pub energy: Vec<PrimitiveEnergy>,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct StageTime {
    pub stage: String,
    pub seconds: f64,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct AtlasReport {
    pub width: u32,
    pub height: u32,
    pub texels_per_unit: f32,
    pub charts: u32,
    pub utilization: f32,
    pub unwrapper: String,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct TexelReport {
    /// Texels that carry a radiosity element.
    pub covered: usize,
    /// Their total world area, m².
    pub area: f64,
    /// Padding texels filled by dilation.
    pub dilated: usize,
}

/// Energy statistics of one baked primitive's texels.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct PrimitiveEnergy {
    pub node: usize,
    pub mesh: usize,
    pub primitive: usize,
    pub name: String,
    pub texels: usize,
    /// World area, m².
    pub area: f64,
    /// Area-weighted mean lightmap value L_lm = E/π, RGB.
    pub mean_lightmap: [f64; 3],
    /// Smallest and largest texel luminance of L_lm.
    pub min_luminance: f64,
    pub max_luminance: f64,
    /// Incident power Σ E·A, RGB (W up to the environment's scale).
    pub power_received: [f64; 3],
    /// Reflected power Σ ρ·E·A, RGB.
    pub power_reflected: [f64; 3],
    /// Texels whose value is NaN, infinite or negative (must be 0).
    pub invalid_texels: usize,
}

pub fn luminance(c: [f64; 3]) -> f64 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// Per-primitive energy of a solution. `names[p]` labels primitive p.
pub fn primitive_energy(
    texels: &TexelSet,
    solution: &Solution,
    keys: &[(usize, usize, usize)],
    names: &[String],
) -> Vec<PrimitiveEnergy> {
    let mut out: Vec<PrimitiveEnergy> = keys
        .iter()
        .zip(names)
        .map(|(&(node, mesh, primitive), name)| PrimitiveEnergy {
            node,
            mesh,
            primitive,
            name: name.clone(),
            texels: 0,
            area: 0.0,
            mean_lightmap: [0.0; 3],
            min_luminance: f64::INFINITY,
            max_luminance: 0.0,
            power_received: [0.0; 3],
            power_reflected: [0.0; 3],
            invalid_texels: 0,
        })
        .collect();
    for (texel, value) in texels.texels.iter().zip(&solution.lightmap) {
        let Some(entry) = out.get_mut(texel.primitive as usize) else {
            continue;
        };
        entry.texels += 1;
        if value.iter().any(|c| !c.is_finite() || *c < 0.0) {
            entry.invalid_texels += 1;
            continue;
        }
        let v = value.map(|c| c as f64);
        let area = texel.area as f64;
        entry.area += area;
        let l = luminance(v);
        entry.min_luminance = entry.min_luminance.min(l);
        entry.max_luminance = entry.max_luminance.max(l);
        for (c, value) in v.iter().enumerate() {
            entry.mean_lightmap[c] += value * area;
            let e = value * std::f64::consts::PI * area;
            entry.power_received[c] += e;
            entry.power_reflected[c] += e * texel.albedo[c] as f64;
        }
    }
    for entry in &mut out {
        if entry.area > 0.0 {
            entry.mean_lightmap = entry.mean_lightmap.map(|m| m / entry.area);
        }
        if entry.texels == 0 || !entry.min_luminance.is_finite() {
            entry.min_luminance = 0.0;
        }
    }
    out
}
