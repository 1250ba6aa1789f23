//! `--reference`: texels of a bake estimated by the path tracer, before the
//! solve, so that the bounce pass can record its error at them as it
//! converges (the report's `reference_error`) and the report its final error.

use std::sync::Arc;

use super::{Reference, ReferenceOptions, ReferencePoint};
use crate::environment::EnvironmentMap;
use crate::scene::Scene;
use crate::texelize::TexelSet;

/// `--reference N`: N texels estimated by the path tracer before the solve;
/// the trace records the bake's error at them as it converges.
#[derive(Clone, Debug)]
pub struct ReferenceCheck {
    /// Texels to estimate (spread evenly over the covered texels with area).
    pub texels: usize,
    /// Paths per texel.
    pub samples: u32,
    /// The full-resolution environment, with its rotation and intensity. `run`
    /// sets it; a library caller of `bake_scene` that bakes under an
    /// environment must set it too (`None` traces against a black sky).
    pub environment: Option<Arc<EnvironmentMap>>,
    pub env_rotation_degrees: f32,
    pub env_intensity: f32,
}

/// Texels with reference values (`--reference`): at every trace point their
/// current lightmap values are read back (a few bytes each) and compared.
#[derive(Clone, Debug, Default)]
pub struct Probes {
    /// Indices into `TexelSet::texels`.
    pub texels: Vec<u32>,
    /// Reference L_lm of each, linear RGB.
    pub reference: Vec<[f64; 3]>,
}

impl Probes {
    /// Relative RMSE of `values` against the reference: the root mean
    /// squared difference over texels and channels, over the reference's mean.
    pub fn relative_rmse(&self, values: impl Iterator<Item = [f64; 3]>) -> f64 {
        let (mut squared, mut sum, mut n) = (0.0f64, 0.0f64, 0usize);
        for (value, reference) in values.zip(&self.reference) {
            for c in 0..3 {
                squared += (value[c] - reference[c]).powi(2);
                sum += reference[c];
                n += 1;
            }
        }
        if n == 0 || sum <= 0.0 { 0.0 } else { (squared / n as f64).sqrt() / (sum / n as f64) }
    }

    /// `relative_rmse` of a whole lightmap (L_lm per texel) at the probes.
    pub fn lightmap_error(&self, lightmap: &[[f32; 3]]) -> f64 {
        self.relative_rmse(self.texels.iter().map(|&i| lightmap[i as usize].map(|v| v as f64)))
    }
}

/// Estimates `check.texels` texels of `texels` with the CPU reference:
/// the probes the bounce pass reads back, and the reference's relative noise.
pub fn reference_probes(scene: &Scene, texels: &TexelSet, check: &ReferenceCheck) -> (Probes, f64) {
    reference_probes_within(scene, texels, check, ReferenceOptions::default().max_bounces)
}

/// As [`reference_probes`], with light that reached the probes by more than
/// `max_bounces` reflections left out (0: the direct light alone).
pub fn reference_probes_within(
    scene: &Scene,
    texels: &TexelSet,
    check: &ReferenceCheck,
    max_bounces: u32,
) -> (Probes, f64) {
    let candidates: Vec<u32> =
        (0..texels.texels.len() as u32).filter(|&i| texels.texels[i as usize].area > 0.0).collect();
    let n = check.texels.min(candidates.len());
    let chosen: Vec<u32> = (0..n).map(|k| candidates[(2 * k + 1) * candidates.len() / (2 * n)]).collect();
    let points: Vec<ReferencePoint> = chosen
        .iter()
        .map(|&i| {
            let t = &texels.texels[i as usize];
            ReferencePoint { position: t.position, normal: t.normal, face_normal: Some(t.face_normal) }
        })
        .collect();
    let options = ReferenceOptions {
        samples: check.samples,
        env_rotation_degrees: check.env_rotation_degrees,
        env_intensity: check.env_intensity,
        max_bounces,
        ..ReferenceOptions::default()
    };
    let estimates = Reference::new(scene, check.environment.as_deref(), &options).estimate(&points);
    let (mut variance, mut sum) = (0.0f64, 0.0f64);
    for e in &estimates {
        for c in 0..3 {
            if e.std_error[c].is_finite() {
                variance += e.std_error[c].powi(2);
            }
            sum += e.lightmap[c];
        }
    }
    let count = (3 * estimates.len()).max(1) as f64;
    let noise = if sum > 0.0 { (variance / count).sqrt() / (sum / count) } else { 0.0 };
    (Probes { texels: chosen, reference: estimates.iter().map(|e| e.lightmap).collect() }, noise)
}
