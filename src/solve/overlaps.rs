//! Surfaces that lie on or just over one another, facing the same way: a
//! floor laid exactly on the ground, an object exported twice in separate
//! primitives, a slab a centimetre over the ground. The depth maps cannot
//! tell such surfaces apart, so each gets the place's light, and in the
//! bounce pass each reflected it: light left that place once per surface
//! (an open box standing on the ground came out far brighter than the
//! reference inside).
//! A path meets one surface there. So each texel gets the share of its area
//! that bounces light:
//! - 1 where no other surface covers its position;
//! - 1/k where k surfaces lie in its plane over its position (each gets the
//!   place's light, as a path tracer's point on either does);
//! - 0 where another lies in front of it within a texel: it is hidden.
//!
//! A texel hidden under an opaque surface also gets no light: the depth maps
//! took the surface over it for its own plane and lit it (0.25 where the
//! reference has 0.0004, under a floor a centimetre over the ground). Under a
//! blended one (baked as opaque) it keeps its light, since it shows through.

use std::collections::HashMap;

use glam::{IVec3, Vec3};
use rayon::prelude::*;

use crate::scene::{AlphaMode, Scene};
use crate::texelize::{Texel, TexelSet};

/// Two triangles face the same way when their normals are within about 2°.
pub(super) const SAME_FACING_COS: f32 = 0.9995;

/// A covering triangle: its corners wound counter-clockwise about `normal`.
struct Cover {
    corners: [Vec3; 3],
    normal: Vec3,
    /// Alpha-BLEND: baked as opaque, but what lies under it shows through.
    see_through: bool,
}

/// Where surfaces overlap, per texel in `TexelSet` order.
pub struct Overlaps {
    /// The share of the texel's area that bounces light (see the module comment).
    pub shares: Vec<f32>,
    /// Hidden under an opaque surface within a texel: no light reaches it.
    pub hidden: Vec<bool>,
}

/// `texels` as the energy sums count them: each at the share of its area
/// that bounces light (`shares`; its tint left out).
pub fn counted(texels: &TexelSet, shares: &[f32]) -> TexelSet {
    TexelSet {
        texels: texels.texels.iter().zip(shares).map(|(t, s)| Texel { area: t.area * s, ..*t }).collect(),
        tint: Vec::new(),
        ..*texels
    }
}

impl Overlaps {
    /// Texels that share their place or are hidden.
    pub fn count(&self) -> usize {
        self.shares.iter().filter(|&&s| s < 1.0).count()
    }
}

/// What a texel's position has over it.
#[derive(Clone, Copy, PartialEq)]
enum Over {
    /// `k` surfaces in its plane, itself included (1: alone).
    Shared(u32),
    /// A surface in front of it within a texel; `opaque` unless all such are blended.
    Hidden { opaque: bool },
}

/// The overlaps of `texels`' surfaces, or `None` when no surface covers
/// another anywhere. `texel_size` is the atlas's texel spacing in metres.
pub fn find(scene: &Scene, texels: &TexelSet, texel_size: f32) -> Option<Overlaps> {
    let covers = covering_triangles(scene);
    let (lo, hi) = scene.bounds()?;
    // Coincident: within millionths of the scene's size (rounding of node
    // transforms). Inside a triangle of the texel's own mesh: at least that
    // far from its edges, so that a texel on an edge its mesh shares is not
    // covered by the triangle beyond it.
    let tolerance = (1e-5 * (hi - lo).length()).max(f32::MIN_POSITIVE);
    let hidden_within = texel_size.max(tolerance);
    let largest = texels.texels.iter().map(|t| t.area).fold(0.0f32, f32::max).sqrt();
    // A covering triangle has a texel within this of the covered position.
    let reach = 1.5 * texel_size.max(largest) + hidden_within;
    let grid = Grid::new(texels.texels.iter().map(|t| Vec3::from(t.position)), reach);

    let over: Vec<Over> = texels
        .texels
        .par_iter()
        // The triangles a texel has looked at, and the other primitives it
        // shares its place with, in lists each thread reuses.
        .map_init(<(Vec<u32>, Vec<u32>)>::default, |(seen, sharing), t| {
            let Some(own) = covers[t.triangle as usize].as_ref().filter(|_| t.area > 0.0) else {
                return Over::Shared(1);
            };
            let (p, n) = (Vec3::from(t.position), Vec3::from(t.face_normal));
            // Another mesh is tested a quarter texel inside the texel's own
            // triangle, leniently: there a copy covers it, also where the
            // texel lies on its own triangle's edge (a chart's border texels
            // do) or on the edge between two of the copy's triangles, and a
            // mesh that only abuts it along that edge (the next floor tile)
            // does not.
            let inside = own.towards_inside(p, 0.25 * texel_size);
            seen.clear();
            sharing.clear();
            let mut coincident = 1;
            let mut hidden = None;
            for j in grid.near(p) {
                let other = &texels.texels[j as usize];
                let u = other.triangle;
                if u == t.triangle || seen.contains(&u) {
                    continue;
                }
                seen.push(u);
                let Some(cover) = &covers[u as usize] else { continue };
                if cover.normal.dot(n) < SAME_FACING_COS {
                    continue;
                }
                // In the texel's plane, a triangle of its own mesh that
                // merely meets its own at the texel (a neighbour) does not
                // cover it; another mesh is counted once (above). In front
                // of it, a triangle whose edge passes over it covers it.
                let ahead = cover.normal.dot(cover.corners[0] - p);
                if ahead.abs() <= tolerance {
                    if other.primitive == t.primitive {
                        coincident += cover.holds(p, tolerance) as u32;
                    } else if !sharing.contains(&other.primitive) && cover.holds(inside, -tolerance) {
                        sharing.push(other.primitive);
                        coincident += 1;
                    }
                } else if ahead > tolerance && ahead <= hidden_within && cover.holds(p, -tolerance) {
                    hidden = Some(hidden.unwrap_or(false) || !cover.see_through);
                }
            }
            match hidden {
                Some(opaque) => Over::Hidden { opaque },
                None => Over::Shared(coincident),
            }
        })
        .collect();
    if over.iter().all(|&o| o == Over::Shared(1)) {
        return None;
    }
    Some(Overlaps {
        shares: over
            .iter()
            .map(|o| match o {
                Over::Shared(k) => 1.0 / *k as f32,
                Over::Hidden { .. } => 0.0,
            })
            .collect(),
        hidden: over.iter().map(|o| matches!(o, Over::Hidden { opaque: true })).collect(),
    })
}

