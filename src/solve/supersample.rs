//! Supersample fix-up: where a shadow edge crosses a texel, its value becomes
//! the mean of the direct light over the texel's footprint instead of the
//! light at its centre, so a hard edge is anti-aliased instead of
//! stair-stepped (issue 6, "a texel's value represents its footprint").
//!
//! After the direct pass, a texel is flagged when its direct irradiance
//! bends sharply across it (second difference over `EDGE_CONTRAST`), and it
//! lies inside its chart (all eight neighbours are covered texels of the same
//! chart, facing within `SAME_SURFACE_COS`): its footprint is then all
//! surface, mapped to the world by the central differences of its
//! neighbours' positions. Eight sub-samples in the footprint (the D3D
//! standard 8× pattern) are gathered by a second direct pass. A sub-sample
//! that the texel's centre cannot reach along the surface (a wall standing
//! on the floor between them) is left out: the texel stands for the part of
//! its footprint a viewer can see, and light from behind the wall must not
//! leak in.
//!
//! Flagging needs the direct light, and the depth maps are gone once it is
//! gathered. Under many lights, a preview under a few merged ones
//! (`preview_lights`) flags the texels instead, so the full set's depth maps
//! are rendered once, for the texels and their sub-samples together.

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::environment::{Light, LightSet, luminance};
use crate::reference::Occluders;
use crate::texelize::{Texel, TexelSet};

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
/// Height of the centre-to-sub-sample segment above the surface, in texel
/// widths: above the curvature of a surface bent at most `SAME_SURFACE_COS`
/// per texel, below anything standing on it.
const LIFT_TEXELS: f64 = 0.05;

/// Lights of the preview that flags texels under a large light set. With
/// 64, the preview flags 1.0–1.4× the texels the full set's light does and
/// misses ones holding 0.1–1.9 % of what the fix-up changes (the statues
/// under three captured skies, a room under a sun); with 16 or 32, up to 23 %.
const PREVIEW_LIGHTS: usize = 64;
/// A preview is made for at least this many lights per preview light: it
/// then costs at most an eighth of a full pass, and saves rendering every
/// depth map a second time.
const LIGHTS_PER_PREVIEW_LIGHT: usize = 8;

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

