//! The direct pass against its bare-kernel ceiling (`--only ceiling`): the
//! same points and lights through kernels that do only the pass's two kinds
//! of work (ceiling.wgsl). The light loop: every texel·light pair's cosine
//! and power, nothing else. The rays: trace.wgsl's walk through the same
//! hierarchy, one ray per lane and turn, towards the scene's lights, every
//! lane walking. The ceiling is the light loop's time plus the pass's own
//! walks (nodes and triangles visited) at the bare rays' rate per visit:
//! what the pass would take if sorting the lights, choosing where to cast,
//! lanes waiting for each other's walks and counting what the rays found
//! cost nothing. (Per visit, not per ray: the pass casts where blockers
//! are, so its walks are longer than those of rays towards any light.)

use std::time::Instant;

use anyhow::Result;
use bake::environment::{Light, LightSet};
use bake::gpu::{Gpu, read_buffer};
use bake::solve::SolveOptions;
use bake::solve::direct::{DEFAULT_RAYS, DirectPass, MAX_BATCH, RayBudget, light_records};
use bake::{Scene, Texel};

/// Lights per dispatch, as the direct pass's largest batches.
const BATCH: usize = MAX_BATCH as usize;
/// Rays per point and dispatch: well under the CPU driver's 65,535 loop turns per invocation.
const RAYS_PER_DISPATCH: u32 = 16;

/// One cell's figures, seconds and counts.
pub struct Ceiling {
    pub points: usize,
    pub lights: usize,
    pub rays: u64,
    /// Nodes and triangles the pass's walks visited.
    pub visits: u64,
    pub direct: f64,
    pub light_loop: f64,
    /// Bare rays cast, what their walks visited, and their seconds.
    pub bare_rays: u64,
    pub bare_visits: u64,
    pub bare_ray_seconds: f64,
}

impl Ceiling {
    pub fn pairs(&self) -> f64 {
        self.points as f64 * self.lights as f64
    }
    /// Nodes and triangles a second the bare rays visited.
    pub fn visit_rate(&self) -> f64 {
        self.bare_visits as f64 / self.bare_ray_seconds.max(1e-9)
    }
    /// The light loop, plus the pass's walks at the bare rate.
    pub fn seconds(&self) -> f64 {
        self.light_loop + self.visits as f64 / self.visit_rate()
    }
}

/// Mirrors `BareParams` in ceiling.wgsl.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct BareParams {
    point_count: u32,
    row_stride: u32,
    light_count: u32,
    first_ray: u32,
    rays: u32,
    _pad: [u32; 3],
}

/// Times the real direct pass at `points`, then both bare kernels.
pub fn measure(gpu: &Gpu, scene: &Scene, points: &[Texel], lights: &LightSet) -> Result<Ceiling> {
    let pass = DirectPass::new(gpu, scene)?;
    let options = SolveOptions { batch_size: MAX_BATCH, direct_rays: DEFAULT_RAYS, ..Default::default() };
    let gathered = pass.gather(points, lights, &options, &mut |_, _| {})?;
    let kernels = Kernels::new(gpu, scene, points, RayBudget::new(lights, DEFAULT_RAYS))?;
    let light_loop = lights.lights.chunks(BATCH).map(|batch| kernels.light_loop(batch)).sum::<Result<f64>>()?;
    // As many rays a point as the pass cast on average.
    let per_point = (gathered.rays as f64 / points.len().max(1) as f64).round().max(1.0) as u32;
    let (bare_rays, bare_visits, bare_ray_seconds) =
        kernels.shadow_rays(&lights.lights[..lights.lights.len().min(BATCH)], per_point)?;
    gpu.check("the bare kernels")?;
    Ok(Ceiling {
        points: points.len(),
        lights: lights.lights.len(),
        rays: gathered.rays,
        visits: gathered.visits,
        direct: gathered.seconds,
        light_loop,
        bare_rays,
        bare_visits,
        bare_ray_seconds,
    })
}

struct Kernels<'a> {
    gpu: &'a Gpu,
    layout: wgpu::BindGroupLayout,
    light_loop: wgpu::ComputePipeline,
    shadow_rays: wgpu::ComputePipeline,
    scene_group: wgpu::BindGroup,
    /// Held for the scene group.
    _scene: bake::trace::GpuScene,
    points: wgpu::Buffer,
    sums: wgpu::Buffer,
    counts: wgpu::Buffer,
    point_count: u32,
    /// The direct pass's ray budget for the light set (its records hold each light's rays).
    budget: RayBudget,
}

