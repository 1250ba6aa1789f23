//! Shadow casters for the depth maps of both solve passes: every triangle of
//! the scene in world space, wound counter-clockwise about its front side's
//! normal and drawn from both sides (a one-sided plane still blocks light).
//! Triangles of cut-out materials (`Material::cutoff`: alpha MASK, or a
//! BLEND with a base colour texture) come last and are drawn with a
//! fragment shader that discards their cut-out texels, so light passes
//! through the holes.

use std::ops::Range;

use bytemuck::{Pod, Zeroable};

use super::surfaces;
use crate::gpu::{self, Gpu, Materials};
use crate::scene::Scene;

/// One caster vertex. Mirrors `CasterIn` in solve_hemicube.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct CasterVertex {
    position: [f32; 3],
    material: u32,
    uv0: [f32; 2],
    uv1: [f32; 2],
    /// 1 where the vertex lies on an open surface (`surfaces`), or on a
    /// cut-out material's: a sheet, not a solid's skin.
    sheet: u32,
}

/// The vertex layout every caster pipeline uses.
pub const VERTEX_LAYOUT: wgpu::VertexBufferLayout<'static> = wgpu::VertexBufferLayout {
    array_stride: std::mem::size_of::<CasterVertex>() as u64,
    step_mode: wgpu::VertexStepMode::Vertex,
    attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Uint32, 2 => Float32x2, 3 => Float32x2, 4 => Uint32],
};

/// The scene's casters on the GPU, with the materials their cut-outs need.
pub struct Casters {
    pub(super) vertices: wgpu::Buffer,
    pub(super) indices: wgpu::Buffer,
    /// Index ranges of opaque and of alpha-MASK triangles, one after the other.
    pub(super) opaque: Range<u32>,
    pub(super) masked: Range<u32>,
    /// The opaque triangles' solids, with `Topology::Solids`.
    pub(super) solids: Option<surfaces::Solids>,
    pub materials: Materials,
}

/// What the casters' topology is worked out for.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum Topology {
    /// Mark the vertices on open surfaces, which the direct pass's depth maps read.
    Sheets,
    /// Find the solids, whose far sides the bounce pass's cull leaves out.
    Solids,
}

impl Casters {
    pub fn new(gpu: &Gpu, scene: &Scene, topology: Topology) -> Casters {
        let materials = Materials::upload(gpu, scene);
        let default_material = scene.materials.len();
        let mut vertices = Vec::new();
        let (mut opaque, mut masked) = (Vec::new(), Vec::new());
        for primitive in &scene.primitives {
            let base = vertices.len() as u32;
            let material = primitive.material.unwrap_or(default_material);
            for (i, &position) in primitive.positions.iter().enumerate() {
                vertices.push(CasterVertex {
                    position,
                    material: material as u32,
                    uv0: primitive.uv0.as_ref().map_or([0.0; 2], |uv| uv[i]),
                    uv1: primitive.uv1.as_ref().map_or([0.0; 2], |uv| uv[i]),
                    sheet: 0,
                });
            }
            let target = if materials.is_masked(material) { &mut masked } else { &mut opaque };
            // Wound so that the front is the side the lightmap faces: the
            // depth maps mark surfaces the light sees from behind.
            for t in 0..primitive.triangle_count() {
                target.extend(primitive.front_corners(t).map(|i| i + base));
            }
        }
        let positions: Vec<[f32; 3]> = vertices.iter().map(|v| v.position).collect();
        let solids = (topology == Topology::Solids).then(|| surfaces::solids(&positions, &opaque));
        if topology == Topology::Sheets {
            for (vertex, open) in vertices.iter_mut().zip(surfaces::open_vertices(&positions, &opaque)) {
                vertex.sheet = open as u32;
            }
            for &i in &masked {
                vertices[i as usize].sheet = 1;
            }
        }
        let (opaque_count, masked_count) = (opaque.len() as u32, masked.len() as u32);
        opaque.extend(masked);
        Casters {
            vertices: gpu.storage_buffer("casters vertices", &vertices, wgpu::BufferUsages::VERTEX),
            indices: gpu.storage_buffer(
                "casters indices",
                &opaque,
                wgpu::BufferUsages::INDEX | wgpu::BufferUsages::COPY_SRC,
            ),
            opaque: 0..opaque_count,
            masked: opaque_count..opaque_count + masked_count,
            solids,
            materials,
        }
    }

