//! Progressive refinement for surfaces (design notes, algorithm step 4; the
//! seed's section 3.2 after Coombe, Harris & Lastra 2004; Cohen et al. 1988
//! for progressive refinement and the ambient term).
//!
//! Each batch: sum every patch's unshot power Σ ΔL·A on the GPU
//! (`solve_patch_power`), pick the K largest (`solve_select`), list the
//! casters each of their hemicube faces can see (`hemicube_cull`), render a
//! hemicube depth map from each (`solve_hemicube`), and let every texel
//! gather from those of the K shooters that may light its group of 64
//! (`shooter_cull`) with the seed's bounded form factor
//! (`solve_shoot`: the far field for every texel, then the exact near field
//! for the few texels next to a shooter, which `main` lists and
//! `near_dispatch` sizes that pass for, on the GPU). Only a 64-byte summary
//! comes back per batch, to decide whether to stop and to record the
//! convergence trace.
//!
//! It has converged when the unshot power, each patch's weighted by how much
//! of its texels' hemispheres the scene covers, is under the tolerance of
//! the power put in, weighted the same way. Unweighted, a sunlit scene (most
//! of whose light leaves for the sky) stopped while a room seen through an
//! opening still held much of its own light, and the ambient term, spread
//! over the whole scene, put little of it back there. (Against the power put
//! in times the share of shot light that landed, a ground whose neighbours
//! show it only their backs never converged.)
//!
//! Overlapping surfaces (`overlaps`) count for their share of the area: in
//! the unshot power, in the form-factor sums and in the received power.
//!
//! The first time a patch shoots, its form factors are normalized: the
//! `measure` and `finish` entry points of `solve_shoot` sum them over every
//! receiver, near and far field apart, and scale its far-field ones from
//! then on so that the sum is the share of its hemicube that sees a
//! surface's front. So a closed room catches exactly what is shot, which a
//! near-white room needs (a 4 % loss per bounce made ρ = 0.99 come out 5×
//! too dark). Scenes that catch little of what they reflect skip it
//! (`NORMALIZE_FROM`).
//!
//! The light not yet shot is spread as an ambient term (Cohen et al.'s,
//! scaled by the measured share of shot light the scene catches), and the
//! report says how much it was: where the shots' light landed when the pass
//! converged, by the scene's coverage of each texel when a budget stopped it
//! (a run stopped early still answers honestly).

use std::time::Instant;

use anyhow::Result;
use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use serde::{Deserialize, Serialize};

use super::casters::{Casters, Topology};
use super::hemicube_cull::HemicubeCull;
use super::patches::Patches;
use super::shooter_cull::{self, ShooterCull};
use crate::colour::luminance;
use crate::gpu::{self, Gpu, Shader, read_buffer};
use crate::reference::Probes;
use crate::scene::Scene;
use crate::texelize::{Texel, TexelSet};

/// Shooter slots per batch (`MAX_SHOOTERS` in common.wgsl): a near-field
/// receiver lists the slots it is near as bits of one u32.
pub const MAX_SHOOTERS: u32 = 32;
const _: () = assert!(MAX_SHOOTERS <= u32::BITS);
/// Parts a shooter patch's light is summed by for the near field
/// (`SUB_CELL_COUNT` in common.wgsl).
const SUB_CELL_COUNT: usize = 16;
/// What is kept per sub-cell (power and area, centroid, normal; `SUB_CELL_ROWS`).
const SUB_CELL_ROWS: usize = 3;

/// Texels one workgroup of the form-factor measure pass sums
/// (`MEASURE_CHUNK` in solve_shoot.wgsl).
const MEASURE_CHUNK: u32 = 4096;
/// Shooter slots one workgroup of the measure pass sums for
/// (`MEASURE_SLOTS` in solve_shoot.wgsl).
const MEASURE_SLOTS: u32 = 8;

/// Normalize the form factors only where the scene catches at least this
/// much of the light it reflects (mean albedo × covered share): below it, a
/// loss of a few percent per bounce changes the lightmap by well under 1 %
/// (ε ρf/(1 − ρf) < ε/4), and the measure pass would add up to 1.9× to every
/// patch's first shot.
const NORMALIZE_FROM: f64 = 0.2;

/// Options of the bounce pass, with their defaults.
#[derive(Clone, Debug)]
pub struct BounceOptions {
    /// Stop when the unshot power, each patch's weighted by the share of its
    /// texels' hemispheres the scene covers, falls below this fraction of the
    /// power put in, weighted the same way.
    pub tolerance: f64,
    /// Stop after this many shots (`None`: 64 per patch, so that even a
    /// near-white room ends; the ambient term covers what is left).
    pub max_shots: Option<u64>,
    /// Stop after this many seconds of bouncing.
    pub max_seconds: Option<f64>,
    /// About how many shooter patches to group the texels into.
    pub patches: u32,
    /// Shooters per GPU batch (at most 32).
    pub shooters_per_batch: u32,
    /// Hemicube face width in texels.
    pub hemicube_size: u32,
    /// Memory for the lists of casters each hemicube face can see
    /// (`hemicube_cull`): a face whose list would not fit draws every
    /// caster, as every face does at 0.
    pub face_list_bytes: u64,
    /// Texels whose error against a reference is recorded at every trace
    /// point (`--reference`); `None`: not measured.
    pub probes: Option<std::sync::Arc<Probes>>,
}

impl Default for BounceOptions {
    fn default() -> Self {
        BounceOptions {
            tolerance: 0.01,
            max_shots: None,
            max_seconds: None,
            patches: 1024,
            shooters_per_batch: 32,
            hemicube_size: 128,
            face_list_bytes: 64 << 20,
            probes: None,
        }
    }
}

/// One point of the convergence trace, recorded before each batch (and
/// one after the contact fix-up, `solve::run`).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct TracePoint {
    /// Seconds since the bounce pass started.
    pub seconds: f64,
    /// Shots taken so far.
    pub shots: u64,
    /// Unshot power over the power put in (luminance).
    pub unshot_fraction: f64,
    /// Estimated relative error of the mean lightmap value: the ambient
    /// term for the unshot light over the mean gathered so far.
    pub error_estimate: f64,
    /// Relative RMSE against the reference at the probe texels, of the
    /// lightmap as it would be if the pass stopped here (ambient term
    /// included); `None` without `--reference`.
    pub reference_error: Option<f64>,
}

/// What the bounce pass did, for the report.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct BounceStats {
    pub patches: usize,
    pub shots: u64,
    pub batches: u64,
    /// Seconds the pass took, less the read-backs of the `--reference`
    /// probes at every trace point (a measurement, not part of the bake; the
    /// trace's clock leaves them out too).
    pub seconds: f64,
    /// Why it stopped.
    pub stopped_by: StopReason,
    /// Unshot power over the power put in when it stopped.
    pub unshot_fraction: f64,
    /// Closure the ambient term used: the share of the unshot power that
    /// would land on the scene (`shot_closure` when the pass converged or
    /// had no direct pass, else from the direct pass's coverage).
    pub closure: f64,
    /// Power that landed on the scene over the power shot (luminance, summed
    /// on the GPU over every batch; 1 when nothing was shot). Not capped: above
    /// 1 the form factors gave out more than was shot.
    pub shot_closure: f64,
    /// Mean ambient term added for the light not yet shot, L_lm RGB: spread
    /// where the shots' light landed when the pass converged, by coverage
    /// when a budget stopped it.
    pub ambient: [f32; 3],
    /// Whether each patch's form factors were normalized to its hemicube's
    /// covered share (skipped where the scene catches little of its light).
    pub normalized: bool,
    pub trace: Vec<TracePoint>,
}

