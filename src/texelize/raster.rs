//! The GPU side of texelization: two raster passes in lightmap-UV space
//! (`texelize_raster.wgsl`: nearest triangle + barycentrics, exact covered
//! area) and a compute pass (`texelize_attributes.wgsl`) that interpolates the
//! texel attributes band by band.

use anyhow::Result;
use bytemuck::{Pod, Zeroable};

use super::{Mesh, Texel};
use crate::gpu::{self, Gpu, Materials, Shader, read_buffer};

/// Half the texel diagonal plus a hair: a texel square overlaps a triangle
/// only if its centre is this close to it.
const DILATION: f32 = 0.7072;
/// How far (texels) a sharp UV corner may move when dilated.
const MAX_MITER: f32 = 4.0;
/// How far inside the chart a border texel (centre outside every triangle)
/// takes its position and normal from, texels.
const BORDER_INSET: f32 = 0.5;
/// Upper bound on the bytes of one attribute band (storage bindings are limited).
const BAND_BYTES: u64 = 64 << 20;

/// Mirrors `RasterParams` in texelize_raster.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct RasterParams {
    size: [f32; 2],
    dilation: f32,
    max_miter: f32,
    _pad: [f32; 4],
}

/// Mirrors `AttributeParams` in texelize_attributes.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct AttributeParams {
    width: u32,
    height: u32,
    first_row: u32,
    rows: u32,
    inset: f32,
    _pad: [f32; 3],
}

struct Targets {
    triangle: wgpu::Texture,
    bary: wgpu::Texture,
    area: wgpu::Texture,
    depth: wgpu::Texture,
}

/// Rasterizes `mesh` into a `width`×`height` atlas and returns its covered texels
/// (`chart` and `primitive` still unset).
pub(super) fn texelize(gpu: &Gpu, mesh: &Mesh, materials: &Materials, width: u32, height: u32) -> Result<Vec<Texel>> {
    let targets = Targets {
        triangle: gpu.render_target("texelize triangle ids", width, height, wgpu::TextureFormat::R32Uint),
        bary: gpu.render_target("texelize barycentrics", width, height, wgpu::TextureFormat::Rgba32Float),
        area: gpu.render_target("texelize areas", width, height, wgpu::TextureFormat::Rg32Float),
        depth: gpu.depth_target("texelize distance", width, height),
    };
    let corners = gpu.storage_buffer("texelize corners", &mesh.corners, wgpu::BufferUsages::empty());
    rasterize(gpu, mesh, &corners, width, height, &targets);
    interpolate(gpu, mesh, &corners, materials, width, height, &targets)
}

fn rasterize(gpu: &Gpu, mesh: &Mesh, corners: &wgpu::Buffer, width: u32, height: u32, targets: &Targets) {
    let params = gpu.uniform_buffer(
        "texelize_raster params",
        &RasterParams { size: [width as f32, height as f32], dilation: DILATION, max_miter: MAX_MITER, _pad: [0.0; 4] },
    );
    let ratios = gpu.storage_buffer("texelize area ratios", &mesh.area_ratio, wgpu::BufferUsages::empty());
    let stages = wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT;
    let layout = gpu.bind_group_layout(
        "texelize_raster",
        &[
            // 0: RasterParams (atlas size, dilation)
            gpu::uniform_entry(0, stages),
            // 1: triangle corners in texel units, three per triangle
            gpu::storage_entry(1, true, wgpu::ShaderStages::VERTEX),
            // 2: world area per UV area, one per triangle
            gpu::storage_entry(2, true, wgpu::ShaderStages::VERTEX),
        ],
    );
    let bind_group = gpu::bind_buffers(gpu, "texelize_raster", &layout, &[&params, corners, &ratios]);
    let pipelines = RasterPipelines::new(gpu, &layout);
    draw(gpu, &pipelines, &bind_group, mesh.corners.len() as u32, targets);
}

