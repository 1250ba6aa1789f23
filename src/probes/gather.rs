//! The probe pass (`probes_gather.wgsl`): every probe's six ambient-cube
//! sums from the environment's lights (one shadow ray each) and from the
//! solved surfaces (gather rays over the sphere, each reading the outgoing
//! radiance of the texel it meets).

use anyhow::Result;
use bytemuck::{Pod, Zeroable};
use glam::DVec3;

use crate::environment::Light;
use crate::export::lightmap::Image;
use crate::gpu::{self, Gpu, Shader};
use crate::scene::Scene;
use crate::solve::Solution;
use crate::texelize::TexelSet;
use crate::trace::GpuScene;
use crate::unwrap::Atlas;

/// Invocations per workgroup (`LANES` in the shader).
const LANES: u32 = 64;
/// Most rays one invocation casts: a CPU driver ends a shader's loops
/// after 65,535 turns, and a ray's walk takes up to hundreds.
const RAYS_PER_LANE: u32 = 8;
/// Probes per submission, so one never runs long enough to trip the GPU
/// timeout and progress can be told.
const PROBES_PER_BATCH: usize = 2048;

/// Mirrors `ProbeParams` in probes_gather.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct ProbeParams {
    probe_count: u32,
    light_count: u32,
    ray_count: u32,
    groups: u32,
    atlas_width: u32,
    atlas_height: u32,
    _pad: [u32; 2],
}

/// Mirrors `ProbeLight` in probes_gather.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct ProbeLight {
    direction: [f32; 3],
    solid_angle: f32,
    radiance: [f32; 3],
    _pad: f32,
}

/// Mirrors `ProbeSums` in probes_gather.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct ProbeSums {
    faces: [[f32; 4]; 6],
    counts: [f32; 4],
}

/// One probe's sums: the six faces' cosine-weighted incident radiance
/// (irradiance, not yet over π), and how many gather rays met a back face.
#[derive(Clone, Copy, Debug, Default)]
pub struct Gathered {
    pub faces: [DVec3; 6],
    pub back_hits: u32,
}

/// What the pass cast, for the report.
#[derive(Clone, Copy, Debug, Default)]
pub struct GatherCounts {
    /// Walks stopped at their longest (the ray counted as blocked).
    pub cut_walks: u64,
}

/// The pass: its pipeline and the layout of its own bind group (group 0;
/// the scene is group 1).
pub struct GatherPass {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    /// Held for as long as `scene_group` binds it.
    _scene: GpuScene,
    scene_group: wgpu::BindGroup,
}

/// What the pass reads besides the probes: the solved scene.
pub struct Solved<'a> {
    pub scene: &'a Scene,
    pub atlas: &'a Atlas,
    pub texels: &'a TexelSet,
    pub solution: &'a Solution,
}

impl GatherPass {
    pub fn new(gpu: &Gpu, scene: &Scene) -> Result<GatherPass> {
        let compute = wgpu::ShaderStages::COMPUTE;
        let layout = gpu.bind_group_layout(
            "probes_gather",
            &[
                // 0: ProbeParams
                gpu::uniform_entry(0, compute),
                // 1: the probes' positions
                gpu::storage_entry(1, true, compute),
                // 2: the environment's lights
                gpu::storage_entry(2, true, compute),
                // 3: the gather directions
                gpu::storage_entry(3, true, compute),
                // 4: each texel triangle's lightmap UVs
                gpu::storage_entry(4, true, compute),
                // 5: outgoing radiance per atlas texel
                gpu::storage_entry(5, true, compute),
                // 6: the sums (written)
                gpu::storage_entry(6, false, compute),
            ],
        );
        let scene_gpu = GpuScene::new(gpu, scene)?;
        let scene_layout = GpuScene::bind_group_layout(gpu);
        let scene_group = scene_gpu.bind_group(gpu, &scene_layout);
        let constants = [("CUT_OUTS", scene_gpu.cut_out_constant())];
        let pipeline = gpu.compute_pipeline_with(Shader::ProbesGather, "main", &[&layout, &scene_layout], &constants);
        Ok(GatherPass { pipeline, layout, _scene: scene_gpu, scene_group })
    }