/// Why the bounce pass stopped. The report writes it as it always has
/// ("converged", "max shots", "max time"), so its layout is unchanged.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum StopReason {
    /// The weighted unshot power fell to `--tolerance` of the power put in,
    /// or no patch had any left to shoot.
    #[serde(rename = "converged")]
    Converged,
    /// `--max-shots` shots were taken.
    #[serde(rename = "max shots")]
    MaxShots,
    /// `--max-time` ran out.
    #[serde(rename = "max time")]
    MaxTime,
}

impl std::fmt::Display for StopReason {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.pad(match self {
            StopReason::Converged => "converged",
            StopReason::MaxShots => "max shots",
            StopReason::MaxTime => "max time",
        })
    }
}

/// Mirrors `BounceParams` in common.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(super) struct BounceParams {
    texel_count: u32,
    patch_count: u32,
    shooter_count: u32,
    row_stride: u32,
    face_size: f32,
    tiles_per_row: u32,
    far: f32,
    near: f32,
    receiver_offset: f32,
    max_slope: f32,
    chunk_count: u32,
    atlas_width: u32,
    cell: u32,
    /// A receiver this close to a shooter's plane lies in it, metres: twice
    /// the rounding `shooter_cull` allows for.
    in_plane: f32,
    _pad: u32,
}

impl BounceParams {
    /// The same for a dispatch of `row_stride` invocations per row.
    pub(super) fn with_row_stride(self, row_stride: u32) -> BounceParams {
        BounceParams { row_stride, ..self }
    }
}

/// Mirrors `Shooter` in common.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable, Default)]
struct Shooter {
    position: [f32; 3],
    area: f32,
    normal: [f32; 3],
    patch_index: u32,
    radiance: [f32; 3],
    radius: f32,
    rect_centre: [f32; 3],
    lift: f32,
    half_u: [f32; 3],
    rect_area: f32,
    half_v: [f32; 3],
    _pad: u32,
}

/// Mirrors `HemicubeFace` in common.wgsl: one face of a shooter's hemicube,
/// written on the GPU by the select pass.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable, Default)]
struct HemicubeFace {
    position: [f32; 3],
    lift: f32,
    normal: [f32; 3],
    face: u32,
}

/// The hemicube pass's instance attributes (`FaceIn` in solve_hemicube.wgsl).
const FACE_INSTANCES: wgpu::VertexBufferLayout<'static> = wgpu::VertexBufferLayout {
    array_stride: std::mem::size_of::<HemicubeFace>() as u64,
    step_mode: wgpu::VertexStepMode::Instance,
    attributes: &wgpu::vertex_attr_array![5 => Float32x3, 6 => Float32, 7 => Float32x3, 8 => Uint32],
};

/// Mirrors `BounceStats` in common.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable, Default, Debug)]
struct GpuStats {
    unshot: [f32; 4],
    received: [f32; 4],
    shot: [f32; 4],
    shooters: u32,
    landing: f32,
    _pad: [u32; 2],
}

/// Everything the bounce pass binds, created once.
struct Resources {
    params: wgpu::Buffer,
    texels: wgpu::Buffer,
    /// Per texel: the share of its area that bounces light (`overlaps`).
    shares: wgpu::Buffer,
    texel_patch: wgpu::Buffer,
    patches: wgpu::Buffer,
    /// Per patch: the covered share of its texels' hemispheres.
    patch_coverage: wgpu::Buffer,
    members: wgpu::Buffer,
    /// Per patch member, in `members`' order: its texel's position and its
    /// area that bounces (area × share), read in order by the power pass.
    member_points: wgpu::Buffer,
    unshot: wgpu::Buffer,
    lightmap: wgpu::Buffer,
    patch_power: wgpu::Buffer,
    patch_origin: wgpu::Buffer,
    chosen: wgpu::Buffer,
    shooters: wgpu::Buffer,
    /// Five faces per shooter slot: the hemicube pass's instances.
    hemicube_faces: wgpu::Buffer,
    stats: wgpu::Buffer,
    /// Per patch: the scale of its form factors, 0 until it first shoots.
    patch_scale: wgpu::Buffer,
    /// The batch's shooters' scales by slot (written by `finish`), which the
    /// gather reads as a uniform buffer.
    slot_scales: wgpu::Buffer,
    /// Near- and far-field sums of the measure pass per shooter slot and texel chunk.
    partials: wgpu::Buffer,
    /// Receivers in a shooter's near field: a count, then (texel, slots) pairs.
    near_list: wgpu::Buffer,
    /// The near-field pass's workgroup counts, written on the GPU from the
    /// list's length (so no batch waits to read it back).
    near_args: wgpu::Buffer,
    /// Each shooter's unshot light and area centroid by sub-cells of its patch.
    shooter_cells: wgpu::Buffer,
    depth_view: wgpu::TextureView,
    casters: Casters,
}

struct Pipelines {
    power: (wgpu::ComputePipeline, wgpu::BindGroup),
    select: (wgpu::ComputePipeline, wgpu::BindGroup),
    /// The chosen shooters' light by sub-cells; shares the power pass's bind group.
    shooter_cells: wgpu::ComputePipeline,
    /// Opaque and alpha-cut-out casters, and their bind group.
    hemicube: (wgpu::RenderPipeline, wgpu::RenderPipeline, wgpu::BindGroup),
    /// The form-factor normalization (measure, then finish); they share the
    /// shots' bind group, and `finish` writes the slots' scales in its own.
    measure: wgpu::ComputePipeline,
    finish: (wgpu::ComputePipeline, wgpu::BindGroup),
    /// The far field of every receiver, then the near field of those `main`
    /// listed; the far field reads the slots' scales in a bind group of its own.
    shoot: (wgpu::ComputePipeline, wgpu::BindGroup),
    slot_scales: wgpu::BindGroup,
    /// Sizes the near-field pass from the list's length, with its own bind group.
    near_dispatch: (wgpu::ComputePipeline, wgpu::BindGroup),
    near_field: wgpu::ComputePipeline,
}

/// What the bounce pass bounces light between.
pub struct Surfaces<'a> {
    pub scene: &'a Scene,
    pub texels: &'a TexelSet,
    /// Per texel: the share of its area that bounces light (`overlaps`);
    /// `None`: all of it.
    pub shares: Option<&'a [f32]>,
    pub patches: &'a Patches,
    /// The direct pass's covered share of each texel's hemisphere, where it ran.
    pub coverage: Option<&'a [f32]>,
    pub texels_per_unit: f32,
}

