//! Contact fix-up: where another surface comes close to a texel (a ball's
//! underside over the floor, the wedge between a ring's tube and the floor
//! under it, a statue's foot), its light is traced along rays on the CPU
//! instead of read from the GPU passes, which see the scene from too few
//! points there:
//!
//! - the bounce pass takes each shooter patch's visibility from one
//!   hemicube and its light from 4 × 4 sub-cells, both coarser than the gap
//!   between two surfaces near their contact (the corner fixture's ring:
//!   its underside's lowest 5 cm got 0.77 of the path tracer's light, the
//!   floor under the tube 0.83 of its bounced light);
//! - the direct pass reads depth maps whose texels are wider than that gap
//!   (the floor under the tube: 0.87 of its direct light, 0.5 where the sun
//!   shines in under the tube).
//!
//! A texel is in contact when one of `PROBE_SIDE`² cosine rays meets a
//! surface within `REACH_CELLS` shooter patches or `REACH_TEXELS` texels,
//! whichever is farther; a texel that only borders a chart (no area) too,
//! since a viewer's bilinear filter reads it at the chart's edge (left
//! out, those beside a ring's contact kept 0.76 of the path tracer's light
//! while the chart's inner texels were fixed). Its bounced light becomes the
//! mean reflected radiance (albedo · L_lm) of the texels that `GATHER_SIDE`²
//! stratified cosine rays meet, which is L_lm = E/π by definition, plus the
//! light emitters send it (`emitted`: the same rays and samples on the
//! emitters, each counted by the balance heuristic); what each ray meets is
//! found once, and the gather is repeated (Jacobi) until light between
//! texels in contact with each other stops changing. Where a surface lies
//! within `DIRECT_REACH_TEXELS` its direct light is traced too
//! (`DIRECT_SAMPLES` shadow rays spread over the lights by what each
//! brings). Texels where few probe rays meet a surface are blended with the
//! GPU passes' value (`FULL_WEIGHT_HITS`), so the fix-up's edge leaves no
//! step.
//!
//! Texels whose rays meet an alpha-masked or blended surface keep the GPU
//! passes' value: the CPU scene here is geometry only.

use glam::{DVec3, IVec3, Vec3};
use rayon::prelude::*;
use rustc_hash::FxHashMap;

use crate::environment::Light;
use crate::scene::{AlphaMode, Scene};
use crate::solve::overlaps::SAME_FACING_COS;
use crate::texelize::{Texel, TexelSet};
use crate::trace::Surfaces;
use crate::trace::random::{Rng, basis, cosine_hemisphere};

use super::emitted::Emitters;

/// Probe rays per texel, per side of their stratified grid (16 rays).
const PROBE_SIDE: u32 = 4;
/// A texel is in contact with a surface a probe ray meets within this
/// many shooter-patch cells (world size of the patch grid's cell): the
/// distance below which one hemicube and 16 sub-cells per patch misjudge
/// the light between two surfaces. On the corner fixture half a cell was as
/// accurate as one or two, at a fraction of the cost.
const REACH_CELLS: f64 = 0.5;
/// ... and at least this many lightmap texels: where the patches' cells are
/// small (3 texels at a 128² atlas) half a cell left the second and third
/// rows of a wall over a floor 2.4 % and 1.2 % dark in a room lit by a panel
/// (BENCHMARKS.md).
const REACH_TEXELS: f64 = 3.0;
/// Surfaces within this many lightmap texels also get their direct light
/// traced: the depth maps' texels track the lightmap's.
const DIRECT_REACH_TEXELS: f64 = 2.0;
/// Gather rays per texel, per side of their stratified grid (256 rays):
/// more changed the corner fixture's error by next to nothing at several
/// times the cost.
const GATHER_SIDE: u32 = 16;
/// What the gather rays meet is kept for every round, 4 bytes a ray: past
/// this many bytes the rays per texel are fewer (down to `MIN_GATHER_SIDE`²).
const HIT_BYTES: usize = 512 << 20;
const MIN_GATHER_SIDE: u32 = 8;
/// Shadow rays per texel whose direct light is traced.
const DIRECT_SAMPLES: u32 = 1024;
/// Probe rays that must meet a surface within reach for the texel to take
/// the traced light in full; with fewer it is blended in proportion.
const FULL_WEIGHT_HITS: f32 = 4.0;
/// The gather is repeated until no texel's light changes by more than this
/// share of the brightest texel's, or `MAX_ROUNDS` times.
const SETTLED: f64 = 1e-4;
const MAX_ROUNDS: usize = 64;
/// Only surfaces turned at least this far (cosine) from the one a gather
/// ray meets stand between it and the texel it takes (a wall on the floor;
/// not the facets of a curved surface, which a chord dips under).
const STANDING_COS: f64 = 0.5;
/// Shadow rays leave a texel's face at least this steeply (sine).
const SKIM: f64 = 1e-3;
/// Ray origins sit this far off the surface, texels (`Tracer::origin`),
/// and at least `MIN_LIFT_TEXELS`: clear of the f32 rounding of a texel's
/// position.
const LIFT_TEXELS: f64 = 0.05;
const MIN_LIFT_TEXELS: f64 = 1e-3;

