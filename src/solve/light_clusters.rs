//! Lights too small to earn a ray each share them (the direct pass's
//! clusters, after Lightcuts: Walter et al. 2005). A light earns rays by its
//! share of the sphere or of the power (`direct::RayBudget`'s rays in all);
//! with more lights than that, each would still get one where something may block it,
//! and rays would grow with the light count rather than with what the
//! scene's shadows need. Neighbouring small lights are grouped instead, a
//! group earning the rays its members earn together, and a point casts them
//! at its members in turn: each member takes the share its cluster's rays
//! find open. Where nothing varies over a cluster that is exact; where a
//! shadow's edge crosses it, the edge is sampled as finely as a light of the
//! cluster's size would sample it.

use std::borrow::Cow;

use glam::Vec3;

use crate::environment::Light;

/// Most lights in one cluster (solve_direct.wgsl finds a member among eight bits).
const MAX_MEMBERS: usize = 8;
/// A cluster holds small lights that together earn at most this many rays,
/// and gets that many rounded up: no part of the sphere gets fewer rays than
/// it earns, as with lights alone.
const MAX_SHARE: f32 = 1.0;
/// Lights a shader word of bits holds: no cluster spans two.
const WORD: usize = 32;

/// A light's place in its cluster: how many lights back the cluster's first
/// is, how many lights it holds, and the rays it gets at a point where all
/// of them may be blocked.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Membership {
    pub offset: u32,
    pub size: u32,
    pub rays: u32,
}

/// Whether a set of `lights` forms clusters: only with at least twice as
/// many lights as rays for the sphere (`rays`). With fewer, lights that earn
/// under a ray pair up at best, and the saving does not pay for the cluster
/// order, which changes how the lights fall into batches (BENCHMARKS.md,
/// stop 66).
pub fn clustered(lights: usize, rays: f32) -> bool {
    lights as f32 >= 2.0 * rays
}

/// The lights in cluster order, and which of them start a cluster. Where
/// clusters form, the sphere is cut in halves by count along the directions'
/// widest spread, at multiples of a shader word's 32 lights, down to parts
/// of one word (so no cluster spans two words of a batch); each part is
/// ordered the same way down to single lights, and its small lights
/// (`wanted`: the rays each earns, before rounding up; small: under one)
/// run into clusters of at most `MAX_MEMBERS` that earn at most `MAX_SHARE`
/// together, its large ones standing alone. Else every light stands alone,
/// in the set's order.
pub fn order<'a>(lights: &'a [Light], wanted: &[f32], clustered: bool) -> (Cow<'a, [Light]>, Vec<bool>) {
    if !clustered {
        return (Cow::Borrowed(lights), vec![true; lights.len()]);
    }
    let mut items: Vec<(Light, f32)> = lights.iter().copied().zip(wanted.iter().copied()).collect();
    let mut starts = Vec::with_capacity(lights.len());
    for word in cut(&mut items, WORD) {
        cut(word, 1);
        starts.extend(cluster_starts(word));
    }
    (Cow::Owned(items.into_iter().map(|(light, _)| light).collect()), starts)
}

/// Orders `items` by halves along the directions' widest spread, each cut
/// at a multiple of `unit`, down to parts of at most `unit` items; returns
/// the parts in order.
fn cut(items: &mut [(Light, f32)], unit: usize) -> Vec<&mut [(Light, f32)]> {
    if items.len() <= unit {
        return vec![items];
    }
    let axis = widest_axis(items);
    items.sort_by(|a, b| a.0.direction[axis].total_cmp(&b.0.direction[axis]));
    let middle = ((items.len() / 2 + unit / 2) / unit * unit).clamp(unit, items.len() - 1);
    let (left, right) = items.split_at_mut(middle);
    let mut parts = cut(left, unit);
    parts.extend(cut(right, unit));
    parts
}

