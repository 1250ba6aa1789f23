//! Which of a batch's shooters each group of 64 receiver texels can take
//! light from (`solve_shooter_cull`), so that the gather (`solve_shoot`'s
//! `main`, one workgroup a group) loops over those alone: on a CPU driver a
//! pair that gets no light costs as much as one that does, and in an open
//! scene most pairs are a floor's texels and a patch of the same floor.
//! The pass also lists the groups the gather visits at all, and writes the
//! gather's indirect dispatch over them.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;

use super::resources::BounceParams;
use crate::gpu::{self, Gpu, Shader};
use crate::texelize::Texel;

/// Texels per group: `solve_shoot`'s workgroup size.
const GROUP_TEXELS: usize = 64;

/// Relative rounding allowance of the test (`in_plane` is twice it): the
/// shader's sums and the gather's each round at about 1e-7 of the
/// coordinates' magnitude.
const ROUNDING: f32 = 1e-5;
/// Widening of each group's cone of normals, radians, for normals not
/// quite unit length.
const SPREAD_MARGIN: f32 = 1e-3;

/// Mirrors `ReceiverGroup` in solve_shooter_cull.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable, Debug, PartialEq)]
pub struct ReceiverGroup {
    lo: [f32; 3],
    cos_spread: f32,
    hi: [f32; 3],
    sin_spread: f32,
    axis: [f32; 3],
    _pad: f32,
}

pub struct ShooterCull {
    cull: wgpu::ComputePipeline,
    gather_dispatch: wgpu::ComputePipeline,
    group: wgpu::BindGroup,
    dispatch: (u32, u32),
    /// Per group: a bit per shooter slot that may light it.
    pub group_shooters: wgpu::Buffer,
    /// The groups the gather visits (`GatheredGroups` in solve_shoot.wgsl).
    pub gathered: wgpu::Buffer,
    /// The gather's workgroup counts over them.
    pub gather_args: wgpu::Buffer,
}

impl ShooterCull {
    /// For the bounce pass's `params` and its batch of `shooters` (a
    /// `ShooterBatch` uniform buffer), with the gather taking `texels` in
    /// `order`; `texel_patch`: each texel's patch.
    pub fn new(
        gpu: &Gpu,
        texels: &[Texel],
        order: &[u32],
        texel_patch: &[u32],
        params: BounceParams,
        shooters: &wgpu::Buffer,
    ) -> ShooterCull {
        let groups = receiver_groups(texels, order);
        let patches = group_patches(texel_patch, order);
        let dispatch = gpu.dispatch_size(groups.len() as u32, 64);
        let params = gpu.uniform_buffer("solve_shooter_cull params", &params.with_row_stride(dispatch.0 * 64));
        let none = wgpu::BufferUsages::empty();
        let bounds = gpu.storage_buffer("solve_shooter_cull groups", &groups, none);
        let patches = gpu.storage_buffer("solve_shooter_cull group patches", &patches, none);
        let group_shooters = gpu.zeroed_storage_buffer::<[u32; 2]>("solve_shooter_cull masks", groups.len(), none);
        let received = gpu.zeroed_storage_buffer::<u32>("solve_shooter_cull received", groups.len(), none);
        // Two counts, then at most every group.
        let gathered = gpu.zeroed_storage_buffer::<u32>("solve_shooter_cull gathered", 2 + groups.len(), none);
        let gather_args =
            gpu.zeroed_storage_buffer::<u32>("solve_shooter_cull gather dispatch", 3, wgpu::BufferUsages::INDIRECT);
        let layout = bind_group_layout(gpu);
        let buffers = [&params, shooters, &bounds, &group_shooters, &patches, &received, &gathered, &gather_args];
        let group = gpu::bind_buffers(gpu, "solve_shooter_cull", &layout, &buffers);
        let [cull, gather_dispatch] = pipelines(gpu);
        ShooterCull { cull, gather_dispatch, group, dispatch, group_shooters, gathered, gather_args }
    }

    /// Writes each group's slots for the batch's shooters, lists the groups
    /// the gather visits and sizes its dispatch over them. The gather reads
    /// its dispatch in a later pass: no bind group of its pass may hold it.
    pub fn record(&self, pass: &mut wgpu::ComputePass) {
        pass.set_bind_group(0, &self.group, &[]);
        pass.set_pipeline(&self.cull);
        pass.dispatch_workgroups(self.dispatch.0, self.dispatch.1, 1);
        pass.set_pipeline(&self.gather_dispatch);
        pass.dispatch_workgroups(1, 1, 1);
    }
}

/// The pass's pipelines, the cull and the gather's dispatch (built once per
/// device, `solve::warm`).
pub(super) fn pipelines(gpu: &Gpu) -> [wgpu::ComputePipeline; 2] {
    let layout = bind_group_layout(gpu);
    ["main", "gather_dispatch"].map(|entry| gpu.compute_pipeline(Shader::SolveShooterCull, entry, &[&layout]))
}

fn bind_group_layout(gpu: &Gpu) -> wgpu::BindGroupLayout {
    let compute = wgpu::ShaderStages::COMPUTE;
    gpu.bind_group_layout(
        "solve_shooter_cull",
        &[
            // 0: BounceParams (shooter count, receiver offset; row stride of this dispatch)
            gpu::uniform_entry(0, compute),
            // 1: the batch's shooters
            gpu::uniform_entry(1, compute),
            // 2: each group's bounds, 3: each group's slots (written)
            gpu::storage_entry(2, true, compute),
            gpu::storage_entry(3, false, compute),
            // 4: each group's patches, 5: whether it received light (read, written)
            gpu::storage_entry(4, true, compute),
            gpu::storage_entry(5, false, compute),
            // 6: the groups the gather visits, 7: its dispatch (both written)
            gpu::storage_entry(6, false, compute),
            gpu::storage_entry(7, false, compute),
        ],
    )
}