/// Shoots until converged or out of budget. `lightmap` holds L_lm after the
/// direct pass and is updated in place; returns what happened.
pub fn run(
    gpu: &Gpu,
    surfaces: &Surfaces,
    lightmap: &mut [[f32; 3]],
    options: &BounceOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<BounceStats> {
    let start = Instant::now();
    let Surfaces { scene, texels, shares, patches, coverage, texels_per_unit } = *surfaces;
    // The GPU weighs each texel's unshot light and what it receives by its
    // share of the area that bounces (`overlaps`); the sums here weigh them
    // by the same areas.
    let gpu_texels = texels;
    let weighted = shares.map(|shares| TexelSet {
        texels: texels.texels.iter().zip(shares).map(|(t, s)| Texel { area: t.area * s, ..*t }).collect(),
        tint: Vec::new(),
        ..*texels
    });
    let texels = weighted.as_ref().unwrap_or(texels);
    let ones;
    let shares = match shares {
        Some(shares) => shares,
        None => {
            ones = vec![1.0f32; texels.texels.len()];
            &ones
        }
    };
    let sums = Sums::new(texels, lightmap, coverage);
    let (params, dispatch) = params(gpu, scene, texels, patches, texels_per_unit, options);
    let patch_coverage = patch_coverage(texels, patches, coverage);
    let inputs =
        Inputs { texels: gpu_texels, shares, patches, patch_coverage: &patch_coverage, unshot: &sums.unshot, lightmap };
    // Without a direct pass (emitters only) the share is unknown: normalize.
    let normalized = sums.initial_closure.is_none_or(|f| f * luminance(sums.mean_albedo) >= NORMALIZE_FROM);
    let passes = Passes::new(gpu, scene, &inputs, params, dispatch, options.face_list_bytes, normalized);

    let max_shots = options.max_shots.unwrap_or(64 * patches.patches.len() as u64);
    let mut tally = Tally { gathered: sums.gathered, ..Tally::default() };
    let (stopped_by, last) = loop {
        // Sum and select on the GPU; read back only the totals.
        let stats = passes.select(gpu)?;
        let settled = tally.record(gpu, &stats, &sums, &passes.resources, options.probes.as_deref(), start)?;
        // Converged when the unshot light, each patch's weighted by how much
        // of its hemisphere the scene covers, is a `tolerance` share of the
        // light put in, weighted so: a room seen through an opening in a
        // sunlit scene, where most of the light put in leaves for the sky,
        // is shot until its own light has settled.
        if settled <= options.tolerance || stats.shooters == 0 {
            break (StopReason::Converged, stats);
        }
        if tally.shots >= max_shots {
            break (StopReason::MaxShots, stats);
        }
        if options.max_seconds.is_some_and(|max| start.elapsed().as_secs_f64() >= max) {
            break (StopReason::MaxTime, stats);
        }
        passes.shoot(gpu);
        tally.shots += stats.shooters as u64;
        tally.shot_total += stats.shot[3] as f64;
        tally.batches += 1;
        // Progress in "orders of magnitude converged" towards the tolerance.
        let goal = (1.0 / options.tolerance.max(1e-12)).ln();
        let done = ((1.0 / settled.max(1e-300)).ln() / goal * 1000.0).clamp(0.0, 1000.0);
        progress(done as u64, 1000);
    };

    let values: Vec<[f32; 4]> = read_buffer(gpu, &passes.resources.lightmap, texels.texels.len())?;
    let remaining: Vec<[f32; 4]> = read_buffer(gpu, &passes.resources.unshot, texels.texels.len())?;
    gpu.check("solve (bounce)")?;
    // How much of the light not yet shot would land. Converged, the share the
    // shots' light landed (it goes where theirs went, `ambient_weights`): the
    // coverage counts surfaces seen from behind, which absorb it, and would
    // pile it onto the few texels a shot reached. Stopped by a budget, the
    // scene-covered share of each texel's hemisphere (from the direct pass),
    // weighted by its unshot power; without a direct pass, the measured one.
    let converged = stopped_by == StopReason::Converged;
    let closure = match coverage {
        Some(coverage) if !converged => covered_share(texels, &remaining, coverage),
        _ => measured_closure(tally.received_total, tally.shot_total),
    };
    let ambient = ambient_term(last.unshot, closure, sums.mean_albedo, sums.total_area).map(|a| a as f32);
    let weights = ambient_weights(texels, &values, lightmap, coverage, converged);
    for ((out, v), w) in lightmap.iter_mut().zip(values).zip(weights) {
        *out = [0, 1, 2].map(|c| v[c] + ambient[c] * w);
    }
    let unshot_fraction = tally.trace.last().map_or(0.0, |t| t.unshot_fraction);
    Ok(BounceStats {
        patches: patches.patches.len(),
        shots: tally.shots,
        batches: tally.batches,
        seconds: start.elapsed().as_secs_f64() - tally.probe_seconds,
        stopped_by,
        unshot_fraction,
        closure,
        shot_closure: if tally.shot_total > 0.0 { tally.received_total / tally.shot_total } else { 1.0 },
        ambient,
        normalized,
        trace: tally.trace,
    })
}

/// The pass's sums over the texels, each weighted by its area (its share
/// of it, `overlaps`), before the first shot.
struct Sums {
    /// Initial unshot radiosity per texel: reflected direct light plus emission.
    unshot: Vec<[f32; 4]>,
    /// Σ ΔL·A of `unshot` (luminance): the power put in.
    power_in: f64,
    /// The share of the power put in that would land, from the direct
    /// pass's coverage (`None` without one).
    initial_closure: Option<f64>,
    total_area: f64,
    mean_albedo: [f64; 3],
    /// Σ L_lm·A of the direct light (luminance).
    gathered: f64,
}

impl Sums {
    fn new(texels: &TexelSet, lightmap: &[[f32; 3]], coverage: Option<&[f32]>) -> Sums {
        let unshot: Vec<[f32; 4]> = texels
            .texels
            .iter()
            .zip(lightmap.iter())
            .map(|(t, l)| {
                let [r, g, b] = [0, 1, 2].map(|c| t.albedo[c] * l[c] + t.emission[c]);
                [r, g, b, 0.0]
            })
            .collect();
        let power_in = texels
            .texels
            .iter()
            .zip(&unshot)
            .map(|(t, u)| luminance([u[0] as f64, u[1] as f64, u[2] as f64]) * t.area as f64)
            .sum::<f64>();
        let initial_closure = coverage.map(|c| covered_share(texels, &unshot, c));
        let total_area: f64 = texels.total_area();
        let mean_albedo = {
            let mut sum = [0.0f64; 3];
            for t in &texels.texels {
                for (s, a) in sum.iter_mut().zip(t.albedo) {
                    *s += a as f64 * t.area as f64;
                }
            }
            sum.map(|s| s / total_area.max(1e-30))
        };
        let gathered: f64 = texels
            .texels
            .iter()
            .zip(lightmap.iter())
            .map(|(t, l)| luminance([l[0] as f64, l[1] as f64, l[2] as f64]) * t.area as f64)
            .sum();
        Sums { unshot, power_in, initial_closure, total_area, mean_albedo, gathered }
    }
}

/// The batch loop's running totals.
#[derive(Default)]
struct Tally {
    shots: u64,
    batches: u64,
    trace: Vec<TracePoint>,
    /// Σ of the power shot and of the power that landed (luminance).
    shot_total: f64,
    received_total: f64,
    /// Σ L_lm·A so far (luminance), to turn the ambient term into a relative error.
    gathered: f64,
    /// Time spent reading back `--reference` probes, left out of the trace's clock.
    probe_seconds: f64,
    /// The first batch's coverage-weighted unshot power: the light put in.
    landing_in: Option<f64>,
}

impl Tally {
    /// Adds a batch's totals and its trace point; returns how much of the
    /// light put in is still to settle (coverage-weighted).
    fn record(
        &mut self,
        gpu: &Gpu,
        stats: &GpuStats,
        sums: &Sums,
        resources: &Resources,
        probes: Option<&Probes>,
        start: Instant,
    ) -> Result<f64> {
        self.received_total += stats.received[3] as f64;
        self.gathered += stats.received[3] as f64;
        let unshot_power = stats.unshot[3] as f64;
        let unshot_fraction = if sums.power_in > 0.0 { unshot_power / sums.power_in } else { 0.0 };
        let closure = sums.initial_closure.unwrap_or_else(|| measured_closure(self.received_total, self.shot_total));
        let ambient = ambient_term(stats.unshot, closure, sums.mean_albedo, sums.total_area);
        let error_estimate =
            if self.gathered > 0.0 { luminance(ambient) * sums.total_area / self.gathered } else { 0.0 };
        let seconds = start.elapsed().as_secs_f64() - self.probe_seconds;
        let probe_start = Instant::now();
        let reference_error = probe_error(gpu, &resources.lightmap, probes, ambient)?;
        self.probe_seconds += probe_start.elapsed().as_secs_f64();
        self.trace.push(TracePoint { seconds, shots: self.shots, unshot_fraction, error_estimate, reference_error });
        let landing_in = *self.landing_in.get_or_insert(stats.landing as f64);
        Ok(if landing_in > 0.0 { stats.landing as f64 / landing_in } else { 0.0 })
    }
}

/// How each batch is laid out: shooters, hemicube faces in the depth
/// atlas, and workgroups over the texels and over the patches.
#[derive(Clone, Copy)]
struct Dispatch {
    shooter_count: u32,
    face: u32,
    tiles_per_row: u32,
    tile_rows: u32,
    groups: (u32, u32),
    patch_groups: (u32, u32),
}

/// The shaders' parameters and the batches' layout.
fn params(
    gpu: &Gpu,
    scene: &Scene,
    texels: &TexelSet,
    patches: &Patches,
    texels_per_unit: f32,
    options: &BounceOptions,
) -> (BounceParams, Dispatch) {
    let radius = scene_radius(scene);
    let shooter_count = options.shooters_per_batch.clamp(1, MAX_SHOOTERS);
    let face = options.hemicube_size.clamp(16, 2048);
    let tiles_per_row = ((gpu.limits.max_texture_dimension_2d / (3 * face)).max(1)).min(shooter_count);
    let tile_rows = shooter_count.div_ceil(tiles_per_row);
    let texel_world = 1.0 / texels_per_unit.max(1e-30);
    let groups = gpu.dispatch_size(texels.texels.len() as u32, 64);
    let patch_groups = gpu.dispatch_size(patches.patches.len() as u32, 64);
    let params = BounceParams {
        texel_count: texels.texels.len() as u32,
        patch_count: patches.patches.len() as u32,
        shooter_count,
        row_stride: groups.0 * 64,
        face_size: face as f32,
        tiles_per_row,
        far: 2.0 * radius,
        near: (radius * 1e-5).max(texel_world * 1e-3),
        // Half a lightmap texel: off the surface, well inside any occluder.
        receiver_offset: 0.5 * texel_world,
        max_slope: 10.0,
        chunk_count: (texels.texels.len() as u32).div_ceil(MEASURE_CHUNK).max(1),
        atlas_width: texels.width,
        cell: patches.cell,
        in_plane: shooter_cull::in_plane(&texels.texels),
        _pad: 0,
    };
    (params, Dispatch { shooter_count, face, tiles_per_row, tile_rows, groups, patch_groups })
}

/// The pass on the GPU: its buffers, pipelines and culls, and the two
/// submissions of each batch.
struct Passes {
    resources: Resources,
    pipelines: Pipelines,
    shooter_cull: ShooterCull,
    /// The casters each hemicube face draws (`None`: every caster).
    cull: Option<HemicubeCull>,
    params: BounceParams,
    dispatch: Dispatch,
    /// Whether each patch's form factors are normalized (`NORMALIZE_FROM`).
    normalized: bool,
}

impl Passes {
    fn new(
        gpu: &Gpu,
        scene: &Scene,
        inputs: &Inputs,
        params: BounceParams,
        dispatch: Dispatch,
        face_list_bytes: u64,
        normalized: bool,
    ) -> Passes {
        let Dispatch { shooter_count, face, tiles_per_row, tile_rows, .. } = dispatch;
        let resources = resources(gpu, scene, inputs, params, face, tiles_per_row, tile_rows);
        let (casters, faces) = (&resources.casters, &resources.hemicube_faces);
        let shooter_cull = ShooterCull::new(gpu, &inputs.texels.texels, params, &resources.shooters);
        let cull = HemicubeCull::new(gpu, casters, faces, 5 * shooter_count, params.near, face_list_bytes);
        if !normalized {
            // Every patch's scale known (1): the measure and finish passes skip.
            let ones = vec![1f32; inputs.patches.patches.len().max(1)];
            gpu.queue.write_buffer(&resources.patch_scale, 0, bytemuck::cast_slice(&ones));
        }
        let patch_params = params.with_row_stride(dispatch.patch_groups.0 * 64);
        let patch_params_buffer = gpu.uniform_buffer("solve_patch_power params", &patch_params);
        let pipelines = Pipelines::new(gpu, &resources, &patch_params_buffer, &shooter_cull.group_shooters);
        Passes { resources, pipelines, shooter_cull, cull, params, dispatch, normalized }
    }

    /// Sums every patch's unshot power, chooses the batch's shooters and
    /// their light by sub-cells, and reads back the totals.
    fn select(&self, gpu: &Gpu) -> Result<GpuStats> {
        let (pipelines, dispatch) = (&self.pipelines, &self.dispatch);
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(&pipelines.power.0);
            pass.set_bind_group(0, &pipelines.power.1, &[]);
            pass.dispatch_workgroups(dispatch.patch_groups.0, dispatch.patch_groups.1, 1);
            pass.set_pipeline(&pipelines.select.0);
            pass.set_bind_group(0, &pipelines.select.1, &[]);
            pass.dispatch_workgroups(1, 1, 1);
            pass.set_pipeline(&pipelines.shooter_cells);
            pass.set_bind_group(0, &pipelines.power.1, &[]);
            pass.dispatch_workgroups(dispatch.shooter_count, 1, 1);
        }
        gpu.queue.submit([encoder.finish()]);
        Ok(read_buffer(gpu, &self.resources.stats, 1)?[0])
    }

    /// Renders the chosen shooters' hemicubes and gathers their light at
    /// every texel: the far field everywhere, then the near field where
    /// `main` listed it.
    fn shoot(&self, gpu: &Gpu) {
        let (pipelines, resources) = (&self.pipelines, &self.resources);
        let Dispatch { shooter_count, face, tiles_per_row, groups, .. } = self.dispatch;
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        encoder.clear_buffer(&resources.near_list, 0, Some(8));
        // What each hemicube face of the batch draws (None: every caster).
        if let Some(cull) = &self.cull {
            cull.record(&mut encoder);
        }
        render_hemicubes(&mut encoder, pipelines, resources, self.cull.as_ref(), shooter_count, face, tiles_per_row);
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            self.shooter_cull.record(&mut pass);
            pass.set_bind_group(0, &pipelines.shoot.1, &[]);
            if self.normalized {
                pass.set_pipeline(&pipelines.measure);
                pass.dispatch_workgroups(self.params.chunk_count, shooter_count.div_ceil(MEASURE_SLOTS), 1);
                pass.set_pipeline(&pipelines.finish.0);
                pass.set_bind_group(1, &pipelines.finish.1, &[]);
                pass.dispatch_workgroups(shooter_count, 1, 1);
            }
            pass.set_pipeline(&pipelines.shoot.0);
            pass.set_bind_group(1, &pipelines.slot_scales, &[]);
            pass.dispatch_workgroups(groups.0, groups.1, 1);
            pass.set_pipeline(&pipelines.near_dispatch.0);
            pass.set_bind_group(0, &pipelines.near_dispatch.1, &[]);
            pass.dispatch_workgroups(1, 1, 1);
        }
        {
            // The near field only for the receivers listed (a few per shooter).
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_bind_group(0, &pipelines.shoot.1, &[]);
            pass.set_pipeline(&pipelines.near_field);
            pass.dispatch_workgroups_indirect(&resources.near_args, 0);
        }
        gpu.queue.submit([encoder.finish()]);
    }
}

