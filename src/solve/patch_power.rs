//! Each patch's unshot power Σ ΔL·A and where its unshot light lies
//! (`solve_patch_power`'s `main`, one invocation a patch), which the select
//! pass ranks; and once the batch's shooters are chosen, their light by
//! sub-cells of their patches for the near field (`shooter_cells_of_batch`).
//! Both entry points share one bind group.
//!
//! Each patch's members are sorted by sub-cell (`SubCellOrder`; the
//! members buffer is shared, in `resources`), with where each sub-cell's
//! run starts, so that an invocation of `shooter_cells_of_batch`
//! reads only its own sub-cell's texels: a CPU driver reads a storage
//! buffer lane by lane, and every lane reading every member was most of
//! that pass.

use super::patches::Patches;
use super::resources::Resources;
use crate::gpu::{self, Gpu, Shader};
use crate::texelize::TexelSet;

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
    pub(super) fn new(gpu: &Gpu, r: &Resources, order: &SubCellOrder) -> PatchPower {
        let groups = r.dispatch.patch_groups;
        let params = gpu.uniform_buffer("solve_patch_power params", &r.params.with_row_stride(groups.0 * 64));
        let none = wgpu::BufferUsages::empty();
        let cell_starts = gpu.storage_buffer("solve_patch_power sub-cell starts", &order.starts, none);
        let layout = bind_group_layout(gpu);
        let buffers = [
            (0, &params),
            (2, &r.patches),
            (3, &r.members),
            (4, &r.unshot),
            (5, &r.patch_power),
            (6, &r.patch_origin),
            (7, &r.shooters),
            (8, &r.shooter_cells),
            (9, &cell_starts),
            (10, &r.patch_overshoot),
        ];
        let mut entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .map(|&(binding, buffer)| wgpu::BindGroupEntry { binding, resource: buffer.as_entire_binding() })
            .collect();
        entries.push(wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(&r.receivers) });
        let group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("solve_patch_power"),
            layout: &layout,
            entries: &entries,
        });
        let [power, shooter_cells] = pipelines(gpu);
        PatchPower { power, shooter_cells, group, groups, shooter_count: r.dispatch.shooter_count }
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

/// The pass's pipelines, the power sums and the shooters' sub-cells (built
/// once per device, `solve::warm`).
pub(super) fn pipelines(gpu: &Gpu) -> [wgpu::ComputePipeline; 2] {
    let layout = bind_group_layout(gpu);
    ["main", "shooter_cells_of_batch"].map(|entry| gpu.compute_pipeline(Shader::SolvePatchPower, entry, &[&layout]))
}

fn bind_group_layout(gpu: &Gpu) -> wgpu::BindGroupLayout {
    let compute = wgpu::ShaderStages::COMPUTE;
    gpu.bind_group_layout(
        "solve_patch_power",
        &[
            // 0: BounceParams (patch count, dispatch stride)
            gpu::uniform_entry(0, compute),
            // 1: the receivers' records (`resources::receiver_records`)
            gpu::texture_array_entry(1, compute, wgpu::TextureSampleType::Uint),
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
            // 9: where each patch's sub-cells start among its members
            gpu::storage_entry(9, true, compute),
            // 10: per-patch light it would shoot ahead, per unit albedo
            gpu::storage_entry(10, true, compute),
        ],
    )
}

/// Sub-cells to a side of a patch's atlas cell (`SUB_CELLS` in include/bounce.wgsl).
const SUB_CELLS: u32 = 4;

/// The members of every patch, each patch's sorted by sub-cell (in place:
/// a patch keeps its `first` and `count`), and where each sub-cell's run
/// starts: `starts[16 p + c]`, the last one's run ending at the patch's end.
/// One more entry closes the array, so that the shader may read one past a
/// patch's last start.
pub(super) struct SubCellOrder {
    pub(super) members: Vec<u32>,
    starts: Vec<u32>,
}

