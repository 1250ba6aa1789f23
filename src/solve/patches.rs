//! Shooter patches: groups of texels that shoot their unshot light together
//! (design notes, algorithm step 4). The seed mipmaps the radiosity texture
//! to 32×32, but a mip texel mixes unrelated charts; here a patch never
//! leaves its chart: texels are grouped by chart, by a square cell of the
//! atlas (charts are continuous, so a cell is a compact piece of surface),
//! and by the major axis of their normal (so a patch stays nearly flat).
//!
//! Each patch also carries the parallelogram its atlas cell maps to in the
//! world (a least-squares affine fit of its texels' positions against their
//! atlas coordinates), so receivers close to it can use the exact
//! point-to-polygon form factor instead of the far-field disc formula.

use std::collections::HashMap;

use bytemuck::{Pod, Zeroable};
use glam::{DVec3, IVec3, Vec3};
use rayon::prelude::*;

use crate::texelize::TexelSet;
use crate::trace::Surfaces;

/// A patch as the GPU sees it. Mirrors `struct Patch` in include/bounce.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct Patch {
    /// Area-weighted centroid of its texels, world space.
    pub position: [f32; 3],
    /// Total world area, m².
    pub area: f32,
    /// Unit area-weighted mean shading normal.
    pub normal: [f32; 3],
    /// First entry of the patch in `Patches::members`.
    pub first: u32,
    /// Centre of the patch's parallelogram.
    pub rect_centre: [f32; 3],
    /// Number of member texels.
    pub count: u32,
    /// Half of the parallelogram's first side.
    pub half_u: [f32; 3],
    /// How far the patch's own surface rises above its centroid's tangent
    /// plane (curved patches); the hemicube starts this far above it.
    pub lift: f32,
    /// Half of the parallelogram's second side.
    pub half_v: [f32; 3],
    /// Distance from the parallelogram's centre to its farthest corner.
    pub radius: f32,
}

/// All patches, and which texels belong to which.
#[derive(Clone, Debug, Default)]
pub struct Patches {
    pub patches: Vec<Patch>,
    /// Texel indices (into `TexelSet::texels`) grouped by patch.
    pub members: Vec<u32>,
    /// The patch of every texel.
    pub texel_patch: Vec<u32>,
    /// Side of the atlas cell used, texels.
    pub cell: u32,
}

fn normal_axis(n: Vec3) -> u32 {
    let a = n.abs();
    if a.x >= a.y && a.x >= a.z {
        if n.x >= 0.0 { 0 } else { 1 }
    } else if a.y >= a.z {
        if n.y >= 0.0 { 2 } else { 3 }
    } else if n.z >= 0.0 {
        4
    } else {
        5
    }
}

/// A patch's cell is split in four (at most this many times over, down to
/// a texel) while a smaller object stands over it within its own size: the
/// hemicube sees from one point, and a small prop on a large floor patch is
/// lit by parts of the patch that point does not see (a ball's underside
/// got 0.69 of the reference on a 40 m ground, BENCHMARKS.md).
const MAX_SPLITS: u8 = 4;

/// An emissive texel's cell starts split up to this many times: an emitter's
/// first shot is the scene's direct light from it, and a hemicube sees from
/// one point, so each patch casts one hard shadow where the emitter casts a
/// penumbra: a 1 m panel's penumbra on a floor past a plate's edge was off
/// by 6.4 % of the unshaded light (rms) in patches of 3 × 3 texels, 3.4 %
/// split so (BENCHMARKS.md).
const EMITTER_SPLITS: u8 = 2;

/// A patch is cut into at most this many parts by what its hemicube's
/// origin sees (`split_by_sight`).
const MAX_PARTS: u32 = 4;
/// Only surfaces turned at least this far from a patch (cosine) cut it: a
/// wall standing on a floor, not a ball's underside touching it.
const STANDING_COS: f64 = 0.5;
/// Sight lines run this far off the surface, texels.
const SIGHT_CLEARANCE_TEXELS: f32 = 0.25;

