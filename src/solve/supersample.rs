//! Supersample fix-up: where a shadow edge crosses a texel, its value becomes
//! the mean of the direct light over the texel's footprint instead of the
//! light at its centre, so a hard edge is anti-aliased instead of
//! stair-stepped (issue 6, "a texel's value represents its footprint").
//!
//! After the direct pass, a texel is flagged when the direct light other
//! surfaces block of it bends sharply across it (second difference over
//! `EDGE_CONTRAST` of the light there; a punctual light's irradiance counts
//! whole), and it lies inside its chart (all eight neighbours are covered
//! texels of the same chart, facing within `SAME_SURFACE_COS`): its footprint
//! is then all surface, mapped to the world by the central differences of its
//! neighbours' positions. Eight sub-samples in the footprint (the D3D
//! standard 8× pattern) are gathered by a second direct pass. A sub-sample
//! that the texel's centre cannot reach along the surface (a wall standing on
//! the floor between them) is left out: the texel stands for the part of its
//! footprint a viewer can see, and light from behind the wall must not leak
//! in. Where a concave surface rises above the footprint's flat plane (past a
//! crease), a sub-sample is moved up onto it (`on_surface`): on the plane it
//! would lie behind the surface and cast its rays from there.
//!
//! The direct pass gathers the texels first, which flags them, then the
//! sub-samples alone.

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::colour::luminance;
use crate::texelize::{Texel, TexelSet};
use crate::trace::Surfaces;

/// Sub-sample offsets in texels from the texel's centre: the D3D standard
/// 8× multisample pattern (in 1/16 texel), one sample per row and column
/// of an 8 × 8 grid, so a straight edge at any angle steps in eighths.
const PATTERN: [[f32; 2]; 8] =
    [[1.0, -3.0], [-1.0, 3.0], [5.0, 1.0], [-3.0, -5.0], [-5.0, 5.0], [-7.0, -1.0], [3.0, 7.0], [7.0, -7.0]];
/// Second difference of direct irradiance along an atlas row or column,
/// over the largest of the three texels, above which the middle one is
/// gathered at sub-samples.
const EDGE_CONTRAST: f64 = 0.2;
/// Neighbours whose normals turn further than this (cosine) are not the
/// same smooth surface: the footprint would not be flat across them.
const SAME_SURFACE_COS: f32 = 0.9;
/// Height of the segment from the centre to each sub-sample above the
/// surface, in texel widths: above the curvature of a surface bent at most
/// `SAME_SURFACE_COS` per texel, below anything standing on it.
const LIFT_TEXELS: f64 = 0.05;

/// The sub-samples of the flagged texels, as texels for a direct pass.
pub struct Plan {
    /// One texel per sub-sample: the owner's data at the sub-sample's position.
    pub samples: TexelSet,
    /// Index into the original `TexelSet` of each sub-sample's texel (a
    /// texel's sub-samples are consecutive).
    pub owner: Vec<u32>,
    /// Texels flagged (some may keep only part of their sub-samples).
    pub texels: usize,
}

/// Flags the texels across which a shadow's edge bends the light and
/// places their sub-samples. `None` when no texel needs them.
pub fn plan(occluders: &Surfaces, texels: &TexelSet, edges: &Edges) -> Option<Plan> {
    let atlas = Atlas { texels };
    let flagged = flag(&atlas, edges);
    if flagged.is_empty() {
        return None;
    }
    // Each flagged texel's sub-samples, in texel order (rayon keeps it).
    let per_texel: Vec<Vec<Texel>> = flagged.par_iter().map(|&i| sub_samples(occluders, &atlas, i)).collect();
    let mut samples = Vec::new();
    let mut owner = Vec::new();
    let mut count = 0;
    for (&i, subs) in flagged.iter().zip(per_texel) {
        count += usize::from(!subs.is_empty());
        owner.extend(std::iter::repeat_n(i as u32, subs.len()));
        samples.extend(subs);
    }
    (count > 0).then_some(Plan {
        samples: TexelSet { width: texels.width, height: texels.height, texels: samples, tint: Vec::new() },
        owner,
        texels: count,
    })
}

/// The texels laid out on their atlas page, to find a texel's neighbours.
struct Atlas<'a> {
    texels: &'a TexelSet,
}

