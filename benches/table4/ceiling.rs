//! The "bare kernel" ceiling of the direct pass on this adapter: the same
//! shape as `solve_depth.wgsl` + `solve_direct.wgsl` with nothing else in it.
//! Per batch of lights, an orthographic depth map of the scene per light
//! (positions only, one draw per light, tiled into one depth atlas of the
//! real pass's size), then per texel a loop over the batch's lights (uniform
//! array, as the real pass): one dot product, the light-space projection, one
//! depth-texture load and a compare. No soft-shadow filter, no receiver-plane
//! test, no coverage output. The real pass's time over this one's is the gap
//! to the adapter's limit for this shape of work.

use std::time::Instant;

use anyhow::Result;
use bytemuck::{Pod, Zeroable};
use glam::Vec3;

use bake::environment::LightSet;
use bake::gpu::{self, Gpu};
use bake::scene::Scene;
use bake::texelize::Texel;

/// Lights per uniform array (as `MAX_BATCH` in common.wgsl).
const MAX_BATCH: usize = 256;

const SHADER: &str = r#"
struct Params {
    centre: vec3f,
    radius: f32,
    map_size: f32,
    light_count: u32,
    texel_count: u32,
    row_stride: u32,
    tiles_per_row: u32,
    taps: u32,
    _p2: u32,
    _p3: u32,
}
struct Light { direction: vec4f, power: vec4f }
struct Lights { items: array<Light, 256> }
struct Texel {
    position: vec3f, area: f32, normal: vec3f, index: u32,
    face_normal: vec3f, triangle: u32, albedo: vec3f, chart: u32, emission: vec3f, primitive: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<uniform> lights: Lights;
@group(0) @binding(2) var<storage, read> texels: array<Texel>;
@group(0) @binding(3) var<storage, read_write> irradiance: array<vec4f>;
@group(0) @binding(4) var depth_maps: texture_depth_2d;

fn basis(n: vec3f) -> mat3x3f {
    let s = select(-1.0, 1.0, n.z >= 0.0);
    let a = -1.0 / (s + n.z);
    let b = n.x * n.y * a;
    return mat3x3f(vec3f(1.0 + s * n.x * n.x * a, s * b, -s * n.x), vec3f(b, s + n.y * n.y * a, -n.y), n);
}

// The light's direction is an instance attribute, as in solve_depth.wgsl.
@vertex
fn vs_depth(@location(0) position: vec3f, @location(5) direction: vec4f) -> @builtin(position) vec4f {
    let w = direction.xyz;
    let m = basis(w);
    let d = position - params.centre;
    return vec4f(dot(d, m[0]) / params.radius, dot(d, m[1]) / params.radius, 0.5 - 0.5 * dot(d, w) / params.radius, 1.0);
}

@compute @workgroup_size(64)
fn gather(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x + id.y * params.row_stride;
    if (i >= params.texel_count) {
        return;
    }
    let t = texels[i];
    let size = params.map_size;
    var sum = vec3f(0.0);
    for (var k = 0u; k < params.light_count; k++) {
        let light = lights.items[k];
        let w = light.direction.xyz;
        let c = dot(t.normal, w);
        if (c <= 0.0) {
            continue;
        }
        let m = basis(w);
        let d = t.position + t.face_normal * 0.01 - params.centre;
        let ls = vec3f(dot(d, m[0]), dot(d, m[1]), 0.5 * params.radius - 0.5 * dot(d, w)) / params.radius;
        let pixel = vec2f(ls.x * 0.5 + 0.5, 0.5 - ls.y * 0.5) * size;
        let tile = vec2<i32>(i32(k % params.tiles_per_row), i32(k / params.tiles_per_row)) * i32(size);
        if (params.taps <= 1u) {
            let stored = textureLoad(depth_maps, vec2<i32>(clamp(floor(pixel), vec2f(0.0), vec2f(size - 1.0))) + tile, 0);
            if (ls.z <= stored + 1e-4) {
                sum += light.power.rgb * c;
            }
        } else {
            // A filter of `taps` loads on a spiral two texels wide (percentage-closer filtering).
            var lit = 0.0;
            for (var j = 0u; j < params.taps; j++) {
                let r = 2.0 * sqrt((f32(j) + 0.5) / f32(params.taps));
                let a = f32(j) * 2.39996323;
                let at = pixel + r * vec2f(cos(a), sin(a));
                let stored = textureLoad(depth_maps, vec2<i32>(clamp(floor(at), vec2f(0.0), vec2f(size - 1.0))) + tile, 0);
                lit += select(0.0, 1.0, ls.z <= stored + 1e-4);
            }
            sum += light.power.rgb * c * lit / f32(params.taps);
        }
    }
    irradiance[i] += vec4f(sum, 0.0);
}
"#;

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Params {
    centre: [f32; 3],
    radius: f32,
    map_size: f32,
    light_count: u32,
    texel_count: u32,
    row_stride: u32,
    tiles_per_row: u32,
    taps: u32,
    _pad: [u32; 2],
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable, Default)]
struct Light {
    direction: [f32; 4],
    power: [f32; 4],
}