/// Where the ambient term lands: per texel, a weight of area-weighted
/// mean 1 (1 everywhere when a budget stopped a pass with no direct pass
/// before it).
fn ambient_weights(
    texels: &TexelSet,
    values: &[[f32; 4]],
    direct: &[[f32; 3]],
    coverage: Option<&[f32]>,
    converged: bool,
) -> Vec<f32> {
    if converged {
        // Converged, the little left would land where the shots' light
        // landed: later bounces spread as earlier ones did. A texel no
        // reflected light reached (inside a closed room the light never
        // entered) gets none.
        let bounced: Vec<f32> = values.iter().zip(direct.iter()).map(|(v, d)| bounced_luminance(*v, *d)).collect();
        mean_one_weights(texels, &bounced)
    } else {
        // Stopped by a budget, early shots say little about where the rest
        // goes: it is spread in proportion to how much of each texel's
        // hemisphere the scene covers (a texel under open sky gets none).
        match coverage {
            Some(c) => mean_one_weights(texels, c),
            None => vec![1.0; texels.texels.len()],
        }
    }
}

/// The radius of the scene's bounding sphere about the centre of its
/// bounds, with a margin so that geometry never touches a hemicube's far
/// plane.
fn scene_radius(scene: &Scene) -> f32 {
    let (lo, hi) = scene.bounds().unwrap_or((Vec3::ZERO, Vec3::ZERO));
    let centre = (lo + hi) * 0.5;
    let radius = scene
        .primitives
        .iter()
        .flat_map(|p| p.positions.iter())
        .map(|&p| (Vec3::from(p) - centre).length())
        .fold(0.0f32, f32::max);
    (radius * 1.02).max(f32::MIN_POSITIVE * 1e6)
}

