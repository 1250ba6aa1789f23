//! Direct environment light (design notes, algorithm step 3): every point
//! (texel, or sub-sample of the supersample fix-up) gathers
//! ΔE = L_k Ω_k max(0, n·ω_k) V_k(p) from each distant light k, with V_k
//! the share of rays within the light's cone that leave the point's face and
//! meet nothing (`solve_direct.wgsl`).
//!
//! Most texel·light pairs cannot be shadowed: the occluder pass
//! (`occluders`) sums up what above each point's face could block its light,
//! and only lights whose cone reaches it get rays, traced through the
//! scene's hierarchy on the GPU (`trace`). Rays are spread over a light's
//! cone, turned per point, so a penumbra is soft and unbiased, and a wide or
//! bright light gets more of them (`RayBudget`, `ray_count`). With twice as
//! many lights as the budget's rays, small neighbouring ones share their
//! rays (`light_clusters`).
//!
//! A CPU driver stops a shader's loops after 65,535 turns in all; the
//! points where that cut a batch short add nothing, and the batch is
//! gathered again in halves at them alone.

use std::time::Instant;

use anyhow::{Result, bail};
use bytemuck::{Pod, Zeroable};
use serde::{Deserialize, Serialize};

use super::light_clusters;
use super::occluders::OccluderPass;
use crate::colour::luminance;
use crate::environment::{Light, LightSet};
use crate::gpu::{self, Gpu, Shader, read_buffer};
use crate::scene::Scene;
use crate::texelize::{Texel, TexelSet};
use crate::trace::GpuScene;

/// Lights one batch holds (the uniform array in solve_direct.wgsl). Large:
/// a lane's loops turn as often as the busiest lane's of its group, batch
/// by batch, so fewer batches turn fewer times in all.
pub const MAX_BATCH: u32 = 1024;
/// Rays a point may cast in all where every light may be blocked, unless
/// `--direct-rays` says otherwise (`RayBudget`).
pub const DEFAULT_RAYS: u32 = 1024;
/// Most rays one light gets at one point (the first few of them spread over
/// its cone; the rest where those disagree, solve_direct.wgsl).
const MAX_RAYS: u32 = 64;

/// A texel counts as shadowed when more than this share of the light in
/// front of it is blocked. Below it, the rays that graze a curved surface's
/// neighbouring facets are what is counted, not another surface; a bounce
/// pass skipped for want of such texels leaves out less than this share of
/// the light times the albedo.
pub const SHADOWED_SHARE: f32 = 0.005;

/// Status bit the pass reports (`status[0]` in solve_direct.wgsl).
const WALK_CUT: u32 = 2;

/// What the direct pass did, for the report.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct DirectStats {
    pub lights: usize,
    pub batches: usize,
    /// Texel-light pairs evaluated (sub-samples of the supersample fix-up included).
    pub evaluations: u64,
    /// Rays cast through the scene (pairs no blocker could reach need none;
    /// 0 in reports before version 6).
    #[serde(default)]
    pub rays: u64,
    /// Texels that some light in front of them does not reach (geometry in the way).
    pub shadowed_texels: u64,
    pub seconds: f64,
    /// Power the pass delivered to the texels, Σ E·A, RGB (irradiance × m²;
    /// W when the environment is in W/(m²·sr)). The report's energy balance
    /// separates direct from bounced light with it.
    pub power_received: [f64; 3],
}

/// Mirrors `DirectParams` in solve_direct.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct DirectParams {
    point_count: u32,
    row_stride: u32,
    light_count: u32,
    first_light: u32,
    _pad3: f32,
    listed: u32,
    _pad: [u32; 2],
}