/// The two raster passes' pipelines, over the same dilated triangles.
struct RasterPipelines {
    /// Nearest triangle and its barycentrics per texel (depth: distance to the triangle).
    nearest: wgpu::RenderPipeline,
    /// Covered area per texel, summed additively.
    area: wgpu::RenderPipeline,
}

impl RasterPipelines {
    fn new(gpu: &Gpu, layout: &wgpu::BindGroupLayout) -> Self {
        let module = gpu.shader(Shader::TexelizeRaster);
        let pipeline_layout = gpu.device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("texelize_raster"),
            bind_group_layouts: &[Some(layout)],
            immediate_size: 0,
        });
        let pipeline =
            |fragment: &str, targets: &[Option<wgpu::ColorTargetState>], depth: Option<wgpu::DepthStencilState>| {
                gpu.device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                    label: Some("texelize_raster"),
                    layout: Some(&pipeline_layout),
                    vertex: wgpu::VertexState {
                        module: &module,
                        entry_point: Some("vs_dilated"),
                        compilation_options: Default::default(),
                        buffers: &[],
                    },
                    primitive: wgpu::PrimitiveState { cull_mode: None, ..Default::default() },
                    depth_stencil: depth,
                    multisample: Default::default(),
                    fragment: Some(wgpu::FragmentState {
                        module: &module,
                        entry_point: Some(fragment),
                        compilation_options: Default::default(),
                        targets,
                    }),
                    multiview_mask: None,
                    cache: None,
                })
            };
        let nearest = pipeline(
            "fs_nearest",
            &[Some(wgpu::TextureFormat::R32Uint.into()), Some(wgpu::TextureFormat::Rgba32Float.into())],
            Some(wgpu::DepthStencilState {
                format: wgpu::TextureFormat::Depth32Float,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: Default::default(),
                bias: Default::default(),
            }),
        );
        let additive = wgpu::BlendComponent {
            src_factor: wgpu::BlendFactor::One,
            dst_factor: wgpu::BlendFactor::One,
            operation: wgpu::BlendOperation::Add,
        };
        let area = pipeline(
            "fs_area",
            &[Some(wgpu::ColorTargetState {
                format: wgpu::TextureFormat::Rg32Float,
                blend: Some(wgpu::BlendState { color: additive, alpha: additive }),
                write_mask: wgpu::ColorWrites::ALL,
            })],
            None,
        );
        RasterPipelines { nearest, area }
    }
}

/// Clears the targets and draws both passes, `vertex_count` corners each.
fn draw(gpu: &Gpu, pipelines: &RasterPipelines, bind_group: &wgpu::BindGroup, vertex_count: u32, targets: &Targets) {
    let view = |t: &wgpu::Texture| t.create_view(&Default::default());
    let (triangle_view, bary_view, area_view, depth_view) =
        (view(&targets.triangle), view(&targets.bary), view(&targets.area), view(&targets.depth));
    let clear = |v| {
        Some(wgpu::RenderPassColorAttachment {
            view: v,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations { load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT), store: wgpu::StoreOp::Store },
        })
    };
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("texelize_raster nearest"),
            color_attachments: &[clear(&triangle_view), clear(&bary_view)],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &depth_view,
                depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&pipelines.nearest);
        pass.set_bind_group(0, bind_group, &[]);
        pass.draw(0..vertex_count, 0..1);
    }
    {
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("texelize_raster area"),
            color_attachments: &[clear(&area_view)],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&pipelines.area);
        pass.set_bind_group(0, bind_group, &[]);
        pass.draw(0..vertex_count, 0..1);
    }
    gpu.queue.submit([encoder.finish()]);
}