impl SubCellOrder {
    pub(super) fn new(patches: &Patches, texels: &TexelSet) -> SubCellOrder {
        let cell_of = |i: &u32| sub_cell(texels.texels[*i as usize].index, texels.width, patches.cell);
        let mut members = patches.members.clone();
        let mut starts = Vec::with_capacity(patches.patches.len() * (SUB_CELLS * SUB_CELLS) as usize + 1);
        for p in &patches.patches {
            let run = &mut members[p.first as usize..(p.first + p.count) as usize];
            run.sort_by_key(cell_of);
            for c in 0..SUB_CELLS * SUB_CELLS {
                starts.push(p.first + run.partition_point(|i| cell_of(i) < c) as u32);
            }
        }
        starts.push(members.len() as u32);
        SubCellOrder { members, starts }
    }
}

/// The sub-cell of its patch that atlas texel `index` lies in, as
/// `sub_cell` in include/bounce.wgsl: its place in its `cell`-wide atlas
/// cell, SUB_CELLS to a side.
fn sub_cell(index: u32, atlas_width: u32, cell: u32) -> u32 {
    let (x, y) = (index % atlas_width % cell, index / atlas_width % cell);
    y * SUB_CELLS / cell * SUB_CELLS + x * SUB_CELLS / cell
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::patches::Patch;
    use crate::texelize::Texel;

    #[test]
    fn a_texel_s_sub_cell_is_its_quarter_of_its_cell_across_and_down() {
        // 8-texel cells in a 32-wide atlas: texel (13, 10) is at (5, 2) in its cell.
        assert_eq!(sub_cell(10 * 32 + 13, 32, 8), 4 + 2);
        assert_eq!(sub_cell(0, 32, 8), 0);
        assert_eq!(sub_cell(7 * 32 + 7, 32, 8), 15);
        // A cell narrower than four sub-cells leaves some empty.
        assert_eq!(sub_cell(32 + 1, 32, 2), 2 * 4 + 2);
    }

    #[test]
    fn members_are_sorted_by_sub_cell_within_their_patch_and_each_run_starts_where_it_says() {
        // Two patches of a 4-wide atlas cut into 4-texel cells: the first
        // holds texels of both rows in a jumbled order, the second one texel.
        // Texel k covers atlas texel atlas[k]: a member's sub-cell is its
        // atlas texel's, not its place in the texel list.
        let atlas = [7, 5, 4, 1, 3, 0, 6, 2];
        let texels = TexelSet {
            width: 4,
            height: 2,
            texels: atlas.iter().map(|&index| Texel { index, ..Default::default() }).collect(),
            tint: Vec::new(),
        };
        let members = vec![1, 5, 2, 3, 0, 4];
        let patches = Patches {
            patches: vec![
                Patch { first: 0, count: 5, ..Default::default() },
                Patch { first: 5, count: 1, ..Default::default() },
            ],
            members,
            texel_patch: Vec::new(),
            cell: 4,
        };
        let order = SubCellOrder::new(&patches, &texels);
        // Atlas texels 5, 0, 4, 1, 7 and 3; each atlas texel is its own sub-cell.
        let in_atlas: Vec<u32> = order.members.iter().map(|&i| atlas[i as usize]).collect();
        assert_eq!(in_atlas, [0, 1, 4, 5, 7, 3]);
        let first: Vec<u32> = order.starts[..16].to_vec();
        assert_eq!(first, [0, 1, 2, 2, 2, 3, 4, 4, 5, 5, 5, 5, 5, 5, 5, 5]);
        // The second patch's one texel is in sub-cell 3; the array is closed by the total.
        assert_eq!(order.starts[16..], [5, 5, 5, 5, 6, 6, 6, 6, 6, 6, 6, 6, 6, 6, 6, 6, 6]);
        for p in 0..2 {
            for c in 0..16u32 {
                let (start, end) = (order.starts[16 * p + c as usize], order.starts[16 * p + c as usize + 1]);
                let end = if c == 15 { patches.patches[p].first + patches.patches[p].count } else { end };
                let run = &order.members[start as usize..end as usize];
                assert!(run.iter().all(|&i| sub_cell(atlas[i as usize], 4, 4) == c));
            }
        }
    }
}