impl<'a> Kernels<'a> {
    fn new(gpu: &'a Gpu, scene: &Scene, points: &[Texel], budget: RayBudget) -> Result<Kernels<'a>> {
        let gpu_scene = bake::trace::GpuScene::new(gpu, scene)?;
        let scene_layout = bake::trace::GpuScene::bind_group_layout(gpu);
        let compute = wgpu::ShaderStages::COMPUTE;
        let entries = [
            bake::gpu::uniform_entry(0, compute),
            bake::gpu::uniform_entry(1, compute),
            bake::gpu::storage_entry(2, true, compute),
            bake::gpu::storage_entry(3, false, compute),
            bake::gpu::storage_entry(4, false, compute),
        ];
        let layout = gpu
            .device
            .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some("ceiling"), entries: &entries });
        let source = [
            include_str!("../../shaders/include/texel.wgsl"),
            include_str!("../../shaders/include/materials.wgsl"),
            include_str!("../../shaders/include/trace.wgsl"),
            include_str!("ceiling.wgsl"),
        ]
        .join("\n");
        let module = gpu.device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("ceiling"),
            source: wgpu::ShaderSource::Wgsl(source.into()),
        });
        let pipeline_layout = gpu.device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("ceiling"),
            bind_group_layouts: &[Some(&layout), Some(&scene_layout)],
            immediate_size: 0,
        });
        let constants = [("CUT_OUTS", gpu_scene.cut_out_constant())];
        let pipeline = |entry: &str| {
            gpu.device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: Some(&pipeline_layout),
                module: &module,
                entry_point: Some(entry),
                compilation_options: wgpu::PipelineCompilationOptions { constants: &constants, ..Default::default() },
                cache: None,
            })
        };
        Ok(Kernels {
            gpu,
            light_loop: pipeline("light_loop"),
            shadow_rays: pipeline("shadow_rays"),
            scene_group: gpu_scene.bind_group(gpu, &scene_layout),
            _scene: gpu_scene,
            layout,
            points: gpu.storage_buffer("ceiling points", points, wgpu::BufferUsages::empty()),
            sums: gpu.zeroed_storage_buffer::<[f32; 4]>("ceiling sums", points.len(), wgpu::BufferUsages::empty()),
            counts: gpu.zeroed_storage_buffer::<u32>(
                "ceiling counts",
                3,
                wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            ),
            point_count: points.len() as u32,
            budget,
        })
    }

    /// Seconds of one dispatch of `pipeline` over every point, waited for.
    fn dispatch(&self, pipeline: &wgpu::ComputePipeline, lights: &[Light], first_ray: u32, rays: u32) -> Result<f64> {
        let gpu = self.gpu;
        let (x, y) = gpu.dispatch_size(self.point_count, 64);
        let params = BareParams {
            point_count: self.point_count,
            row_stride: x * 64,
            light_count: lights.len() as u32,
            first_ray,
            rays,
            _pad: [0; 3],
        };
        let params = gpu.uniform_buffer("ceiling params", &params);
        let records =
            gpu.uniform_buffer("ceiling lights", &light_records(lights, &vec![true; lights.len()], &self.budget));
        let buffers = [&params, &records, &self.points, &self.sums, &self.counts];
        let group = bake::gpu::bind_buffers(gpu, "ceiling", &self.layout, &buffers);
        gpu.wait()?;
        let start = Instant::now();
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &group, &[]);
            pass.set_bind_group(1, &self.scene_group, &[]);
            pass.dispatch_workgroups(x, y, 1);
        }
        gpu.queue.submit([encoder.finish()]);
        gpu.wait()?;
        Ok(start.elapsed().as_secs_f64())
    }

    /// Seconds of the bare light loop over one batch of lights.
    fn light_loop(&self, lights: &[Light]) -> Result<f64> {
        self.dispatch(&self.light_loop, lights, 0, 0)
    }

    /// `per_point` bare rays from every point towards `lights`: rays cast,
    /// nodes and triangles visited, and seconds.
    fn shadow_rays(&self, lights: &[Light], per_point: u32) -> Result<(u64, u64, f64)> {
        // One short dispatch first, so that no first-use cost lands in the timing.
        self.dispatch(&self.shadow_rays, lights, 0, 1)?;
        self.gpu.queue.write_buffer(&self.counts, 0, bytemuck::cast_slice(&[0u32; 3]));
        let mut seconds = 0.0;
        let mut first = 0;
        while first < per_point {
            let rays = RAYS_PER_DISPATCH.min(per_point - first);
            seconds += self.dispatch(&self.shadow_rays, lights, 1 + first, rays)?;
            first += rays;
        }
        let counts: Vec<u32> = read_buffer(self.gpu, &self.counts, 3)?;
        Ok((counts[0] as u64, counts[2] as u64, seconds))
    }
}