/// The luminance a texel received from other surfaces: its lightmap value
/// after the shots (`after`) less its direct light (`direct`).
fn bounced_luminance(after: [f32; 4], direct: [f32; 3]) -> f32 {
    let d = [0, 1, 2].map(|c| (after[c] - direct[c]).max(0.0) as f64);
    luminance(d) as f32
}

/// `values` scaled to an area-weighted mean of 1 over the texels, so that
/// spreading the ambient term by them spreads its power whatever their
/// distribution; all zero where the values are.
fn mean_one_weights(texels: &TexelSet, values: &[f32]) -> Vec<f32> {
    let sum: f64 = texels.texels.iter().zip(values).map(|(t, v)| *v as f64 * t.area as f64).sum();
    let mean = sum / texels.total_area().max(1e-30);
    values.iter().map(|v| if mean > 0.0 { (*v as f64 / mean) as f32 } else { 0.0 }).collect()
}

/// `--reference`: the probes' error now, from a read-back of their values
/// plus the ambient term (outside the timed part of the trace point).
fn probe_error(gpu: &Gpu, lightmap: &wgpu::Buffer, probes: Option<&Probes>, ambient: [f64; 3]) -> Result<Option<f64>> {
    let Some(probes) = probes.filter(|p| !p.texels.is_empty()) else {
        return Ok(None);
    };
    let values: Vec<[f32; 4]> = gpu::read_elements(gpu, lightmap, &probes.texels)?;
    Ok(Some(probes.relative_rmse(values.iter().map(|v| [0, 1, 2].map(|c| v[c] as f64 + ambient[c])))))
}

/// The share of `unshot` power that would land on the scene: each texel's
/// covered share of its hemisphere, weighted by its unshot power.
fn covered_share(texels: &TexelSet, unshot: &[[f32; 4]], coverage: &[f32]) -> f64 {
    let (mut covered, mut total) = (0.0f64, 0.0f64);
    for ((t, u), c) in texels.texels.iter().zip(unshot).zip(coverage) {
        let power = luminance([u[0] as f64, u[1] as f64, u[2] as f64]) * t.area as f64;
        covered += power * *c as f64;
        total += power;
    }
    if total > 0.0 { covered / total } else { 0.0 }
}

/// Each patch's area-weighted share of its texels' hemispheres the scene
/// covers (the direct pass's), or 1 for every patch without it.
fn patch_coverage(texels: &TexelSet, patches: &Patches, coverage: Option<&[f32]>) -> Vec<f32> {
    let Some(coverage) = coverage else {
        return vec![1.0; patches.patches.len().max(1)];
    };
    let mut per_patch: Vec<f32> = patches
        .patches
        .iter()
        .map(|p| {
            let members = &patches.members[p.first as usize..(p.first + p.count) as usize];
            let (mut covered, mut area) = (0.0f64, 0.0f64);
            for &i in members {
                let a = texels.texels[i as usize].area as f64;
                covered += coverage[i as usize] as f64 * a;
                area += a;
            }
            if area > 0.0 { (covered / area) as f32 } else { 0.0 }
        })
        .collect();
    // A buffer is never empty.
    per_patch.resize(per_patch.len().max(1), 0.0);
    per_patch
}

