//! Direct environment light (design notes, algorithm step 3; the seed's
//! section 3, after Coombe et al. 2004): for each batch of distant lights,
//! render an orthographic depth map of the scene along −ω per light
//! (`solve_depth.wgsl`), then let every texel gather
//! ΔE = L_k Ω_k max(0, n·ω_k) V_k(p) (`solve_direct.wgsl`).
//!
//! Shadow-map bias is scaled by the shadow map's texel size in world units,
//! so it is the same fraction of the scene at 1 mm and at 10 km.

use std::time::Instant;

use anyhow::Result;
use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use serde::{Deserialize, Serialize};

use super::SolveOptions;
use super::casters::{Casters, Topology};
use crate::environment::LightSet;
use crate::gpu::{self, Gpu, Shader, read_buffer};
use crate::scene::Scene;
use crate::texelize::{Texel, TexelSet};

/// Lights per batch the uniform array holds (`MAX_BATCH` in common.wgsl).
const MAX_BATCH: u32 = 256;
/// Memory the shadow maps of one batch (two depth layers each) may take.
const DEPTH_BUDGET_BYTES: u64 = 128 << 20;

/// Receivers test a point this far off their surface, in shadow-map texels
/// (world size 2R/S): curved surfaces are not quite their tangent plane.
/// Half a texel: the lift also raises the point towards whatever overhangs
/// it, and a whole texel darkened floors under a ball by a third within
/// 15 cm of the contact.
const NORMAL_OFFSET_TEXELS: f32 = 0.5;
/// Depth tolerance, shadow-map texels. The receiver's own plane is carried to
/// each stored texel centre exactly (receiver-plane depth bias), so this only
/// absorbs rounding; anything larger lets light through geometry that meets
/// the receiver.
const CONSTANT_BIAS_TEXELS: f32 = 0.05;
/// A stored depth within this many shadow-map texels (in depth) of the
/// receiver's plane, carried to the stored texel's centre, is that plane: the
/// receiver seeing itself. It absorbs curvature and rasterization within the
/// filter's reach.
const PLANE_TOLERANCE_TEXELS: f32 = 0.5;
/// Largest receiver-plane slope followed: planes lit within about 0.6° of
/// grazing are treated as lit at that angle.
const MAX_SLOPE: f32 = 100.0;

/// A texel counts as shadowed when more than this share of the light in
/// front of it is blocked. Below it, grazing filter taps on a curved
/// surface's neighbouring facets are what is counted, not another surface
/// (a lone sphere measured up to 0.06 %); a bounce pass skipped for want of
/// such texels leaves out less than this share of the light times the albedo.
pub const SHADOWED_SHARE: f32 = 0.005;

/// What the direct pass did, for the report.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct DirectStats {
    pub lights: usize,
    pub batches: usize,
    pub shadow_map_size: u32,
    /// Texel-light pairs evaluated (sub-samples of the supersample fix-up included).
    pub evaluations: u64,
    /// Texels that some light in front of them does not reach (geometry in the way).
    pub shadowed_texels: u64,
    pub seconds: f64,
    /// Power the pass delivered to the texels, Σ E·A, RGB (irradiance × m²;
    /// W when the environment is in W/(m²·sr)). The report's energy balance
    /// separates direct from bounced light with it.
    pub power_received: [f64; 3],
}

/// Mirrors `DirectParams` in common.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct DirectParams {
    centre: [f32; 3],
    radius: f32,
    map_size: f32,
    light_count: u32,
    texel_count: u32,
    row_stride: u32,
    tiles_per_row: u32,
    normal_offset: f32,
    constant_bias: f32,
    max_slope: f32,
    plane_tolerance: f32,
    _pad: [u32; 3],
}

/// Mirrors `DirectLight` in common.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable, Default)]
struct DirectLight {
    direction: [f32; 4],
    power: [f32; 4],
    nearest: [f32; 4],
}

/// The depth maps' instance attributes: the light's direction (`LightIn` in
/// solve_depth.wgsl), read from the batch's lights, one per instance.
const LIGHT_INSTANCES: wgpu::VertexBufferLayout<'static> = wgpu::VertexBufferLayout {
    array_stride: std::mem::size_of::<DirectLight>() as u64,
    step_mode: wgpu::VertexStepMode::Instance,
    attributes: &wgpu::vertex_attr_array![5 => Float32x4],
};

