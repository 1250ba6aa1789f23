//! Solve stage: TexelSet + LightSet in, `Solution` out: the lightmap value
//! L_lm = E/π (incident irradiance over π, linear RGB) of every texel.
//!
//! Passes: `direct` (environment light through per-light depth maps).

pub mod direct;

use anyhow::Result;
use serde::{Deserialize, Serialize};

use crate::environment::LightSet;
use crate::gpu::Gpu;
use crate::scene::Scene;
use crate::texelize::TexelSet;

/// Options of the solve, with their defaults.
#[derive(Clone, Debug)]
pub struct SolveOptions {
    /// Shadow-map width and height in texels; `None` picks one from the
    /// scene's size and texel density.
    pub shadow_map_size: Option<u32>,
    /// Lights rendered and gathered per GPU batch (at most 256).
    pub batch_size: u32,
}

impl Default for SolveOptions {
    fn default() -> Self {
        SolveOptions {
            shadow_map_size: None,
            batch_size: 64,
        }
    }
}

/// The solved lightmap: one value per covered texel, in `TexelSet` order.
#[derive(Clone, Debug)]
pub struct Solution {
    /// L_lm = E/π per texel, linear RGB.
    pub lightmap: Vec<[f32; 3]>,
    pub direct: Option<direct::DirectStats>,
    /// Passes left out and why, for the report.
    pub skipped: Vec<Skipped>,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Skipped {
    pub pass: String,
    pub reason: String,
}

/// Runs every pass the scene needs.
pub fn run(
    gpu: &Gpu,
    scene: &Scene,
    texels: &TexelSet,
    lights: Option<&LightSet>,
    texels_per_unit: f32,
    options: &SolveOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Solution> {
    let mut skipped = Vec::new();
    let mut lightmap = vec![[0.0f32; 3]; texels.texels.len()];
    let mut direct_stats = None;
    match lights {
        Some(lights) if !lights.lights.is_empty() => {
            let (irradiance, stats) = direct::run(
                gpu,
                scene,
                texels,
                lights,
                texels_per_unit,
                options,
                progress,
            )?;
            for (value, e) in lightmap.iter_mut().zip(irradiance) {
                *value = e.map(|c| c / std::f32::consts::PI);
            }
            direct_stats = Some(stats);
        }
        Some(_) => skipped.push(Skipped {
            pass: "direct".into(),
            reason: "the environment has no energy".into(),
        }),
        None => skipped.push(Skipped {
            pass: "direct".into(),
            reason: "no environment was given".into(),
        }),
    }
    Ok(Solution {
        lightmap,
        direct: direct_stats,
        skipped,
    })
}
