//! The batch's shooters (`solve_select`, one workgroup): the patches with
//! the most power to shoot (unshot, owed or shot ahead), each with the five
//! faces of its hemicube, and the batch's totals, the one thing the batch
//! loop reads back.

use anyhow::Result;
use bytemuck::{Pod, Zeroable};

use super::resources::{Inputs, Resources};
use crate::gpu::{self, Gpu, Shader, read_buffer};

/// Mirrors `Shooter` in include/bounce.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable, Default)]
pub(super) struct Shooter {
    position: [f32; 3],
    area: f32,
    normal: [f32; 3],
    patch_index: u32,
    radiance: [f32; 3],
    radius: f32,
    rect_centre: [f32; 3],
    lift: f32,
    half_u: [f32; 3],
    rect_area: f32,
    half_v: [f32; 3],
    _pad: u32,
    overshoot: [f32; 3],
    _pad2: u32,
}

/// Mirrors `BounceStats` in include/bounce.wgsl: the totals of a batch.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable, Default, Debug)]
pub(super) struct GpuStats {
    pub(super) unshot: [f32; 4],
    pub(super) received: [f32; 4],
    pub(super) shot: [f32; 4],
    pub(super) shooters: u32,
    pub(super) landing: f32,
    /// Σ |luminance(ΔL·A)| over the patches: light unshot or owed.
    pub(super) unsettled: f32,
    _pad: u32,
}

pub(super) struct Select {
    pipeline: wgpu::ComputePipeline,
    group: wgpu::BindGroup,
    /// The batch's totals (`GpuStats`), read back.
    stats: wgpu::Buffer,
}

impl Select {
    pub(super) fn new(gpu: &Gpu, r: &Resources, inputs: &Inputs) -> Select {
        let none = wgpu::BufferUsages::empty();
        let patch_albedo = gpu.storage_buffer("solve_select patch albedo", inputs.patch_albedo, none);
        let stats = gpu.storage_buffer("solve_select stats", &[GpuStats::default()], wgpu::BufferUsages::COPY_SRC);
        let layout = bind_group_layout(gpu);
        let group = gpu::bind_buffers(
            gpu,
            "solve_select",
            &layout,
            &[
                &r.params_buffer,
                &r.patches,
                &r.patch_power,
                &r.chosen,
                &r.shooters,
                &stats,
                &r.patch_origin,
                &r.patch_coverage,
                &r.hemicube_faces,
                &patch_albedo,
                &r.patch_overshoot,
            ],
        );
        Select { pipeline: pipeline(gpu), group, stats }
    }

    /// Chooses the batch's shooters (after the power pass).
    pub(super) fn record(&self, pass: &mut wgpu::ComputePass) {
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.group, &[]);
        pass.dispatch_workgroups(1, 1, 1);
    }

    /// The totals of the batch last selected.
    pub(super) fn stats(&self, gpu: &Gpu) -> Result<GpuStats> {
        Ok(read_buffer(gpu, &self.stats, 1)?[0])
    }
}

/// The pass's pipeline (built once per device, `solve::warm`).
pub(super) fn pipeline(gpu: &Gpu) -> wgpu::ComputePipeline {
    gpu.compute_pipeline(Shader::SolveSelect, "main", &[&bind_group_layout(gpu)])
}

fn bind_group_layout(gpu: &Gpu) -> wgpu::BindGroupLayout {
    let compute = wgpu::ShaderStages::COMPUTE;
    gpu.bind_group_layout(
        "solve_select",
        &[
            // 0: BounceParams
            gpu::uniform_entry(0, compute),
            // 1: patches
            gpu::storage_entry(1, true, compute),
            // 2: per-patch power
            gpu::storage_entry(2, true, compute),
            // 3: chosen flags (written)
            gpu::storage_entry(3, false, compute),
            // 4: shooters (written)
            gpu::storage_entry(4, false, compute),
            // 5: totals (written)
            gpu::storage_entry(5, false, compute),
            // 6: per-patch origins
            gpu::storage_entry(6, true, compute),
            // 7: per-patch coverage
            gpu::storage_entry(7, true, compute),
            // 8: the shooters' hemicube faces (written)
            gpu::storage_entry(8, false, compute),
            // 9: per-patch Σ albedo·A
            gpu::storage_entry(9, true, compute),
            // 10: per-patch light it would shoot ahead, per unit albedo (written)
            gpu::storage_entry(10, false, compute),
        ],
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::mirror::assert_mirrors;

    #[test]
    fn the_shooter_and_the_totals_mirror_bounce_wgsl() {
        assert_mirrors!(
            Shader::SolveShoot,
            "Shooter",
            Shooter {
                position,
                area,
                normal,
                patch_index,
                radiance,
                radius,
                rect_centre,
                lift,
                half_u,
                rect_area,
                half_v,
                overshoot
            }
        );
        assert_mirrors!(
            Shader::SolveSelect,
            "BounceStats",
            GpuStats { unshot, received, shot, shooters, landing, unsettled }
        );
    }
}