/// What the fix-up did.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ContactStats {
    /// Texels whose bounced light was gathered along rays.
    pub gathered: usize,
    /// Of them, those whose direct light was traced too.
    pub traced: usize,
    /// Rounds of the gather until it settled.
    pub rounds: usize,
    pub seconds: f64,
    /// Received power the fix-up added (negative: took away), Σ ΔE·A per
    /// channel in irradiance × m²: the texels' light after it less what the
    /// GPU passes gave them. It is no share of the bounce pass's shots, so
    /// the energy balance leaves it out.
    pub power_received_change: [f64; 3],
    /// The reflected power that change adds, Σ ρ·ΔE·A per channel.
    pub power_reflected_change: [f64; 3],
}

/// The direct light the passes gave each texel (L_lm), and what it came
/// from.
pub struct Direct<'a> {
    /// The environment's lights, when there were any.
    pub environment: Option<&'a [Light]>,
    /// The punctual lights' share of `total`, when the scene has any: traced
    /// already, it is kept where the environment's is traced again.
    pub punctual: Option<&'a [[f32; 3]]>,
    /// Both together.
    pub total: &'a [[f32; 3]],
}

/// What the contact fix-up traces against: the scene, its surfaces for
/// rays, its texels, and which texels lie hidden under an opaque surface
/// (no light; what rays meeting their place take: `Tracer::texel_at`).
pub struct Geometry<'a> {
    pub scene: &'a Scene,
    pub surfaces: &'a Surfaces,
    pub texels: &'a TexelSet,
    pub hidden: Option<&'a [bool]>,
    /// Each texel's share of its area that bounces light (`overlaps`): the
    /// power changes weigh texels by it.
    pub shares: Option<&'a [f32]>,
    /// The world width of a lightmap texel.
    pub texel_size: f64,
}

