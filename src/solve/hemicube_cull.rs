//! Per-face lists of the casters a batch's hemicube faces can see
//! (`solve_hemicube_cull`), drawn indirectly by the bounce pass. Each face
//! sees part of the scene, while a draw costs every triangle it names: on a
//! CPU driver, drawing the whole scene five times a shooter was most of the
//! bounce pass. A list also leaves out a solid's far side when the shooter
//! is outside the solid (`surfaces::solids`): about half of a statue.
//!
//! The lists sit in one index buffer after a copy of the casters' indices,
//! so a face whose list overflows draws every opaque caster instead, and
//! alpha-MASK casters (not culled) draw from the same buffer. A scene too
//! large for the adapter to bind that way is drawn whole.

use bytemuck::{Pod, Zeroable};

use super::casters::Casters;
use super::surfaces;
use crate::gpu::{self, Gpu, Shader};

/// Words per face in `draws` (`DRAW_WORDS` in the shader): the indirect
/// draw's five, then the list's count.
const DRAW_WORDS: u64 = 8;

/// Mirrors `CullParams` in solve_hemicube_cull.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct CullParams {
    triangles: u32,
    capacity: u32,
    lists_first: u32,
    faces: u32,
    near: f32,
    row_stride: u32,
    _pad: [u32; 2],
}

/// Mirrors `Solid` in solve_hemicube_cull.wgsl (`surfaces::Solid`).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct GpuSolid {
    lo: [f32; 3],
    /// 1 where the outside is the front, -1 where it is the back.
    outside_facing: f32,
    hi: [f32; 3],
    _pad: f32,
}

pub struct HemicubeCull {
    /// The casters' indices, then each face's list.
    indices: wgpu::Buffer,
    /// Per face: its indirect draw, then its list's count.
    draws: wgpu::Buffer,
    cull: wgpu::ComputePipeline,
    write_draws: wgpu::ComputePipeline,
    group: wgpu::BindGroup,
    groups: (u32, u32),
    faces: u32,
}

impl HemicubeCull {
    /// Lists for `faces` hemicube faces, whose shooters `hemicube_faces`
    /// holds (`HemicubeFace`, five a slot); `near` is the hemicubes' near
    /// plane. The lists take at most `list_bytes`: a face that sees more
    /// than its share draws every opaque caster. None where no list has
    /// room (the casters are too many for the adapter to bind with lists, or
    /// `list_bytes` is 0): every face then draws every caster.
    pub fn new(
        gpu: &Gpu,
        casters: &Casters,
        hemicube_faces: &wgpu::Buffer,
        faces: u32,
        near: f32,
        list_bytes: u64,
    ) -> Option<HemicubeCull> {
        let triangles = casters.opaque.len() as u32 / 3;
        let copied = casters.masked.end as u64;
        let binding = gpu.limits.max_storage_buffer_binding_size.min(gpu.limits.max_buffer_size);
        let list_words = list_bytes.min(binding.saturating_sub(4 * copied)) / 4;
        let capacity = (list_words / (3 * faces as u64)).min(triangles as u64) as u32;
        if capacity == 0 || casters.vertices.size() > binding {
            return None;
        }
        let indices = gpu.zeroed_storage_buffer::<u32>(
            "solve_hemicube_cull indices",
            (copied + 3 * faces as u64 * capacity as u64) as usize,
            wgpu::BufferUsages::INDEX | wgpu::BufferUsages::COPY_DST,
        );
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&casters.indices, 0, &indices, 0, 4 * copied);
        gpu.queue.submit([encoder.finish()]);
        let draws = gpu.zeroed_storage_buffer::<u32>(
            "solve_hemicube_cull draws",
            (DRAW_WORDS * faces as u64) as usize,
            wgpu::BufferUsages::INDIRECT,
        );
        let groups = gpu.dispatch_size(triangles, 64);
        let params = CullParams {
            triangles,
            capacity,
            lists_first: copied as u32,
            faces,
            near,
            row_stride: groups.0 * 64,
            _pad: [0; 2],
        };
        let params = gpu.uniform_buffer("solve_hemicube_cull params", &params);
        let (triangle_solid, solids) = solid_buffers(gpu, casters, triangles);
        let layout = bind_group_layout(gpu);
        let group = gpu::bind_buffers(
            gpu,
            "solve_hemicube_cull",
            &layout,
            &[&params, &casters.vertices, hemicube_faces, &indices, &draws, &triangle_solid, &solids],
        );
        let [cull, write_draws] = pipelines(gpu);
        Some(HemicubeCull { cull, write_draws, indices, draws, group, groups, faces })
    }

    /// Lists the batch's faces (after its shooters are chosen) and writes their draws.
    pub fn record(&self, encoder: &mut wgpu::CommandEncoder) {
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_bind_group(0, &self.group, &[]);
        pass.set_pipeline(&self.cull);
        pass.dispatch_workgroups(self.groups.0, self.groups.1, 1);
        pass.set_pipeline(&self.write_draws);
        pass.dispatch_workgroups(self.faces.div_ceil(64), 1, 1);
    }

    /// Binds the index buffer the draws read.
    pub fn bind(&self, pass: &mut wgpu::RenderPass) {
        pass.set_index_buffer(self.indices.slice(..), wgpu::IndexFormat::Uint32);
    }

    /// Draws face `face`'s list (or every opaque caster) with the bound pipeline.
    pub fn draw(&self, pass: &mut wgpu::RenderPass, face: u32) {
        pass.draw_indexed_indirect(&self.draws, 4 * DRAW_WORDS * face as u64);
    }
}

