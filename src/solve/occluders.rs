//! The occluder pass (`solve_occluders.wgsl`): for every point the direct
//! pass will gather at, what above the plane of its face can block its
//! light: up to two convex polygons, tested exactly, and up to four cones
//! around everything else. The direct pass casts rays only into them.

use bytemuck::{Pod, Zeroable};

use crate::gpu::{self, Gpu, Shader};

/// Mirrors `OccluderParams` in solve_occluders.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct OccluderParams {
    point_count: u32,
    row_stride: u32,
    _pad: [u32; 2],
}

/// Mirrors `Occluders` in include/occluders.wgsl: 96 bytes a point.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub struct Occluders {
    pub cones: [[f32; 4]; 4],
    pub sines: [f32; 4],
    pub polygons: [u32; 2],
    pub flags: u32,
    pub visits: u32,
}

/// The pass: its pipeline and the layout of its own bind group (group 0;
/// the scene is group 1).
pub struct OccluderPass {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
}

impl OccluderPass {
    pub fn new(gpu: &Gpu, scene_layout: &wgpu::BindGroupLayout) -> OccluderPass {
        let compute = wgpu::ShaderStages::COMPUTE;
        let layout = gpu.bind_group_layout(
            "solve_occluders",
            &[
                // 0: OccluderParams
                gpu::uniform_entry(0, compute),
                // 1: the points (texels and sub-samples)
                gpu::storage_entry(1, true, compute),
                // 2: their occluders (written)
                gpu::storage_entry(2, false, compute),
            ],
        );
        let pipeline = gpu.compute_pipeline(Shader::SolveOccluders, "main", &[&layout, scene_layout]);
        OccluderPass { pipeline, layout }
    }

    /// Records the pass over `point_count` points of `points` into
    /// `encoder`; returns the buffer it fills.
    pub fn record(
        &self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        scene: &wgpu::BindGroup,
        points: &wgpu::Buffer,
        point_count: u32,
    ) -> wgpu::Buffer {
        let (groups_x, groups_y) = gpu.dispatch_size(point_count, 64);
        let params = OccluderParams { point_count, row_stride: groups_x * 64, _pad: [0; 2] };
        let params = gpu.uniform_buffer("solve_occluders params", &params);
        let occluders = gpu.zeroed_storage_buffer::<Occluders>(
            "solve_occluders",
            point_count as usize,
            wgpu::BufferUsages::COPY_SRC,
        );
        let group = gpu::bind_buffers(gpu, "solve_occluders", &self.layout, &[&params, points, &occluders]);
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.set_bind_group(1, scene, &[]);
        pass.dispatch_workgroups(groups_x, groups_y, 1);
        occluders
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_rust_structs_mirror_the_shaders() {
        use crate::gpu::{Shader, mirror::assert_mirrors};
        assert_mirrors!(Shader::SolveOccluders, "OccluderParams", OccluderParams { point_count, row_stride });
        assert_mirrors!(Shader::SolveDirect, "Occluders", Occluders { cones, sines, polygons, flags, visits });
    }
}