/// Groups `texels` into about `target` patches, and more where a surface
/// stands close over one (`MAX_SPLITS`) or across one (`split_by_sight`,
/// where `sight` is given). `texel_size` is the world size of one lightmap
/// texel (1 / texels per unit).
pub fn build(texels: &TexelSet, target: u32, texel_size: f32, sight: Option<Sight>) -> Patches {
    let n = texels.texels.len();
    if n == 0 {
        return Patches::default();
    }
    let cell = cell_size(texels, target);
    // How many times each texel's cell was split.
    let emitter_splits = emitter_splits(texels, cell, target);
    let mut splits: Vec<u8> = texels.texels.iter().map(|t| if t.emits() { emitter_splits } else { 0 }).collect();
    let key = |i: usize, splits: &[u8]| {
        let t = &texels.texels[i];
        let (x, y) = (t.x(texels.width), t.y(texels.width));
        let level = splits[i] as u32;
        let part = (cell >> level).max(1);
        let sub = (level << 16) | (((y % cell) / part) << 8) | ((x % cell) / part);
        (t.chart, y / cell, x / cell, normal_axis(t.normal()), sub, 0)
    };
    // Keys computed once, not per comparison (at a 1024² atlas the sort
    // took most of the patch set-up). The index breaks ties, so the order is
    // one and the same in any thread count.
    let sorted = |splits: &[u8]| {
        let mut keyed: Vec<(Key, u32)> = (0..n).into_par_iter().map(|i| (key(i, splits), i as u32)).collect();
        keyed.par_sort_unstable();
        keyed
    };
    let mut keyed = sorted(&splits);
    let sizes = object_sizes(texels);
    for _ in 0..MAX_SPLITS {
        if cell < 2 {
            break;
        }
        let groups: Vec<&[(Key, u32)]> = keyed.chunk_by(|a, b| a.0 == b.0).collect();
        let crowded = crowded(texels, &groups, &sizes);
        let mut any = false;
        for (group, crowded) in groups.iter().zip(crowded) {
            let level = splits[group[0].1 as usize];
            if crowded && (cell >> level) >= 2 {
                any = true;
                for &(_, i) in *group {
                    splits[i as usize] += 1;
                }
            }
        }
        if !any {
            break;
        }
        keyed = sorted(&splits);
    }
    if let Some(sight) = sight {
        keyed = split_by_sight(texels, keyed, texel_size, &sight);
    }
    let order: Vec<u32> = keyed.iter().map(|&(_, i)| i).collect();

    // Each patch's range of `order`, then the patches fitted in parallel.
    let mut ranges = Vec::new();
    let mut texel_patch = vec![0u32; n];
    let mut start = 0;
    for group in keyed.chunk_by(|a, b| a.0 == b.0) {
        for &(_, i) in group {
            texel_patch[i as usize] = ranges.len() as u32;
        }
        ranges.push(start..start + group.len());
        start += group.len();
    }
    let patches =
        ranges.into_par_iter().map(|r| patch(texels, &order[r.clone()], r.start as u32, texel_size)).collect();
    Patches { patches, members: order, texel_patch, cell }
}

/// How many times the emitters' cells are split: `EMITTER_SPLITS`, or fewer
/// where their patches would then outnumber the `target` for the whole
/// scene (a scene that is mostly emitter, such as a glowing dome).
fn emitter_splits(texels: &TexelSet, cell: u32, target: u32) -> u8 {
    let emissive = texels.texels.iter().filter(|t| t.emits()).count() as f64;
    let patches_at = |level: u8| emissive * 4f64.powi(level as i32) / (cell as f64 * cell as f64);
    (0..=EMITTER_SPLITS).rev().find(|&level| patches_at(level) <= target as f64).unwrap_or(0)
}

/// Per primitive, the diagonal of its texels' world bounding box.
fn object_sizes(texels: &TexelSet) -> Vec<f32> {
    let primitives = texels.texels.iter().map(|t| t.primitive + 1).max().unwrap_or(0) as usize;
    let mut bounds = vec![(Vec3::MAX, Vec3::MIN); primitives];
    for t in &texels.texels {
        let b = &mut bounds[t.primitive as usize];
        *b = (b.0.min(t.position()), b.1.max(t.position()));
    }
    bounds.iter().map(|(lo, hi)| (*hi - *lo).length()).collect()
}