/// Replaces the light of texels in contact with another surface by light
/// traced along rays (module docs). `direct` is each texel's direct light,
/// `lightmap` the solution so far (direct and bounced), updated in place.
/// `cell` is the world width of a shooter patch's cell.
pub fn fix(geometry: &Geometry, direct: &Direct, lightmap: &mut [[f32; 3]], cell: f64) -> ContactStats {
    let start = std::time::Instant::now();
    let tracer = Tracer::new(geometry);
    let texels = geometry.texels;
    let reach = (REACH_CELLS * cell).max(REACH_TEXELS * geometry.texel_size);
    // Hidden texels keep no light (a slab's shadow on the ground under it
    // would take its underside's).
    let probes: Vec<Option<Probe>> = (0..texels.texels.len())
        .into_par_iter()
        .map(|i| if tracer.is_hidden(i as u32) { None } else { tracer.probe(&texels.texels[i], i, reach) })
        .collect();
    let contacts: Vec<(usize, Probe)> = probes.into_iter().enumerate().filter_map(|(i, p)| p.map(|p| (i, p))).collect();
    // Each texel's direct light (traced, or the direct pass's) and what its
    // gather rays meet; none where a ray met a surface light passes.
    let direct_reach = DIRECT_REACH_TEXELS * geometry.texel_size;
    let side = gather_side(contacts.len());
    let emitters = Emitters::new(&texels.texels);
    let contacts: Vec<Contact> = contacts
        .par_iter()
        .filter_map(|&(i, probe)| {
            let t = &texels.texels[i];
            let (own_direct, direct_traced) = tracer.own_direct(i, &probe, direct, direct_reach)?;
            let gathered = tracer.gather_hits(t, i, probe.origin, side, emitters.as_ref())?;
            let sampled = emitters.as_ref().map_or(DVec3::ZERO, |e| {
                let mut rng = Rng::new(&[i as u64, 4]);
                e.sampled(tracer.occluders, probe.origin, t.normal().as_dvec3(), face_of(t), side * side, &mut rng)
            });
            let emitted = gathered.emitted + sampled;
            Some(Contact {
                texel: i,
                weight: (probe.hits as f32 / FULL_WEIGHT_HITS).min(1.0),
                direct: [0, 1, 2].map(|c| own_direct[c] + emitted[c] as f32),
                direct_traced,
                hits: gathered.hits,
            })
        })
        .collect();
    let mut stats = ContactStats {
        gathered: contacts.len(),
        traced: contacts.iter().filter(|c| c.direct_traced).count(),
        ..Default::default()
    };
    // The GPU passes' value, blended with the traced one by weight.
    let before: Vec<[f32; 3]> = contacts.iter().map(|c| lightmap[c.texel]).collect();
    let peak = lightmap.iter().map(|v| v.iter().cloned().fold(0.0f32, f32::max)).fold(0.0f32, f32::max) as f64;
    let rays = (side * side) as f64;
    for round in 1..=MAX_ROUNDS {
        let gathered: Vec<[f32; 3]> = contacts
            .par_iter()
            .map(|contact| {
                let sum = contact.hits.iter().fold(DVec3::ZERO, |sum, &j| {
                    let t = &texels.texels[j as usize];
                    let l = lightmap[j as usize];
                    sum + (Vec3::from(t.albedo) * Vec3::from(l)).as_dvec3()
                });
                let mean = sum / rays;
                [mean.x as f32, mean.y as f32, mean.z as f32]
            })
            .collect();
        let mut change = 0.0f64;
        for ((contact, gathered), before) in contacts.iter().zip(gathered).zip(&before) {
            let w = contact.weight;
            let value = [0, 1, 2].map(|c| w * (contact.direct[c] + gathered[c]) + (1.0 - w) * before[c]);
            let old = &mut lightmap[contact.texel];
            for c in 0..3 {
                change = change.max((value[c] - old[c]).abs() as f64);
            }
            *old = value;
        }
        stats.rounds = round;
        if change <= SETTLED * peak {
            break;
        }
    }
    for (contact, before) in contacts.iter().zip(&before) {
        let t = &texels.texels[contact.texel];
        let area = t.area as f64 * geometry.shares.map_or(1.0, |s| s[contact.texel] as f64);
        for c in 0..3 {
            let change = std::f64::consts::PI * area * (lightmap[contact.texel][c] - before[c]) as f64;
            stats.power_received_change[c] += change;
            stats.power_reflected_change[c] += t.albedo[c] as f64 * change;
        }
    }
    stats.seconds = start.elapsed().as_secs_f64();
    stats
}

/// What a texel's gather rays meet: the texels, and the emitted light
/// they count.
struct Gathered {
    hits: Vec<u32>,
    emitted: DVec3,
}

/// A texel in contact, as traced.
struct Contact {
    texel: usize,
    /// Share of its value taken from the traced light (`FULL_WEIGHT_HITS`).
    weight: f32,
    /// Its direct light (L_lm), and what it receives straight from emitters
    /// (`emitted`).
    direct: [f32; 3],
    /// Whether `direct` was traced here (else the direct pass's).
    direct_traced: bool,
    /// The texels its gather rays meet.
    hits: Vec<u32>,
}

/// What a texel's probe rays found within reach: how many met a surface,
/// and the nearest one's distance.
#[derive(Clone, Copy, Debug)]
struct Probe {
    hits: u32,
    nearest: f64,
    /// Where the texel's rays start (`Tracer::origin`).
    origin: DVec3,
}

/// The scene's geometry for rays, and its texels by place.
struct Tracer<'a> {
    texels: &'a TexelSet,
    occluders: &'a Surfaces,
    grid: TexelGrid,
    /// Texels hidden under an opaque surface (`overlaps`), when any are.
    hidden: Option<&'a [bool]>,
    /// Per primitive: whether light passes parts of it (alpha MASK or BLEND).
    passes_light: Vec<bool>,
    lift: f64,
    min_lift: f64,
    texel_size: f64,
}