/// The scene's bounding sphere (centre, radius with a margin so that
/// geometry never touches the near or far plane).
pub(super) fn bounding_sphere(scene: &Scene) -> (Vec3, f32) {
    let (lo, hi) = scene.bounds().unwrap_or((Vec3::ZERO, Vec3::ZERO));
    let centre = (lo + hi) * 0.5;
    let radius = scene
        .primitives
        .iter()
        .flat_map(|p| p.positions.iter())
        .map(|&p| (Vec3::from(p) - centre).length())
        .fold(0.0f32, f32::max);
    (centre, (radius * 1.02).max(f32::MIN_POSITIVE * 1e6))
}

/// The shadow-map depth (0 at the near plane, 1 at the far) of the corner of
/// the scene's bounding box nearest the light from `towards_light`: nothing
/// the light's map holds lies in front of it, so no blocker can be further
/// in front of a receiver than that.
fn nearest_depth((lo, hi): (Vec3, Vec3), centre: Vec3, radius: f32, towards_light: Vec3) -> f32 {
    let corner = Vec3::select(towards_light.cmpge(Vec3::ZERO), hi, lo);
    (0.5 - 0.5 * (corner - centre).dot(towards_light) / radius).max(0.0)
}

/// Shadow maps resolve about two texels per lightmap texel across the scene.
fn auto_shadow_map_size(radius: f32, texels_per_unit: f32, max_dimension: u32) -> u32 {
    let wanted = (4.0 * radius * texels_per_unit).ceil().max(1.0) as u32;
    wanted.next_power_of_two().clamp(512, 2048).min(max_dimension)
}

/// Lights per batch for `map_size`² shadow maps: as many as the depth budget
/// holds (two layers per light: the first surface and the one behind it), at
/// most `requested`.
pub fn batch_size(gpu: &Gpu, map_size: u32, requested: u32) -> u32 {
    let per_map = map_size as u64 * map_size as u64 * 4 * 2;
    (DEPTH_BUDGET_BYTES / per_map)
        .clamp(1, MAX_BATCH as u64)
        .min(requested.clamp(1, MAX_BATCH) as u64)
        .min(gpu.limits.max_texture_array_layers as u64) as u32
}

/// What the direct pass found, per texel in `TexelSet` order.
pub struct Direct {
    /// Irradiance E (rgb).
    pub irradiance: Vec<[f32; 3]>,
    /// Irradiance at the extra points gathered with the texels (`run`'s
    /// `samples`), in their order.
    pub at_samples: Vec<[f32; 3]>,
    /// Share of the texel's hemisphere (cosine-weighted) that scene geometry
    /// covers, as seen along the light directions: where its reflected light goes.
    pub coverage: Vec<f32>,
    pub stats: DirectStats,
}