/// Side of the atlas cell, texels, that groups `texels` into about `target` patches.
pub fn cell_size(texels: &TexelSet, target: u32) -> u32 {
    ((texels.texels.len() as f64 / target.max(1) as f64).sqrt().round() as u32).max(1)
}

/// A texel's patch: chart, cell row and column, normal axis, the part of a
/// split cell, and the part `split_by_sight` put it in.
type Key = (u32, u32, u32, u32, u32, u32);

/// What `split_by_sight` looks through: the scene's geometry, and which texels
/// lie hidden under another surface (`overlaps`). Hidden texels take no
/// part in it: a floor's texels under a statue's base are behind the statue
/// from anywhere, and they bounce no light.
#[derive(Clone, Copy)]
pub struct Sight<'a> {
    pub occluders: &'a Surfaces,
    pub hidden: Option<&'a [bool]>,
}

/// Cuts each group of `keyed` (sorted by key) into the parts its hemicube
/// would see from different places: the texels its origin sees, then of
/// the rest those their own origin sees, and so on (`MAX_PARTS`). A wall
/// standing across a floor's cell hid the far side's texels from the
/// origin on the near side, and the cell's light, shot from there, reached
/// the wall's foot on one side only (its lowest 3 cm got 0.26 of the path
/// tracer's bounced light, BENCHMARKS.md). Only surfaces standing up from
/// the patch (`STANDING_COS`) block a sight line, its own primitive's too
/// (a wall merged into the ground's mesh, as exporters often do: cut by
/// other primitives only, its foot's middle band came out dark). Lines run over the patch, so a convex patch's own facets never
/// meet one, and a concave one's rim is not turned that far. Surfaces
/// lying along the patch do not block: a ball's
/// or a ring's underside touching a floor cut its cells into slivers around
/// the contact, whose parallelograms (their atlas cells' bounds) then lit
/// the contact as if it were open floor (every variant that let them cut
/// lost accuracy on the corner fixture's ring). An origin that sees
/// none of its texels (under the floor, inside an object resting on them)
/// leaves the group whole.
fn split_by_sight(texels: &TexelSet, keyed: Vec<(Key, u32)>, texel_size: f32, sight: &Sight) -> Vec<(Key, u32)> {
    let occluders = sight.occluders;
    let hidden = |i: u32| sight.hidden.is_some_and(|h| h[i as usize]);
    let groups: Vec<&[(Key, u32)]> = keyed.chunk_by(|a, b| a.0 == b.0).collect();
    let parts: Vec<Vec<u32>> = groups
        .par_iter()
        .map(|group| {
            // Hidden texels stay in the first part.
            let members: Vec<u32> = group.iter().map(|&(_, i)| i).filter(|&i| !hidden(i)).collect();
            let mut parts = sight_parts(texels, &members, texel_size, occluders).into_iter();
            group.iter().map(|&(_, i)| if hidden(i) { 0 } else { parts.next().unwrap_or(0) }).collect::<Vec<u32>>()
        })
        .collect();
    let mut split: Vec<(Key, u32)> = groups
        .iter()
        .zip(parts)
        .flat_map(|(group, parts)| group.iter().zip(parts).map(|(&(k, i), part)| ((k.0, k.1, k.2, k.3, k.4, part), i)))
        .collect();
    split.par_sort_unstable();
    split
}