fn interpolate(
    gpu: &Gpu,
    mesh: &Mesh,
    corners: &wgpu::Buffer,
    materials: &Materials,
    width: u32,
    height: u32,
    targets: &Targets,
) -> Result<Vec<Texel>> {
    let texel_size = std::mem::size_of::<Texel>() as u64;
    let band_limit = BAND_BYTES.min(gpu.limits.max_storage_buffer_binding_size);
    let rows_per_band = ((band_limit / (texel_size * width as u64)).max(1) as u32).min(height);

    let vertices = gpu.storage_buffer("texelize vertices", &mesh.vertices, wgpu::BufferUsages::empty());
    let triangles = gpu.storage_buffer("texelize triangles", &mesh.triangles, wgpu::BufferUsages::empty());
    let band = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("texelize band"),
        size: texel_size * width as u64 * rows_per_band as u64,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let texture_entry = |binding, sample_type| wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Texture {
            sample_type,
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        },
        count: None,
    };
    let compute = wgpu::ShaderStages::COMPUTE;
    let unfilterable = wgpu::TextureSampleType::Float { filterable: false };
    let layout = gpu.bind_group_layout(
        "texelize_attributes",
        &[
            // 0: AttributeParams (atlas size, band rows)
            gpu::uniform_entry(0, compute),
            // 1: nearest triangle id + 1 per texel
            texture_entry(1, wgpu::TextureSampleType::Uint),
            // 2: barycentrics (corners b, c) of the nearest point and its distance
            texture_entry(2, unfilterable),
            // 3: covered world area and covered share of the texel
            texture_entry(3, unfilterable),
            // 4: vertices, 5: triangles, 6: materials
            gpu::storage_entry(4, true, compute),
            gpu::storage_entry(5, true, compute),
            gpu::storage_entry(6, true, compute),
            // 7: the band's texels, written
            gpu::storage_entry(7, false, compute),
            // 8: triangle corners in lightmap texels (for the texture footprint)
            gpu::storage_entry(8, true, compute),
            // 9, 10: material textures and their sampler
            gpu::texture_array_entry(9, compute, gpu::FILTERABLE),
            gpu::sampler_entry(10, compute),
        ],
    );
    let pipeline = gpu.compute_pipeline(Shader::TexelizeAttributes, "main", &[&layout]);
    let views = [&targets.triangle, &targets.bary, &targets.area].map(|t| t.create_view(&Default::default()));

    let mut covered = Vec::new();
    let mut first_row = 0;
    while first_row < height {
        let rows = rows_per_band.min(height - first_row);
        let params = gpu.uniform_buffer(
            "texelize_attributes params",
            &AttributeParams { width, height, first_row, rows, inset: BORDER_INSET, _pad: [0.0; 3] },
        );
        let bind_group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("texelize_attributes"),
            layout: &layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: params.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(&views[0]) },
                wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::TextureView(&views[1]) },
                wgpu::BindGroupEntry { binding: 3, resource: wgpu::BindingResource::TextureView(&views[2]) },
                wgpu::BindGroupEntry { binding: 4, resource: vertices.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 5, resource: triangles.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 6, resource: materials.buffer.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 7, resource: band.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 8, resource: corners.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 9, resource: wgpu::BindingResource::TextureView(&materials.textures) },
                wgpu::BindGroupEntry { binding: 10, resource: wgpu::BindingResource::Sampler(&materials.sampler) },
            ],
        });
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &bind_group, &[]);
            pass.dispatch_workgroups(width.div_ceil(8), rows.div_ceil(8), 1);
        }
        gpu.queue.submit([encoder.finish()]);
        let values: Vec<Texel> = read_buffer(gpu, &band, (width * rows) as usize)?;
        covered.extend(values.into_iter().filter(|t| t.triangle != u32::MAX));
        first_row += rows;
    }
    Ok(covered)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::mirror::assert_mirrors;

    #[test]
    fn the_params_mirror_their_shaders() {
        assert_mirrors!(Shader::TexelizeRaster, "RasterParams", RasterParams { size, dilation, max_miter });
        assert_mirrors!(
            Shader::TexelizeAttributes,
            "AttributeParams",
            AttributeParams { width, height, first_row, rows, inset }
        );
    }
}