/// Flags the texels on a sharp change of `irradiance` and places their
/// sub-samples. `None` when no texel needs them.
pub fn plan(occluders: &Occluders, texels: &TexelSet, irradiance: &[[f32; 3]]) -> Option<Plan> {
    let (width, height) = (texels.width as i64, texels.height as i64);
    // Texels are in row-major atlas order: a neighbour is found by binary
    // search (a lookup table would take 1 GiB at 16384²).
    let at = |t: &Texel, dx: i64, dy: i64| -> Option<usize> {
        let (x, y) = (t.x(texels.width) as i64 + dx, t.y(texels.width) as i64 + dy);
        if x < 0 || y < 0 || x >= width || y >= height {
            return None;
        }
        texels.texels.binary_search_by_key(&((x + y * width) as u32), |n| n.index).ok()
    };
    let level: Vec<f64> = irradiance.iter().map(|&e| luminance(e)).collect();
    let peak = level.iter().cloned().fold(0.0f64, f64::max);
    if peak <= 0.0 {
        return None;
    }
    // Bent, not sloped: a texel's mean over its square is its centre's value
    // wherever the light changes linearly across it (a penumbra several
    // texels wide), so only a kink or a step (second difference) needs
    // sub-samples.
    let flagged: Vec<usize> = (0..texels.texels.len())
        .into_par_iter()
        .filter(|&i| {
            let t = &texels.texels[i];
            t.area > 0.0
                && [(1, 0), (0, 1)].iter().any(|&(dx, dy)| {
                    let (Some(before), Some(after)) = (at(t, -dx, -dy), at(t, dx, dy)) else {
                        return false;
                    };
                    let (a, b, c) = (level[before], level[i], level[after]);
                    let top = a.max(b).max(c);
                    // Far below the brightest texel, a difference is invisible.
                    top > 1e-6 * peak && (a - 2.0 * b + c).abs() > EDGE_CONTRAST * top
                })
        })
        .collect();
    if flagged.is_empty() {
        return None;
    }
    // Each flagged texel's sub-samples, in texel order (rayon keeps it).
    let per_texel: Vec<Vec<Texel>> = flagged
        .par_iter()
        .map(|&i| {
            let t = &texels.texels[i];
            // Inside its chart: all eight neighbours are its surface.
            let mut around = [[0usize; 3]; 3];
            let inside = (-1..=1i64).all(|dy| {
                (-1..=1i64).all(|dx| {
                    at(t, dx, dy).is_some_and(|j| {
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
                    let position = t.position() + du * (ox / 16.0) + dv * (oy / 16.0);
                    (!occluders.blocks(centre, position.as_dvec3() + lift)).then(|| Texel {
                        position: position.to_array(),
                        // A different filter turn per sub-sample (the direct pass turns its taps by index).
                        index: t.index.wrapping_mul(PATTERN.len() as u32).wrapping_add(k as u32),
                        ..*t
                    })
                })
                .collect()
        })
        .collect();
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

/// The lights merged into `PREVIEW_LIGHTS` groups of nearby directions, for
/// flagging texels; `None` under too few lights for a preview to pay.
///
/// Groups are split top-down, the one whose light is most spread (energy ×
/// angular spread) first, at its energy median along its widest axis: a
/// bright light stays alone, so its shadow edges stay where they are, and
/// a dim sky merges into groups whose edges are too faint to flag. A group
/// keeps its energy; its light covers the members' solid angle, so its
/// shadows are as soft as theirs together.
pub fn preview_lights(lights: &LightSet) -> Option<LightSet> {
    if lights.lights.len() < LIGHTS_PER_PREVIEW_LIGHT * PREVIEW_LIGHTS {
        return None;
    }
    let energy = |l: &Light| luminance(l.radiance).max(0.0) * l.solid_angle as f64;
    let direction = |l: &Light| DVec3::from(Vec3::from(l.direction));
    // The energy-weighted mean direction (not unit) and the energy of a group.
    let centroid = |group: &[Light]| {
        let total: f64 = group.iter().map(energy).sum();
        let sum: DVec3 = group.iter().map(|l| direction(l) * energy(l)).sum();
        (if total > 0.0 { sum / total } else { DVec3::ZERO }, total)
    };
    // Σ e |d − m|² / Σ e = 1 − |m|² for unit directions: the group's spread².
    let spread = |group: &[Light]| {
        let (mean, total) = centroid(group);
        if group.len() < 2 { 0.0 } else { total * (1.0 - mean.length_squared()).max(0.0).sqrt() }
    };
    let mut groups: Vec<Vec<Light>> = vec![lights.lights.clone()];
    while groups.len() < PREVIEW_LIGHTS {
        let (widest, score) = groups
            .iter()
            .enumerate()
            .map(|(i, g)| (i, spread(g)))
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .expect("at least one group");
        if score <= 0.0 {
            break;
        }
        let mut group = groups.swap_remove(widest);
        let (mean, total) = centroid(&group);
        let variance =
            |axis: usize| group.iter().map(|l| energy(l) * (direction(l)[axis] - mean[axis]).powi(2)).sum::<f64>();
        let axis = (0..3).max_by(|&a, &b| variance(a).total_cmp(&variance(b))).expect("three axes");
        group.sort_by(|a, b| a.direction[axis].total_cmp(&b.direction[axis]));
        // The energy median, with at least one light on each side.
        let mut below = 0.0;
        let cut = group
            .iter()
            .position(|l| {
                below += energy(l);
                below >= 0.5 * total
            })
            .map_or(1, |i| i + 1)
            .clamp(1, group.len() - 1);
        let upper = group.split_off(cut);
        groups.push(group);
        groups.push(upper);
    }
    let merged = groups
        .iter()
        .map(|group| {
            let (mean, _) = centroid(group);
            let omega: f64 = group.iter().map(|l| l.solid_angle as f64).sum();
            let power =
                [0, 1, 2].map(|c| group.iter().map(|l| l.radiance[c] as f64 * l.solid_angle as f64).sum::<f64>());
            let direction = if mean.length_squared() > 1e-12 { mean.normalize() } else { direction(&group[0]) };
            Light {
                direction: direction.as_vec3().to_array(),
                solid_angle: omega as f32,
                radiance: power.map(|p| (p / omega) as f32),
            }
        })
        .collect();
    Some(LightSet {
        lights: merged,
        mode: lights.mode,
        map_integral: lights.map_integral,
        captured: lights.captured,
        dropped: lights.dropped,
        notes: Vec::new(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::environment::LightMode;

    /// A sun ten times as bright as the whole sky, and a sky of equal lights
    /// spread over the sphere (a Fibonacci lattice).
    fn sun_and_sky(sky_lights: usize) -> (LightSet, Vec3) {
        let sun = Vec3::new(0.3, 0.8, -0.52).normalize();
        let omega = 4.0 * std::f32::consts::PI / sky_lights as f32;
        let mut lights: Vec<Light> = (0..sky_lights)
            .map(|k| {
                let y = 1.0 - 2.0 * (k as f32 + 0.5) / sky_lights as f32;
                let (r, phi) = ((1.0 - y * y).sqrt(), k as f32 * 2.399_963);
                Light { direction: [r * phi.cos(), y, r * phi.sin()], solid_angle: omega, radiance: [0.2, 0.3, 0.5] }
            })
            .collect();
        let sky_energy: f64 = lights.iter().map(|l| luminance(l.radiance) * l.solid_angle as f64).sum();
        let sun_omega = 6.8e-5f32;
        let sun_radiance = (10.0 * sky_energy / sun_omega as f64 / luminance([1.0, 0.9, 0.8])) as f32;
        lights.push(Light {
            direction: sun.to_array(),
            solid_angle: sun_omega,
            radiance: [sun_radiance, 0.9 * sun_radiance, 0.8 * sun_radiance],
        });
        let set = LightSet {
            lights,
            mode: LightMode::Budget { count: sky_lights as u32 + 1 },
            map_integral: [0.0; 3],
            captured: [0.0; 3],
            dropped: 0,
            notes: Vec::new(),
        };
        (set, sun)
    }

    fn power(lights: &[Light]) -> [f64; 3] {
        [0, 1, 2].map(|c| lights.iter().map(|l| l.radiance[c] as f64 * l.solid_angle as f64).sum())
    }

    #[test]
    fn preview_keeps_the_energy_and_the_suns_direction_in_fewer_lights() {
        let (lights, sun) = sun_and_sky(2000);
        let preview = preview_lights(&lights).expect("2001 lights get a preview");
        assert_eq!(preview.lights.len(), PREVIEW_LIGHTS);
        let (before, after) = (power(&lights.lights), power(&preview.lights));
        for c in 0..3 {
            assert!((after[c] / before[c] - 1.0).abs() < 1e-5, "channel {c}: {} → {}", before[c], after[c]);
        }
        // The brightest merged light is the sun, within a tenth of its radius.
        let brightest = preview
            .lights
            .iter()
            .max_by(|a, b| {
                (luminance(a.radiance) * a.solid_angle as f64)
                    .total_cmp(&(luminance(b.radiance) * b.solid_angle as f64))
            })
            .unwrap();
        let off = Vec3::from(brightest.direction).angle_between(sun).to_degrees();
        assert!(off < 0.05, "the sun's light points {off}° off the sun");
        // A sky group carries a small share of the sky: none merges more than a sixteenth of it.
        let sky = luminance([0.2, 0.3, 0.5]) * 4.0 * std::f64::consts::PI;
        let largest_sky_group = preview
            .lights
            .iter()
            .filter(|l| !std::ptr::eq(*l, brightest))
            .map(|l| luminance(l.radiance) * l.solid_angle as f64)
            .fold(0.0, f64::max);
        assert!(largest_sky_group < sky / 16.0, "a group holds {:.3} of the sky", largest_sky_group / sky);
    }

    #[test]
    fn few_lights_get_no_preview() {
        let (lights, _) = sun_and_sky(LIGHTS_PER_PREVIEW_LIGHT * PREVIEW_LIGHTS - 2);
        assert!(preview_lights(&lights).is_none());
    }
}