/// The share of shot power that landed on the scene so far (1 before any
/// shot: a closed room is the cautious guess).
fn measured_closure(received: f64, shot: f64) -> f64 {
    if shot > 0.0 { (received / shot).min(1.0) } else { 1.0 }
}

/// The light still unshot, spread evenly over the scene as incident
/// radiance (L_lm): U·f / (A (1 − ρ̄ f)) per channel, where f is the share of
/// shot light the scene catches (1 in a closed room, Cohen et al.'s case).
fn ambient_term(unshot: [f32; 4], closure: f64, albedo: [f64; 3], area: f64) -> [f64; 3] {
    if area <= 0.0 {
        return [0.0; 3];
    }
    [0, 1, 2].map(|c| {
        let reflect = (albedo[c] * closure).min(0.999);
        unshot[c].max(0.0) as f64 * closure / (area * (1.0 - reflect))
    })
}

/// What the bounce pass uploads once.
struct Inputs<'a> {
    texels: &'a TexelSet,
    /// Per texel: the share of its area that bounces (`overlaps`).
    shares: &'a [f32],
    patches: &'a Patches,
    /// Per patch: the covered share of its texels' hemispheres.
    patch_coverage: &'a [f32],
    unshot: &'a [[f32; 4]],
    lightmap: &'a [[f32; 3]],
}

fn resources(
    gpu: &Gpu,
    scene: &Scene,
    inputs: &Inputs,
    params: BounceParams,
    face: u32,
    tiles_per_row: u32,
    tile_rows: u32,
) -> Resources {
    let Inputs { texels, shares, patches, patch_coverage, unshot, lightmap } = *inputs;
    let none = wgpu::BufferUsages::empty();
    let depth = gpu.depth_target("solve_hemicube depth", 3 * face * tiles_per_row, face * tile_rows);
    let lightmap4: Vec<[f32; 4]> = lightmap.iter().map(|l| [l[0], l[1], l[2], 0.0]).collect();
    Resources {
        params: gpu.uniform_buffer("solve_shoot params", &params),
        texels: gpu.storage_buffer("solve_shoot texels", &texels.texels, none),
        shares: gpu.storage_buffer("solve_shoot shares", shares, none),
        texel_patch: gpu.storage_buffer("solve_shoot texel patches", &patches.texel_patch, none),
        patches: gpu.storage_buffer("solve_select patches", &patches.patches, none),
        patch_coverage: gpu.storage_buffer("solve_select patch coverage", patch_coverage, none),
        members: gpu.storage_buffer("solve_patch_power members", &patches.members, none),
        member_points: gpu.storage_buffer("solve_patch_power member points", &member_points(inputs), none),
        unshot: gpu.storage_buffer("solve_shoot unshot", unshot, wgpu::BufferUsages::COPY_SRC),
        lightmap: gpu.storage_buffer("solve_shoot lightmap", &lightmap4, wgpu::BufferUsages::COPY_SRC),
        patch_power: gpu.zeroed_storage_buffer::<[f32; 4]>("solve_patch_power power", patches.patches.len(), none),
        patch_origin: gpu.zeroed_storage_buffer::<[f32; 4]>("solve_patch_power origins", patches.patches.len(), none),
        chosen: gpu.zeroed_storage_buffer::<u32>("solve_select chosen", patches.patches.len(), none),
        shooters: gpu.storage_buffer(
            "solve_select shooters",
            &[Shooter::default(); MAX_SHOOTERS as usize],
            wgpu::BufferUsages::UNIFORM,
        ),
        stats: gpu.storage_buffer("solve_select stats", &[GpuStats::default()], wgpu::BufferUsages::COPY_SRC),
        patch_scale: gpu.zeroed_storage_buffer::<f32>(
            "solve_shoot patch scales",
            patches.patches.len(),
            wgpu::BufferUsages::COPY_DST,
        ),
        slot_scales: gpu.storage_buffer(
            "solve_shoot slot scales",
            &[1f32; MAX_SHOOTERS as usize],
            wgpu::BufferUsages::UNIFORM,
        ),
        partials: gpu.zeroed_storage_buffer::<f32>(
            "solve_shoot measured sums",
            (2 * MAX_SHOOTERS * params.chunk_count) as usize,
            none,
        ),
        // A count (padded to 8 bytes), then at most one entry per texel.
        near_list: gpu.zeroed_storage_buffer::<[u32; 2]>(
            "solve_shoot near-field receivers",
            1 + texels.texels.len().max(1),
            wgpu::BufferUsages::COPY_DST,
        ),
        near_args: gpu.zeroed_storage_buffer::<u32>("solve_shoot near-field dispatch", 3, wgpu::BufferUsages::INDIRECT),
        shooter_cells: gpu.storage_buffer(
            "solve_patch_power shooter cells",
            // Per slot and sub-cell: unshot power and area, the centroid, the normal.
            &vec![[0f32; 4]; MAX_SHOOTERS as usize * SUB_CELL_ROWS * SUB_CELL_COUNT],
            wgpu::BufferUsages::UNIFORM,
        ),
        hemicube_faces: gpu.zeroed_storage_buffer::<HemicubeFace>(
            "solve_select hemicube faces",
            5 * MAX_SHOOTERS as usize,
            wgpu::BufferUsages::VERTEX,
        ),
        depth_view: depth.create_view(&Default::default()),
        casters: Casters::new(gpu, scene, Topology::Solids),
    }
}

impl Pipelines {
    fn new(gpu: &Gpu, r: &Resources, patch_params: &wgpu::Buffer, group_shooters: &wgpu::Buffer) -> Pipelines {
        let (power_layout, power_group) = power_bindings(gpu, r, patch_params);
        let (select_layout, select_group) = select_bindings(gpu, r);
        let (shoot_layout, shoot_group) = shoot_bindings(gpu, r, group_shooters);
        let scales = SlotScales::new(gpu, r);
        let (near_dispatch_layout, near_dispatch_group) = near_dispatch_bindings(gpu, r);
        Pipelines {
            power: (gpu.compute_pipeline(Shader::SolvePatchPower, "main", &[&power_layout]), power_group),
            shooter_cells: gpu.compute_pipeline(Shader::SolvePatchPower, "shooter_cells_of_batch", &[&power_layout]),
            select: (gpu.compute_pipeline(Shader::SolveSelect, "main", &[&select_layout]), select_group),
            hemicube: hemicube_pipelines(gpu, r),
            measure: gpu.compute_pipeline(Shader::SolveShoot, "measure", &[&shoot_layout]),
            finish: (
                gpu.compute_pipeline(Shader::SolveShoot, "finish", &[&shoot_layout, &scales.write_layout]),
                scales.write_group,
            ),
            shoot: (
                gpu.compute_pipeline(Shader::SolveShoot, "main", &[&shoot_layout, &scales.read_layout]),
                shoot_group,
            ),
            slot_scales: scales.read_group,
            near_field: gpu.compute_pipeline(Shader::SolveShoot, "near_field", &[&shoot_layout]),
            near_dispatch: (
                gpu.compute_pipeline(Shader::SolveShoot, "near_dispatch", &[&near_dispatch_layout]),
                near_dispatch_group,
            ),
        }
    }
}

