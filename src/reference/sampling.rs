//! Importance sampling of the full-resolution environment map.
//!
//! The environment is treated as what its texels say it is: a function
//! that is constant over each pixel of the equirectangular grid
//! (no filtering, no mip levels). Pixels are chosen with probability
//! proportional to weight × solid angle from a 2-D table (a marginal
//! distribution over rows, a conditional one over the columns of each row),
//! then a direction is drawn uniformly within the pixel in (φ, cos θ), which
//! is uniform in solid angle. The density with respect to solid angle is
//! therefore exactly `weight(pixel) / Σ(weight × solid angle)` everywhere,
//! which is what [`EnvSampler::pdf`] returns (Pharr, Jakob and Humphreys,
//! *Physically Based Rendering*, 3rd ed., §13.6.7 and §14.2.4, with the
//! sin θ Jacobian replaced by exact per-row solid angles).
//!
//! The weight is the pixel's luminance less the map's mean luminance over
//! the sphere, clamped at zero: "MIS compensation" (Karlík, Šik, Vévoda,
//! Skřivan and Křivánek, "MIS Compensation: Optimizing Sampling Techniques
//! in Multiple Importance Sampling", SIGGRAPH Asia 2019). The part of the
//! map at or below its mean is integrated well by the cosine-weighted
//! technique it is combined with, so light samples go where they are
//! needed: to the sun. The combination stays unbiased because cosine
//! sampling covers every direction. Under a small sun far brighter than the
//! sky nearly every light sample finds the sun, and a constant map needs
//! no light samples at all and is integrated exactly.

use std::f64::consts::{PI, TAU};

use glam::DVec3;

use crate::colour::luminance;
use crate::environment::EnvironmentMap;

/// The sampling weight of a pixel of luminance `lum` when `mean` is left to
/// cosine sampling: the excess over the mean, or 0 where that excess is only
/// rounding (so a constant map has no light samples at all).
fn compensated(lum: f64, mean: f64) -> f64 {
    let excess = lum - mean;
    if excess > 1e-9 * mean { excess } else { 0.0 }
}

/// A sample of the environment: world direction, radiance (scaled), and the
/// density with respect to solid angle with which it was drawn.
pub(crate) struct EnvSample {
    pub direction: DVec3,
    pub radiance: DVec3,
    pub pdf: f64,
}

/// The environment map, ready for look-ups and importance sampling in world
/// space (its rotation about +Y and intensity scale applied).
pub(crate) struct EnvSampler {
    width: usize,
    height: usize,
    /// Sanitised texels (non-finite or negative channels set to 0), unscaled.
    texels: Vec<[f32; 3]>,
    intensity: f64,
    /// cos and sin of the rotation angle: d_world = R_y(angle) · d_map.
    cos_rot: f64,
    sin_rot: f64,
    /// cos θ at the H + 1 row boundaries (θ from the zenith).
    cos_edges: Vec<f64>,
    /// Cumulative row weights (Σ weight × solid angle), H + 1 entries.
    marginal: Vec<f64>,
    /// Per row, cumulative column weights, W + 1 entries each.
    conditional: Vec<f64>,
    /// Σ over all pixels of weight × solid angle (the normaliser).
    total: f64,
    /// Luminance subtracted from every pixel's sampling weight: the map's
    /// mean over the sphere.
    mean: f64,
}

impl EnvSampler {
    pub(crate) fn new(map: &EnvironmentMap, rotation_degrees: f64, intensity: f64) -> EnvSampler {
        let (width, height) = (map.width as usize, map.height as usize);
        assert_eq!(
            map.texels.len(),
            width * height,
            "environment map: {}×{} pixels but {} texels",
            map.width,
            map.height,
            map.texels.len()
        );
        let texels: Vec<[f32; 3]> =
            map.texels.iter().map(|t| t.map(|c| if c.is_finite() && c > 0.0 { c } else { 0.0 })).collect();
        let cos_edges: Vec<f64> = (0..=height)
            .map(|k| {
                if k == 0 {
                    1.0
                } else if k == height {
                    -1.0
                } else {
                    (k as f64 * PI / height as f64).cos()
                }
            })
            .collect();
        let solid_angle = |r: usize| TAU / width as f64 * (cos_edges[r] - cos_edges[r + 1]);
        // MIS compensation (see the module's documentation): the mean
        // luminance over the sphere is left to cosine sampling.
        let mean = (0..height)
            .map(|r| (0..width).map(|c| luminance(texels[r * width + c])).sum::<f64>() * solid_angle(r))
            .sum::<f64>()
            / (2.0 * TAU);
        let mut marginal = Vec::with_capacity(height + 1);
        let mut conditional = Vec::with_capacity(height * (width + 1));
        marginal.push(0.0);
        for r in 0..height {
            let mut sum = 0.0;
            conditional.push(0.0);
            for c in 0..width {
                sum += compensated(luminance(texels[r * width + c]), mean);
                conditional.push(sum);
            }
            let last = *marginal.last().unwrap();
            marginal.push(last + sum * solid_angle(r));
        }
        let total = marginal.last().copied().unwrap_or(0.0);
        let radians = rotation_degrees.to_radians();
        EnvSampler {
            width,
            height,
            texels,
            intensity,
            cos_rot: radians.cos(),
            sin_rot: radians.sin(),
            cos_edges,
            marginal,
            conditional,
            total,
            mean,
        }
    }

    /// Sampling weight of a pixel per steradian.
    fn weight(&self, row: usize, col: usize) -> f64 {
        compensated(luminance(self.texels[row * self.width + col]), self.mean)
    }