/// What the direct pass found, per texel in `TexelSet` order.
pub struct Direct {
    /// Irradiance E (rgb).
    pub irradiance: Vec<[f32; 3]>,
    /// Share of the texel's hemisphere (cosine-weighted) that scene geometry
    /// covers, as seen along the light directions: where its reflected light goes.
    pub coverage: Vec<f32>,
    /// Luminance of the irradiance other surfaces block: where it bends, a
    /// shadow's edge crosses the texel (`supersample`).
    pub shadowed: Vec<f32>,
    pub stats: DirectStats,
}

/// Builds the pass's pipelines ahead (`solve::warm`) for the common case:
/// a scene without cut-outs and a light set without clusters.
pub(super) fn warm(gpu: &Gpu) {
    let scene_layout = GpuScene::bind_group_layout(gpu);
    OccluderPass::new(gpu, &scene_layout);
    GatherPipeline::new(gpu, &scene_layout, 0.0);
}

/// The gather: its pipelines and its own bind group's layout (group 0; the
/// scene is group 1). The pipeline for lights in clusters is built when a
/// light set first needs it.
struct GatherPipeline {
    pipeline: wgpu::ComputePipeline,
    clustered: std::cell::OnceCell<wgpu::ComputePipeline>,
    layout: wgpu::BindGroupLayout,
    scene_layout: wgpu::BindGroupLayout,
    cut_outs: f64,
}

impl GatherPipeline {
    /// `cut_outs`: 1.0 when the scene has cut-out triangles (the alpha
    /// test is compiled in), else 0.0.
    fn new(gpu: &Gpu, scene_layout: &wgpu::BindGroupLayout, cut_outs: f64) -> GatherPipeline {
        let compute = wgpu::ShaderStages::COMPUTE;
        let layout = gpu.bind_group_layout(
            "solve_direct",
            &[
                // 0: DirectParams
                gpu::uniform_entry(0, compute),
                // 1: the batch's lights, two records each
                gpu::uniform_entry(1, compute),
                // 2: the points (texels, then sub-samples)
                gpu::storage_entry(2, true, compute),
                // 3: their occluders (solve_occluders)
                gpu::storage_entry(3, true, compute),
                // 4: irradiance and coverage, added to in place
                gpu::storage_entry(4, false, compute),
                // 5: the points to gather, when listed
                gpu::storage_entry(5, true, compute),
                // 6: status bits, the count of rays cast and of points cut short
                gpu::storage_entry(6, false, compute),
                // 7: the points cut short
                gpu::storage_entry(7, false, compute),
            ],
        );
        let pipeline = Self::pipeline(gpu, &layout, scene_layout, cut_outs, false);
        let scene_layout = scene_layout.clone();
        GatherPipeline { pipeline, clustered: Default::default(), layout, scene_layout, cut_outs }
    }

    fn pipeline(
        gpu: &Gpu,
        layout: &wgpu::BindGroupLayout,
        scene_layout: &wgpu::BindGroupLayout,
        cut_outs: f64,
        clustered: bool,
    ) -> wgpu::ComputePipeline {
        let constants = [("CUT_OUTS", cut_outs), ("CLUSTERS", f64::from(u8::from(clustered)))];
        gpu.compute_pipeline_with(Shader::SolveDirect, "main", &[layout, scene_layout], &constants)
    }

    /// The pipeline for a light set with (`clustered`) or without clusters.
    fn for_lights(&self, gpu: &Gpu, clustered: bool) -> &wgpu::ComputePipeline {
        if !clustered {
            return &self.pipeline;
        }
        self.clustered.get_or_init(|| Self::pipeline(gpu, &self.layout, &self.scene_layout, self.cut_outs, true))
    }
}

/// Everything one gather's batches bind.
struct Batches<'a> {
    gpu: &'a Gpu,
    pass: &'a GatherPipeline,
    /// The pass's pipeline for this light set.
    pipeline: &'a wgpu::ComputePipeline,
    scene: &'a wgpu::BindGroup,
    points: wgpu::Buffer,
    occluders: wgpu::Buffer,
    /// Irradiance and coverage, two records a point.
    sums: wgpu::Buffer,
    status: wgpu::Buffer,
    /// Bound as the point list where every point is gathered.
    no_list: wgpu::Buffer,
    /// Where a pass lists the points it cut short (room for every point;
    /// each retry reads a sorted copy, so one buffer serves them all).
    cut: wgpu::Buffer,
    point_count: u32,
    rays: u64,
    /// Nodes and triangles the rays' walks visited (a benchmark's figure).
    visits: u64,
    budget: RayBudget,
}

