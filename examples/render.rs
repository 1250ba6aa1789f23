//! Renders a baked glTF as a glTF viewer shows it (the default material,
//! KHR_materials_unlit: base colour × texture through its UV set), with wgpu,
//! into a PNG. The README's pictures come from here:
//!
//! ```sh
//! cargo run --release --example render -- baked/sphere_on_ground.glb docs/sphere_on_ground.png [AZIMUTH ELEVATION]
//! ```
//!
//! It reads the file through bake's own importer, so it sees what a viewer
//! sees: the baked texture on TEXCOORD_1 (the emissive texture of a
//! cut-out's baked form, whose holes it does not cut), sampled bilinearly
//! with the glTF sampler's clamp, into an sRGB target.

use std::path::Path;

use anyhow::{Context, Result, bail};
use bake::gpu::{Gpu, read_buffer};
use bake::scene::Scene;
use glam::{Mat4, Vec3, Vec4};
use wgpu::util::DeviceExt;

const WIDTH: u32 = 960; // 960 · 4 bytes is a multiple of 256: rows copy unpadded.
const HEIGHT: u32 = 540;
const BACKGROUND: f64 = 0.18;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Vertex {
    position: [f32; 3],
    uv: [f32; 2],
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct MaterialUniform {
    factor: [f32; 4],
    row0: [f32; 4],
    row1: [f32; 4],
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() != 2 && args.len() != 4 {
        bail!("usage: render BAKED.glb OUT.png [AZIMUTH_DEGREES ELEVATION_DEGREES]");
    }
    let (azimuth, elevation) = match args.len() {
        4 => (args[2].parse::<f32>()?, args[3].parse::<f32>()?),
        _ => (35.0, 25.0),
    };
    let source = bake::asset::SourceAsset::load(Path::new(&args[0]))?;
    let scene = bake::import::from_asset(source)?;
    let gpu = Gpu::new(None)?;
    let rgba = render(&gpu, &scene, azimuth, elevation)?;
    image::RgbaImage::from_raw(WIDTH, HEIGHT, rgba)
        .context("image size")?
        .save(&args[1])
        .with_context(|| format!("writing {}", args[1]))?;
    eprintln!("{} → {} ({WIDTH}×{HEIGHT}, {})", args[0], args[1], gpu.adapter);
    Ok(())
}

/// A camera that frames the scene's bounding sphere from the given direction.
fn camera(scene: &Scene, azimuth: f32, elevation: f32) -> Mat4 {
    let points = scene.primitives.iter().flat_map(|p| p.positions.iter().map(|&q| Vec3::from(q)));
    let (lo, hi) = points.fold((Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)), |(lo, hi), p| (lo.min(p), hi.max(p)));
    let centre = (lo + hi) * 0.5;
    let radius = ((hi - lo).length() * 0.5).max(1e-6);
    let (a, e) = (azimuth.to_radians(), elevation.to_radians());
    let direction = Vec3::new(e.cos() * a.sin(), e.sin(), e.cos() * a.cos());
    let fov = 35f32.to_radians();
    let distance = radius / (fov * 0.5).sin() * 0.85;
    let eye = centre + direction * distance;
    // Right-handed look-at and a perspective onto wgpu's 0..1 depth.
    let f = (centre - eye).normalize();
    let s = f.cross(Vec3::Y).normalize();
    let u = s.cross(f);
    let view = Mat4::from_cols(
        Vec4::new(s.x, u.x, -f.x, 0.0),
        Vec4::new(s.y, u.y, -f.y, 0.0),
        Vec4::new(s.z, u.z, -f.z, 0.0),
        Vec4::new(-s.dot(eye), -u.dot(eye), f.dot(eye), 1.0),
    );
    let (near, far) = (distance * 0.01, distance + radius * 2.0);
    let focal = 1.0 / (fov * 0.5).tan();
    let projection = Mat4::from_cols(
        Vec4::new(focal * HEIGHT as f32 / WIDTH as f32, 0.0, 0.0, 0.0),
        Vec4::new(0.0, focal, 0.0, 0.0),
        Vec4::new(0.0, 0.0, far / (near - far), -1.0),
        Vec4::new(0.0, 0.0, near * far / (near - far), 0.0),
    );
    projection * view
}