    /// Whether light sampling is possible (some pixel is above the mean).
    pub(crate) fn can_sample(&self) -> bool {
        self.total > 0.0 && self.total.is_finite() && self.intensity != 0.0
    }

    fn to_map(&self, d: DVec3) -> DVec3 {
        // R_y(-angle) · d
        DVec3::new(self.cos_rot * d.x - self.sin_rot * d.z, d.y, self.sin_rot * d.x + self.cos_rot * d.z)
    }

    fn to_world(&self, d: DVec3) -> DVec3 {
        // R_y(angle) · d (right-handed: +X turns towards -Z for a positive angle).
        DVec3::new(self.cos_rot * d.x + self.sin_rot * d.z, d.y, -self.sin_rot * d.x + self.cos_rot * d.z)
    }

    /// The pixel (row, column) a unit world direction falls in.
    fn pixel(&self, world: DVec3) -> (usize, usize) {
        let d = self.to_map(world);
        let u = 0.5 + d.z.atan2(d.x) / TAU;
        let t = d.y.clamp(-1.0, 1.0).acos() / PI;
        let col = ((u * self.width as f64) as usize).min(self.width - 1);
        let row = ((t * self.height as f64) as usize).min(self.height - 1);
        (row, col)
    }

    fn texel_radiance(&self, row: usize, col: usize) -> DVec3 {
        let t = self.texels[row * self.width + col];
        DVec3::new(t[0] as f64, t[1] as f64, t[2] as f64) * self.intensity
    }

    /// Radiance arriving from unit world direction `d` (intensity applied).
    pub(crate) fn radiance(&self, d: DVec3) -> DVec3 {
        if self.width == 0 || self.height == 0 {
            return DVec3::ZERO;
        }
        let (row, col) = self.pixel(d);
        self.texel_radiance(row, col)
    }

    /// Density per steradian with which [`EnvSampler::sample`] draws unit world
    /// direction `d` (0 where the map is black or sampling is off).
    pub(crate) fn pdf(&self, d: DVec3) -> f64 {
        if !self.can_sample() {
            return 0.0;
        }
        let (row, col) = self.pixel(d);
        self.weight(row, col) / self.total
    }

    /// Index `i` of the interval `[cdf[i], cdf[i+1])` that holds `x`, skipping
    /// empty intervals. `cdf` is non-decreasing, starts at 0 and its last entry
    /// is positive.
    fn find(cdf: &[f64], x: f64) -> usize {
        let n = cdf.len() - 1;
        let mut i = cdf.partition_point(|&v| v <= x).saturating_sub(1).min(n - 1);
        // Rounding can land on an empty interval at the end: step back to a
        // non-empty one (one exists because the total is positive).
        while i > 0 && cdf[i + 1] <= cdf[i] {
            i -= 1;
        }
        while cdf[i + 1] <= cdf[i] && i + 1 < n {
            i += 1;
        }
        i
    }

    /// Draws a direction from four uniforms in [0, 1). Only valid when
    /// [`EnvSampler::can_sample`].
    pub(crate) fn sample(&self, u: [f64; 4]) -> EnvSample {
        let row = Self::find(&self.marginal, u[0] * self.total);
        let cdf = &self.conditional[row * (self.width + 1)..(row + 1) * (self.width + 1)];
        let col = Self::find(cdf, u[1] * cdf[self.width]);
        let cos_theta = self.cos_edges[row] + u[2] * (self.cos_edges[row + 1] - self.cos_edges[row]);
        let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
        let phi = ((col as f64 + u[3]) / self.width as f64 - 0.5) * TAU;
        let map_dir = DVec3::new(sin_theta * phi.cos(), cos_theta, sin_theta * phi.sin());
        EnvSample {
            direction: self.to_world(map_dir),
            radiance: self.texel_radiance(row, col),
            pdf: self.weight(row, col) / self.total,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trace::random::Rng;

    #[test]
    fn density_integrates_to_one_and_skips_the_mean() {
        let map = EnvironmentMap::from_fn(32, 16, |d| [d[1].max(0.0) * 3.0, 1.0, 0.0]);
        let env = EnvSampler::new(&map, 0.0, 1.0);
        let mut integral = 0.0;
        for r in 0..16 {
            let omega = TAU / 32.0 * (env.cos_edges[r] - env.cos_edges[r + 1]);
            for c in 0..32 {
                integral += env.weight(r, c) / env.total * omega;
            }
        }
        assert!((integral - 1.0).abs() < 1e-12, "{integral}");
        // The lower half is below the mean: never sampled.
        assert_eq!(env.pdf(DVec3::NEG_Y), 0.0);
        assert!(env.pdf(DVec3::Y) > 0.0);
        assert!(!EnvSampler::new(&EnvironmentMap::constant([2.0; 3]), 0.0, 1.0).can_sample());
    }

    #[test]
    fn samples_land_in_their_pixel_with_the_reported_density() {
        let map = EnvironmentMap::from_fn(16, 8, |d| [d[0].abs() + 0.1, d[1].max(0.0), 0.3]);
        let env = EnvSampler::new(&map, 37.0, 2.0);
        let mut rng = Rng::new(&[7]);
        for _ in 0..2000 {
            let s = env.sample([rng.next_f64(), rng.next_f64(), rng.next_f64(), rng.next_f64()]);
            assert!((s.direction.length() - 1.0).abs() < 1e-12);
            assert!((env.pdf(s.direction) - s.pdf).abs() <= 1e-9 * s.pdf);
            assert!((env.radiance(s.direction) - s.radiance).length() <= 1e-9 * s.radiance.length());
        }
    }
}