impl Atlas<'_> {
    /// The index of the texel `dx`, `dy` from `t`, if one is there. Texels
    /// are in row-major atlas order: a neighbour is found by binary search
    /// (a lookup table would take 1 GiB at 16384²).
    fn at(&self, t: &Texel, dx: i64, dy: i64) -> Option<usize> {
        let texels = self.texels;
        let (width, height) = (texels.width as i64, texels.height as i64);
        let (x, y) = (t.x(texels.width) as i64 + dx, t.y(texels.width) as i64 + dy);
        if x < 0 || y < 0 || x >= width || y >= height {
            return None;
        }
        texels.texels.binary_search_by_key(&((x + y * width) as u32), |n| n.index).ok()
    }
}

/// What flags a texel, per texel (luminance): all the direct light that
/// reaches it or would but for shadows, and the parts of it whose bends
/// mark a shadow's edge.
pub struct Edges {
    light: Vec<f64>,
    /// The environment's light that other surfaces block, and the
    /// punctual lights' irradiance (their shadows are exact, taken whole).
    shadows: Vec<Vec<f64>>,
}

impl Edges {
    /// From the environment's irradiance and the luminance of its
    /// irradiance other surfaces block, and the punctual lights' irradiance.
    pub fn new(count: usize, environment: Option<(&[[f32; 3]], &[f32])>, punctual: Option<&[[f32; 3]]>) -> Edges {
        let mut light = vec![0.0; count];
        let mut shadows = Vec::new();
        if let Some((irradiance, shadowed)) = environment {
            for ((sum, &e), &s) in light.iter_mut().zip(irradiance).zip(shadowed) {
                *sum += luminance(e) + s as f64;
            }
            shadows.push(shadowed.iter().map(|&s| s as f64).collect());
        }
        if let Some(irradiance) = punctual {
            let level: Vec<f64> = irradiance.iter().map(|&e| luminance(e)).collect();
            light.iter_mut().zip(&level).for_each(|(sum, l)| *sum += l);
            shadows.push(level);
        }
        Edges { light, shadows }
    }

    /// Whether some part bends across texel `b` by more than
    /// `EDGE_CONTRAST` of the light at `a`, `b` or `c`, its neighbours on
    /// either side along a row or a column.
    fn bend(&self, a: usize, b: usize, c: usize, peak: f64) -> bool {
        let top = self.light[a].max(self.light[b]).max(self.light[c]);
        // Far below the brightest texel, a difference is invisible.
        top > 1e-6 * peak && self.shadows.iter().any(|s| (s[a] - 2.0 * s[b] + s[c]).abs() > EDGE_CONTRAST * top)
    }
}

/// The texels a shadow's edge crosses, in order.
fn flag(atlas: &Atlas, edges: &Edges) -> Vec<usize> {
    let texels = atlas.texels;
    let peak = edges.light.iter().cloned().fold(0.0f64, f64::max);
    if peak <= 0.0 {
        return Vec::new();
    }
    // Bent, not sloped: a texel's mean over its square is its centre's value
    // wherever the light changes linearly across it (a penumbra several
    // texels wide), so only a kink or a step (second difference) needs
    // sub-samples. And in the shadows only: sub-samples take the texel's
    // own normal, so light that bends with a curved surface's normal (a
    // statue's folds) they would gather at the centre's value again.
    (0..texels.texels.len())
        .into_par_iter()
        .filter(|&i| {
            let t = &texels.texels[i];
            t.area > 0.0
                && [(1, 0), (0, 1)].iter().any(|&(dx, dy)| {
                    let (Some(before), Some(after)) = (atlas.at(t, -dx, -dy), atlas.at(t, dx, dy)) else {
                        return false;
                    };
                    edges.bend(before, i, after, peak)
                })
        })
        .collect()
}