/// The part of each of `members` (`split_by_sight`).
fn sight_parts(texels: &TexelSet, members: &[u32], texel_size: f32, occluders: &Surfaces) -> Vec<u32> {
    const UNSET: u32 = u32::MAX;
    let mut parts = vec![UNSET; members.len()];
    if members.is_empty() {
        return parts;
    }
    let clearance = (SIGHT_CLEARANCE_TEXELS * texel_size) as f64;
    for part in 0..MAX_PARTS {
        let left: Vec<usize> = (0..members.len()).filter(|&k| parts[k] == UNSET).collect();
        if left.is_empty() {
            break;
        }
        let ids: Vec<u32> = left.iter().map(|&k| members[k]).collect();
        let frame = hemicube_frame(texels, &ids, texel_size);
        let normal = frame.normal.as_dvec3();
        let eye = frame.origin().as_dvec3() + normal * clearance;
        let last = part + 1 == MAX_PARTS;
        let seen: Vec<bool> = left
            .iter()
            .map(|&k| {
                let t = &texels.texels[members[k] as usize];
                // Sight lines run in the eye's plane, across the patch: off
                // the texel's own face, one touching another surface (a
                // statue's base on the floor, a ring's underside) would step
                // through it, and a line up to a patch that faces the floor
                // from just above it would pass through the floor.
                let position = t.position().as_dvec3();
                let at = position + normal * (eye - position).dot(normal);
                let standing = |_, face: DVec3| face.dot(normal).abs() < STANDING_COS;
                last || !occluders.blocks_where(eye, at, standing)
            })
            .collect();
        let hidden = seen.iter().filter(|&&s| !s).count();
        let whole = hidden == 0 || hidden == left.len();
        for (&k, &seen) in left.iter().zip(&seen) {
            if seen || whole {
                parts[k] = part;
            }
        }
        if whole {
            break;
        }
    }
    parts
}

/// Where a patch's hemicube stands: its texels' area-weighted centroid and
/// mean normal, and how far above the centroid it starts.
struct HemicubeFrame {
    centroid: Vec3,
    normal: Vec3,
    area: f64,
    lift: f32,
}

impl HemicubeFrame {
    fn origin(&self) -> Vec3 {
        self.centroid + self.normal * self.lift
    }
}

fn hemicube_frame(texels: &TexelSet, members: &[u32], texel_size: f32) -> HemicubeFrame {
    let mut area = 0.0f64;
    let mut centroid = DVec3::ZERO;
    let mut normal = Vec3::ZERO;
    for &i in members {
        let t = &texels.texels[i as usize];
        area += t.area as f64;
        centroid += t.position().as_dvec3() * t.area as f64;
        normal += t.normal() * t.area.max(1e-30);
    }
    let first_texel = &texels.texels[members[0] as usize];
    let centroid = if area > 0.0 { (centroid / area).as_vec3() } else { first_texel.position() };
    let normal = normal.try_normalize().unwrap_or(Vec3::Y);
    // The hemicube must start above the patch's own surface, or it sees the
    // surface from behind and its view is blocked. Texel centres give the
    // rise above the centroid's plane; between them a facet tilted from the
    // normal by θ rises up to half a texel's diagonal × sin θ more.
    let mut lift = 0.0f32;
    let mut tilt = 0.0f32;
    for &i in members {
        let t = &texels.texels[i as usize];
        lift = lift.max((t.position() - centroid).dot(normal));
        // sin θ (1 for a facet turned 90° or more away).
        let face = Vec3::from(t.face_normal);
        let sin = if face.dot(normal) > 0.0 { face.cross(normal).length() } else { 1.0 };
        tilt = tilt.max(sin);
    }
    let lift = lift + std::f32::consts::FRAC_1_SQRT_2 * texel_size * tilt;
    HemicubeFrame { centroid, normal, area, lift }
}

