//! The gather (`solve_shoot`): every texel takes the light of the batch's
//! shooters that may light its group of 64 (`main`, the far field, after
//! `shooter_cull`), and `main` lists the receivers next to a shooter, whose
//! exact near field `near_field` then gathers, in a pass `near_dispatch`
//! sizes on the GPU. Where the form factors are normalized, `measure` and
//! `finish` first sum those of each patch shooting for the first time and
//! write its scale.

use super::bounce::MAX_SHOOTERS;
use super::resources::{Inputs, Resources};
use super::shooter_cull::ShooterCull;
use crate::gpu::{self, Gpu, Shader};

/// Texels one workgroup of the form-factor measure pass sums
/// (`MEASURE_CHUNK` in solve_shoot.wgsl).
pub(super) const MEASURE_CHUNK: u32 = 4096;
/// Shooter slots one workgroup of the measure pass sums for
/// (`MEASURE_SLOTS` in solve_shoot.wgsl) where it does not take all of them.
const NARROW_MEASURE_SLOTS: u32 = 8;
/// A CPU driver's measure workgroups take all the slots where the texel
/// chunks alone give each of its threads (one a core) this many workgroups:
/// each texel's reads then serve every slot at once (the pass's time fell by
/// a fifth to a quarter in the closed rooms of BENCHMARKS.md). A GPU keeps
/// more, narrower workgroups.
const WIDE_MEASURE_CHUNKS_PER_CORE: u32 = 4;

pub(super) struct Shoot {
    /// The measure pass for the slots a workgroup takes (`measure_slots_for`).
    measure: wgpu::ComputePipeline,
    finish: wgpu::ComputePipeline,
    main: wgpu::ComputePipeline,
    near_dispatch: wgpu::ComputePipeline,
    near_field: wgpu::ComputePipeline,
    /// Group 0 of every entry point but `near_dispatch`.
    group: wgpu::BindGroup,
    /// Group 1: the slots' scales, written by `finish`, read by `main`.
    scales: SlotScales,
    /// `near_dispatch`'s own group.
    near_dispatch_group: wgpu::BindGroup,
    /// Receivers in a shooter's near field: a count, then (texel, slots) pairs.
    near_list: wgpu::Buffer,
    /// The near-field pass's workgroup counts, written on the GPU from the
    /// list's length (so no batch waits to read it back).
    near_args: wgpu::Buffer,
    /// Whether each patch's form factors are normalized (`measure`, `finish`).
    normalized: bool,
    /// Workgroups of `measure` (texel chunks × groups of slots) and of
    /// `finish` (one a slot).
    measure_groups: (u32, u32),
    shooter_count: u32,
    /// `main`'s workgroup counts, one a listed group (`shooter_cull`).
    gather_args: wgpu::Buffer,
}

/// The buffers only the gather binds.
struct Buffers {
    /// Per patch: the scale of its form factors, 0 until it first shoots.
    patch_scale: wgpu::Buffer,
    /// The batch's shooters' scales by slot (written by `finish`), which
    /// `main` reads as a uniform buffer.
    slot_scales: wgpu::Buffer,
    /// Near- and far-field sums of `measure` per shooter slot and texel chunk.
    partials: wgpu::Buffer,
    near_list: wgpu::Buffer,
    near_args: wgpu::Buffer,
}