    /// Layout entries for bindings `first`, `first + 1`, `first + 2`: the
    /// materials, their textures and the sampler, for the masked fragment shader.
    pub fn layout_entries(first: u32) -> [wgpu::BindGroupLayoutEntry; 3] {
        let fragment = wgpu::ShaderStages::FRAGMENT;
        [
            gpu::storage_entry(first, true, fragment),
            gpu::texture_array_entry(first + 1, fragment, gpu::FILTERABLE),
            gpu::sampler_entry(first + 2, fragment),
        ]
    }

    /// The bind-group entries matching `layout_entries(first)`.
    pub fn bind_entries(&self, first: u32) -> [wgpu::BindGroupEntry<'_>; 3] {
        [
            wgpu::BindGroupEntry { binding: first, resource: self.materials.buffer.as_entire_binding() },
            wgpu::BindGroupEntry {
                binding: first + 1,
                resource: wgpu::BindingResource::TextureView(&self.materials.textures),
            },
            wgpu::BindGroupEntry {
                binding: first + 2,
                resource: wgpu::BindingResource::Sampler(&self.materials.sampler),
            },
        ]
    }

    /// Binds the geometry for drawing, with `instances` (what the vertex
    /// shader needs of each instance's light or hemicube face, as the
    /// pipeline's `instances` layout reads it) in vertex buffer 1.
    pub fn bind(&self, pass: &mut wgpu::RenderPass, instances: &wgpu::Buffer) {
        pass.set_vertex_buffer(0, self.vertices.slice(..));
        pass.set_vertex_buffer(1, instances.slice(..));
        pass.set_index_buffer(self.indices.slice(..), wgpu::IndexFormat::Uint32);
    }

    /// Draws the opaque casters for `instance` with the bound pipeline.
    pub fn draw_opaque(&self, pass: &mut wgpu::RenderPass, instance: u32) {
        if !self.opaque.is_empty() {
            pass.draw_indexed(self.opaque.clone(), 0, instance..instance + 1);
        }
    }

    /// Draws the cut-out casters for `instance` with `masked`, from an
    /// index buffer that holds the casters' own indices first; whether
    /// there were any (and `masked` is now bound).
    pub fn draw_masked(&self, pass: &mut wgpu::RenderPass, masked: &wgpu::RenderPipeline, instance: u32) -> bool {
        if self.masked.is_empty() {
            return false;
        }
        pass.set_pipeline(masked);
        pass.draw_indexed(self.masked.clone(), 0, instance..instance + 1);
        true
    }

    /// A depth-only pipeline for casters, with its vertex and fragment entry
    /// points (the fragment stage discards what alpha cuts out and writes no
    /// colour). `instances` lays out the per-instance attributes (locations
    /// 5 on): a CPU driver fetches an instance's attributes once per draw,
    /// where a buffer read indexed by the instance costs a load per vertex
    /// and lane.
    pub fn pipeline(
        gpu: &Gpu,
        label: &str,
        layout: &wgpu::PipelineLayout,
        module: &wgpu::ShaderModule,
        [vertex, fragment]: [&str; 2],
        instances: wgpu::VertexBufferLayout<'_>,
    ) -> wgpu::RenderPipeline {
        gpu.device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some(label),
            layout: Some(layout),
            vertex: wgpu::VertexState {
                module,
                entry_point: Some(vertex),
                compilation_options: Default::default(),
                buffers: &[Some(VERTEX_LAYOUT), Some(instances)],
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
            fragment: Some(wgpu::FragmentState {
                module,
                entry_point: Some(fragment),
                compilation_options: Default::default(),
                targets: &[],
            }),
            multiview_mask: None,
            cache: None,
        })
    }
}