/// For each group of texels, whether another group's centroid stands over
/// it, within twice its radius (half the diagonal of a square of its area)
/// and in front of its plane (by a quarter of the radius or of the other's
/// object), on an object (a primitive) smaller than twice the group's
/// diagonal (the object's world bounding box's diagonal). Groups of the
/// same size on larger objects (statues on their floor, walls at a corner)
/// stay whole. `object_size` is `object_sizes`.
fn crowded(texels: &TexelSet, groups: &[&[(Key, u32)]], object_size: &[f32]) -> Vec<bool> {
    let summary: Vec<(Vec3, Vec3, f32)> = groups
        .par_iter()
        .map(|group| {
            let (mut area, mut centroid, mut normal) = (0.0f64, DVec3::ZERO, Vec3::ZERO);
            for &(_, i) in *group {
                let t = &texels.texels[i as usize];
                area += t.area as f64;
                centroid += t.position().as_dvec3() * t.area as f64;
                normal += t.normal() * t.area;
            }
            let first = texels.texels[group[0].1 as usize].position();
            let centroid = if area > 0.0 { (centroid / area).as_vec3() } else { first };
            (centroid, normal.normalize_or_zero(), (area / 2.0).sqrt() as f32)
        })
        .collect();
    // Centroids in a grid of cells as wide as the farthest reach.
    let reach = summary.iter().map(|s| 2.0 * s.2).fold(0.0f32, f32::max).max(f32::MIN_POSITIVE);
    let grid_cell = |p: Vec3| (p / reach).floor().as_ivec3();
    let mut grid: HashMap<IVec3, Vec<u32>> = HashMap::new();
    for (g, s) in summary.iter().enumerate() {
        grid.entry(grid_cell(s.0)).or_default().push(g as u32);
    }
    summary
        .par_iter()
        .enumerate()
        .map(|(g, &(centre, normal, radius))| {
            let home = grid_cell(centre);
            (-1..=1).any(|dz| {
                (-1..=1).any(|dy| {
                    (-1..=1).any(|dx| {
                        grid.get(&(home + IVec3::new(dx, dy, dz))).is_some_and(|others| {
                            others.iter().any(|&o| {
                                let d = summary[o as usize].0 - centre;
                                let size =
                                    object_size[texels.texels[groups[o as usize][0].1 as usize].primitive as usize];
                                o as usize != g
                                    && d.dot(normal) > 0.25 * radius.min(size)
                                    && d.length() < 2.0 * radius
                                    && size < 4.0 * radius
                            })
                        })
                    })
                })
            })
        })
        .collect()
}

fn patch(texels: &TexelSet, members: &[u32], first: u32, texel_size: f32) -> Patch {
    let HemicubeFrame { centroid, normal, area, lift } = hemicube_frame(texels, members, texel_size);
    let first_texel = &texels.texels[members[0] as usize];

    // Affine fit P(x, y) ≈ c + U (x − x̄) + V (y − ȳ), from the texels that
    // lie wholly on the surface (border texels take an inset position, not
    // the image of their atlas cell).
    let largest = members.iter().map(|&i| texels.texels[i as usize].area).fold(0.0f32, f32::max);
    let whole: Vec<u32> =
        members.iter().copied().filter(|&i| texels.texels[i as usize].area >= 0.9 * largest).collect();
    let first_xy = (first_texel.x(texels.width) as f64, first_texel.y(texels.width) as f64);
    // A patch along a chart's border may hold a single row of whole texels:
    // the row gives one side, the surface's normal the other. A fit to the
    // border texels' inset positions instead skewed the parallelogram off
    // the surface, and receivers beside the border saw half their light.
    let fitted = if whole.len() >= 3 { &whole } else { members };
    let (c, mean_xy, u, v) = affine_fit(texels, fitted)
        .or_else(|| line_fit(texels, fitted, members, normal.as_dvec3()))
        .unwrap_or_else(|| {
            // A single texel: its sides in the tangent plane.
            let t = normal.as_dvec3().any_orthonormal_vector() * texel_size as f64;
            (first_texel.position().as_dvec3(), first_xy, t, normal.as_dvec3().cross(t))
        });
    // The parallelogram is the image of the atlas cells the patch's surface
    // texels occupy: patches share no texel, so their parallelograms do not
    // overlap and together shoot exactly their light. At a chart's border it
    // reaches up to a texel beyond the surface; the shot scales by area.
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &i in members.iter().filter(|&&i| texels.texels[i as usize].area > 0.0) {
        let t = &texels.texels[i as usize];
        let (x, y) = (t.x(texels.width) as f64, t.y(texels.width) as f64);
        (x0, x1, y0, y1) = (x0.min(x - 0.5), x1.max(x + 0.5), y0.min(y - 0.5), y1.max(y + 0.5));
    }
    if x0 > x1 {
        (x0, x1, y0, y1) = (first_xy.0 - 0.5, first_xy.0 + 0.5, first_xy.1 - 0.5, first_xy.1 + 0.5);
    }
    let mut rect_centre = c + u * ((x0 + x1) * 0.5 - mean_xy.0) + v * ((y0 + y1) * 0.5 - mean_xy.1);
    let mut half_u = u * ((x1 - x0) * 0.5);
    let mut half_v = v * ((y1 - y0) * 0.5);
    // Texels along a chart's border sit at inset positions that can all lie
    // on one edge, and a fit to them collapses to a sliver that would shoot
    // almost nothing: stand in a square of the patch's area at its centroid.
    let rect_area = 4.0 * half_u.cross(half_v).length();
    if rect_area.is_nan() || rect_area < 0.5 * area {
        let side = area.sqrt().max(texel_size as f64 * 1e-3);
        let t = normal.as_dvec3().any_orthonormal_vector();
        rect_centre = centroid.as_dvec3();
        half_u = t * (0.5 * side);
        half_v = normal.as_dvec3().cross(t) * (0.5 * side);
    }
    Patch {
        position: centroid.to_array(),
        area: area as f32,
        normal: normal.to_array(),
        first,
        rect_centre: rect_centre.as_vec3().to_array(),
        count: members.len() as u32,
        half_u: half_u.as_vec3().to_array(),
        lift,
        half_v: half_v.as_vec3().to_array(),
        radius: (half_u.length() + half_v.length()) as f32,
    }
}