impl Batches<'_> {
    /// Gathers `lights` (at most `MAX_BATCH`, the first being light
    /// `first_light` of the set; `starts`: which start a cluster) into the
    /// sums at every point, or at the `listed` ones (a buffer of indices,
    /// and how many); returns the points a loop limit cut short, which added
    /// nothing, when there are any.
    fn batch(
        &mut self,
        (lights, starts): (&[Light], &[bool]),
        first_light: u32,
        listed: Option<&PointList>,
    ) -> Result<Option<PointList>> {
        let gpu = self.gpu;
        let count = listed.map_or(self.point_count, |l| l.count);
        let (groups_x, groups_y) = gpu.dispatch_size(count, 64);
        let params = DirectParams {
            point_count: count,
            row_stride: groups_x * 64,
            light_count: lights.len() as u32,
            first_light,
            _pad3: 0.0,
            listed: listed.is_some() as u32,
            _pad: [0; 2],
        };
        let params = gpu.uniform_buffer("solve_direct params", &params);
        let records = light_records(lights, starts, &self.budget);
        let lights_buffer = gpu.uniform_buffer("solve_direct lights", &records);
        let list = listed.map_or(&self.no_list, |l| &l.buffer);
        let buffers =
            [&params, &lights_buffer, &self.points, &self.occluders, &self.sums, list, &self.status, &self.cut];
        let group = gpu::bind_buffers(gpu, "solve_direct", &self.pass.layout, &buffers);
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        encoder.clear_buffer(&self.status, 0, None);
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(self.pipeline);
            pass.set_bind_group(0, &group, &[]);
            pass.set_bind_group(1, self.scene, &[]);
            pass.dispatch_workgroups(groups_x, groups_y, 1);
        }
        gpu.queue.submit([encoder.finish()]);
        let [flags, rays, visits, cut_count]: [u32; 4] =
            read_buffer(gpu, &self.status, 4)?.try_into().expect("four status words");
        if flags & WALK_CUT != 0 {
            bail!("a ray's walk through the scene's hierarchy ran past its limit: the hierarchy is degenerate");
        }
        self.rays += rays as u64;
        self.visits += visits as u64;
        if cut_count == 0 {
            return Ok(None);
        }
        // In index order, whatever order the lanes listed them in: a lane's
        // loops turn with its group's, so which points share a group must
        // not vary from run to run.
        let mut cut_points: Vec<u32> = read_buffer(gpu, &self.cut, cut_count as usize)?;
        cut_points.sort_unstable();
        let buffer = gpu.storage_buffer("solve_direct cut points", &cut_points, wgpu::BufferUsages::empty());
        Ok(Some(PointList { buffer, count: cut_count }))
    }

    /// Gathers `lights` at every point or the `listed` ones, again in halves
    /// at the points a loop limit cuts short; returns the passes it took.
    fn lights(
        &mut self,
        (lights, starts): (&[Light], &[bool]),
        first_light: u32,
        listed: Option<&PointList>,
    ) -> Result<usize> {
        let Some(cut) = self.batch((lights, starts), first_light, listed)? else {
            return Ok(1);
        };
        if lights.len() == 1 {
            bail!("the GPU driver's loop limit cut the direct pass short at a single light");
        }
        let half = lights.len() / 2;
        let (a, b) = (lights.split_at(half), starts.split_at(half));
        Ok(1 + self.lights((a.0, b.0), first_light, Some(&cut))?
            + self.lights((a.1, b.1), first_light + half as u32, Some(&cut))?)
    }
}