fn bind_group_layout(gpu: &Gpu, label: &str, entries: &[wgpu::BindGroupLayoutEntry]) -> wgpu::BindGroupLayout {
    gpu.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(label), entries })
}

/// `solve_patch_power`'s bindings: each patch's unshot power, and the
/// chosen shooters' light by sub-cells.
fn power_bindings(gpu: &Gpu, r: &Resources, patch_params: &wgpu::Buffer) -> (wgpu::BindGroupLayout, wgpu::BindGroup) {
    let compute = wgpu::ShaderStages::COMPUTE;
    let layout = bind_group_layout(
        gpu,
        "solve_patch_power",
        &[
            // 0: BounceParams (patch count, dispatch stride)
            gpu::uniform_entry(0, compute),
            // 1: texels (areas), 2: patches, 3: patch members
            gpu::storage_entry(1, true, compute),
            gpu::storage_entry(2, true, compute),
            gpu::storage_entry(3, true, compute),
            // 4: unshot radiance per texel, 5: per-patch power, 6: per-patch origins (written)
            gpu::storage_entry(4, true, compute),
            gpu::storage_entry(5, false, compute),
            gpu::storage_entry(6, false, compute),
            // 7: the batch's shooters, 8: their light by sub-cells (written)
            gpu::uniform_entry(7, compute),
            gpu::storage_entry(8, false, compute),
            // 9: each texel's share of the area that bounces
            gpu::storage_entry(9, true, compute),
            // 10: each member's position and bouncing area
            gpu::storage_entry(10, true, compute),
        ],
    );
    let group = gpu::bind_buffers(
        gpu,
        "solve_patch_power",
        &layout,
        &[
            patch_params,
            &r.texels,
            &r.patches,
            &r.members,
            &r.unshot,
            &r.patch_power,
            &r.patch_origin,
            &r.shooters,
            &r.shooter_cells,
            &r.shares,
            &r.member_points,
        ],
    );
    (layout, group)
}

/// `Resources::member_points`: the patch members' texels' positions and
/// bouncing areas in the members' order, so that the power pass, run every
/// batch, reads them in order rather than whole texels by index.
fn member_points(inputs: &Inputs) -> Vec<[f32; 4]> {
    let points = inputs.patches.members.iter().map(|&i| {
        let t = &inputs.texels.texels[i as usize];
        [t.position[0], t.position[1], t.position[2], t.area * inputs.shares[i as usize]]
    });
    points.collect()
}

/// `solve_select`'s bindings: the batch's shooters, their hemicube faces and
/// the totals read back.
fn select_bindings(gpu: &Gpu, r: &Resources) -> (wgpu::BindGroupLayout, wgpu::BindGroup) {
    let compute = wgpu::ShaderStages::COMPUTE;
    let layout = bind_group_layout(
        gpu,
        "solve_select",
        &[
            // 0: BounceParams, 1: patches, 2: per-patch power
            gpu::uniform_entry(0, compute),
            gpu::storage_entry(1, true, compute),
            gpu::storage_entry(2, true, compute),
            // 3: chosen flags, 4: shooters, 5: totals (all written)
            gpu::storage_entry(3, false, compute),
            gpu::storage_entry(4, false, compute),
            gpu::storage_entry(5, false, compute),
            // 6: per-patch origins, 7: per-patch coverage
            gpu::storage_entry(6, true, compute),
            gpu::storage_entry(7, true, compute),
            // 8: the shooters' hemicube faces (written)
            gpu::storage_entry(8, false, compute),
        ],
    );
    let group = gpu::bind_buffers(
        gpu,
        "solve_select",
        &layout,
        &[
            &r.params,
            &r.patches,
            &r.patch_power,
            &r.chosen,
            &r.shooters,
            &r.stats,
            &r.patch_origin,
            &r.patch_coverage,
            &r.hemicube_faces,
        ],
    );
    (layout, group)
}

/// `solve_hemicube`'s pipelines for opaque and alpha-cut-out casters, and
/// their bind group.
fn hemicube_pipelines(gpu: &Gpu, r: &Resources) -> (wgpu::RenderPipeline, wgpu::RenderPipeline, wgpu::BindGroup) {
    let vertex = wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT;
    let [materials_entry, textures_entry, sampler_entry] = Casters::layout_entries(2);
    let layout = bind_group_layout(
        gpu,
        "solve_hemicube",
        &[
            // 0: BounceParams (near, far)
            gpu::uniform_entry(0, vertex),
            // 2, 3, 4: materials, their textures and sampler (alpha cut-outs)
            materials_entry,
            textures_entry,
            sampler_entry,
        ],
    );
    let [materials_binding, textures_binding, sampler_binding] = r.casters.bind_entries(2);
    let group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("solve_hemicube"),
        layout: &layout,
        entries: &[
            wgpu::BindGroupEntry { binding: 0, resource: r.params.as_entire_binding() },
            materials_binding,
            textures_binding,
            sampler_binding,
        ],
    });
    let module = gpu.shader(Shader::SolveHemicube);
    let pipeline_layout = gpu.device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("solve_hemicube"),
        bind_group_layouts: &[Some(&layout)],
        immediate_size: 0,
    });
    let pipeline =
        |label, vs, fs| Casters::pipeline(gpu, label, &pipeline_layout, &module, vs, FACE_INSTANCES, Some(fs), &[]);
    let opaque = pipeline("solve_hemicube", "vs_hemicube", "fs_hemicube");
    let masked = pipeline("solve_hemicube masked", "vs_hemicube_masked", "fs_hemicube_masked");
    (opaque, masked, group)
}