impl<'a> Tracer<'a> {
    fn new(g: &Geometry<'a>) -> Tracer<'a> {
        let Geometry { scene, surfaces: occluders, texels, hidden, texel_size, .. } = *g;
        Tracer {
            texels,
            occluders,
            grid: TexelGrid::new(texels, 1.5 * texel_size),
            hidden: hidden.filter(|h| h.contains(&true)),
            passes_light: scene.primitives.iter().map(|p| scene.material(p).alpha != AlphaMode::Opaque).collect(),
            lift: LIFT_TEXELS * texel_size,
            min_lift: MIN_LIFT_TEXELS * texel_size,
            texel_size,
        }
    }

    /// Where the texel's rays start, from `start`, its point `MIN_LIFT_TEXELS`
    /// off its surface along the face normal `f`: `LIFT_TEXELS` further, or
    /// half way to a surface nearer in front of it (a ring's underside 1.7 mm
    /// over the floor: a fixed twentieth of a texel started its rays under
    /// the floor, and a fixed thousandth let a statue's creases block rays
    /// leaving them).
    fn origin(&self, start: DVec3, f: DVec3) -> DVec3 {
        let room = self.occluders.first_hit(start, f, self.lift).map_or(self.lift, |h| 0.5 * h.0);
        start + f * room
    }

    /// Contact texel `i`'s direct light (L_lm), and whether it was traced:
    /// where another surface lies within `direct_reach`, traced (`direct`),
    /// else the direct pass's. `None` where a ray met a surface light passes.
    fn own_direct(&self, i: usize, probe: &Probe, direct: &Direct, direct_reach: f64) -> Option<([f32; 3], bool)> {
        let Some(lights) = direct.environment.filter(|_| probe.nearest < direct_reach) else {
            return Some((direct.total[i], false));
        };
        let environment = self.direct(&self.texels.texels[i], i, probe.origin, lights)?;
        let punctual = direct.punctual.map_or([0.0; 3], |p| p[i]);
        Some(([0, 1, 2].map(|c| environment[c] + punctual[c]), true))
    }

    /// `None` when no probe ray meets a surface within `reach`, or one meets
    /// a surface light passes.
    fn probe(&self, t: &Texel, i: usize, reach: f64) -> Option<Probe> {
        // Every probe ray leaves `origin`, at most `lift` over this point,
        // into the face's side: with nothing within reach there, none meets
        // anything (most texels; the rays would say so at 17 times the cost).
        let f = face_of(t);
        let start = t.position().as_dvec3() + f * self.min_lift;
        if !self.occluders.any_near_above(start, reach + self.lift, f) {
            return None;
        }
        let o = self.origin(start, f);
        let mut probe = Probe { hits: 0, nearest: f64::INFINITY, origin: o };
        for d in cosine_directions(t, PROBE_SIDE, &[i as u64, 1]) {
            if let Some((distance, primitive, _)) = self.occluders.first_hit(o, d, reach) {
                if self.passes_light[primitive as usize] {
                    return None;
                }
                probe.hits += 1;
                probe.nearest = probe.nearest.min(distance);
            }
        }
        (probe.hits > 0).then_some(probe)
    }

    /// The texels `side`² cosine rays meet from the front (rays that leave
    /// the scene, or meet a surface's back, bring no bounced light), and
    /// the emitted light they find as their share (`emitted::Emitters`).
    fn gather_hits(&self, t: &Texel, i: usize, o: DVec3, side: u32, emitters: Option<&Emitters>) -> Option<Gathered> {
        let mut hits = Vec::with_capacity((side * side) as usize);
        let mut emitted = DVec3::ZERO;
        let n = t.normal().as_dvec3();
        for d in cosine_directions(t, side, &[i as u64, 2]) {
            let Some((distance, primitive, face)) = self.occluders.first_hit(o, d, f64::INFINITY) else {
                continue;
            };
            if self.passes_light[primitive as usize] {
                return None;
            }
            if let Some(j) = self.texel_at(o + d * distance, primitive, face, d, distance) {
                hits.push(j);
                if let Some(e) = emitters {
                    emitted += e.counted(j, d, distance, n, side * side);
                }
            }
        }
        Some(Gathered { hits, emitted })
    }

    /// The texel whose light a ray along `d` takes where it meets the
    /// triangle of `primitive` and face normal `face` at `p`, `distance`
    /// from its origin: the nearest (`TexelGrid::nearest`) that `p` reaches
    /// along the surface, past nothing standing up from it
    /// (`STANDING_COS`). (A ray meeting a room's floor beside its wall took
    /// the light of the lit ground outside, a texel nearer than the
    /// floor's.) `None` where it has no light.
    ///
    /// Where an opaque surface lies over `p` within a texel, parallel to
    /// its own, `p` is in the dark gap between them (`overlaps` hides the
    /// texels there). Where the texel met is hidden nonetheless (its centre
    /// is under such a surface, `p` is not), the nearest texel not hidden
    /// stands in, one no higher over `p` than the ray's origin (the ray
    /// cannot have seen a surface above itself): on a floor laid on the
    /// ground, where a ray meets either's triangle, the floor's; just
    /// outside a slab's edge, the ground's next texel out. (Taking the
    /// light of the surface over the gap, a slab's underside 5 mm over the
    /// ground got 431 times the path tracer's light, that of its sunlit
    /// top.)
    fn texel_at(&self, p: DVec3, primitive: u32, face: DVec3, d: DVec3, distance: f64) -> Option<u32> {
        let front = if face.dot(d) < 0.0 { face } else { -face };
        let side = front * self.min_lift;
        if self.hidden.is_some() && self.under_a_sheet(p + side, front) {
            return None;
        }
        let reaches = |i: u32| {
            let t = self.texels.texels[i as usize].position().as_dvec3();
            !self.occluders.blocks_where(p + side, t + side, |_, other| other.dot(face).abs() < STANDING_COS)
        };
        let j = self.grid.nearest(p, primitive, face, d, reaches)?;
        if !self.is_hidden(j) {
            return Some(j);
        }
        let origin_height = -front.dot(d) * distance;
        self.grid.nearest(p, primitive, face, d, |i| {
            let t = &self.texels.texels[i as usize];
            !self.is_hidden(i) && (t.position().as_dvec3() - p).dot(front) <= origin_height && reaches(i)
        })
    }

    /// Whether texel `i` lies hidden under an opaque surface (`overlaps`).
    fn is_hidden(&self, i: u32) -> bool {
        self.hidden.is_some_and(|h| h[i as usize])
    }

    /// Whether an opaque surface parallel to the plane of normal `front`
    /// lies within a texel in front of `p`.
    fn under_a_sheet(&self, p: DVec3, front: DVec3) -> bool {
        self.occluders.first_hit(p, front, self.texel_size).is_some_and(|(_, primitive, face)| {
            !self.passes_light[primitive as usize] && face.dot(front).abs() >= SAME_FACING_COS as f64
        })
    }

    /// Direct light L_lm = Σ_k L_k Ω_k max(0, n·ω_k) V_k / π, as the direct
    /// pass defines it, with V traced: `DIRECT_SAMPLES` rays, spread over
    /// the lights in front of the texel by L_k Ω_k n·ω_k (systematic
    /// sampling of their running sum), each to a point of its light's cone.
    /// A ray below the texel's own face is not blocked by it, as in the
    /// direct pass (the shading normal's cosine weighs that part of the
    /// light): it is turned to skim the face, so that other surfaces still
    /// block it. (Blocked by the face, a faceted ball's underside over the
    /// ground came out dark.)
    fn direct(&self, t: &Texel, i: usize, o: DVec3, lights: &[Light]) -> Option<[f32; 3]> {
        let n = t.normal().as_dvec3();
        let f = face_of(t);
        let contribution = |l: &Light| {
            let cos = n.dot(Vec3::from(l.direction).as_dvec3());
            DVec3::from_array(l.radiance.map(|c| c as f64)) * (l.solid_angle as f64 * cos.max(0.0))
        };
        let total: f64 = lights.iter().map(|l| contribution(l).element_sum()).sum();
        if total.is_nan() || total <= 0.0 {
            return Some([0.0; 3]);
        }
        let mut rng = Rng::new(&[i as u64, 3]);
        let step = total / DIRECT_SAMPLES as f64;
        let mut next = rng.next_f64() * step;
        let mut running = 0.0;
        let mut light = DVec3::ZERO;
        for l in lights {
            let c = contribution(l);
            let weight = c.element_sum();
            running += weight;
            // This light's share of the samples, each carrying `step`.
            let mut samples = 0u32;
            let mut open = 0u32;
            while next < running {
                next += step;
                samples += 1;
                let d = skim_above(point_in_cone(l, &mut rng), f);
                match self.occluders.any_blocker(o, d) {
                    Some(primitive) if self.passes_light[primitive as usize] => return None,
                    Some(_) => continue,
                    None => open += 1,
                }
            }
            if samples > 0 {
                light += c / weight * (step * open as f64);
            }
        }
        let l = light / std::f64::consts::PI;
        Some([l.x as f32, l.y as f32, l.z as f32])
    }
}

/// `d`, turned up to skim the face of normal `f` where it goes below it.
pub(super) fn skim_above(d: DVec3, f: DVec3) -> DVec3 {
    let height = d.dot(f);
    if height >= SKIM {
        return d;
    }
    (d + f * (SKIM - height)).normalize()
}

/// Gather rays per side for `contacts` texels: `GATHER_SIDE`, fewer where
/// their hits would pass `HIT_BYTES`.
fn gather_side(contacts: usize) -> u32 {
    let rays = HIT_BYTES / 4 / contacts.max(1);
    ((rays as f64).sqrt() as u32).clamp(MIN_GATHER_SIDE, GATHER_SIDE)
}

/// A direction uniformly within light `l`'s cone (the cap of its solid angle).
fn point_in_cone(l: &Light, rng: &mut Rng) -> DVec3 {
    let w = Vec3::from(l.direction).as_dvec3();
    let cos_max = (1.0 - l.solid_angle as f64 / std::f64::consts::TAU).max(-1.0);
    let cos = 1.0 - rng.next_f64() * (1.0 - cos_max);
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    let phi = std::f64::consts::TAU * rng.next_f64();
    let (u, v) = basis(w);
    (w * cos + u * (sin * phi.cos()) + v * (sin * phi.sin())).normalize()
}

fn face_of(t: &Texel) -> DVec3 {
    Vec3::from(t.face_normal).as_dvec3()
}

/// `side`² cosine-distributed directions about the texel's normal, one per
/// cell of a stratified grid, jittered by a generator keyed by `key`; those
/// below the texel's face are left out.
fn cosine_directions(t: &Texel, side: u32, key: &[u64]) -> impl Iterator<Item = DVec3> {
    let n = t.normal().as_dvec3();
    let f = face_of(t);
    let mut rng = Rng::new(key);
    (0..side * side).filter_map(move |k| {
        let u1 = ((k / side) as f64 + rng.next_f64()) / side as f64;
        let u2 = ((k % side) as f64 + rng.next_f64()) / side as f64;
        let (d, _) = cosine_hemisphere(n, u1, u2);
        (d.dot(f) > 0.0).then_some(d)
    })
}

/// The 27 cubes about a cube, z outermost; `HOME` is the cube itself.
const NEIGHBOURS: [IVec3; 27] = {
    let mut cubes = [IVec3::ZERO; 27];
    let mut n = 0;
    while n < 27 {
        cubes[n] = IVec3::new(n as i32 % 3 - 1, n as i32 / 3 % 3 - 1, n as i32 / 9 - 1);
        n += 1;
    }
    cubes
};
const HOME: usize = 13;

/// Texels with area by world position, in cubes `cell` wide.
/// Each cube's texels lie together in `entries`, with what a lookup reads
/// (a gather ray's lookup read whole texels from all over the set, and
/// hashed its 27 cubes with SipHash: half the fix-up's time).
struct TexelGrid {
    cell: f64,
    /// Each cube's range of `entries`.
    cubes: FxHashMap<IVec3, (u32, u32)>,
    entries: Vec<GridTexel>,
}

struct GridTexel {
    position: Vec3,
    face: Vec3,
    primitive: u32,
    index: u32,
}

impl TexelGrid {
    fn new(texels: &TexelSet, cell: f64) -> TexelGrid {
        let with_area = (0..texels.texels.len()).filter(|&i| texels.texels[i].area > 0.0).map(|i| {
            let t = &texels.texels[i];
            GridTexel {
                position: t.position(),
                face: Vec3::from(t.face_normal),
                primitive: t.primitive,
                index: i as u32,
            }
        });
        TexelGrid::of(with_area.collect(), cell)
    }