/// Each opaque triangle's solid, and the solids (one unused where there is
/// none: a binding holds at least one), as the shader's buffers.
fn solid_buffers(gpu: &Gpu, casters: &Casters, triangles: u32) -> (wgpu::Buffer, wgpu::Buffer) {
    let none;
    let (triangle_solid, solids) = match &casters.solids {
        Some(s) => (&s.triangle_solid[..], &s.solids[..]),
        None => {
            none = vec![surfaces::NOT_SOLID; triangles as usize];
            (&none[..], &[][..])
        }
    };
    let mut solids: Vec<GpuSolid> = solids
        .iter()
        .map(|s| GpuSolid {
            lo: s.lo.into(),
            outside_facing: if s.outward { 1.0 } else { -1.0 },
            hi: s.hi.into(),
            _pad: 0.0,
        })
        .collect();
    if solids.is_empty() {
        solids.push(GpuSolid::zeroed());
    }
    let triangle_solid =
        gpu.storage_buffer("solve_hemicube_cull triangle solids", triangle_solid, wgpu::BufferUsages::empty());
    let solids = gpu.storage_buffer("solve_hemicube_cull solids", &solids, wgpu::BufferUsages::empty());
    (triangle_solid, solids)
}

/// The pass's pipelines, the cull and the draws' writer (built once per
/// device, `solve::warm`).
pub(super) fn pipelines(gpu: &Gpu) -> [wgpu::ComputePipeline; 2] {
    let layout = bind_group_layout(gpu);
    ["cull_triangles", "write_draws"].map(|entry| gpu.compute_pipeline(Shader::SolveHemicubeCull, entry, &[&layout]))
}

fn bind_group_layout(gpu: &Gpu) -> wgpu::BindGroupLayout {
    let compute = wgpu::ShaderStages::COMPUTE;
    gpu.bind_group_layout(
        "solve_hemicube_cull",
        &[
            // 0: CullParams, 1: caster vertices, 2: the batch's hemicube faces
            gpu::uniform_entry(0, compute),
            gpu::storage_entry(1, true, compute),
            gpu::uniform_entry(2, compute),
            // 3: the indices and lists, 4: the draws (both written)
            gpu::storage_entry(3, false, compute),
            gpu::storage_entry(4, false, compute),
            // 5: each opaque triangle's solid, 6: the solids
            gpu::storage_entry(5, true, compute),
            gpu::storage_entry(6, true, compute),
        ],
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::mirror::assert_mirrors;

    #[test]
    fn the_cull_structs_mirror_their_shader() {
        assert_mirrors!(
            Shader::SolveHemicubeCull,
            "CullParams",
            CullParams { triangles, capacity, lists_first, faces, near, row_stride }
        );
        assert_mirrors!(Shader::SolveHemicubeCull, "Solid", GpuSolid { lo, outside_facing, hi });
    }
}