/// How close to a shooter's plane a receiver lies in it
/// (`BounceParams::in_plane`): twice the test's allowance for rounding,
/// `ROUNDING` of the largest coordinate.
pub fn in_plane(texels: &[Texel]) -> f32 {
    2.0 * ROUNDING * texels.iter().map(|t| Vec3::from(t.position).abs().max_element()).fold(0.0f32, f32::max)
}

/// The bounds of each run of `GROUP_TEXELS` texels of `order`.
fn receiver_groups(texels: &[Texel], order: &[u32]) -> Vec<ReceiverGroup> {
    order.chunks(GROUP_TEXELS).map(|run| group_bounds(run.iter().map(|&i| &texels[i as usize]))).collect()
}

/// The lowest and highest patch of each run of `GROUP_TEXELS` texels of
/// `order`: a range, as `order` runs by patch.
fn group_patches(texel_patch: &[u32], order: &[u32]) -> Vec<[u32; 2]> {
    let range = |run: &[u32]| {
        let patches = run.iter().map(|&i| texel_patch[i as usize]);
        [patches.clone().min().unwrap_or(0), patches.max().unwrap_or(0)]
    };
    order.chunks(GROUP_TEXELS).map(range).collect()
}

fn group_bounds<'a>(texels: impl Iterator<Item = &'a Texel> + Clone) -> ReceiverGroup {
    let positions = texels.clone().map(|t| Vec3::from(t.position));
    let lo = positions.clone().fold(Vec3::INFINITY, Vec3::min);
    let hi = positions.fold(Vec3::NEG_INFINITY, Vec3::max);
    let normals: Vec<Vec3> = texels.map(|t| Vec3::from(t.normal).normalize_or_zero()).collect();
    let sum: Vec3 = normals.iter().sum();
    let axis = sum.normalize_or_zero();
    let widest = normals.iter().map(|n| n.dot(axis).clamp(-1.0, 1.0).acos()).fold(0.0f32, f32::max);
    let spread = widest + SPREAD_MARGIN;
    // A cone past a half turn (or normals that cancel) bounds nothing.
    let (cos_spread, sin_spread) = if axis == Vec3::ZERO || normals.contains(&Vec3::ZERO) || spread >= 3.0 {
        (-1.0, 0.0)
    } else {
        (spread.cos(), spread.sin())
    };
    ReceiverGroup { lo: lo.into(), cos_spread, hi: hi.into(), sin_spread, axis: axis.into(), _pad: 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn texel(position: [f32; 3], normal: [f32; 3]) -> Texel {
        Texel { position, normal, ..Texel::default() }
    }

    #[test]
    fn a_group_bounds_every_texel_position_and_normal() {
        // A strip across a ball's flank: positions and normals both vary.
        let texels: Vec<Texel> = (0..GROUP_TEXELS)
            .map(|i| {
                let a = i as f32 * 0.02;
                texel([a.cos() * 2.0, a.sin() * 2.0, 0.5 - a], [a.cos(), a.sin(), 0.0])
            })
            .collect();
        let g = group_bounds(texels.iter());
        let (lo, hi, axis) = (Vec3::from(g.lo), Vec3::from(g.hi), Vec3::from(g.axis));
        for t in &texels {
            let p = Vec3::from(t.position);
            assert!(p.cmpge(lo).all() && p.cmple(hi).all(), "{p} outside {lo}..{hi}");
            assert!(Vec3::from(t.normal).dot(axis) >= g.cos_spread, "{:?} outside the cone", t.normal);
        }
        // The cone is no wider than the normals need: 63 × 0.02 rad across.
        let half_angle = g.cos_spread.acos();
        assert!((0.63..0.64).contains(&half_angle), "half-angle {half_angle}");
    }

    #[test]
    fn a_group_names_the_range_of_its_texels_patches() {
        // 130 texels in gather order: three groups, the last a short one.
        let texel_patch: Vec<u32> = (0..130).map(|i| [7, 3, 9][i % 3]).collect();
        let order: Vec<u32> = (0..130).rev().collect();
        let ranges = group_patches(&texel_patch, &order);
        assert_eq!(ranges.len(), 3);
        for (run, range) in order.chunks(GROUP_TEXELS).zip(&ranges) {
            for &i in run {
                let p = texel_patch[i as usize];
                assert!(range[0] <= p && p <= range[1], "patch {p} outside {range:?}");
            }
        }
        assert_eq!(ranges[2], [3, 7], "the short group: texels 1 and 0");
    }

    #[test]
    fn normals_that_cancel_bound_nothing() {
        let texels = [texel([0.0; 3], [0.0, 1.0, 0.0]), texel([1.0, 0.0, 0.0], [0.0, -1.0, 0.0])];
        assert_eq!(group_bounds(texels.iter()).cos_spread, -1.0);
    }

    #[test]
    fn the_receiver_group_mirrors_its_shader() {
        use crate::gpu::{Shader, mirror::assert_mirrors};
        assert_mirrors!(
            Shader::SolveShooterCull,
            "ReceiverGroup",
            ReceiverGroup { lo, cos_spread, hi, sin_spread, axis }
        );
    }
}
