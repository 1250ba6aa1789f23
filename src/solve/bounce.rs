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
//! show it only their backs never converged: that coverage counts backs.)
//! Without a direct pass (no `--env`), a patch's coverage is the share of
//! its hemicube that sees a surface's front, measured on its first shot
//! (`finish`; 1 before), and the light put in is weighted by the share of
//! shot light that landed so far: both count fronts alone.
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
//! A patch shoots ahead (Feda & Purgathofer's overshooting): with its
//! unshot light it shoots the light it will still receive by the ambient
//! term's estimate (the batch's unshot power times the ambient factor,
//! `overshoot_factor`, times its coverage and albedo), and its texels are
//! left owing that much. Light received later pays the debt; a patch whose
//! debt is the largest unsettled light shoots it back, negative. A closed
//! room, which took about six shots a patch, settles in about two. Owed
//! light counts as unsettled as unshot light does, so the stop and the
//! patch chosen weigh its magnitude. Only a run that goes on until it
//! settles shoots ahead: one a budget (`max_shots`, `max_seconds`) stops
//! early leaves light owed where the ambient term, spread evenly, misses it
//! (a uniform room at ρ = 0.95 stopped after 1,000 shots was 16 % off in
//! places, against 4 % without, BENCHMARKS.md).
//!
//! The light not yet shot is spread as an ambient term (Cohen et al.'s,
//! scaled by the measured share of shot light the scene catches), and the
//! report says how much it was: where the shots' light landed when the pass
//! converged, by the scene's coverage of each texel when a budget stopped it
//! (a run stopped early still answers honestly).
//!
//! Here: the options and the report's figures, the CPU's sums, and the page
//! that strings the GPU passes together (`Passes`). Each pass is a file of
//! its own beside its shader, over the buffers they share (`resources`).

use std::time::Instant;

use anyhow::Result;
use serde::{Deserialize, Serialize};

use super::hemicube::Hemicube;
use super::hemicube_cull::HemicubeCull;
use super::pass_times::{self, PassSeconds, PassTimes};
use super::patch_power::{PatchPower, SubCellOrder};
use super::patches::Patches;
use super::resources::{self, BounceParams, Dispatch, Inputs, Resources};
use super::select::{GpuStats, Select};
use super::shoot::Shoot;
use super::shooter_cull::ShooterCull;
use crate::colour::luminance;
use crate::gpu::{self, Gpu, read_buffer};
use crate::reference::Probes;
use crate::scene::Scene;
use crate::texelize::TexelSet;

/// Shooter slots per batch (`MAX_SHOOTERS` in include/bounce.wgsl): the
/// shaders hold a set of slots as the bits of two u32s.
pub const MAX_SHOOTERS: u32 = 64;
const _: () = assert!(MAX_SHOOTERS <= 2 * u32::BITS);
/// Normalize the form factors only where the scene catches at least this
/// much of the light it reflects (mean albedo × covered share): below it, a
/// loss of a few percent per bounce changes the lightmap by well under 1 %
/// (ε ρf/(1 − ρf) < ε/4), and the measure pass would add up to 1.9× to every
/// patch's first shot.
const NORMALIZE_FROM: f64 = 0.2;

/// Options of the bounce pass, with their defaults.
#[derive(Clone, Debug)]
pub struct BounceOptions {
    /// Stop when the unshot and owed power, each patch's weighted by the
    /// share of its texels' hemispheres the scene covers, falls below this
    /// fraction of the power put in, weighted the same way.
    pub tolerance: f64,
    /// Stop after this many shots (`None`: 64 per patch, so that even a
    /// near-white room ends; the ambient term covers what is left).
    pub max_shots: Option<u64>,
    /// Stop after this many seconds of bouncing.
    pub max_seconds: Option<f64>,
    /// About how many shooter patches to group the texels into.
    pub patches: u32,
    /// Shooters per GPU batch (at most 64).
    pub shooters_per_batch: u32,
    /// Hemicube face width in texels.
    pub hemicube_size: u32,
    /// Memory for the lists of casters each hemicube face can see
    /// (`hemicube_cull`): a face whose list would not fit draws every
    /// caster, as every face does at 0. The default is 2 MiB a shooter slot.
    pub face_list_bytes: u64,
    /// Texels whose error against a reference is recorded at every trace
    /// point (`--reference`); `None`: not measured.
    pub probes: Option<std::sync::Arc<Probes>>,
    /// Shooter slots one workgroup of the form-factor measure sums for, 8 or
    /// 64 (`None`: chosen for the adapter, `shoot::measure_slots_for`); the
    /// sums are the same either way.
    pub measure_slots: Option<u32>,
    /// Wait on the GPU after each pass of every batch and record its seconds
    /// (`--time-passes`; slower, the same result unless `max_seconds` stops
    /// the pass sooner).
    pub time_passes: bool,
}