    /// The sums of every probe at `positions` (scene coordinates), with
    /// `rays` gather directions each; `progress(done, total)` after each batch.
    pub fn run(
        &self,
        gpu: &Gpu,
        solved: &Solved,
        lights: &[Light],
        positions: &[DVec3],
        rays: u32,
        progress: &mut dyn FnMut(u64, u64),
    ) -> Result<(Vec<Gathered>, GatherCounts)> {
        let extra = wgpu::BufferUsages::empty();
        let lights: Vec<ProbeLight> = lights.iter().map(probe_light).collect();
        let lights_buffer = gpu.storage_buffer("probe lights", &lights, extra);
        let directions = gpu.storage_buffer("probe directions", &sphere_directions(rays), extra);
        let uvs = gpu.storage_buffer("probe triangle uvs", &triangle_uvs(solved.scene, solved.atlas), extra);
        let radiance = gpu.storage_buffer("probe radiance", &outgoing_radiance(solved.texels, solved.solution), extra);
        let total_rays = lights.len() as u32 + rays;
        let groups = total_rays.div_ceil(LANES * RAYS_PER_LANE).max(1);
        let mut gathered = Vec::with_capacity(positions.len());
        let mut counts = GatherCounts::default();
        for batch in positions.chunks(PROBES_PER_BATCH) {
            let params = ProbeParams {
                probe_count: batch.len() as u32,
                light_count: lights.len() as u32,
                ray_count: rays,
                groups,
                atlas_width: solved.texels.width,
                atlas_height: solved.texels.height,
                _pad: [0; 2],
            };
            let points: Vec<[f32; 4]> = batch.iter().map(|p| [p.x as f32, p.y as f32, p.z as f32, 0.0]).collect();
            let params = gpu.uniform_buffer("probe params", &params);
            let points = gpu.storage_buffer("probe positions", &points, extra);
            let slots = batch.len() * groups as usize;
            let sums = gpu.zeroed_storage_buffer::<ProbeSums>("probe sums", slots, wgpu::BufferUsages::COPY_SRC);
            let buffers = [&params, &points, &lights_buffer, &directions, &uvs, &radiance, &sums];
            let group = gpu::bind_buffers(gpu, "probes_gather", &self.layout, &buffers);
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            {
                let mut pass = encoder.begin_compute_pass(&Default::default());
                pass.set_pipeline(&self.pipeline);
                pass.set_bind_group(0, &group, &[]);
                pass.set_bind_group(1, &self.scene_group, &[]);
                pass.dispatch_workgroups(batch.len() as u32, groups, 1);
            }
            gpu.queue.submit([encoder.finish()]);
            let sums: Vec<ProbeSums> = gpu::read_buffer(gpu, &sums, slots)?;
            for probe in sums.chunks(groups as usize) {
                gathered.push(add_up(probe, &mut counts));
            }
            progress(gathered.len() as u64, positions.len() as u64);
        }
        Ok((gathered, counts))
    }
}

/// One probe's workgroups' sums added up in order, in f64.
fn add_up(groups: &[ProbeSums], counts: &mut GatherCounts) -> Gathered {
    let mut gathered = Gathered::default();
    for sums in groups {
        for (face, s) in gathered.faces.iter_mut().zip(&sums.faces) {
            *face += DVec3::new(s[0].into(), s[1].into(), s[2].into());
        }
        gathered.back_hits += sums.counts[0] as u32;
        counts.cut_walks += sums.counts[1] as u64;
    }
    gathered
}

fn probe_light(light: &Light) -> ProbeLight {
    ProbeLight { direction: light.direction, solid_angle: light.solid_angle, radiance: light.radiance, _pad: 0.0 }
}

/// `count` unit directions spread evenly over the sphere (a spherical
/// Fibonacci lattice), the same for every probe.
pub fn sphere_directions(count: u32) -> Vec<[f32; 4]> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..count)
        .map(|i| {
            let z = 1.0 - (2.0 * f64::from(i) + 1.0) / f64::from(count);
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = golden * f64::from(i);
            [(r * phi.cos()) as f32, z as f32, (r * phi.sin()) as f32, 0.0]
        })
        .collect()
}

/// Per texel triangle id (`texelize::Texel::triangle`), its corners'
/// lightmap UVs in the order `trace::GpuScene` records its corners
/// (`ScenePrimitive::front_corners`).
fn triangle_uvs(scene: &Scene, atlas: &Atlas) -> Vec<[f32; 2]> {
    let mut uvs = Vec::new();
    for (primitive, unwrapped) in scene.primitives.iter().zip(&atlas.meshes) {
        let repeat = crate::repeats::mask(&primitive.repeats, unwrapped.indices.len() / 3);
        for (t, corners) in unwrapped.indices.chunks_exact(3).enumerate() {
            if repeat[t] {
                continue;
            }
            let [a, b, c] = [0, 1, 2].map(|k| unwrapped.vertices[corners[k] as usize].uv);
            uvs.extend(if primitive.mirrored { [a, c, b] } else { [a, b, c] });
        }
    }
    uvs
}

/// Outgoing radiance (albedo · L_lm + emission) per atlas texel, charts
/// grown by one ring.
fn outgoing_radiance(texels: &TexelSet, solution: &Solution) -> Vec<[f32; 4]> {
    let mut image = Image::from_texels(texels, |i| solution.radiosity(texels, i));
    image.dilate(1);
    image.pixels.iter().map(|&[r, g, b]| [r, g, b, 0.0]).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_rust_structs_mirror_the_shader() {
        use crate::gpu::mirror::assert_mirrors;
        let shader = Shader::ProbesGather;
        assert_mirrors!(
            shader,
            "ProbeParams",
            ProbeParams { probe_count, light_count, ray_count, groups, atlas_width, atlas_height }
        );
        assert_mirrors!(shader, "ProbeLight", ProbeLight { direction, solid_angle, radiance });
        assert_mirrors!(shader, "ProbeSums", ProbeSums { faces, counts });
    }

    #[test]
    fn the_gather_directions_weigh_every_face_alike() {
        // Each face's cosine-lobe over the sphere is π: with equal shares
        // 4π/N, the directions' summed positive cosines must be N/4 per axis.
        let count = 1024;
        let directions = sphere_directions(count);
        for axis in 0..3 {
            for sign in [1.0f64, -1.0] {
                let sum: f64 = directions.iter().map(|d| (sign * f64::from(d[axis])).max(0.0)).sum();
                let relative = sum / (f64::from(count) / 4.0) - 1.0;
                assert!(relative.abs() < 2e-3, "axis {axis} sign {sign}: {relative}");
            }
        }
    }
}