/// Least-squares P(x, y) ≈ c + U (x − x̄) + V (y − ȳ) over `members`:
/// (c, (x̄, ȳ), U, V), or `None` when they do not span two atlas directions.
fn affine_fit(texels: &TexelSet, members: &[u32]) -> Option<(DVec3, (f64, f64), DVec3, DVec3)> {
    let width = texels.width;
    let count = members.len() as f64;
    let (mut mx, mut my, mut mp) = (0.0f64, 0.0f64, DVec3::ZERO);
    for &i in members {
        let t = &texels.texels[i as usize];
        mx += t.x(width) as f64;
        my += t.y(width) as f64;
        mp += t.position().as_dvec3();
    }
    let (mx, my, mp) = (mx / count, my / count, mp / count);
    let (mut sxx, mut sxy, mut syy, mut sxp, mut syp) = (0.0, 0.0, 0.0, DVec3::ZERO, DVec3::ZERO);
    for &i in members {
        let t = &texels.texels[i as usize];
        let dx = t.x(width) as f64 - mx;
        let dy = t.y(width) as f64 - my;
        let dp = t.position().as_dvec3() - mp;
        sxx += dx * dx;
        sxy += dx * dy;
        syy += dy * dy;
        sxp += dp * dx;
        syp += dp * dy;
    }
    let det = sxx * syy - sxy * sxy;
    if !(sxx > 0.0 && syy > 0.0 && det > 1e-9 * sxx * syy) {
        return None;
    }
    let u = (sxp * syy - syp * sxy) / det;
    let v = (syp * sxx - sxp * sxy) / det;
    (u.cross(v).length() > 0.0).then_some((mp, (mx, my), u, v))
}