/// Gathers the environment's light at every texel, and at `samples` (points
/// that are not texels, such as sub-samples) from the same depth maps.
#[allow(clippy::too_many_arguments)]
pub fn run(
    gpu: &Gpu,
    scene: &Scene,
    texels: &TexelSet,
    samples: &[Texel],
    lights: &LightSet,
    texels_per_unit: f32,
    options: &SolveOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Direct> {
    let start = Instant::now();
    let (centre, radius) = bounding_sphere(scene);
    let bounds = scene.bounds().unwrap_or((Vec3::ZERO, Vec3::ZERO));
    let size = options
        .shadow_map_size
        .unwrap_or_else(|| auto_shadow_map_size(radius, texels_per_unit, gpu.limits.max_texture_dimension_2d))
        .min(gpu.limits.max_texture_dimension_2d);
    let batch = batch_size(gpu, size, options.batch_size);
    let tiles_per_row_value = (batch as f64).sqrt().ceil() as u32;
    let texel_world = 2.0 * radius / size as f32;
    // The texels, then the samples, gathered as one list of points.
    let point_count = texels.texels.len() + samples.len();
    let texel_count = point_count as u32;
    let (groups_x, groups_y) = gpu.dispatch_size(texel_count, 64);
    let mut params = DirectParams {
        centre: centre.to_array(),
        radius,
        map_size: size as f32,
        light_count: 0,
        texel_count,
        row_stride: groups_x * 64,
        tiles_per_row: tiles_per_row_value,
        normal_offset: NORMAL_OFFSET_TEXELS * texel_world,
        constant_bias: CONSTANT_BIAS_TEXELS * texel_world,
        max_slope: MAX_SLOPE,
        plane_tolerance: PLANE_TOLERANCE_TEXELS / size as f32,
        _pad: [0; 3],
    };

    let casters = Casters::new(gpu, scene, Topology::Sheets);

    let params_buffer = gpu.uniform_buffer("solve_direct params", &params);
    // Also the depth maps' instance attributes: each light's direction.
    let lights_buffer = gpu.uniform_buffer_with(
        "solve_direct lights",
        &[DirectLight::default(); MAX_BATCH as usize],
        wgpu::BufferUsages::VERTEX,
    );
    let texel_buffer =
        gpu.storage_buffer_of_parts("solve_direct texels", &[&texels.texels, samples], wgpu::BufferUsages::empty());
    let coverage =
        gpu.zeroed_storage_buffer::<[f32; 2]>("solve_direct coverage", point_count, wgpu::BufferUsages::COPY_SRC);
    let irradiance =
        gpu.zeroed_storage_buffer::<[f32; 4]>("solve_direct irradiance", point_count, wgpu::BufferUsages::COPY_SRC);
    let tiles_per_row = (batch as f64).sqrt().ceil() as u32;
    let tile_rows = batch.div_ceil(tiles_per_row);
    // The first surface along each light (layer 0), and the nearest one
    // behind it (layer 1): one texture, so that the gather picks the layer
    // it reads by index.
    let depth_maps = gpu.depth_layers("solve_depth maps", size * tiles_per_row, size * tile_rows, 2);
    let layer_view = |layer| {
        depth_maps.create_view(&wgpu::TextureViewDescriptor {
            dimension: Some(wgpu::TextureViewDimension::D2),
            base_array_layer: layer,
            array_layer_count: Some(1),
            ..Default::default()
        })
    };
    let front_view = layer_view(0);
    let behind_view = layer_view(1);
    let both_layers = depth_maps.create_view(&wgpu::TextureViewDescriptor {
        dimension: Some(wgpu::TextureViewDimension::D2Array),
        ..Default::default()
    });

    let both = wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT | wgpu::ShaderStages::COMPUTE;
    let [materials_entry, textures_entry, sampler_entry] = Casters::layout_entries(2);
    let depth_layout = gpu.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("solve_depth"),
        entries: &[
            // 0: DirectParams (scene sphere, shadow-map size)
            gpu::uniform_entry(0, both),
            // 1: the batch's lights
            gpu::uniform_entry(1, both),
            // 2, 3, 4: materials, their textures and sampler (alpha cut-outs)
            materials_entry,
            textures_entry,
            sampler_entry,
        ],
    });
    let [materials_binding, textures_binding, sampler_binding] = casters.bind_entries(2);
    let depth_group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("solve_depth"),
        layout: &depth_layout,
        entries: &[
            wgpu::BindGroupEntry { binding: 0, resource: params_buffer.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 1, resource: lights_buffer.as_entire_binding() },
            materials_binding,
            textures_binding,
            sampler_binding,
        ],
    });
    let depth_module = gpu.shader(Shader::SolveDepth);
    let depth_pipeline_layout = gpu.device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("solve_depth"),
        bind_group_layouts: &[Some(&depth_layout)],
        immediate_size: 0,
    });
    let opaque_pipeline = Casters::pipeline(
        gpu,
        "solve_depth",
        &depth_pipeline_layout,
        &depth_module,
        "vs_depth_opaque",
        LIGHT_INSTANCES,
        Some("fs_depth"),
        &[],
    );
    let masked_pipeline = Casters::pipeline(
        gpu,
        "solve_depth masked",
        &depth_pipeline_layout,
        &depth_module,
        "vs_depth",
        LIGHT_INSTANCES,
        Some("fs_depth_masked"),
        &[],
    );

    // The second layer's pass reads the first layer.
    let front_layout = gpu.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("solve_depth peel"),
        entries: &[gpu::depth_texture_entry(0, wgpu::ShaderStages::FRAGMENT)],
    });
    let front_group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("solve_depth peel"),
        layout: &front_layout,
        entries: &[wgpu::BindGroupEntry { binding: 0, resource: wgpu::BindingResource::TextureView(&front_view) }],
    });
    let peel_pipeline_layout = gpu.device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("solve_depth peel"),
        bind_group_layouts: &[Some(&depth_layout), Some(&front_layout)],
        immediate_size: 0,
    });
    let peel_opaque_pipeline = Casters::pipeline(
        gpu,
        "solve_depth peel",
        &peel_pipeline_layout,
        &depth_module,
        "vs_depth_opaque",
        LIGHT_INSTANCES,
        Some("fs_depth_peel"),
        &[],
    );
    let peel_masked_pipeline = Casters::pipeline(
        gpu,
        "solve_depth peel masked",
        &peel_pipeline_layout,
        &depth_module,
        "vs_depth",
        LIGHT_INSTANCES,
        Some("fs_depth_peel_masked"),
        &[],
    );

    let compute = wgpu::ShaderStages::COMPUTE;
    let gather_layout = gpu.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("solve_direct"),
        entries: &[
            // 0: DirectParams, 1: the batch's lights
            gpu::uniform_entry(0, both),
            gpu::uniform_entry(1, both),
            // 2: texels (read), 3: irradiance (accumulated)
            gpu::storage_entry(2, true, compute),
            gpu::storage_entry(3, false, compute),
            // 4: the batch's depth maps, both layers
            gpu::depth_array_texture_entry(4, compute),
            // 5: blocked and total Ω cos θ per texel (accumulated)
            gpu::storage_entry(5, false, compute),
        ],
    });
    let gather_group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("solve_direct"),
        layout: &gather_layout,
        entries: &[
            wgpu::BindGroupEntry { binding: 0, resource: params_buffer.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 1, resource: lights_buffer.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 2, resource: texel_buffer.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 3, resource: irradiance.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 4, resource: wgpu::BindingResource::TextureView(&both_layers) },
            wgpu::BindGroupEntry { binding: 5, resource: coverage.as_entire_binding() },
        ],
    });
    let gather_pipeline = gpu.compute_pipeline(Shader::SolveDirect, "main", &[&gather_layout]);

    let total = lights.lights.len() as u64;
    let mut batches = 0;
    for (chunk_index, chunk) in lights.lights.chunks(batch as usize).enumerate() {
        let mut slots = [DirectLight::default(); MAX_BATCH as usize];
        for (slot, light) in slots.iter_mut().zip(chunk) {
            let [r, g, b] = light.radiance;
            let omega = light.solid_angle;
            // The light as a cone of its solid angle: tan of the cone's half-angle.
            let cos_alpha = (1.0 - omega / std::f32::consts::TAU).max(0.5);
            let tan_alpha = (1.0 - cos_alpha * cos_alpha).sqrt() / cos_alpha;
            slot.direction = [light.direction[0], light.direction[1], light.direction[2], tan_alpha];
            slot.power = [r * omega, g * omega, b * omega, omega];
            slot.nearest = [nearest_depth(bounds, centre, radius, Vec3::from(light.direction)), 0.0, 0.0, 0.0];
        }
        params.light_count = chunk.len() as u32;
        gpu.queue.write_buffer(&params_buffer, 0, bytemuck::bytes_of(&params));
        gpu.queue.write_buffer(&lights_buffer, 0, bytemuck::cast_slice(&slots));
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        for (view, second) in [(&front_view, false), (&behind_view, true)] {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some(if second { "solve_depth second layer" } else { "solve_depth" }),
                color_attachments: &[],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view,
                    depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_bind_group(0, &depth_group, &[]);
            if second {
                pass.set_bind_group(1, &front_group, &[]);
            }
            casters.bind(&mut pass, &lights_buffer);
            let (opaque, masked) = if second {
                (&peel_opaque_pipeline, &peel_masked_pipeline)
            } else {
                (&opaque_pipeline, &masked_pipeline)
            };
            for slot in 0..chunk.len() as u32 {
                let (tx, ty) = (slot % tiles_per_row, slot / tiles_per_row);
                pass.set_viewport((tx * size) as f32, (ty * size) as f32, size as f32, size as f32, 0.0, 1.0);
                casters.draw(&mut pass, opaque, masked, slot);
            }
        }
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(&gather_pipeline);
            pass.set_bind_group(0, &gather_group, &[]);
            pass.dispatch_workgroups(groups_x, groups_y, 1);
        }
        gpu.queue.submit([encoder.finish()]);
        gpu.wait()?;
        batches += 1;
        progress((chunk_index * batch as usize + chunk.len()) as u64, total);
    }
    let count = texels.texels.len();
    let sums: Vec<[f32; 4]> = read_buffer(gpu, &irradiance, point_count)?;
    let covered: Vec<[f32; 2]> = read_buffer(gpu, &coverage, count)?;
    gpu.check("solve (direct)")?;
    let mut irradiance: Vec<[f32; 3]> = sums.into_iter().map(|e| [e[0], e[1], e[2]]).collect();
    let at_samples = irradiance.split_off(count);
    let stats = DirectStats {
        lights: lights.lights.len(),
        batches,
        shadow_map_size: size,
        evaluations: total * texel_count as u64,
        shadowed_texels: covered.iter().filter(|c| c[0] > SHADOWED_SHARE * c[1]).count() as u64,
        seconds: start.elapsed().as_secs_f64(),
        power_received: power_received(texels, &irradiance),
    };
    Ok(Direct {
        stats,
        irradiance,
        at_samples,
        coverage: covered.iter().map(|c| if c[1] > 0.0 { c[0] / c[1] } else { 0.0 }).collect(),
    })
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