    /// The grid of `texels` (their indices distinct), in cubes `cell` wide.
    fn of(mut texels: Vec<GridTexel>, cell: f64) -> TexelGrid {
        let cube_of = |t: &GridTexel| (t.position.as_dvec3() / cell).floor().as_ivec3();
        // By cube, and by texel index within one.
        texels.par_sort_by_cached_key(|t| (cube_of(t).to_array(), t.index));
        let mut cubes = FxHashMap::default();
        for (k, t) in texels.iter().enumerate() {
            cubes.entry(cube_of(t)).or_insert((k as u32, k as u32)).1 += 1;
        }
        TexelGrid { cell, cubes, entries: texels }
    }

    /// The nearest texel `accept`s of those in the 27 cubes around `p`
    /// whose face lies the same way as `face` (either side) and whose front
    /// a ray along `d` meets, another primitive's than `primitive` taken
    /// as if half a cube farther. The nearest is tried first; the rest,
    /// nearest first, only when it is refused.
    fn nearest(&self, p: DVec3, primitive: u32, face: DVec3, d: DVec3, accept: impl Fn(u32) -> bool) -> Option<u32> {
        let home = (p / self.cell).floor().as_ivec3();
        let nearest = self.nearest_in_reach(p, home, primitive, face, d)?;
        if accept(nearest) {
            return Some(nearest);
        }
        let mut rest: Vec<(f64, u32)> = self.candidates(p, home, primitive, face, d).collect();
        rest.sort_by(|a, b| a.0.total_cmp(&b.0));
        rest.into_iter().map(|(_, i)| i).filter(|&i| i != nearest).find(|&i| accept(i))
    }