fn render(gpu: &Gpu, scene: &Scene, azimuth: f32, elevation: f32) -> Result<Vec<u8>> {
    let device = &gpu.device;
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("render"),
        source: wgpu::ShaderSource::Wgsl(include_str!("render.wgsl").into()),
    });
    let uniform = |binding, stage| wgpu::BindGroupLayoutEntry {
        binding,
        visibility: stage,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    };
    let camera_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("camera"),
        entries: &[uniform(0, wgpu::ShaderStages::VERTEX)],
    });
    let material_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("material"),
        entries: &[
            uniform(0, wgpu::ShaderStages::VERTEX_FRAGMENT),
            wgpu::BindGroupLayoutEntry {
                binding: 1,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: true },
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
                count: None,
            },
            wgpu::BindGroupLayoutEntry {
                binding: 2,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                count: None,
            },
        ],
    });
    let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("render"),
        bind_group_layouts: &[Some(&camera_layout), Some(&material_layout)],
        immediate_size: 0,
    });
    let target_format = wgpu::TextureFormat::Rgba8UnormSrgb;
    let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("render"),
        layout: Some(&layout),
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("vs_main"),
            compilation_options: Default::default(),
            buffers: &[Some(wgpu::VertexBufferLayout {
                array_stride: std::mem::size_of::<Vertex>() as u64,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x2],
            })],
        },
        primitive: wgpu::PrimitiveState { cull_mode: None, ..Default::default() },
        depth_stencil: Some(wgpu::DepthStencilState {
            format: wgpu::TextureFormat::Depth32Float,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Less),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        multisample: wgpu::MultisampleState { count: 4, ..Default::default() },
        fragment: Some(wgpu::FragmentState {
            module: &module,
            entry_point: Some("fs_main"),
            compilation_options: Default::default(),
            targets: &[Some(target_format.into())],
        }),
        multiview_mask: None,
        cache: None,
    });

    let camera_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("camera"),
        contents: bytemuck::cast_slice(&camera(scene, azimuth, elevation).to_cols_array()),
        usage: wgpu::BufferUsages::UNIFORM,
    });
    let camera_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("camera"),
        layout: &camera_layout,
        entries: &[wgpu::BindGroupEntry { binding: 0, resource: camera_buffer.as_entire_binding() }],
    });
    let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
        mag_filter: wgpu::FilterMode::Linear,
        min_filter: wgpu::FilterMode::Linear,
        ..Default::default()
    });
    let white = bake::scene::LinearImage { width: 1, height: 1, pixels: vec![[1.0; 4]] };

    // One draw per primitive: its vertices through the UV set its base
    // colour texture reads, its factor, its texture.
    let mut draws = Vec::new();
    for primitive in &scene.primitives {
        let mut material = primitive.drawn_material.map(|m| scene.materials[m].clone()).unwrap_or_default();
        // A cut-out's baked form shows the atlas as emission over a black base colour.
        if material.base_color[..3] == [0.0; 3] && material.emissive_texture.is_some() {
            material.base_color = [material.emission[0], material.emission[1], material.emission[2], 1.0];
            material.base_color_texture = material.emissive_texture.take();
        }
        let texture_ref = material.base_color_texture.as_ref();
        let image = texture_ref.and_then(|t| scene.images[t.image].as_deref());
        let uvs = match texture_ref.map(|t| t.tex_coord) {
            Some(1) => primitive.uv1.as_ref(),
            Some(_) => primitive.uv0.as_ref(),
            None => None,
        };
        let vertices: Vec<Vertex> = primitive
            .positions
            .iter()
            .enumerate()
            .map(|(i, &position)| Vertex { position, uv: uvs.map_or([0.0; 2], |u| u[i]) })
            .collect();
        let transform = texture_ref.map_or(bake::scene::TextureRef::IDENTITY, |t| t.transform);
        let has_texture = if image.is_some() && uvs.is_some() { 1.0 } else { 0.0 };
        let uniform = MaterialUniform {
            factor: material.base_color,
            row0: [transform[0][0], transform[0][1], transform[0][2], has_texture],
            row1: [transform[1][0], transform[1][1], transform[1][2], 0.0],
        };
        let texture = upload(gpu, image.unwrap_or(&white));
        let uniform_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("material"),
            contents: bytemuck::bytes_of(&uniform),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let view = texture.create_view(&Default::default());
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("material"),
            layout: &material_layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: uniform_buffer.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(&view) },
                wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::Sampler(&sampler) },
            ],
        });
        let vertex_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("vertices"),
            contents: bytemuck::cast_slice(&vertices),
            usage: wgpu::BufferUsages::VERTEX,
        });
        let index_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("indices"),
            contents: bytemuck::cast_slice(&primitive.indices),
            usage: wgpu::BufferUsages::INDEX,
        });
        draws.push((group, vertex_buffer, index_buffer, primitive.indices.len() as u32));
    }

    let attachment = |format, samples, usage| {
        device.create_texture(&wgpu::TextureDescriptor {
            label: Some("render target"),
            size: wgpu::Extent3d { width: WIDTH, height: HEIGHT, depth_or_array_layers: 1 },
            mip_level_count: 1,
            sample_count: samples,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage,
            view_formats: &[],
        })
    };
    let msaa = attachment(target_format, 4, wgpu::TextureUsages::RENDER_ATTACHMENT);
    let resolved = attachment(target_format, 1, wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC);
    let depth = attachment(wgpu::TextureFormat::Depth32Float, 4, wgpu::TextureUsages::RENDER_ATTACHMENT);
    let (msaa_view, resolved_view, depth_view) = (
        msaa.create_view(&Default::default()),
        resolved.create_view(&Default::default()),
        depth.create_view(&Default::default()),
    );
    let mut encoder = device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("render"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &msaa_view,
                depth_slice: None,
                resolve_target: Some(&resolved_view),
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color { r: BACKGROUND, g: BACKGROUND, b: BACKGROUND, a: 1.0 }),
                    store: wgpu::StoreOp::Discard,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &depth_view,
                depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Discard }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &camera_group, &[]);
        for (group, vertices, indices, count) in &draws {
            pass.set_bind_group(1, group, &[]);
            pass.set_vertex_buffer(0, vertices.slice(..));
            pass.set_index_buffer(indices.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..*count, 0, 0..1);
        }
    }
    let readback = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("render readback"),
        size: (WIDTH * HEIGHT * 4) as u64,
        usage: wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    encoder.copy_texture_to_buffer(
        resolved.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &readback,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(WIDTH * 4),
                rows_per_image: Some(HEIGHT),
            },
        },
        wgpu::Extent3d { width: WIDTH, height: HEIGHT, depth_or_array_layers: 1 },
    );
    gpu.queue.submit([encoder.finish()]);
    gpu.check("render")?;
    read_buffer::<u8>(gpu, &readback, (WIDTH * HEIGHT * 4) as usize)
}

/// A linear-light texture (Rgba16Float, filterable) of `image`.
fn upload(gpu: &Gpu, image: &bake::scene::LinearImage) -> wgpu::Texture {
    let halves: Vec<half::f16> = image.pixels.iter().flatten().map(|&v| half::f16::from_f32(v)).collect();
    gpu.device.create_texture_with_data(
        &gpu.queue,
        &wgpu::TextureDescriptor {
            label: Some("base colour"),
            size: wgpu::Extent3d { width: image.width, height: image.height, depth_or_array_layers: 1 },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba16Float,
            usage: wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        },
        wgpu::util::TextureDataOrder::LayerMajor,
        bytemuck::cast_slice(&halves),
    )
}