/// Flagged texel `i`'s sub-samples that its centre reaches along the
/// surface; none where it is not inside its chart or touches another surface.
fn sub_samples(occluders: &Surfaces, atlas: &Atlas, i: usize) -> Vec<Texel> {
    let texels = atlas.texels;
    let t = &texels.texels[i];
    // Inside its chart: all eight neighbours are its surface.
    let mut around = [[0usize; 3]; 3];
    let inside = (-1..=1i64).all(|dy| {
        (-1..=1i64).all(|dx| {
            atlas.at(t, dx, dy).is_some_and(|j| {
                let n = &texels.texels[j];
                around[(dy + 1) as usize][(dx + 1) as usize] = j;
                n.chart == t.chart && n.area > 0.0 && n.normal().dot(t.normal()) >= SAME_SURFACE_COS
            })
        })
    });
    if !inside {
        return Vec::new();
    }
    let p = |j: usize| texels.texels[j].position();
    let du = (p(around[1][2]) - p(around[1][0])) * 0.5;
    let dv = (p(around[2][1]) - p(around[0][1])) * 0.5;
    let lift = DVec3::from(Vec3::from(t.face_normal)) * LIFT_TEXELS * du.length().min(dv.length()) as f64;
    let centre = t.position().as_dvec3() + lift;
    // A texel whose lift crosses another surface touches it (a
    // ring's underside on the floor): its flat footprint would dip
    // behind that surface where its own surface curves away, and
    // the centre, lifted, is behind it already. It keeps its centre.
    if occluders.blocks(t.position().as_dvec3() + lift * 1e-3, centre) {
        return Vec::new();
    }
    PATTERN
        .iter()
        .enumerate()
        .filter_map(|(k, [ox, oy])| {
            let on_plane = (t.position() + du * (ox / 16.0) + dv * (oy / 16.0)).as_dvec3();
            (!occluders.blocks(centre, on_plane + lift)).then(|| Texel {
                position: on_surface(occluders, on_plane, lift).as_vec3().to_array(),
                // A different filter turn per sub-sample (the direct pass turns its taps by index).
                index: t.index.wrapping_mul(PATTERN.len() as u32).wrapping_add(k as u32),
                ..*t
            })
        })
        .collect()
}

/// The sub-sample at `on_plane`, on the footprint's flat plane, moved up
/// onto the surface where the surface rises above that plane (a concave
/// one, past a crease): searched from `lift` above, which the reach check
/// found in front of every surface. Where the surface falls away below the
/// plane (a convex one) the point stays on the plane, in front of it.
fn on_surface(occluders: &Surfaces, on_plane: DVec3, lift: DVec3) -> DVec3 {
    let above = on_plane + lift;
    occluders.first_hit(above, -lift, 1.0).map_or(on_plane, |(t, _, _)| above - lift * t)
}

/// Replaces each flagged texel's irradiance with the mean of its
/// sub-samples' (`gathered`, in `plan.samples` order).
pub fn fold(plan: &Plan, gathered: &[[f32; 3]], irradiance: &mut [[f32; 3]]) {
    // A texel's sub-samples are consecutive.
    let mut first = 0;
    for run in plan.owner.chunk_by(|a, b| a == b) {
        let samples = &gathered[first..first + run.len()];
        first += run.len();
        let mean = |c: usize| (samples.iter().map(|e| e[c] as f64).sum::<f64>() / samples.len() as f64) as f32;
        irradiance[run[0] as usize] = [mean(0), mean(1), mean(2)];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One atlas row of `n` texels with area.
    fn row(n: u32) -> TexelSet {
        let texels = (0..n).map(|index| Texel { index, area: 1.0, ..Default::default() }).collect();
        TexelSet { width: n, height: 1, texels, tint: Vec::new() }
    }

    #[test]
    fn a_shadow_s_edge_flags_the_texels_it_bends_across_and_a_curved_surface_s_light_does_not() {
        let texels = row(8);
        let atlas = Atlas { texels: &texels };
        // Light falling off with a folded surface's normal, nothing blocked:
        // the second difference at texel 3 is 0.6 of the light there.
        let folded = [1.0, 1.0, 1.0, 0.4, 1.0, 1.0, 1.0, 1.0];
        let unshadowed = Edges::new(8, Some((&folded.map(|l| [l; 3]), &[0.0; 8])), None);
        assert!(flag(&atlas, &unshadowed).is_empty());
        // A hard shadow from texel 4 on: its light blocked there, bent at 3 and 4.
        let lit = [1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0];
        let blocked = lit.map(|l| 1.0 - l);
        let shadowed = Edges::new(8, Some((&lit.map(|l| [l; 3]), &blocked)), None);
        assert_eq!(flag(&atlas, &shadowed), vec![3, 4]);
        // A punctual light's irradiance counts whole.
        let punctual = Edges::new(8, None, Some(&folded.map(|l| [l; 3])));
        assert_eq!(flag(&atlas, &punctual), vec![2, 3, 4]);
    }
}