impl Cover {
    /// `p` moved `by` towards the triangle's centroid (at most half way).
    fn towards_inside(&self, p: Vec3, by: f32) -> Vec3 {
        let [a, b, c] = self.corners;
        let to_centre = (a + b + c) / 3.0 - p;
        p + to_centre * (by / to_centre.length()).min(0.5)
    }

    /// Whether `p`, projected onto the triangle's plane, lies inside it at
    /// least `margin` from every edge.
    fn holds(&self, p: Vec3, margin: f32) -> bool {
        let [a, b, c] = self.corners;
        [(a, b), (b, c), (c, a)].iter().all(|&(from, to)| {
            let inward = self.normal.cross(to - from).normalize_or_zero();
            inward.dot(p - from) >= margin
        })
    }
}

/// Every triangle that hides what lies behind it, by the texels' global
/// triangle id (primitives in order, repeated triangles left out), or
/// `None`: alpha-MASK triangles (light passes their holes) and triangles
/// without area.
fn covering_triangles(scene: &Scene) -> Vec<Option<Cover>> {
    let mut covers = Vec::new();
    for primitive in &scene.primitives {
        let material = scene.material(primitive);
        let cut_out = material.cutoff().is_some();
        let see_through = material.alpha == AlphaMode::Blend;
        let repeat = crate::repeats::mask(&primitive.repeats, primitive.triangle_count());
        for t in (0..primitive.triangle_count()).filter(|&t| !repeat[t]) {
            let normal = primitive.face_normal(t);
            let corners = primitive.front_corners(t).map(|i| Vec3::from(primitive.positions[i as usize]));
            covers.push((!cut_out && normal != Vec3::ZERO).then_some(Cover { corners, normal, see_through }));
        }
    }
    covers
}

/// Points hashed into cubes twice `reach` wide: those within `reach` of a
/// position lie in the 2×2×2 cubes nearest it.
struct Grid {
    cell: f32,
    order: Vec<u32>,
    ranges: HashMap<IVec3, (u32, u32)>,
}

impl Grid {
    fn new(points: impl Iterator<Item = Vec3>, reach: f32) -> Grid {
        let cell = 2.0 * reach;
        let mut keyed: Vec<(IVec3, u32)> =
            points.enumerate().map(|(i, p)| ((p / cell).floor().as_ivec3(), i as u32)).collect();
        keyed.sort_unstable_by_key(|&(k, i)| (k.x, k.y, k.z, i));
        let mut ranges = HashMap::new();
        let mut start = 0;
        for run in keyed.chunk_by(|a, b| a.0 == b.0) {
            ranges.insert(run[0].0, (start as u32, (start + run.len()) as u32));
            start += run.len();
        }
        Grid { cell, order: keyed.into_iter().map(|(_, i)| i).collect(), ranges }
    }

    /// Every point within `reach` of `p`, and some further.
    fn near(&self, p: Vec3) -> impl Iterator<Item = u32> + '_ {
        let first = (p / self.cell - 0.5).floor().as_ivec3();
        (0..8).flat_map(move |k| {
            let key = first + IVec3::new(k & 1, (k >> 1) & 1, k >> 2);
            let (a, b) = self.ranges.get(&key).copied().unwrap_or((0, 0));
            self.order[a as usize..b as usize].iter().copied()
        })
    }
}