/// Which lights of a run in cluster order start a cluster, by the rays each
/// earns: a large light stands alone; a small one joins the cluster before
/// it while that holds fewer than `MAX_MEMBERS`, they earn at most
/// `MAX_SHARE` together, and it lies near the cluster's first (`near`).
fn cluster_starts(items: &[(Light, f32)]) -> Vec<bool> {
    let mut first = 0;
    let (mut size, mut share, mut omega) = (0, f32::INFINITY, 0.0);
    let mut starts = Vec::with_capacity(items.len());
    for (k, &(light, w)) in items.iter().enumerate() {
        let joins = w < 1.0
            && share + w <= MAX_SHARE
            && size < MAX_MEMBERS
            && near(&items[first].0, &light, omega + light.solid_angle);
        (first, size, share, omega) =
            if joins { (first, size + 1, share + w, omega + light.solid_angle) } else { (k, 1, w, light.solid_angle) };
        starts.push(!joins);
    }
    starts
}

/// Whether `b` lies within √8 radii of a disc of `omega` sr from `a`
/// (1 − cos θ ≤ 4Ω/π): a cluster stays compact where its order steps from
/// one half of a cut to the other.
fn near(a: &Light, b: &Light, omega: f32) -> bool {
    1.0 - cos_between(a, b) <= 4.0 * omega / std::f32::consts::PI
}

/// The cosine of the angle between two lights' directions.
fn cos_between(a: &Light, b: &Light) -> f32 {
    Vec3::from(a.direction).dot(Vec3::from(b.direction))
}

/// The axis along which the lights' directions spread the most.
fn widest_axis(items: &[(Light, f32)]) -> usize {
    let spread = |axis: usize| {
        let values = items.iter().map(|(l, _)| l.direction[axis]);
        values.clone().fold(f32::NEG_INFINITY, f32::max) - values.fold(f32::INFINITY, f32::min)
    };
    (0..3).max_by(|&a, &b| spread(a).total_cmp(&spread(b))).unwrap_or(0)
}

