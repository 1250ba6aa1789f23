//! The batch's hemicube depth maps (`solve_hemicube`): five faces per
//! shooter, each into its viewport of one depth atlas, drawing the casters
//! `hemicube_cull` listed for the face, or every caster.

use bytemuck::{Pod, Zeroable};

use super::casters::{Casters, Topology};
use super::hemicube_cull::HemicubeCull;
use super::resources::Resources;
use crate::gpu::{self, Gpu, Shader};
use crate::scene::Scene;

/// Mirrors `HemicubeFace` in include/hemicube.wgsl: one face of a shooter's hemicube,
/// written on the GPU by the select pass.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable, Default)]
pub(super) struct HemicubeFace {
    position: [f32; 3],
    lift: f32,
    normal: [f32; 3],
    face: u32,
}

/// The pass's instance attributes (`FaceIn` in solve_hemicube.wgsl).
const FACE_INSTANCES: wgpu::VertexBufferLayout<'static> = wgpu::VertexBufferLayout {
    array_stride: std::mem::size_of::<HemicubeFace>() as u64,
    step_mode: wgpu::VertexStepMode::Instance,
    attributes: &wgpu::vertex_attr_array![5 => Float32x3, 6 => Float32, 7 => Float32x3, 8 => Uint32],
};

pub(super) struct Hemicube {
    /// For opaque and for alpha-cut-out casters.
    opaque: wgpu::RenderPipeline,
    masked: wgpu::RenderPipeline,
    group: wgpu::BindGroup,
    /// The scene's triangles, as the hemicubes draw them (the cull lists them too).
    pub(super) casters: Casters,
    shooter_count: u32,
    /// Face width, and shooters' tiles per row of the atlas.
    face: u32,
    tiles_per_row: u32,
}

impl Hemicube {
    pub(super) fn new(gpu: &Gpu, scene: &Scene, r: &Resources) -> Hemicube {
        let casters = Casters::new(gpu, scene, Topology::Solids);
        let layout = bind_group_layout(gpu);
        let [materials_binding, textures_binding, sampler_binding] = casters.bind_entries(2);
        let group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("solve_hemicube"),
            layout: &layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: r.params_buffer.as_entire_binding() },
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
            |label, vs, fs| Casters::pipeline(gpu, label, &pipeline_layout, &module, [vs, fs], FACE_INSTANCES);
        Hemicube {
            opaque: pipeline("solve_hemicube", "vs_hemicube", "fs_hemicube"),
            masked: pipeline("solve_hemicube masked", "vs_hemicube_masked", "fs_hemicube_masked"),
            group,
            casters,
            shooter_count: r.dispatch.shooter_count,
            face: r.dispatch.face,
            tiles_per_row: r.dispatch.tiles_per_row,
        }
    }

    /// Renders the five faces of every shooter's hemicube, each into its
    /// viewport of the depth atlas (the same layout `hemicube_viewport` in
    /// include/hemicube.wgsl reads): the casters `cull` listed for the face, or every
    /// caster.
    pub(super) fn render(&self, encoder: &mut wgpu::CommandEncoder, r: &Resources, cull: Option<&HemicubeCull>) {
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
        pass.set_bind_group(0, &self.group, &[]);
        self.casters.bind(&mut pass, &r.hemicube_faces);
        if let Some(cull) = cull {
            // The faces' lists, in place of the casters' own indices.
            cull.bind(&mut pass);
        }
        // Binding a pipeline makes a CPU driver derive its state again: the
        // opaque one is bound once, and again only after a masked draw.
        pass.set_pipeline(&self.opaque);
        let face_bytes = std::mem::size_of::<HemicubeFace>() as u64;
        for slot in 0..self.shooter_count {
            for (f, [x, y, w, h]) in self.viewports(slot).into_iter().enumerate() {
                pass.set_viewport(x, y, w, h, 0.0, 1.0);
                // The face's attributes as instance 0: an indirect draw's first
                // instance must be 0 on adapters without INDIRECT_FIRST_INSTANCE.
                let instance = slot * 5 + f as u32;
                pass.set_vertex_buffer(1, r.hemicube_faces.slice(instance as u64 * face_bytes..));
                match cull {
                    Some(cull) => cull.draw(&mut pass, instance),
                    None => self.casters.draw_opaque(&mut pass, 0),
                }
                if self.casters.draw_masked(&mut pass, &self.masked, 0) {
                    pass.set_pipeline(&self.opaque);
                }
            }
        }
    }

    /// The viewports of `slot`'s five faces in the atlas: the full front
    /// face, then the four half faces.
    fn viewports(&self, slot: u32) -> [[f32; 4]; 5] {
        let s = self.face as f32;
        let tile = [(slot % self.tiles_per_row) as f32 * 3.0 * s, (slot / self.tiles_per_row) as f32 * s];
        [
            [tile[0], tile[1], s, s],
            [tile[0] + s, tile[1], s, 0.5 * s],
            [tile[0] + s, tile[1] + 0.5 * s, s, 0.5 * s],
            [tile[0] + 2.0 * s, tile[1], s, 0.5 * s],
            [tile[0] + 2.0 * s, tile[1] + 0.5 * s, s, 0.5 * s],
        ]
    }
}

fn bind_group_layout(gpu: &Gpu) -> wgpu::BindGroupLayout {
    let vertex = wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT;
    let [materials_entry, textures_entry, sampler_entry] = Casters::layout_entries(2);
    gpu.bind_group_layout(
        "solve_hemicube",
        &[
            // 0: BounceParams (near, far)
            gpu::uniform_entry(0, vertex),
            // 2: materials (alpha cut-outs)
            materials_entry,
            // 3: their textures
            textures_entry,
            // 4: their sampler
            sampler_entry,
        ],
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::mirror::assert_mirrors;

    #[test]
    fn the_hemicube_face_mirrors_its_shader() {
        assert_mirrors!(Shader::SolveHemicube, "HemicubeFace", HemicubeFace { position, lift, normal, face });
    }
}