impl Buffers {
    fn new(gpu: &Gpu, inputs: &Inputs, chunk_count: u32) -> Buffers {
        let (none, patch_count) = (wgpu::BufferUsages::empty(), inputs.patches.patches.len());
        Buffers {
            patch_scale: gpu.zeroed_storage_buffer::<f32>(
                "solve_shoot patch scales",
                patch_count,
                wgpu::BufferUsages::COPY_DST,
            ),
            slot_scales: gpu.storage_buffer(
                "solve_shoot slot scales",
                &[1f32; MAX_SHOOTERS as usize],
                wgpu::BufferUsages::UNIFORM,
            ),
            partials: gpu.zeroed_storage_buffer::<f32>(
                "solve_shoot measured sums",
                (2 * MAX_SHOOTERS * chunk_count) as usize,
                none,
            ),
            // A count, then at most one entry (three words) per texel.
            near_list: gpu.zeroed_storage_buffer::<u32>(
                "solve_shoot near-field receivers",
                1 + 3 * inputs.texels.texels.len().max(1),
                wgpu::BufferUsages::COPY_DST,
            ),
            near_args: gpu.zeroed_storage_buffer::<u32>(
                "solve_shoot near-field dispatch",
                3,
                wgpu::BufferUsages::INDIRECT,
            ),
        }
    }
}

impl Shoot {
    /// `cull`: each texel group's slots, and the groups to gather;
    /// `measure_slots`: as `BounceOptions`'.
    pub(super) fn new(
        gpu: &Gpu,
        r: &Resources,
        inputs: &Inputs,
        cull: &ShooterCull,
        normalized: bool,
        measure_slots: Option<u32>,
    ) -> Shoot {
        let b = Buffers::new(gpu, inputs, r.params.chunk_count);
        if !normalized {
            // Every patch's scale known (1): the measure and finish passes skip.
            let ones = vec![1f32; inputs.patches.patches.len().max(1)];
            gpu.queue.write_buffer(&b.patch_scale, 0, bytemuck::cast_slice(&ones));
        }
        let layout = bind_group_layout(gpu);
        let group = bind_group(gpu, &layout, r, &b, cull);
        let scales = SlotScales::new(gpu, &b.slot_scales);
        let near_dispatch_group = near_dispatch_bind_group(gpu, &b);
        let [_, _, finish, main, near_dispatch, near_field] = pipelines(gpu);
        let shooter_count = r.dispatch.shooter_count;
        let slots =
            measure_slots.unwrap_or_else(|| measure_slots_for(gpu, r.params.chunk_count)).clamp(1, MAX_SHOOTERS);
        let measure = measure_pipeline(gpu, slots);
        Shoot {
            measure,
            finish,
            main,
            near_dispatch,
            near_field,
            group,
            scales,
            near_dispatch_group,
            near_list: b.near_list,
            near_args: b.near_args,
            normalized,
            measure_groups: (r.params.chunk_count, shooter_count.div_ceil(slots)),
            shooter_count,
            gather_args: cull.gather_args.clone(),
        }
    }

    /// Empties the near-field list (its count), first in each batch.
    pub(super) fn clear_near_list(&self, encoder: &mut wgpu::CommandEncoder) {
        encoder.clear_buffer(&self.near_list, 0, Some(4));
    }

    /// Where the form factors are normalized, their sums for each patch
    /// shooting for the first time, and its scale.
    pub(super) fn record_measure(&self, encoder: &mut wgpu::CommandEncoder) {
        if !self.normalized {
            return;
        }
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_bind_group(0, &self.group, &[]);
        pass.set_pipeline(&self.measure);
        pass.dispatch_workgroups(self.measure_groups.0, self.measure_groups.1, 1);
        pass.set_pipeline(&self.finish);
        pass.set_bind_group(1, &self.scales.write_group, &[]);
        pass.dispatch_workgroups(self.shooter_count, 1, 1);
    }

    /// The far field of the groups `shooter_cull` listed and the size of
    /// the near-field pass, in a pass after the cull's, which wrote `main`'s
    /// workgroup counts.
    pub(super) fn record_far_field(&self, encoder: &mut wgpu::CommandEncoder) {
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_bind_group(0, &self.group, &[]);
        pass.set_pipeline(&self.main);
        pass.set_bind_group(1, &self.scales.read_group, &[]);
        pass.dispatch_workgroups_indirect(&self.gather_args, 0);
        pass.set_pipeline(&self.near_dispatch);
        pass.set_bind_group(0, &self.near_dispatch_group, &[]);
        pass.dispatch_workgroups(1, 1, 1);
    }