/// Points of a gather listed by index (those a batch cut short).
struct PointList {
    buffer: wgpu::Buffer,
    count: u32,
}

/// Three records per light: its direction and the cosine of its cone's
/// half-angle (the cone of its solid angle); L·Ω (rgb) and Ω; the sine of
/// the half-angle, the rays it gets where something may block it, at every
/// 32nd light the bits of its word's lights that start a cluster, and its
/// cluster's size and rays (`light_clusters`: a cluster runs from a light
/// that `starts` one to the next).
pub fn light_records(lights: &[Light], starts: &[bool], budget: &RayBudget) -> [[f32; 4]; 3 * MAX_BATCH as usize] {
    let mut records = [[0.0; 4]; 3 * MAX_BATCH as usize];
    let wanted = budget.wanted(lights);
    let members = light_clusters::memberships(starts, &wanted, |k| ray_count(wanted[k]));
    for (((slot, light), member), wanted) in records.chunks_exact_mut(3).zip(lights).zip(&members).zip(wanted) {
        let omega = light.solid_angle;
        // 1 − cos α = Ω/2π; sin α from it in f64, exact for a sun's tiny cone.
        let versine = (omega as f64 / std::f64::consts::TAU).min(2.0);
        let cos_alpha = (1.0 - versine) as f32;
        let sin_alpha = (versine * (2.0 - versine)).sqrt() as f32;
        let [x, y, z] = light.direction;
        let power = light.radiance.map(|c| c * omega);
        slot[0] = [x, y, z, cos_alpha];
        slot[1] = [power[0], power[1], power[2], omega];
        let rays = ray_count(wanted);
        let cluster = member.size | member.rays.min(MAX_RAYS) << 16;
        slot[2] = [sin_alpha, f32::from_bits(rays), 0.0, f32::from_bits(cluster)];
    }
    // Which lights of each word start a cluster, at the word's first light.
    for (word, members) in members.chunks(32).enumerate() {
        let starts = members.iter().enumerate().filter(|(_, m)| m.offset == 0).fold(0u32, |s, (k, _)| s | 1 << k);
        records[3 * 32 * word + 2][2] = f32::from_bits(starts);
    }
    records
}

/// How a point's rays are shared out among a light set's lights where
/// something may block them: `rays` in all, a light getting at least one,
/// and more as it is wide (one per 1/`rays` of the sphere) or bright (one
/// per 1/`rays` of the set's power), so that what a point's rays miss of a
/// penumbra is spread evenly over the light.
#[derive(Clone, Copy, Debug)]
pub struct RayBudget {
    rays: f32,
    /// Luminance of L·Ω that earns a light one ray.
    power_per_ray: f32,
}

impl RayBudget {
    pub fn new(lights: &LightSet, rays: u32) -> RayBudget {
        let rays = rays.max(1) as f32;
        let total: f64 = lights.lights.iter().map(power).sum();
        RayBudget { rays, power_per_ray: (total / rays as f64).max(f64::MIN_POSITIVE) as f32 }
    }

    /// The rays each light earns, before rounding up: one per 1/`rays` of
    /// the sphere or of the power, whichever is more.
    fn wanted(&self, lights: &[Light]) -> Vec<f32> {
        let sphere = |omega: f32| omega * self.rays / (4.0 * std::f32::consts::PI);
        lights.iter().map(|l| sphere(l.solid_angle).max(power(l) as f32 / self.power_per_ray)).collect()
    }
}

/// A light's power, luminance of L·Ω.
fn power(light: &Light) -> f64 {
    luminance(light.radiance.map(|c| c * light.solid_angle))
}

/// Rays a light that earns `wanted` gets where something may block it, alone.
fn ray_count(wanted: f32) -> u32 {
    let wanted = wanted.ceil();
    if wanted.is_finite() { (wanted as u32).clamp(1, MAX_RAYS) } else { MAX_RAYS }
}