/// P(x, y) ≈ c + U (x − x̄) + V (y − ȳ) from `line`, texels along one atlas
/// row or column: the least-squares side along it, and the other side as long,
/// at right angles in the tangent plane of `normal` (texels are square on the
/// surface), turned towards the other `members` with area. `None` unless
/// `line` is a row or column of at least two texels.
fn line_fit(
    texels: &TexelSet,
    line: &[u32],
    members: &[u32],
    normal: DVec3,
) -> Option<(DVec3, (f64, f64), DVec3, DVec3)> {
    let width = texels.width;
    let xy = |i: u32| {
        let t = &texels.texels[i as usize];
        (t.x(width) as f64, t.y(width) as f64)
    };
    let first = xy(*line.first()?);
    let row = line.iter().all(|&i| xy(i).1 == first.1);
    let column = line.iter().all(|&i| xy(i).0 == first.0);
    if row == column {
        return None;
    }
    let count = line.len() as f64;
    let sum = line.iter().fold((0.0, 0.0), |(x, y), &i| (x + xy(i).0, y + xy(i).1));
    let mean = (sum.0 / count, sum.1 / count);
    let centre = line.iter().map(|&i| texels.texels[i as usize].position().as_dvec3()).sum::<DVec3>() / count;
    // Along the line: position against the atlas coordinate that changes.
    let along = |i: u32| if row { xy(i).0 - mean.0 } else { xy(i).1 - mean.1 };
    let across = |i: u32| if row { xy(i).1 - mean.1 } else { xy(i).0 - mean.0 };
    let spread: f64 = line.iter().map(|&i| along(i).powi(2)).sum();
    let side =
        line.iter().map(|&i| (texels.texels[i as usize].position().as_dvec3() - centre) * along(i)).sum::<DVec3>()
            / spread;
    let mut other = normal.cross(side);
    let turn: f64 = members
        .iter()
        .filter(|&&i| texels.texels[i as usize].area > 0.0)
        .map(|&i| (texels.texels[i as usize].position().as_dvec3() - centre).dot(other) * across(i))
        .sum();
    if turn < 0.0 {
        other = -other;
    }
    let (u, v) = if row { (side, other) } else { (other, side) };
    (u.cross(v).length() > 0.0).then_some((centre, mean, u, v))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::texelize::Texel;

    /// A flat 8×8-texel chart of 0.1 m texels in the XZ plane.
    fn grid() -> TexelSet {
        grid_of(8)
    }

    /// A flat n×n-texel chart of 0.1 m texels in the XZ plane.
    fn grid_of(n: u32) -> TexelSet {
        let mut texels = Vec::new();
        for y in 0..n {
            for x in 0..n {
                texels.push(Texel {
                    position: [x as f32 * 0.1, 0.0, y as f32 * 0.1],
                    area: 0.01,
                    normal: [0.0, 1.0, 0.0],
                    face_normal: [0.0, 1.0, 0.0],
                    index: x + y * n,
                    ..Default::default()
                });
            }
        }
        TexelSet { width: n, height: n, texels, tint: Vec::new() }
    }

    #[test]
    fn patches_cover_every_texel_once_and_keep_area() {
        let texels = grid();
        let patches = build(&texels, 4, 0.1, None);
        assert_eq!(patches.patches.len(), 4);
        let mut seen = patches.members.clone();
        seen.sort();
        assert_eq!(seen, (0..64).collect::<Vec<_>>());
        let area: f32 = patches.patches.iter().map(|p| p.area).sum();
        assert!((area - 0.64).abs() < 1e-5);
    }

    /// `grid_of(16)` with target 16 patches (cells of 4×4 texels), the
    /// texels at or past `from` (both columns and rows) emissive: the
    /// emissive patches' and the others' sizes in texels.
    fn patch_sizes_with_emitter(from: u32) -> (Vec<u32>, Vec<u32>) {
        let mut texels = grid_of(16);
        for t in texels.texels.iter_mut().filter(|t| t.x(16) >= from && t.y(16) >= from) {
            t.emission = [1.0; 3];
        }
        let patches = build(&texels, 16, 0.1, None);
        let emits = |p: &&Patch| texels.texels[patches.members[p.first as usize] as usize].emits();
        let (lit, dark): (Vec<&Patch>, Vec<&Patch>) = patches.patches.iter().partition(emits);
        (lit.iter().map(|p| p.count).collect(), dark.iter().map(|p| p.count).collect())
    }

    #[test]
    fn an_emitter_shoots_from_smaller_patches() {
        // One cell emits: split twice, down to a texel, its shadows are
        // cast from 16 points instead of one.
        assert_eq!(patch_sizes_with_emitter(12), (vec![1; 16], vec![16; 15]));
    }

    #[test]
    fn emitters_split_no_further_than_the_target_allows() {
        // A quarter emits: split twice it would be 64 patches, past the
        // target of 16, so it is split once.
        assert_eq!(patch_sizes_with_emitter(8), (vec![4; 16], vec![16; 12]));
        // All of it emits: not split at all.
        assert_eq!(patch_sizes_with_emitter(0), (vec![16; 16], vec![]));
    }

    #[test]
    fn a_full_cell_maps_to_its_exact_square() {
        let texels = grid();
        let patches = build(&texels, 4, 0.1, None);
        let p = &patches.patches[0];
        // Texels 0..4 in x and y: centres 0..0.3, so the cell spans −0.05..0.35.
        assert!((Vec3::from(p.rect_centre) - Vec3::new(0.15, 0.0, 0.15)).length() < 1e-5);
        assert!((Vec3::from(p.half_u).length() - 0.2).abs() < 1e-5);
        assert!((Vec3::from(p.half_v).length() - 0.2).abs() < 1e-5);
        let rect_area = 4.0 * Vec3::from(p.half_u).cross(Vec3::from(p.half_v)).length();
        assert!((rect_area - p.area).abs() < 1e-5);
        assert_eq!(p.lift, 0.0);
    }

    #[test]
    fn texels_squeezed_near_one_edge_still_shoot_their_area() {
        // Border texels take inset positions; when a patch's texels sit
        // nearly on one line the affine fit collapses to a sliver, and the
        // patch must fall back to a square of its area.
        let mut texels = grid();
        for t in &mut texels.texels {
            t.position[2] *= 1e-3;
        }
        let patches = build(&texels, 4, 0.1, None);
        for p in &patches.patches {
            let rect_area = 4.0 * Vec3::from(p.half_u).cross(Vec3::from(p.half_v)).length();
            assert!((rect_area - p.area).abs() < 1e-5, "rect {rect_area} for area {}", p.area);
            assert!(Vec3::from(p.half_u).dot(Vec3::from(p.normal)).abs() < 1e-6, "in the patch's plane");
        }
    }

    #[test]
    fn a_border_row_of_whole_texels_maps_to_its_own_cells() {
        // A patch at a chart's border: one row of whole texels (x 0..3 at
        // z = 0, 0.1 m texels) and the row beyond it, with `beyond_area` and
        // positions inset to z = `beyond_z`. The parallelogram must be the
        // cells of the texels with area, on the surface.
        let patch_of = |beyond_area: f32, beyond_z: f32| {
            let mut texels = grid();
            for x in 0..3usize {
                texels.texels[8 + x].area = beyond_area;
                texels.texels[8 + x].position[2] = beyond_z;
            }
            patch(&texels, &[0, 1, 2, 8, 9, 10], 0, 0.1)
        };
        let close = |a: [f32; 3], b: Vec3| (Vec3::from(a) - b).length() < 1e-5;
        // Texels beyond the surface have no area and sit on its edge: the row alone.
        let p = patch_of(0.0, 0.0);
        assert!(close(p.rect_centre, Vec3::new(0.1, 0.0, 0.0)), "centre {:?}", p.rect_centre);
        assert!(close(p.half_u, Vec3::new(0.15, 0.0, 0.0)), "half_u {:?}", p.half_u);
        assert!(close(p.half_v.map(f32::abs), Vec3::new(0.0, 0.0, 0.05)), "half_v {:?}", p.half_v);
        // Partly covered texels beyond: both rows, the second on their side.
        let p = patch_of(0.004, 0.03);
        assert!(close(p.rect_centre, Vec3::new(0.1, 0.0, 0.05)), "centre {:?}", p.rect_centre);
        assert!(close(p.half_v, Vec3::new(0.0, 0.0, 0.1)), "half_v {:?}", p.half_v);
    }

    #[test]
    fn the_patch_mirrors_bounce_wgsl() {
        use crate::gpu::{Shader, mirror::assert_mirrors};
        assert_mirrors!(
            Shader::SolveShoot,
            "Patch",
            Patch { position, area, normal, first, rect_centre, count, half_u, lift, half_v, radius }
        );
    }
}