    /// `nearest`'s candidates about `p` (in the cube `home`), keyed
    /// (`keyed`), in the order of `NEIGHBOURS` and then of `entries`.
    fn candidates(
        &self,
        p: DVec3,
        home: IVec3,
        primitive: u32,
        face: DVec3,
        d: DVec3,
    ) -> impl Iterator<Item = (f64, u32)> {
        NEIGHBOURS
            .iter()
            .filter_map(move |&offset| self.cubes.get(&(home + offset)))
            .flat_map(|&(start, end)| &self.entries[start as usize..end as usize])
            .filter_map(move |t| self.keyed(t, p, primitive, face, d))
    }

    /// The nearest of `nearest`'s candidates, the first of equally near
    /// ones in the order of `NEIGHBOURS` and then of `entries`. Cubes are
    /// read home first and then only where their box comes nearer to `p`
    /// than the best so far: the lookups of all 27 were most of the
    /// fix-up's time.
    fn nearest_in_reach(&self, p: DVec3, home: IVec3, primitive: u32, face: DVec3, d: DVec3) -> Option<u32> {
        // (key, cube's place in NEIGHBOURS, place in entries, texel)
        let mut best: Option<(f64, usize, usize, u32)> = None;
        let home_first = std::iter::once(HOME).chain((0..NEIGHBOURS.len()).filter(|&n| n != HOME));
        for n in home_first {
            let cube = home + NEIGHBOURS[n];
            if best.is_some_and(|b| self.box_distance_squared(p, cube) > b.0) {
                continue;
            }
            let Some(&(start, end)) = self.cubes.get(&cube) else {
                continue;
            };
            for k in start as usize..end as usize {
                let Some((key, index)) = self.keyed(&self.entries[k], p, primitive, face, d) else {
                    continue;
                };
                if best.is_none_or(|b| (key, n, k) < (b.0, b.1, b.2)) {
                    best = Some((key, n, k, index));
                }
            }
        }
        best.map(|b| b.3)
    }