/// Each light's place in its cluster, for one batch (or part of one) of
/// lights in cluster order: a cluster runs from a light that `starts` one to
/// the next, cut at each 32nd light of the batch. A light alone gets its own
/// rays (`own_rays`); a cluster the rays its lights earn together
/// (`wanted`), rounded up.
pub fn memberships(starts: &[bool], wanted: &[f32], own_rays: impl Fn(usize) -> u32) -> Vec<Membership> {
    let mut members = Vec::with_capacity(starts.len());
    let mut start = 0;
    while start < starts.len() {
        let end = (start + 1..starts.len())
            .find(|&k| starts[k] || k % WORD == 0 || k - start == MAX_MEMBERS)
            .unwrap_or(starts.len());
        let size = end - start;
        let share = wanted[start..end].iter().sum::<f32>();
        let rays = if size == 1 { own_rays(start) } else { share.ceil().max(1.0) as u32 };
        members.extend((0..size).map(|k| Membership { offset: k as u32, size: size as u32, rays }));
        start = end;
    }
    members
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::environment::{EnvironmentMap, LightMode, LightSet};

    fn light(direction: [f32; 3], solid_angle: f32) -> Light {
        Light { direction, solid_angle, radiance: [1.0; 3] }
    }

    fn row(count: usize) -> Vec<Light> {
        (0..count).map(|k| light([k as f32 * 0.01, 0.0, 1.0], 0.01)).collect()
    }

    #[test]
    fn lights_that_earn_a_ray_each_stand_alone() {
        let wanted = [1.0, 2.0, 1.5, 3.0];
        let lights = row(4);
        let (ordered, starts) = order(&lights, &wanted, true);
        assert_eq!(starts, [true; 4]);
        let members = memberships(&starts, &wanted, |k| wanted[k].ceil() as u32);
        let rays: Vec<u32> = ordered.iter().zip(&members).map(|(_, m)| m.rays).collect();
        assert!(members.iter().all(|m| m.offset == 0 && m.size == 1));
        assert_eq!(rays.iter().sum::<u32>(), 1 + 2 + 2 + 3);
    }

    #[test]
    fn small_neighbours_share_the_rays_they_earn_together() {
        let (_, starts) = order(&row(9), &[0.3; 9], true);
        let members = memberships(&starts, &[0.3; 9], |_| 1);
        // 0.3 rays each: three to a ray.
        let expected = [(0, 3), (1, 3), (2, 3)].repeat(3);
        assert_eq!(members.iter().map(|m| (m.offset, m.size)).collect::<Vec<_>>(), expected);
        assert!(members.iter().all(|m| m.rays == 1));
        let (_, starts) = order(&row(8), &[0.1; 8], true);
        let members = memberships(&starts, &[0.1; 8], |_| 1);
        assert!(members.iter().all(|m| m.size == 8 && m.rays == 1));
        // A large light among small ones stands alone.
        let items: Vec<(Light, f32)> = row(5).into_iter().zip([0.2, 0.2, 4.0, 0.2, 0.2]).collect();
        assert_eq!(cluster_starts(&items), [true, false, true, true, false]);
    }

    #[test]
    fn a_cluster_ends_at_a_word_s_end_and_at_eight_lights() {
        let mut starts = [false; 40];
        starts[0] = true;
        let members = memberships(&starts, &[0.01; 40], |_| 1);
        let firsts: Vec<usize> = (0..40).filter(|&k| members[k].offset == 0).collect();
        assert_eq!(firsts, [0, 8, 16, 24, 32]);
        starts[1] = true;
        let members = memberships(&starts, &[0.01; 40], |_| 1);
        let firsts: Vec<usize> = (0..40).filter(|&k| members[k].offset == 0).collect();
        assert_eq!(firsts, [0, 1, 9, 17, 25, 32]);
    }

    #[test]
    fn clusters_of_a_fine_cube_map_are_compact_and_full() {
        let set = LightSet::extract(&EnvironmentMap::constant([1.0; 3]), LightMode::Cube { face_size: 32 }, 0.0, 1.0);
        let wanted = |lights: &[Light]| -> Vec<f32> {
            lights.iter().map(|l| l.solid_angle * 1024.0 / (4.0 * std::f32::consts::PI)).collect()
        };
        let (ordered, starts) = order(&set.lights, &wanted(&set.lights), true);
        assert_eq!(ordered.len(), 6144);
        let members = memberships(&starts, &wanted(&ordered), |_| 1);
        let clusters = members.iter().filter(|m| m.offset == 0).count();
        // A cube texel's light earns 0.09–0.32 rays (0.17 on average): about five of them a
        // cluster, and a cluster one ray, where each alone would get one.
        assert!(clusters * 9 <= 6144 * 2, "{clusters} clusters");
        let rays: u32 = members.iter().filter(|m| m.offset == 0).map(|m| m.rays).sum();
        assert_eq!(rays as usize, clusters);
        for (k, m) in members.iter().enumerate() {
            let (head, member) = (&ordered[k - m.offset as usize], &ordered[k]);
            let cos = cos_between(head, member);
            // Within four cube texels' widths (2/32 of a face each) of the cluster's first.
            assert!(
                cos > (4.0f32 * 2.0 / 32.0).cos(),
                "light {k} is {}° from its cluster's first",
                cos.acos().to_degrees()
            );
            assert_eq!(k / WORD, (k - m.offset as usize) / WORD, "the cluster of light {k} spans two words");
        }
    }

    #[test]
    fn without_clusters_the_lights_keep_their_order() {
        let lights = row(5);
        let (ordered, starts) = order(&lights, &[0.1; 5], false);
        assert!(matches!(ordered, Cow::Borrowed(_)));
        assert_eq!(starts, [true; 5]);
    }
}
