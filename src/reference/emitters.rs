//! Next-event estimation towards emissive surfaces: a point is drawn on an
//! emissive triangle, the triangle chosen in proportion to its area × its
//! material's brightest emission channel (its power, up to the emissive
//! texture, which only darkens it), the point uniformly over the triangle's
//! area (Pharr, Jakob and Humphreys, *Physically Based Rendering*, 3rd ed.,
//! §13.6.4 and §14.2). The density over area is `pick(t) / area(t)`; over
//! solid angle, seen from x, `pick(t) · d² / (area(t) · |cos θ_e|)`, which is
//! what the path's cosine-sampled hits are weighted against (the balance
//! heuristic, as for the environment).

use glam::DVec3;

use crate::trace::rays::Triangle;

/// The emissive triangles of a scene and how to draw them.
pub(super) struct Emitters {
    /// Indices into the BVH's triangles.
    triangles: Vec<u32>,
    /// Running sums of the weights, the last the total.
    cumulative: Vec<f64>,
    /// Per BVH triangle: its chance of being picked (0 for a dark one).
    pick: Vec<f64>,
}

/// A point drawn on an emitter.
pub(super) struct EmitterSample {
    pub triangle: u32,
    pub u: f64,
    pub v: f64,
}

impl Emitters {
    /// The triangles whose `emission` (the material's factor, before
    /// textures) is positive, weighted by area × its brightest channel.
    pub(super) fn new(triangles: &[Triangle], emission: impl Fn(&Triangle) -> DVec3) -> Emitters {
        let mut chosen = Vec::new();
        let mut cumulative = Vec::new();
        let mut total = 0.0;
        for (i, tri) in triangles.iter().enumerate() {
            let weight = area(tri) * emission(tri).max_element();
            if weight > 0.0 && weight.is_finite() {
                total += weight;
                chosen.push(i as u32);
                cumulative.push(total);
            }
        }
        let mut pick = vec![0.0; triangles.len()];
        let mut before = 0.0;
        for (&i, &sum) in chosen.iter().zip(&cumulative) {
            pick[i as usize] = (sum - before) / total;
            before = sum;
        }
        Emitters { triangles: chosen, cumulative, pick }
    }

    pub(super) fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// A point on an emitter from three uniform numbers in [0, 1).
    pub(super) fn sample(&self, r: [f64; 3]) -> EmitterSample {
        let total = *self.cumulative.last().expect("sampled only when there are emitters");
        let target = r[0] * total;
        let k = self.cumulative.partition_point(|&c| c <= target).min(self.triangles.len() - 1);
        let triangle = self.triangles[k];
        // Uniform over the triangle: (1 − √r1, r2 √r1) as barycentrics of v1 and v2.
        let s = r[1].sqrt();
        let (u, v) = (1.0 - s, r[2] * s);
        EmitterSample { triangle, u, v }
    }

    /// The density over solid angle, seen from `distance` away at cosine
    /// `cos_emitter` to the emitter's plane, of drawing the point where a
    /// ray met `triangle`.
    pub(super) fn pdf_solid_angle(
        &self,
        triangles: &[Triangle],
        triangle: u32,
        distance: f64,
        cos_emitter: f64,
    ) -> f64 {
        let pick = self.pick[triangle as usize];
        if pick == 0.0 || cos_emitter <= 0.0 {
            return 0.0;
        }
        pick / area(&triangles[triangle as usize]) * distance * distance / cos_emitter
    }
}

fn area(tri: &Triangle) -> f64 {
    0.5 * tri.e1.cross(tri.e2).length()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn triangle(scale: f64, material: u32) -> Triangle {
        Triangle {
            v0: DVec3::ZERO,
            e1: DVec3::X * scale,
            e2: DVec3::Z * scale,
            face: DVec3::Y,
            normals: None,
            material,
            primitive: 0,
            texcoords: crate::trace::rays::NO_TEXCOORDS,
        }
    }

    #[test]
    fn picks_by_power_and_samples_inside() {
        // Areas 0.5, 0.5 and 2; emission 2, 0 and 1: powers 1, 0 and 2.
        let triangles = [triangle(1.0, 1), triangle(1.0, 0), triangle(2.0, 2)];
        let emitters = Emitters::new(&triangles, |t| DVec3::splat([0.0, 2.0, 1.0][t.material as usize]));
        let third = 1.0 / 3.0;
        assert!(emitters.pick.iter().zip([third, 0.0, 2.0 * third]).all(|(a, b)| (a - b).abs() < 1e-12));
        let n = 30_000;
        let mut counts = [0usize; 3];
        for i in 0..n {
            let x = (i as f64 + 0.5) / n as f64;
            let s = emitters.sample([x, (x * 7.3).fract(), (x * 13.7).fract()]);
            counts[s.triangle as usize] += 1;
            assert!(s.u >= 0.0 && s.v >= 0.0 && s.u + s.v <= 1.0 + 1e-12);
            // Over area (seen head-on from 1 m): pick / area, the emission over the total power.
            let expected = if s.triangle == 0 { 2.0 * third } else { third };
            assert!((emitters.pdf_solid_angle(&triangles, s.triangle, 1.0, 1.0) - expected).abs() < 1e-12);
        }
        assert_eq!(counts[1], 0);
        assert!((counts[0] as f64 / n as f64 - third).abs() < 1e-3);
        // Over solid angle: pick/area · d²/cos.
        let pdf = emitters.pdf_solid_angle(&triangles, 2, 3.0, 0.5);
        assert!((pdf - third * 9.0 / 0.5).abs() < 1e-12);
        assert_eq!(emitters.pdf_solid_angle(&triangles, 1, 3.0, 0.5), 0.0);
    }

    #[test]
    fn no_emission_means_no_emitters() {
        let triangles = [triangle(1.0, 0)];
        assert!(Emitters::new(&triangles, |_| DVec3::ZERO).is_empty());
    }
}