    /// `nearest`'s ordering key of grid texel `t` (its squared distance to
    /// `p`, another primitive's half a cube farther), `None` where it is
    /// no candidate.
    fn keyed(&self, t: &GridTexel, p: DVec3, primitive: u32, face: DVec3, d: DVec3) -> Option<(f64, u32)> {
        let f = t.face.as_dvec3();
        if f.dot(face).abs() < 0.5 || f.dot(d) >= 0.0 {
            return None;
        }
        let distance = (t.position.as_dvec3() - p).length_squared();
        let other = (0.5 * self.cell).powi(2);
        Some((if t.primitive == primitive { distance } else { distance + other }, t.index))
    }

    /// A lower bound on the squared distance from `p` to a point of `cube`,
    /// with a margin for the rounding of positions into cubes.
    fn box_distance_squared(&self, p: DVec3, cube: IVec3) -> f64 {
        let margin = 1e-6 * self.cell;
        let low = cube.as_dvec3() * self.cell - margin;
        let high = low + (self.cell + 2.0 * margin);
        let outside = (low - p).max(p - high).max(DVec3::ZERO);
        outside.length_squared()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trace::random::Rng;

    /// `TexelGrid::nearest_in_reach` by its definition: every candidate of
    /// the 27 cubes in turn, the first of equally near ones.
    fn nearest_of_all_27(grid: &TexelGrid, p: DVec3, primitive: u32, face: DVec3, d: DVec3) -> Option<u32> {
        let home = (p / grid.cell).floor().as_ivec3();
        let nearest =
            grid.candidates(p, home, primitive, face, d).reduce(|best, c| if c.0 < best.0 { c } else { best });
        nearest.map(|c| c.1)
    }

    /// A floor (primitive 0, facing up), a second floor laid over half of
    /// it (primitive 1) and a wall across it (primitive 2, facing +x), texels
    /// `size` apart on a lattice, so that many points lie equally near two.
    fn floor_and_wall(size: f32) -> Vec<GridTexel> {
        let mut texels = Vec::new();
        let mut add = |position: Vec3, face: Vec3, primitive: u32| {
            let index = texels.len() as u32;
            texels.push(GridTexel { position, face, primitive, index });
        };
        for i in 0..40 {
            for j in 0..40 {
                let (x, y) = ((i as f32 + 0.5) * size, (j as f32 + 0.5) * size);
                add(Vec3::new(x, y, 0.0), Vec3::Z, 0);
                if i >= 20 {
                    add(Vec3::new(x, y, 0.0), Vec3::Z, 1);
                }
                add(Vec3::new(0.0, x, y), Vec3::X, 2);
            }
        }
        texels
    }

    #[test]
    fn a_gather_rays_texel_is_the_one_a_search_of_all_27_cubes_finds() {
        let size = 0.1;
        let grid = TexelGrid::of(floor_and_wall(size), 1.5 * size as f64);
        let mut rng = Rng::new(&[78]);
        let (mut ties, mut found) = (0, 0);
        for q in 0..20_000 {
            // Half the points on the lattice of half-texels (ties), half anywhere.
            let on_lattice = q % 2 == 0;
            let mut coordinate = || {
                let c = rng.next_f64() * 4.0;
                if on_lattice { (c * 20.0).round() / 20.0 } else { c }
            };
            let (a, b) = (coordinate(), coordinate());
            let slant = DVec3::new(rng.next_f64() - 0.5, rng.next_f64() - 0.5, rng.next_f64() - 0.5);
            let (p, face, primitive) = if q % 3 == 0 {
                (DVec3::new(0.0, a, b), DVec3::X, 2)
            } else {
                (DVec3::new(a, b, 0.0), DVec3::Z, (q % 3 == 1) as u32)
            };
            let d = (-face + 0.9 * slant.reject_from(face)).normalize();
            let home = (p / grid.cell).floor().as_ivec3();
            let expected = nearest_of_all_27(&grid, p, primitive, face, d);
            assert_eq!(grid.nearest_in_reach(p, home, primitive, face, d), expected, "at {p} on {primitive}");
            found += expected.is_some() as u32;
            let keys: Vec<(f64, u32)> = grid.candidates(p, home, primitive, face, d).collect();
            let best = keys.iter().find(|k| Some(k.1) == expected).map(|k| k.0);
            ties += keys.iter().any(|k| Some(k.1) != expected && Some(k.0) == best) as u32;
        }
        // The lattice's points put some candidates exactly as near as the one found.
        assert!(found > 19_000, "found {found}");
        assert!(ties > 500, "ties {ties}");
    }
}