    /// The near field only for the receivers listed (a few per shooter), in
    /// a pass of its own: its workgroup counts are written by the pass before.
    pub(super) fn record_near_field(&self, encoder: &mut wgpu::CommandEncoder) {
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_bind_group(0, &self.group, &[]);
        pass.set_pipeline(&self.near_field);
        pass.dispatch_workgroups_indirect(&self.near_args, 0);
    }
}

/// Group 0 of every entry point but `near_dispatch`: the gather, its
/// normalization and the near field.
fn bind_group_layout(gpu: &Gpu) -> wgpu::BindGroupLayout {
    let compute = wgpu::ShaderStages::COMPUTE;
    gpu.bind_group_layout(
        "solve_shoot",
        &[
            // 0: BounceParams
            gpu::uniform_entry(0, compute),
            // 1: the receivers' records (`resources::receiver_records`)
            gpu::texture_array_entry(1, compute, wgpu::TextureSampleType::Uint),
            // 3: the batch's shooters
            gpu::uniform_entry(3, compute),
            // 4: lightmap L_lm (accumulated)
            gpu::storage_entry(4, false, compute),
            // 5: unshot ΔL (accumulated)
            gpu::storage_entry(5, false, compute),
            // 6: the batch's hemicube depth atlas
            gpu::depth_texture_entry(6, compute),
            // 7: per-patch form-factor scales
            gpu::storage_entry(7, false, compute),
            // 8: the measure pass's sums
            gpu::storage_entry(8, false, compute),
            // 10: receivers in a shooter's near field (listed, then gathered)
            gpu::storage_entry(10, false, compute),
            // 11: the shooters' light by sub-cells
            gpu::uniform_entry(11, compute),
            // 14: each patch's slot + 1 in the batch
            gpu::storage_entry(14, true, compute),
            // 15: each texel group's slots (solve_shooter_cull)
            gpu::storage_entry(15, true, compute),
            // 16: the receivers in the gather's order (by patch)
            gpu::storage_entry(16, true, compute),
            // 17: the groups `main` gathers (solve_shooter_cull)
            gpu::storage_entry(17, true, compute),
            // 18: per-patch covered share (written by `finish` where measured)
            gpu::storage_entry(18, false, compute),
        ],
    )
}

fn bind_group(
    gpu: &Gpu,
    layout: &wgpu::BindGroupLayout,
    r: &Resources,
    b: &Buffers,
    cull: &ShooterCull,
) -> wgpu::BindGroup {
    fn buffer(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
        wgpu::BindGroupEntry { binding, resource: buffer.as_entire_binding() }
    }
    gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("solve_shoot"),
        layout,
        entries: &[
            buffer(0, &r.params_buffer),
            wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(&r.receivers) },
            buffer(3, &r.shooters),
            buffer(4, &r.lightmap),
            buffer(5, &r.unshot),
            wgpu::BindGroupEntry { binding: 6, resource: wgpu::BindingResource::TextureView(&r.depth_view) },
            buffer(7, &b.patch_scale),
            buffer(8, &b.partials),
            buffer(10, &b.near_list),
            buffer(11, &r.shooter_cells),
            buffer(14, &r.chosen),
            buffer(15, &cull.group_shooters),
            buffer(16, &r.members),
            buffer(17, &cull.gathered),
            buffer(18, &r.patch_coverage),
        ],
    })
}

/// The slots' form-factor scales: written by `finish`, read by `main` as a
/// uniform buffer, so in a group of each one's own.
struct SlotScales {
    write_group: wgpu::BindGroup,
    read_group: wgpu::BindGroup,
}