/// The direct pass, set up once for a scene: the scene laid out for rays,
/// and the occluder and gather pipelines.
pub struct DirectPass<'a> {
    gpu: &'a Gpu,
    /// The scene as rays see it, held for its bind group.
    _scene: GpuScene,
    scene_group: wgpu::BindGroup,
    occluders: OccluderPass,
    gather: GatherPipeline,
}

impl<'a> DirectPass<'a> {
    pub fn new(gpu: &'a Gpu, scene: &Scene) -> Result<DirectPass<'a>> {
        let gpu_scene = GpuScene::new(gpu, scene)?;
        let scene_layout = GpuScene::bind_group_layout(gpu);
        let scene_group = gpu_scene.bind_group(gpu, &scene_layout);
        let occluders = OccluderPass::new(gpu, &scene_layout);
        let gather = GatherPipeline::new(gpu, &scene_layout, gpu_scene.cut_out_constant());
        Ok(DirectPass { gpu, _scene: gpu_scene, scene_group, occluders, gather })
    }

    /// Gathers the environment's light at `points` (texels, or sub-samples
    /// of them), in batches of at most `options.batch_size` lights, on a
    /// budget of `options.direct_rays` rays a point.
    pub fn gather(
        &self,
        points: &[Texel],
        lights: &LightSet,
        options: &super::SolveOptions,
        progress: &mut dyn FnMut(u64, u64),
    ) -> Result<Gathered> {
        let start = Instant::now();
        let gpu = self.gpu;
        let point_count = points.len();
        let point_buffer = gpu.storage_buffer("solve_direct points", points, wgpu::BufferUsages::empty());
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        let occluder_buffer =
            self.occluders.record(gpu, &mut encoder, &self.scene_group, &point_buffer, point_count as u32);
        gpu.queue.submit([encoder.finish()]);
        let budget = RayBudget::new(lights, options.direct_rays);
        let clustered = light_clusters::clustered(lights.lights.len(), budget.rays);
        let mut batches = Batches {
            gpu,
            pass: &self.gather,
            pipeline: self.gather.for_lights(gpu, clustered),
            scene: &self.scene_group,
            points: point_buffer,
            occluders: occluder_buffer,
            sums: gpu.zeroed_storage_buffer::<[f32; 4]>(
                "solve_direct sums",
                2 * point_count,
                wgpu::BufferUsages::COPY_SRC,
            ),
            status: gpu.zeroed_storage_buffer::<u32>(
                "solve_direct status",
                4,
                wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            ),
            no_list: gpu.zeroed_storage_buffer::<u32>("solve_direct no list", 1, wgpu::BufferUsages::empty()),
            cut: gpu.zeroed_storage_buffer::<u32>("solve_direct cut points", point_count, wgpu::BufferUsages::COPY_SRC),
            point_count: point_count as u32,
            rays: 0,
            visits: 0,
            budget,
        };
        let wanted = budget.wanted(&lights.lights);
        let (ordered, starts) = light_clusters::order(&lights.lights, &wanted, clustered);
        let batch = options.batch_size.clamp(1, MAX_BATCH) as usize;
        let total = lights.lights.len() as u64;
        let mut count = 0;
        for (index, chunk) in ordered.chunks(batch).zip(starts.chunks(batch)).enumerate() {
            count += batches.lights(chunk, (index * batch) as u32, None)?;
            progress((index * batch + chunk.0.len()) as u64, total);
        }
        let sums: Vec<[f32; 4]> = read_buffer(gpu, &batches.sums, 2 * point_count)?;
        gpu.check("solve (direct)")?;
        Ok(Gathered {
            irradiance: sums.chunks_exact(2).map(|s| [s[0][0], s[0][1], s[0][2]]).collect(),
            covered: sums.chunks_exact(2).map(|s| [s[1][0], s[1][1]]).collect(),
            shadowed: sums.chunks_exact(2).map(|s| s[1][2]).collect(),
            batches: count,
            rays: batches.rays,
            visits: batches.visits,
            seconds: start.elapsed().as_secs_f64(),
        })
    }
}

/// What one gather found at its points.
pub struct Gathered {
    /// Irradiance E (rgb).
    pub irradiance: Vec<[f32; 3]>,
    /// Ω cos θ over the lights in front of the face: blocked, and in all.
    pub covered: Vec<[f32; 2]>,
    /// Luminance of the irradiance other surfaces block.
    pub shadowed: Vec<f32>,
    pub batches: usize,
    pub rays: u64,
    /// Nodes and triangles the rays' walks visited (read by the benchmarks only).
    #[cfg_attr(not(feature = "internals"), allow(dead_code))]
    pub visits: u64,
    pub seconds: f64,
}

impl Gathered {
    /// The direct pass's result for `texels`, the points this gathered at.
    pub fn into_direct(self, texels: &TexelSet, lights: &LightSet) -> Direct {
        let stats = DirectStats {
            lights: lights.lights.len(),
            batches: self.batches,
            evaluations: lights.lights.len() as u64 * texels.texels.len() as u64,
            rays: self.rays,
            shadowed_texels: self.covered.iter().filter(|c| c[0] > SHADOWED_SHARE * c[1]).count() as u64,
            seconds: self.seconds,
            power_received: power_received(texels, &self.irradiance),
        };
        Direct {
            stats,
            coverage: self.covered.iter().map(|c| if c[1] > 0.0 { c[0] / c[1] } else { 0.0 }).collect(),
            irradiance: self.irradiance,
            shadowed: self.shadowed,
        }
    }
}

/// Gathers the environment's light at every texel (no sub-samples).
#[cfg(feature = "internals")]
pub fn run(
    gpu: &Gpu,
    scene: &Scene,
    texels: &TexelSet,
    lights: &LightSet,
    options: &super::SolveOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Direct> {
    let pass = DirectPass::new(gpu, scene)?;
    let gathered = pass.gather(&texels.texels, lights, options, progress)?;
    Ok(gathered.into_direct(texels, lights))
}

/// Σ E·A over the texels, RGB: the power `irradiance` delivers.
pub(super) fn power_received(texels: &TexelSet, irradiance: &[[f32; 3]]) -> [f64; 3] {
    texels.texels.iter().zip(irradiance).fold([0.0; 3], |mut sum, (t, e)| {
        for (s, e) in sum.iter_mut().zip(e) {
            *s += *e as f64 * t.area as f64;
        }
        sum
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_params_mirror_the_shader() {
        use crate::gpu::{Shader, mirror::assert_mirrors};
        assert_mirrors!(
            Shader::SolveDirect,
            "DirectParams",
            DirectParams { point_count, row_stride, light_count, first_light, listed }
        );
    }

    /// `gpu::built`: a pass asking again for its pipeline (another scene of
    /// the run) gets the one built before, and one with other constants
    /// (cut-outs, clusters) gets its own.
    #[test]
    fn a_pipeline_is_built_once_per_device_and_constants() {
        let gpu = Gpu::new(None).expect("an adapter");
        let pipeline = |cut_outs, clustered| {
            let gather = GatherPipeline::new(&gpu, &GpuScene::bind_group_layout(&gpu), cut_outs);
            gather.for_lights(&gpu, clustered).clone()
        };
        let constants = [(0.0, false), (1.0, false), (0.0, true), (1.0, true)];
        let first: Vec<_> = constants.iter().map(|&(cut_outs, clustered)| pipeline(cut_outs, clustered)).collect();
        for (i, &(cut_outs, clustered)) in constants.iter().enumerate() {
            assert!(pipeline(cut_outs, clustered) == first[i], "{:?} built again", constants[i]);
            assert!(first[..i].iter().all(|p| *p != first[i]), "{:?} shares another's pipeline", constants[i]);
        }
    }
}