/// `solve_shoot`'s bindings (group 0 of every entry point but
/// `near_dispatch`): the gather, its normalization and the near field.
fn shoot_bindings(gpu: &Gpu, r: &Resources, group_shooters: &wgpu::Buffer) -> (wgpu::BindGroupLayout, wgpu::BindGroup) {
    let compute = wgpu::ShaderStages::COMPUTE;
    let layout = bind_group_layout(
        gpu,
        "solve_shoot",
        &[
            // 0: BounceParams, 1: texels, 2: patch of each texel, 3: shooters
            gpu::uniform_entry(0, compute),
            gpu::storage_entry(1, true, compute),
            gpu::storage_entry(2, true, compute),
            gpu::uniform_entry(3, compute),
            // 4: lightmap L_lm, 5: unshot ΔL (both accumulated)
            gpu::storage_entry(4, false, compute),
            gpu::storage_entry(5, false, compute),
            // 6: the batch's hemicube depth atlas
            gpu::depth_texture_entry(6, compute),
            // 7: per-patch form-factor scales, 8: the measure pass's sums
            gpu::storage_entry(7, false, compute),
            gpu::storage_entry(8, false, compute),
            // 10: receivers in a shooter's near field (listed, then gathered)
            gpu::storage_entry(10, false, compute),
            // 11: the shooters' light by sub-cells, 13: each texel's share of the area that bounces
            gpu::uniform_entry(11, compute),
            gpu::storage_entry(13, true, compute),
            // 14: each patch's slot + 1 in the batch, 15: each texel group's slots (solve_shooter_cull)
            gpu::storage_entry(14, true, compute),
            gpu::storage_entry(15, true, compute),
        ],
    );
    let group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("solve_shoot"),
        layout: &layout,
        entries: &[
            wgpu::BindGroupEntry { binding: 0, resource: r.params.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 1, resource: r.texels.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 2, resource: r.texel_patch.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 3, resource: r.shooters.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 4, resource: r.lightmap.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 5, resource: r.unshot.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 6, resource: wgpu::BindingResource::TextureView(&r.depth_view) },
            wgpu::BindGroupEntry { binding: 7, resource: r.patch_scale.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 8, resource: r.partials.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 10, resource: r.near_list.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 11, resource: r.shooter_cells.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 13, resource: r.shares.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 14, resource: r.chosen.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 15, resource: group_shooters.as_entire_binding() },
        ],
    });
    (layout, group)
}

/// The slots' form-factor scales: written by `finish`, read by `main` as a
/// uniform buffer, so in a group of each one's own.
struct SlotScales {
    write_layout: wgpu::BindGroupLayout,
    write_group: wgpu::BindGroup,
    read_layout: wgpu::BindGroupLayout,
    read_group: wgpu::BindGroup,
}

impl SlotScales {
    fn new(gpu: &Gpu, r: &Resources) -> SlotScales {
        let compute = wgpu::ShaderStages::COMPUTE;
        let write_layout =
            bind_group_layout(gpu, "solve_shoot slot scales (written)", &[gpu::storage_entry(1, false, compute)]);
        let read_layout = bind_group_layout(gpu, "solve_shoot slot scales", &[gpu::uniform_entry(0, compute)]);
        let group = |label, layout, binding| {
            gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(label),
                layout,
                entries: &[wgpu::BindGroupEntry { binding, resource: r.slot_scales.as_entire_binding() }],
            })
        };
        let write_group = group("solve_shoot slot scales (written)", &write_layout, 1);
        let read_group = group("solve_shoot slot scales", &read_layout, 0);
        SlotScales { write_layout, write_group, read_layout, read_group }
    }
}

/// `near_dispatch`'s bindings, apart from the shots' group: its output is
/// the near-field pass's indirect arguments, which no bind group of that
/// pass may hold.
fn near_dispatch_bindings(gpu: &Gpu, r: &Resources) -> (wgpu::BindGroupLayout, wgpu::BindGroup) {
    let compute = wgpu::ShaderStages::COMPUTE;
    let layout = bind_group_layout(
        gpu,
        "solve_shoot near_dispatch",
        &[
            // 10: the near-field list (its count), 12: the workgroup counts (written)
            gpu::storage_entry(10, false, compute),
            gpu::storage_entry(12, false, compute),
        ],
    );
    let group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("solve_shoot near_dispatch"),
        layout: &layout,
        entries: &[
            wgpu::BindGroupEntry { binding: 10, resource: r.near_list.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 12, resource: r.near_args.as_entire_binding() },
        ],
    });
    (layout, group)
}

/// The five faces of every shooter's hemicube, each into its viewport of
/// the depth atlas (the same layout `hemicube_viewport` in common.wgsl reads):
/// the casters `cull` listed for the face, or every caster.
fn render_hemicubes(
    encoder: &mut wgpu::CommandEncoder,
    pipelines: &Pipelines,
    r: &Resources,
    cull: Option<&HemicubeCull>,
    shooters: u32,
    face: u32,
    tiles_per_row: u32,
) {
    let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some("solve_hemicube"),
        color_attachments: &[],
        depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
            view: &r.depth_view,
            depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
            stencil_ops: None,
        }),
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    });
    pass.set_bind_group(0, &pipelines.hemicube.2, &[]);
    r.casters.bind(&mut pass, &r.hemicube_faces);
    if let Some(cull) = cull {
        // The faces' lists, in place of the casters' own indices.
        cull.bind(&mut pass);
    }
    let (opaque, masked) = (&pipelines.hemicube.0, &pipelines.hemicube.1);
    // Binding a pipeline makes a CPU driver derive its state again: the
    // opaque one is bound once, and again only after a masked draw.
    pass.set_pipeline(opaque);
    let face_bytes = std::mem::size_of::<HemicubeFace>() as u64;
    let s = face as f32;
    for slot in 0..shooters {
        let tile = [(slot % tiles_per_row) as f32 * 3.0 * s, (slot / tiles_per_row) as f32 * s];
        let views = [
            [tile[0], tile[1], s, s],
            [tile[0] + s, tile[1], s, 0.5 * s],
            [tile[0] + s, tile[1] + 0.5 * s, s, 0.5 * s],
            [tile[0] + 2.0 * s, tile[1], s, 0.5 * s],
            [tile[0] + 2.0 * s, tile[1] + 0.5 * s, s, 0.5 * s],
        ];
        for (f, [x, y, w, h]) in views.into_iter().enumerate() {
            pass.set_viewport(x, y, w, h, 0.0, 1.0);
            // The face's attributes as instance 0: an indirect draw's first
            // instance must be 0 on adapters without INDIRECT_FIRST_INSTANCE.
            let instance = slot * 5 + f as u32;
            pass.set_vertex_buffer(1, r.hemicube_faces.slice(instance as u64 * face_bytes..));
            match cull {
                Some(cull) => cull.draw(&mut pass, instance),
                None => r.casters.draw_opaque(&mut pass, 0),
            }
            if r.casters.draw_masked(&mut pass, masked, 0) {
                pass.set_pipeline(opaque);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::Shader;
    use crate::gpu::mirror::assert_mirrors;

    #[test]
    fn the_bounce_structs_mirror_common_wgsl() {
        assert_mirrors!(
            Shader::SolveShoot,
            "BounceParams",
            BounceParams {
                texel_count,
                patch_count,
                shooter_count,
                row_stride,
                face_size,
                tiles_per_row,
                far,
                near,
                receiver_offset,
                max_slope,
                chunk_count,
                atlas_width,
                cell,
                in_plane,
            }
        );
        assert_mirrors!(
            Shader::SolveShoot,
            "Shooter",
            Shooter {
                position,
                area,
                normal,
                patch_index,
                radiance,
                radius,
                rect_centre,
                lift,
                half_u,
                rect_area,
                half_v
            }
        );
        assert_mirrors!(Shader::SolveHemicube, "HemicubeFace", HemicubeFace { position, lift, normal, face });
        assert_mirrors!(Shader::SolveSelect, "BounceStats", GpuStats { unshot, received, shot, shooters, landing });
    }
}