impl SlotScales {
    /// The layouts of the group `finish` writes the scales through and of
    /// the one `main` reads them through.
    fn layouts(gpu: &Gpu) -> [wgpu::BindGroupLayout; 2] {
        let compute = wgpu::ShaderStages::COMPUTE;
        [
            // 1: the scales (written by `finish`)
            gpu.bind_group_layout("solve_shoot slot scales (written)", &[gpu::storage_entry(1, false, compute)]),
            // 0: the scales (read by `main`)
            gpu.bind_group_layout("solve_shoot slot scales", &[gpu::uniform_entry(0, compute)]),
        ]
    }

    fn new(gpu: &Gpu, slot_scales: &wgpu::Buffer) -> SlotScales {
        let [write_layout, read_layout] = Self::layouts(gpu);
        let group = |label, layout, binding| {
            gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(label),
                layout,
                entries: &[wgpu::BindGroupEntry { binding, resource: slot_scales.as_entire_binding() }],
            })
        };
        let write_group = group("solve_shoot slot scales (written)", &write_layout, 1);
        let read_group = group("solve_shoot slot scales", &read_layout, 0);
        SlotScales { write_group, read_group }
    }
}

/// Slots one measure workgroup sums for over `chunk_count` chunks of texels.
fn measure_slots_for(gpu: &Gpu, chunk_count: u32) -> u32 {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get() as u32);
    let wide = gpu.adapter.is_cpu() && chunk_count >= WIDE_MEASURE_CHUNKS_PER_CORE * cores;
    if wide { MAX_SHOOTERS } else { NARROW_MEASURE_SLOTS }
}

/// The measure pass over `slots` slots a workgroup.
fn measure_pipeline(gpu: &Gpu, slots: u32) -> wgpu::ComputePipeline {
    let layout = bind_group_layout(gpu);
    gpu.compute_pipeline_with(Shader::SolveShoot, "measure", &[&layout], &[("MEASURE_SLOTS", slots as f64)])
}

/// The pass's pipelines: `measure` over 8 slots a workgroup and over 64
/// (on a CPU driver), `finish`, `main`, `near_dispatch` and `near_field`
/// (built once per device, `solve::warm`).
pub(super) fn pipelines(gpu: &Gpu) -> [wgpu::ComputePipeline; 6] {
    let layout = bind_group_layout(gpu);
    let [write_scales, read_scales] = SlotScales::layouts(gpu);
    let near_dispatch = near_dispatch_layout(gpu);
    let pipeline = |entry, layouts: &[&wgpu::BindGroupLayout]| gpu.compute_pipeline(Shader::SolveShoot, entry, layouts);
    let wide = if gpu.adapter.is_cpu() { MAX_SHOOTERS } else { NARROW_MEASURE_SLOTS };
    [
        measure_pipeline(gpu, NARROW_MEASURE_SLOTS),
        measure_pipeline(gpu, wide),
        pipeline("finish", &[&layout, &write_scales]),
        pipeline("main", &[&layout, &read_scales]),
        pipeline("near_dispatch", &[&near_dispatch]),
        pipeline("near_field", &[&layout]),
    ]
}

/// `near_dispatch`'s own group, apart from the shots' group: its output is
/// the near-field pass's indirect arguments, which no bind group of that
/// pass may hold.
fn near_dispatch_layout(gpu: &Gpu) -> wgpu::BindGroupLayout {
    let compute = wgpu::ShaderStages::COMPUTE;
    gpu.bind_group_layout(
        "solve_shoot near_dispatch",
        &[
            // 10: the near-field list (its count)
            gpu::storage_entry(10, false, compute),
            // 12: the workgroup counts (written)
            gpu::storage_entry(12, false, compute),
        ],
    )
}

fn near_dispatch_bind_group(gpu: &Gpu, b: &Buffers) -> wgpu::BindGroup {
    gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("solve_shoot near_dispatch"),
        layout: &near_dispatch_layout(gpu),
        entries: &[
            wgpu::BindGroupEntry { binding: 10, resource: b.near_list.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 12, resource: b.near_args.as_entire_binding() },
        ],
    })
}