impl Default for BounceOptions {
    fn default() -> Self {
        BounceOptions {
            tolerance: 0.005,
            max_shots: None,
            max_seconds: None,
            patches: 1024,
            shooters_per_batch: MAX_SHOOTERS,
            hemicube_size: 128,
            face_list_bytes: 128 << 20,
            probes: None,
            measure_slots: None,
            time_passes: false,
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
    /// Unshot and owed power (their magnitudes) over the power put in (luminance).
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
    /// Unshot and owed power (their magnitudes) over the power put in when it stopped.
    pub unshot_fraction: f64,
    /// Closure the ambient term used: the share of the unshot power that
    /// would land on the scene (`shot_closure` when the pass converged or
    /// had no direct pass, else from the direct pass's coverage).
    pub closure: f64,
    /// Power that landed on the scene over the power shot (luminance, summed
    /// on the GPU over every batch; when nothing was shot, `closure` if the
    /// pass converged, else 1). Not capped: above
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
    /// Seconds each GPU pass took over the run, with `--time-passes`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub passes: Option<Vec<PassSeconds>>,
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
    let weighted = shares.map(|shares| super::overlaps::counted(texels, shares));
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
    let (mut params, dispatch) = resources::params(gpu, scene, texels, patches, texels_per_unit, options);
    // Shooting ahead pays only once the run settles: stopped early, the
    // light still owed is where the ambient term, spread evenly, misses it.
    if options.max_shots.is_none() && options.max_seconds.is_none() {
        params.overshoot = overshoot_factor(&sums);
    }
    let patch_coverage = patch_coverage(texels, patches, coverage);
    // Without a direct pass, each patch's coverage is measured on its first
    // shot: a scene that catches little of its light (a lone quad under a
    // point light) neither shoots ahead nor waits on light that cannot land.
    params.measure_coverage = coverage.is_none() as u32;
    let patch_albedo = patch_albedo(texels, patches);
    let order = SubCellOrder::new(patches, texels);
    let inputs = Inputs {
        texels: gpu_texels,
        shares,
        patches,
        order: &order,
        patch_coverage: &patch_coverage,
        patch_albedo: &patch_albedo,
        unshot: &sums.unshot,
        lightmap,
    };
    // Without a direct pass (emitters only) the share is unknown: normalize.
    let normalized = sums.initial_closure.is_none_or(|f| f * luminance(sums.mean_albedo) >= NORMALIZE_FROM);
    let passes = Passes::new(gpu, scene, &inputs, params, dispatch, options, normalized);

    let max_shots = options.max_shots.unwrap_or(64 * patches.patches.len() as u64);
    let mut tally = Tally::new(start, sums.gathered);
    tally.passes = options.time_passes.then(PassTimes::default);
    let (stopped_by, last) = shoot_until_done(gpu, &passes, &sums, &mut tally, options, max_shots, progress)?;

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
    // Converged before any shot, the scene catches next to none of the light
    // (a lone quad under a point light): its coverage says how little.
    let shot_nothing = tally.shot_total <= 0.0;
    let closure = match coverage {
        Some(coverage) if !converged || shot_nothing => covered_share(texels, &remaining, coverage),
        _ => measured_closure(tally.received_total, tally.shot_total),
    };
    let ambient = ambient_term(last.unshot, closure, sums.mean_albedo, sums.total_area).map(|a| a as f32);
    let weights = ambient_weights(texels, &values, lightmap, coverage, converged);
    for ((out, v), w) in lightmap.iter_mut().zip(values).zip(weights) {
        // Shots ahead of light not yet received and their take-backs reach a
        // texel by slightly different paths (a patch's parts): one the light
        // never reached can end a hair below 0.
        *out = [0, 1, 2].map(|c| (v[c] + ambient[c] * w).max(0.0));
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
        shot_closure: match (shot_nothing, converged) {
            (false, _) => tally.received_total / tally.shot_total,
            (true, true) => closure,
            (true, false) => 1.0,
        },
        ambient,
        normalized,
        trace: tally.trace,
        passes: tally.passes.map(PassTimes::into_vec),
    })
}

/// The batch loop: select, record, stop or shoot. Returns why it stopped
/// and the totals of the last batch selected.
fn shoot_until_done(
    gpu: &Gpu,
    passes: &Passes,
    sums: &Sums,
    tally: &mut Tally,
    options: &BounceOptions,
    max_shots: u64,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<(StopReason, GpuStats)> {
    loop {
        // Sum and select on the GPU; read back only the totals.
        let select_start = Instant::now();
        let stats = passes.select(gpu)?;
        if let Some(times) = &mut tally.passes {
            times.add("select", select_start.elapsed().as_secs_f64());
        }
        let settled = tally.record(gpu, &stats, sums, &passes.resources, options.probes.as_deref())?;
        // Converged when the unshot light, each patch's weighted by how much
        // of its hemisphere the scene covers, is a `tolerance` share of the
        // light put in, weighted so: a room seen through an opening in a
        // sunlit scene, where most of the light put in leaves for the sky,
        // is shot until its own light has settled.
        if settled <= options.tolerance || stats.shooters == 0 {
            return Ok((StopReason::Converged, stats));
        }
        if tally.shots >= max_shots {
            return Ok((StopReason::MaxShots, stats));
        }
        if options.max_seconds.is_some_and(|max| tally.start.elapsed().as_secs_f64() >= max) {
            return Ok((StopReason::MaxTime, stats));
        }
        passes.shoot(gpu, tally.passes.as_mut())?;
        tally.shots += stats.shooters as u64;
        tally.shot_total += stats.shot[3] as f64;
        tally.batches += 1;
        // Progress in "orders of magnitude converged" towards the tolerance.
        let goal = (1.0 / options.tolerance.max(1e-12)).ln();
        let done = ((1.0 / settled.max(1e-300)).ln() / goal * 1000.0).clamp(0.0, 1000.0);
        progress(done as u64, 1000);
    }
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
struct Tally {
    /// When the bounce pass started.
    start: Instant,
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
    /// Each pass's seconds, with `--time-passes`.
    passes: Option<PassTimes>,
}

impl Tally {
    /// Nothing shot yet; `gathered`: Σ L_lm·A of the direct light.
    fn new(start: Instant, gathered: f64) -> Tally {
        Tally {
            start,
            shots: 0,
            batches: 0,
            trace: Vec::new(),
            shot_total: 0.0,
            received_total: 0.0,
            gathered,
            probe_seconds: 0.0,
            landing_in: None,
            passes: None,
        }
    }

    /// Adds a batch's totals and its trace point; returns how much of the
    /// light put in is still to settle (coverage-weighted).
    fn record(
        &mut self,
        gpu: &Gpu,
        stats: &GpuStats,
        sums: &Sums,
        resources: &Resources,
        probes: Option<&Probes>,
    ) -> Result<f64> {
        self.received_total += stats.received[3] as f64;
        self.gathered += stats.received[3] as f64;
        // Light owed counts as much as light unshot.
        let unshot_power = stats.unsettled as f64;
        let unshot_fraction = if sums.power_in > 0.0 { unshot_power / sums.power_in } else { 0.0 };
        let closure = sums.initial_closure.unwrap_or_else(|| measured_closure(self.received_total, self.shot_total));
        let unshot = stats.unshot.map(|u| u.max(0.0));
        let ambient = ambient_term(unshot, closure, sums.mean_albedo, sums.total_area);
        let error_estimate =
            if self.gathered > 0.0 { luminance(ambient) * sums.total_area / self.gathered } else { 0.0 };
        let seconds = self.start.elapsed().as_secs_f64() - self.probe_seconds;
        let probe_start = Instant::now();
        let reference_error = probe_error(gpu, &resources.lightmap, probes, ambient)?;
        self.probe_seconds += probe_start.elapsed().as_secs_f64();
        self.trace.push(TracePoint { seconds, shots: self.shots, unshot_fraction, error_estimate, reference_error });
        let mut landing_in = *self.landing_in.get_or_insert(stats.landing as f64);
        if sums.initial_closure.is_none() {
            // No direct pass weighed the light put in by coverage (each patch
            // measures its own on its first shot): the share of the shot
            // light that landed so far weighs it instead.
            landing_in *= measured_closure(self.received_total, self.shot_total);
        }
        Ok(match (stats.landing > 0.0, landing_in > 0.0) {
            (false, _) => 0.0,
            (true, true) => stats.landing as f64 / landing_in,
            (true, false) => f64::INFINITY,
        })
    }
}

/// The bounce pass on the GPU: the buffers its passes share, and the passes
/// in the order each batch runs them, in two submissions.
struct Passes {
    resources: Resources,
    power: PatchPower,
    select: Select,
    /// The casters each hemicube face draws (`None`: every caster).
    cull: Option<HemicubeCull>,
    hemicube: Hemicube,
    shooter_cull: ShooterCull,
    shoot: Shoot,
}

impl Passes {
    fn new(
        gpu: &Gpu,
        scene: &Scene,
        inputs: &Inputs,
        params: BounceParams,
        dispatch: Dispatch,
        options: &BounceOptions,
        normalized: bool,
    ) -> Passes {
        let resources = Resources::new(gpu, inputs, params, dispatch);
        let hemicube = Hemicube::new(gpu, scene, &resources);
        let (texels, order) = (&inputs.texels.texels, &inputs.order.members);
        let shooter_cull =
            ShooterCull::new(gpu, texels, order, &inputs.patches.texel_patch, params, &resources.shooters);
        let (casters, faces) = (&hemicube.casters, &resources.hemicube_faces);
        let lists = options.face_list_bytes;
        let cull = HemicubeCull::new(gpu, casters, faces, 5 * dispatch.shooter_count, params.near, lists);
        Passes {
            power: PatchPower::new(gpu, &resources, inputs.order),
            select: Select::new(gpu, &resources, inputs),
            shoot: Shoot::new(gpu, &resources, inputs, &shooter_cull, normalized, options.measure_slots),
            cull,
            hemicube,
            shooter_cull,
            resources,
        }
    }

    /// Sums every patch's unshot power, chooses the batch's shooters and
    /// their light by sub-cells, and reads back the totals.
    fn select(&self, gpu: &Gpu) -> Result<GpuStats> {
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            self.power.record_power(&mut pass);
            self.select.record(&mut pass);
            self.power.record_shooter_cells(&mut pass);
        }
        gpu.queue.submit([encoder.finish()]);
        self.select.stats(gpu)
    }

    /// Renders the chosen shooters' hemicubes and gathers their light at
    /// every texel: the far field everywhere, then the near field where
    /// `main` listed it; in one submission, or each pass timed (`times`).
    fn shoot(&self, gpu: &Gpu, times: Option<&mut PassTimes>) -> Result<()> {
        let cull = |encoder: &mut wgpu::CommandEncoder| {
            self.shoot.clear_near_list(encoder);
            // What each hemicube face of the batch draws (None: every caster).
            if let Some(cull) = &self.cull {
                cull.record(encoder);
            }
        };
        let render = |encoder: &mut wgpu::CommandEncoder| {
            self.hemicube.render(encoder, &self.resources, self.cull.as_ref());
        };
        let shooter_cull = |encoder: &mut wgpu::CommandEncoder| {
            self.shooter_cull.record(&mut encoder.begin_compute_pass(&Default::default()));
        };
        let measure = |encoder: &mut wgpu::CommandEncoder| self.shoot.record_measure(encoder);
        let far_field = |encoder: &mut wgpu::CommandEncoder| self.shoot.record_far_field(encoder);
        let near_field = |encoder: &mut wgpu::CommandEncoder| self.shoot.record_near_field(encoder);
        let passes: [pass_times::Recorder; 6] = [
            ("hemicube cull", &cull),
            ("hemicube render", &render),
            ("shooter cull", &shooter_cull),
            ("form-factor measure", &measure),
            ("far field", &far_field),
            ("near field", &near_field),
        ];
        pass_times::submit(gpu, &passes, times)
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
        // Light owed (shot ahead) weighs as much as light unshot.
        let power = luminance([u[0] as f64, u[1] as f64, u[2] as f64]).abs() * t.area as f64;
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
    per_patch(patches, 0.0, |members| {
        let (mut covered, mut area) = (0.0f64, 0.0f64);
        for &i in members {
            let a = texels.texels[i as usize].area as f64;
            covered += coverage[i as usize] as f64 * a;
            area += a;
        }
        if area > 0.0 { (covered / area) as f32 } else { 0.0 }
    })
}

/// Each patch's Σ albedo·A over its texels (rgb; w 0).
fn patch_albedo(texels: &TexelSet, patches: &Patches) -> Vec<[f32; 4]> {
    per_patch(patches, [0.0; 4], |members| {
        let mut sum = [0.0f64; 3];
        for &i in members {
            let t = &texels.texels[i as usize];
            for (s, a) in sum.iter_mut().zip(t.albedo) {
                *s += a as f64 * t.area as f64;
            }
        }
        [sum[0] as f32, sum[1] as f32, sum[2] as f32, 0.0]
    })
}

/// `value` of each patch's member texels, in patch order; one `empty` where
/// there are no patches, as a buffer is never empty.
fn per_patch<T: Clone>(patches: &Patches, empty: T, value: impl Fn(&[u32]) -> T) -> Vec<T> {
    let mut values: Vec<T> = patches
        .patches
        .iter()
        .map(|p| value(&patches.members[p.first as usize..(p.first + p.count) as usize]))
        .collect();
    values.resize(values.len().max(1), empty);
    values
}

/// The light (L_lm) a surface the scene covers whole will still receive,
/// per unit of unshot power: the ambient term's factor with the closure
/// the direct pass measured (1 without one).
fn overshoot_factor(sums: &Sums) -> [f32; 4] {
    let closure = sums.initial_closure.unwrap_or(1.0);
    let [r, g, b] = [0, 1, 2].map(|c| {
        let reflect = (sums.mean_albedo[c] * closure).min(0.999);
        (1.0 / (sums.total_area.max(1e-30) * (1.0 - reflect))) as f32
    });
    [r, g, b, 0.0]
}

/// The share of shot power that landed on the scene so far (1 before any
/// shot: a closed room is the cautious guess).
fn measured_closure(received: f64, shot: f64) -> f64 {
    if shot > 0.0 { (received / shot).min(1.0) } else { 1.0 }
}

/// The light still unshot, spread evenly over the scene as incident
/// radiance (L_lm): U·f / (A (1 − ρ̄ f)) per channel, where f is the share of
/// shot light the scene catches (1 in a closed room, Cohen et al.'s case).
/// Where more light is owed than unshot (shot ahead, never received), U is
/// negative and so is the term: the light delivered ahead is taken back.
fn ambient_term(unshot: [f32; 4], closure: f64, albedo: [f64; 3], area: f64) -> [f64; 3] {
    if area <= 0.0 {
        return [0.0; 3];
    }
    [0, 1, 2].map(|c| {
        let reflect = (albedo[c] * closure).min(0.999);
        unshot[c] as f64 * closure / (area * (1.0 - reflect))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::patches::Patch;
    use crate::texelize::Texel;

    /// Texels of the given areas (their other fields do not matter here).
    fn texels(areas: &[f32]) -> TexelSet {
        let texels = areas.iter().map(|&area| Texel { area, ..Default::default() }).collect();
        TexelSet { width: areas.len() as u32, height: 1, texels, tint: Vec::new() }
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-9 * b.abs().max(1e-30)
    }

    #[test]
    fn the_ambient_term_is_every_later_bounce_of_the_unshot_light_summed() {
        // Unshot power U lands with probability f, is reflected with ρ, lands
        // again with f...: the scene receives U f Σ (ρ f)^k over its area.
        let series =
            |u: f64, f: f64, rho: f64, area: f64| (0..2000).map(|k| u * f * (rho * f).powi(k)).sum::<f64>() / area;
        for (f, albedo) in [(1.0, [0.5, 0.25, 0.8]), (0.3, [0.9, 0.0, 0.6]), (0.75, [0.1, 0.1, 0.1])] {
            let got = ambient_term([2.0, 3.0, 0.5, 0.0], f, albedo, 4.0);
            for (c, u) in [2.0, 3.0, 0.5].into_iter().enumerate() {
                assert!(close(got[c], series(u, f, albedo[c], 4.0)), "f {f}, channel {c}: {got:?}");
            }
        }
        // A closed white furnace never converges: the reflectance is held
        // under 1 so the term stays finite.
        let furnace = ambient_term([1.0, 1.0, 1.0, 0.0], 1.0, [1.0; 3], 2.0);
        assert!(furnace.iter().all(|&v| v.is_finite() && v > 0.0), "{furnace:?}");
        // Nothing lands in an open scene, on no area, or from negative power.
        assert_eq!(ambient_term([1.0; 4], 0.0, [0.5; 3], 1.0), [0.0; 3]);
        assert_eq!(ambient_term([1.0; 4], 1.0, [0.5; 3], 0.0), [0.0; 3]);
        // Light owed is taken back: −1 owed in a closed room of ρ 0.5, area 1.
        assert_eq!(ambient_term([-1.0, 0.0, 0.0, 0.0], 1.0, [0.5; 3], 1.0), [-2.0, 0.0, 0.0]);
    }

    #[test]
    fn the_closure_is_the_share_of_shot_light_that_landed_and_a_closed_room_before_any_shot() {
        assert_eq!(measured_closure(3.0, 4.0), 0.75);
        // Rounding can land a hair more than was shot.
        assert_eq!(measured_closure(4.0 + 1e-9, 4.0), 1.0);
        assert_eq!(measured_closure(0.0, 0.0), 1.0);
    }

    #[test]
    fn weights_have_an_area_weighted_mean_of_one() {
        let set = texels(&[1.0, 3.0]);
        // Mean (2·1 + 4·3) / 4 = 3.5.
        let w = mean_one_weights(&set, &[2.0, 4.0]);
        let f32_close = |a: f32, b: f64| (a as f64 - b).abs() < 1e-6;
        assert!(f32_close(w[0], 4.0 / 7.0) && f32_close(w[1], 8.0 / 7.0), "{w:?}");
        assert_eq!(mean_one_weights(&set, &[0.0, 0.0]), [0.0, 0.0]);
    }

    #[test]
    fn the_ambient_term_goes_where_bounced_light_went_or_where_the_scene_covers_the_sky() {
        let set = texels(&[1.0, 1.0]);
        // The first texel got 0.5 more than its direct light, the second none.
        let after = [[1.5, 1.5, 1.5, 0.0], [1.0, 1.0, 1.0, 0.0]];
        let direct = [[1.0; 3], [1.0; 3]];
        let coverage = [0.25, 0.75];
        assert_eq!(ambient_weights(&set, &after, &direct, Some(&coverage), true), [2.0, 0.0]);
        assert_eq!(ambient_weights(&set, &after, &direct, Some(&coverage), false), [0.5, 1.5]);
        assert_eq!(ambient_weights(&set, &after, &direct, None, false), [1.0, 1.0]);
    }

    #[test]
    fn bounced_luminance_is_the_light_above_the_direct_light() {
        // Red and blue rose by 1, green fell (a later fix-up): Rec. 709 weights of red and blue.
        let got = bounced_luminance([2.0, 2.0, 2.0, 0.0], [1.0, 3.0, 1.0]) as f64;
        assert!((got - (0.2126 + 0.0722)).abs() < 1e-7, "{got}");
    }

    #[test]
    fn the_light_shot_ahead_per_unit_unshot_power_is_the_ambient_term_s_factor() {
        // A closed room (no direct pass: closure 1) of area 4 and albedo 0.5
        // will still receive, per unit of unshot power, 1/(4 (1 − 0.5)).
        let mut set = texels(&[1.0, 3.0]);
        for t in &mut set.texels {
            t.albedo = [0.5, 0.5, 0.25];
        }
        let sums = Sums::new(&set, &[[1.0; 3]; 2], None);
        let factor = overshoot_factor(&sums);
        for (got, expected) in factor.iter().zip([0.5, 0.5, 1.0 / 3.0]) {
            assert!((got - expected).abs() < 1e-6, "{factor:?}");
        }
    }

    #[test]
    fn covered_shares_weigh_texels_by_their_unshot_power() {
        let set = texels(&[1.0, 1.0]);
        // Luminance 1 on a covered texel and 3 on an open one: a quarter lands.
        let unshot = [[1.0, 1.0, 1.0, 0.0], [3.0, 3.0, 3.0, 0.0]];
        assert!(close(covered_share(&set, &unshot, &[1.0, 0.0]), 0.25));
        assert_eq!(covered_share(&set, &[[0.0; 4]; 2], &[1.0, 0.0]), 0.0);
    }

    #[test]
    fn a_patch_covers_the_area_weighted_mean_of_its_texels() {
        let set = texels(&[1.0, 3.0, 2.0]);
        let patches = Patches {
            patches: vec![
                Patch { first: 0, count: 2, ..Default::default() },
                Patch { first: 2, count: 1, ..Default::default() },
            ],
            members: vec![0, 1, 2],
            texel_patch: vec![0, 0, 1],
            cell: 1,
        };
        let got = patch_coverage(&set, &patches, Some(&[1.0, 0.0, 0.5]));
        assert_eq!(got, [0.25, 0.5]);
        assert_eq!(patch_coverage(&set, &patches, None), [1.0, 1.0]);
    }
}