/// Seconds the bare kernel took over all the lights, each way of running it.
pub struct Bare {
    /// Depth maps alone (every batch rendered, submitted and waited for).
    pub render: f64,
    /// The gather alone, over depth maps rendered beforehand.
    pub gather: f64,
    /// Render and gather per batch, one submit and wait per batch: the real pass's shape.
    pub both: f64,
    /// The gather with no lights in each batch: what a batch costs before its first light
    /// (per-texel set-up, read-modify-write of the sum, dispatch and wait).
    pub empty: f64,
    /// The gather alone with a filter of n depth loads per pair instead of one: (n, seconds).
    pub filtered: Vec<(u32, f64)>,
    pub batches: usize,
}

/// Times the bare kernel over `texels` and `lights` with `map_size`² depth maps, `batch`
/// lights per batch (what the real pass chose), and its gather with filters of `taps` loads.
pub fn measure(
    gpu: &Gpu,
    scene: &Scene,
    texels: &[Texel],
    lights: &LightSet,
    map_size: u32,
    batch: u32,
    taps: &[u32],
) -> Result<Bare> {
    let batch = batch.clamp(1, MAX_BATCH as u32);
    let device = &gpu.device;
    // Casters: every triangle's positions.
    let (mut positions, mut indices) = (Vec::<[f32; 3]>::new(), Vec::<u32>::new());
    for p in &scene.primitives {
        let base = positions.len() as u32;
        positions.extend_from_slice(&p.positions);
        indices.extend(p.indices.iter().map(|i| i + base));
    }
    let (lo, hi) = positions
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| (lo.min(Vec3::from(p)), hi.max(Vec3::from(p))));
    let centre = (lo + hi) * 0.5;
    let radius = positions.iter().map(|&p| (Vec3::from(p) - centre).length()).fold(0.0f32, f32::max) * 1.02;
    let vertices = gpu.storage_buffer("bare vertices", &positions, wgpu::BufferUsages::VERTEX);
    let index_buffer = gpu.storage_buffer("bare indices", &indices, wgpu::BufferUsages::INDEX);

    let tiles_per_row = (batch as f64).sqrt().ceil() as u32;
    let rows = batch.div_ceil(tiles_per_row);
    let depth = gpu.depth_target("bare depth", map_size * tiles_per_row, map_size * rows);
    let depth_view = depth.create_view(&Default::default());
    let texel_count = texels.len() as u32;
    let (groups_x, groups_y) = gpu.dispatch_size(texel_count, 64);
    let mut params = Params {
        centre: centre.to_array(),
        radius,
        map_size: map_size as f32,
        light_count: 0,
        texel_count,
        row_stride: groups_x * 64,
        tiles_per_row,
        taps: 1,
        _pad: [0; 2],
    };
    let params_buffer = gpu.uniform_buffer("bare params", &params);
    let lights_buffer =
        gpu.uniform_buffer_with("bare lights", &[Light::default(); MAX_BATCH], wgpu::BufferUsages::VERTEX);
    let texel_buffer = gpu.storage_buffer("bare texels", texels, wgpu::BufferUsages::empty());
    let irradiance =
        gpu.storage_buffer("bare irradiance", &vec![[0.0f32; 4]; texels.len()], wgpu::BufferUsages::empty());

    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("bare kernel"),
        source: wgpu::ShaderSource::Wgsl(SHADER.into()),
    });
    let both = wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::COMPUTE;
    let compute = wgpu::ShaderStages::COMPUTE;
    let render_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("bare depth"),
        entries: &[gpu::uniform_entry(0, both), gpu::uniform_entry(1, both)],
    });
    let gather_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("bare gather"),
        entries: &[
            gpu::uniform_entry(0, both),
            gpu::uniform_entry(1, both),
            gpu::storage_entry(2, true, compute),
            gpu::storage_entry(3, false, compute),
            wgpu::BindGroupLayoutEntry {
                binding: 4,
                visibility: compute,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Depth,
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
                count: None,
            },
        ],
    });
    let render_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("bare depth"),
        layout: &render_layout,
        entries: &[
            wgpu::BindGroupEntry { binding: 0, resource: params_buffer.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 1, resource: lights_buffer.as_entire_binding() },
        ],
    });
    let gather_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("bare gather"),
        layout: &gather_layout,
        entries: &[
            wgpu::BindGroupEntry { binding: 0, resource: params_buffer.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 1, resource: lights_buffer.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 2, resource: texel_buffer.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 3, resource: irradiance.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 4, resource: wgpu::BindingResource::TextureView(&depth_view) },
        ],
    });
    let pipeline_layout = |layout: &wgpu::BindGroupLayout| {
        device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("bare"),
            bind_group_layouts: &[Some(layout)],
            immediate_size: 0,
        })
    };
    let render_pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("bare depth"),
        layout: Some(&pipeline_layout(&render_layout)),
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("vs_depth"),
            compilation_options: Default::default(),
            buffers: &[
                Some(wgpu::VertexBufferLayout {
                    array_stride: 12,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &wgpu::vertex_attr_array![0 => Float32x3],
                }),
                Some(wgpu::VertexBufferLayout {
                    array_stride: std::mem::size_of::<Light>() as u64,
                    step_mode: wgpu::VertexStepMode::Instance,
                    attributes: &wgpu::vertex_attr_array![5 => Float32x4],
                }),
            ],
        },
        primitive: wgpu::PrimitiveState { cull_mode: None, ..Default::default() },
        depth_stencil: Some(wgpu::DepthStencilState {
            format: wgpu::TextureFormat::Depth32Float,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Less),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        multisample: Default::default(),
        fragment: None,
        multiview_mask: None,
        cache: None,
    });
    let gather_pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some("bare gather"),
        layout: Some(&pipeline_layout(&gather_layout)),
        module: &module,
        entry_point: Some("gather"),
        compilation_options: Default::default(),
        cache: None,
    });

    let chunks: Vec<Vec<Light>> = lights
        .lights
        .chunks(batch as usize)
        .map(|chunk| {
            chunk
                .iter()
                .map(|l| {
                    let [r, g, b] = l.radiance.map(|c| c * l.solid_angle);
                    Light { direction: [l.direction[0], l.direction[1], l.direction[2], 0.0], power: [r, g, b, 0.0] }
                })
                .collect()
        })
        .collect();
    let index_count = indices.len() as u32;
    // One batch: upload its lights, record what `render` and `gather` ask for, submit, wait.
    let mut run = |lights: &[Light], light_count: u32, taps: u32, render: bool, gather: bool| -> Result<()> {
        params.light_count = light_count;
        params.taps = taps;
        gpu.queue.write_buffer(&params_buffer, 0, bytemuck::bytes_of(&params));
        gpu.queue.write_buffer(&lights_buffer, 0, bytemuck::cast_slice(lights));
        let mut encoder = device.create_command_encoder(&Default::default());
        if render {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("bare depth"),
                color_attachments: &[],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &depth_view,
                    depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&render_pipeline);
            pass.set_bind_group(0, &render_group, &[]);
            pass.set_vertex_buffer(0, vertices.slice(..));
            pass.set_vertex_buffer(1, lights_buffer.slice(..));
            pass.set_index_buffer(index_buffer.slice(..), wgpu::IndexFormat::Uint32);
            for slot in 0..lights.len() as u32 {
                let (tx, ty) = (slot % tiles_per_row, slot / tiles_per_row);
                let s = map_size as f32;
                pass.set_viewport(tx as f32 * s, ty as f32 * s, s, s, 0.0, 1.0);
                pass.draw_indexed(0..index_count, 0, slot..slot + 1);
            }
        }
        if gather {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(&gather_pipeline);
            pass.set_bind_group(0, &gather_group, &[]);
            pass.dispatch_workgroups(groups_x, groups_y, 1);
        }
        gpu.queue.submit([encoder.finish()]);
        gpu.wait()
    };
    // Warm up (pipeline compilation on first use), then time each way.
    run(&chunks[0], chunks[0].len() as u32, 1, true, true)?;
    let mut time = |render: bool, gather: bool, empty: bool, taps: u32| -> Result<f64> {
        let start = Instant::now();
        for chunk in &chunks {
            run(chunk, if empty { 0 } else { chunk.len() as u32 }, taps, render, gather)?;
        }
        Ok(start.elapsed().as_secs_f64())
    };
    let render = time(true, false, false, 1)?;
    let gather = time(false, true, false, 1)?;
    let both = time(true, true, false, 1)?;
    let empty = time(false, true, true, 1)?;
    let mut filtered = Vec::new();
    for &n in taps {
        filtered.push((n, time(false, true, false, n)?));
    }
    gpu.check("bare kernel")?;
    Ok(Bare { render, gather, both, empty, filtered, batches: chunks.len() })
}
