//! Each patch's unshot power Σ ΔL·A and where its unshot light lies
//! (`solve_patch_power`'s `main`, one invocation a patch), which the select
//! pass ranks; and once the batch's shooters are chosen, their light by
//! sub-cells of their patches for the near field (`shooter_cells_of_batch`).
//! Both entry points share one bind group.

use super::resources::{Inputs, Resources};
use crate::gpu::{self, Gpu, Shader};

pub(super) struct PatchPower {
    power: wgpu::ComputePipeline,
    shooter_cells: wgpu::ComputePipeline,
    group: wgpu::BindGroup,
    /// Workgroups over the patches.
    groups: (u32, u32),
    /// One workgroup per shooter slot.
    shooter_count: u32,
}

impl PatchPower {
    pub(super) fn new(gpu: &Gpu, r: &Resources, inputs: &Inputs) -> PatchPower {
        let groups = r.dispatch.patch_groups;
        let params = gpu.uniform_buffer("solve_patch_power params", &r.params.with_row_stride(groups.0 * 64));
        let none = wgpu::BufferUsages::empty();
        let members = gpu.storage_buffer("solve_patch_power members", &inputs.patches.members, none);
        let member_points = gpu.storage_buffer("solve_patch_power member points", &member_points(inputs), none);
        let layout = bind_group_layout(gpu);
        let group = gpu::bind_buffers(
            gpu,
            "solve_patch_power",
            &layout,
            &[
                &params,
                &r.texels,
                &r.patches,
                &members,
                &r.unshot,
                &r.patch_power,
                &r.patch_origin,
                &r.shooters,
                &r.shooter_cells,
                &r.shares,
                &member_points,
            ],
        );
        PatchPower {
            power: gpu.compute_pipeline(Shader::SolvePatchPower, "main", &[&layout]),
            shooter_cells: gpu.compute_pipeline(Shader::SolvePatchPower, "shooter_cells_of_batch", &[&layout]),
            group,
            groups,
            shooter_count: r.dispatch.shooter_count,
        }
    }

    /// Sums every patch's unshot power.
    pub(super) fn record_power(&self, pass: &mut wgpu::ComputePass) {
        pass.set_pipeline(&self.power);
        pass.set_bind_group(0, &self.group, &[]);
        pass.dispatch_workgroups(self.groups.0, self.groups.1, 1);
    }

    /// Sums the chosen shooters' light by sub-cells (after the select pass).
    pub(super) fn record_shooter_cells(&self, pass: &mut wgpu::ComputePass) {
        pass.set_pipeline(&self.shooter_cells);
        pass.set_bind_group(0, &self.group, &[]);
        pass.dispatch_workgroups(self.shooter_count, 1, 1);
    }
}

fn bind_group_layout(gpu: &Gpu) -> wgpu::BindGroupLayout {
    let compute = wgpu::ShaderStages::COMPUTE;
    gpu.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("solve_patch_power"),
        entries: &[
            // 0: BounceParams (patch count, dispatch stride)
            gpu::uniform_entry(0, compute),
            // 1: texels (areas)
            gpu::storage_entry(1, true, compute),
            // 2: patches
            gpu::storage_entry(2, true, compute),
            // 3: patch members
            gpu::storage_entry(3, true, compute),
            // 4: unshot radiance per texel
            gpu::storage_entry(4, true, compute),
            // 5: per-patch power (written)
            gpu::storage_entry(5, false, compute),
            // 6: per-patch origins (written)
            gpu::storage_entry(6, false, compute),
            // 7: the batch's shooters
            gpu::uniform_entry(7, compute),
            // 8: their light by sub-cells (written)
            gpu::storage_entry(8, false, compute),
            // 9: each texel's share of the area that bounces
            gpu::storage_entry(9, true, compute),
            // 10: each member's position and bouncing area
            gpu::storage_entry(10, true, compute),
        ],
    })
}

/// The patch members' texels' positions and bouncing areas in the members'
/// order, so that the power pass, run every batch, reads them in order
/// rather than whole texels by index.
fn member_points(inputs: &Inputs) -> Vec<[f32; 4]> {
    let points = inputs.patches.members.iter().map(|&i| {
        let t = &inputs.texels.texels[i as usize];
        [t.position[0], t.position[1], t.position[2], t.area * inputs.shares[i as usize]]
    });
    points.collect()
}
