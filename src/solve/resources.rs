//! What the bounce pass's GPU passes share: the shaders' parameters
//! (`BounceParams`), how each batch is laid out, and the buffers more than
//! one pass binds. A buffer only one pass binds belongs to that pass.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;

use super::bounce::{BounceOptions, MAX_SHOOTERS};
use super::hemicube::HemicubeFace;
use super::patch_power::SubCellOrder;
use super::patches::Patches;
use super::select::Shooter;
use super::shoot::MEASURE_CHUNK;
use super::shooter_cull;
use crate::gpu::Gpu;
use crate::scene::Scene;
use crate::texelize::{Texel, TexelSet};

/// Parts a shooter patch's light is summed by for the near field
/// (`SUB_CELL_COUNT` in include/bounce.wgsl).
const SUB_CELL_COUNT: usize = 16;
/// What is kept per sub-cell (power and area, centroid, normal; `SUB_CELL_ROWS`).
const SUB_CELL_ROWS: usize = 3;

/// Mirrors `BounceParams` in include/bounce.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(super) struct BounceParams {
    texel_count: u32,
    patch_count: u32,
    shooter_count: u32,
    row_stride: u32,
    face_size: f32,
    tiles_per_row: u32,
    far: f32,
    pub(super) near: f32,
    receiver_offset: f32,
    max_slope: f32,
    pub(super) chunk_count: u32,
    atlas_width: u32,
    cell: u32,
    /// A receiver this close to a shooter's plane lies in it, metres: twice
    /// the rounding `shooter_cull` allows for.
    in_plane: f32,
    /// Receivers a row of the gather's receiver texture holds, as a shift.
    pub(super) receiver_row_shift: u32,
    /// 1 where no direct pass measured the coverage: the form factors'
    /// `finish` measures each patch's on its first shot.
    pub(super) measure_coverage: u32,
    /// The light a surface of full coverage will still receive per unit of
    /// unshot power (rgb; w unused): what a shooter shoots ahead.
    pub(super) overshoot: [f32; 4],
}

impl BounceParams {
    /// The same for a dispatch of `row_stride` invocations per row.
    pub(super) fn with_row_stride(self, row_stride: u32) -> BounceParams {
        BounceParams { row_stride, ..self }
    }
}

/// How each batch is laid out: shooters, hemicube faces in the depth
/// atlas, and workgroups over the patches.
#[derive(Clone, Copy)]
pub(super) struct Dispatch {
    pub(super) shooter_count: u32,
    pub(super) face: u32,
    pub(super) tiles_per_row: u32,
    pub(super) tile_rows: u32,
    pub(super) patch_groups: (u32, u32),
}

/// The shaders' parameters and the batches' layout.
pub(super) fn params(
    gpu: &Gpu,
    scene: &Scene,
    texels: &TexelSet,
    patches: &Patches,
    texels_per_unit: f32,
    options: &BounceOptions,
) -> (BounceParams, Dispatch) {
    let radius = scene_radius(scene);
    let shooter_count = options.shooters_per_batch.clamp(1, MAX_SHOOTERS);
    let face = options.hemicube_size.clamp(16, 2048);
    // As few rows as the texture's width allows, filled evenly: the atlas
    // is cleared and bound whole every batch, an unused tile included.
    let widest = (gpu.limits.max_texture_dimension_2d / (3 * face)).max(1);
    let tile_rows = shooter_count.div_ceil(widest);
    let tiles_per_row = shooter_count.div_ceil(tile_rows);
    let texel_world = 1.0 / texels_per_unit.max(1e-30);
    let patch_groups = gpu.dispatch_size(patches.patches.len() as u32, 64);
    let params = BounceParams {
        texel_count: texels.texels.len() as u32,
        patch_count: patches.patches.len() as u32,
        shooter_count,
        // No pass dispatches over the shared buffer's rows: each that
        // dispatches in rows has its own copy (`with_row_stride`).
        row_stride: 0,
        face_size: face as f32,
        tiles_per_row,
        far: 2.0 * radius,
        near: (radius * 1e-5).max(texel_world * 1e-3),
        // Half a lightmap texel: off the surface, well inside any occluder.
        receiver_offset: 0.5 * texel_world,
        max_slope: 10.0,
        chunk_count: (texels.texels.len() as u32).div_ceil(MEASURE_CHUNK).max(1),
        atlas_width: texels.width,
        cell: patches.cell,
        in_plane: shooter_cull::in_plane(&texels.texels),
        receiver_row_shift: receiver_row_shift(texels.texels.len() as u32, gpu.limits.max_texture_dimension_2d),
        measure_coverage: 0,
        overshoot: [0.0; 4],
    };
    (params, Dispatch { shooter_count, face, tiles_per_row, tile_rows, patch_groups })
}

/// The radius of the scene's bounding sphere about the centre of its
/// bounds, with a margin so that geometry never touches a hemicube's far
/// plane.
fn scene_radius(scene: &Scene) -> f32 {
    let (lo, hi) = scene.bounds().unwrap_or((Vec3::ZERO, Vec3::ZERO));
    let centre = (lo + hi) * 0.5;
    let radius = scene
        .primitives
        .iter()
        .flat_map(|p| p.positions.iter())
        .map(|&p| (Vec3::from(p) - centre).length())
        .fold(0.0f32, f32::max);
    (radius * 1.02).max(f32::MIN_POSITIVE * 1e6)
}

/// What the bounce pass uploads once.
pub(super) struct Inputs<'a> {
    pub(super) texels: &'a TexelSet,
    /// Per texel: the share of its area that bounces (`overlaps`).
    pub(super) shares: &'a [f32],
    pub(super) patches: &'a Patches,
    /// The patches' members, each patch's sorted by sub-cell: the order the
    /// gather takes the receivers in.
    pub(super) order: &'a SubCellOrder,
    /// Per patch: the covered share of its texels' hemispheres.
    pub(super) patch_coverage: &'a [f32],
    /// Per patch: Σ albedo·A over its texels (rgb, w 0).
    pub(super) patch_albedo: &'a [[f32; 4]],
    pub(super) unshot: &'a [[f32; 4]],
    pub(super) lightmap: &'a [[f32; 3]],
}

/// The buffers more than one pass binds, created once, with the parameters
/// and layout they were made for.
pub(super) struct Resources {
    pub(super) params: BounceParams,
    pub(super) dispatch: Dispatch,
    /// `params` as a uniform buffer.
    pub(super) params_buffer: wgpu::Buffer,
    /// Every receiver texel as four records (`receiver_records`).
    pub(super) receivers: wgpu::TextureView,
    /// `Inputs::order`'s members: the texels by patch, and the gather's
    /// order, in which a group of 64 receivers lies in one or two atlas
    /// cells rather than along a row of the atlas.
    pub(super) members: wgpu::Buffer,
    pub(super) patches: wgpu::Buffer,
    /// Per texel: unshot radiance ΔL (read by the power pass, spent by the gather).
    pub(super) unshot: wgpu::Buffer,
    /// Per texel: L_lm, accumulated by the gather.
    pub(super) lightmap: wgpu::Buffer,
    /// Per patch: its unshot power and where it lies (power pass → select).
    pub(super) patch_power: wgpu::Buffer,
    pub(super) patch_origin: wgpu::Buffer,
    /// Per patch: the light per unit albedo it would shoot ahead now (rgb),
    /// written by the select pass, read by the next batch's power pass.
    pub(super) patch_overshoot: wgpu::Buffer,
    /// Per patch: the covered share of its texels' hemispheres (select; the
    /// form factors' `finish` writes it where `measure_coverage`).
    pub(super) patch_coverage: wgpu::Buffer,
    /// Per patch: its slot + 1 once chosen in the batch (select → gather).
    pub(super) chosen: wgpu::Buffer,
    /// The batch's shooters (select → power pass, culls, gather).
    pub(super) shooters: wgpu::Buffer,
    /// Five faces per shooter slot (select → hemicube cull and render).
    pub(super) hemicube_faces: wgpu::Buffer,
    /// Each shooter's unshot light and area centroid by sub-cells of its
    /// patch (power pass → gather).
    pub(super) shooter_cells: wgpu::Buffer,
    /// The batch's hemicube depth atlas (hemicube → gather).
    pub(super) depth_view: wgpu::TextureView,
}

impl Resources {
    pub(super) fn new(gpu: &Gpu, inputs: &Inputs, params: BounceParams, dispatch: Dispatch) -> Resources {
        let Inputs { patches, unshot, lightmap, .. } = *inputs;
        let Dispatch { face, tiles_per_row, tile_rows, .. } = dispatch;
        let none = wgpu::BufferUsages::empty();
        let depth = gpu.depth_target("solve_hemicube depth", 3 * face * tiles_per_row, face * tile_rows);
        let lightmap4: Vec<[f32; 4]> = lightmap.iter().map(|l| [l[0], l[1], l[2], 0.0]).collect();
        let patch_count = patches.patches.len();
        Resources {
            params,
            dispatch,
            params_buffer: gpu.uniform_buffer("solve_shoot params", &params),
            receivers: receiver_texture(gpu, inputs, params.receiver_row_shift).create_view(&Default::default()),
            members: gpu.storage_buffer("bounce members", &inputs.order.members, none),
            patches: gpu.storage_buffer("solve_select patches", &patches.patches, none),
            unshot: gpu.storage_buffer("solve_shoot unshot", unshot, wgpu::BufferUsages::COPY_SRC),
            lightmap: gpu.storage_buffer("solve_shoot lightmap", &lightmap4, wgpu::BufferUsages::COPY_SRC),
            patch_power: gpu.zeroed_storage_buffer::<[f32; 4]>("solve_patch_power power", patch_count, none),
            patch_origin: gpu.zeroed_storage_buffer::<[f32; 4]>("solve_patch_power origins", patch_count, none),
            patch_overshoot: gpu.zeroed_storage_buffer::<[f32; 4]>("solve_select overshoot", patch_count, none),
            patch_coverage: gpu.storage_buffer("solve_select patch coverage", inputs.patch_coverage, none),
            chosen: gpu.zeroed_storage_buffer::<u32>("solve_select chosen", patch_count, none),
            shooters: gpu.storage_buffer(
                "solve_select shooters",
                &[Shooter::default(); MAX_SHOOTERS as usize],
                wgpu::BufferUsages::UNIFORM,
            ),
            hemicube_faces: gpu.zeroed_storage_buffer::<HemicubeFace>(
                "solve_select hemicube faces",
                5 * MAX_SHOOTERS as usize,
                wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::UNIFORM,
            ),
            shooter_cells: gpu.storage_buffer(
                "solve_patch_power shooter cells",
                // Per slot and sub-cell: unshot power and area, the centroid, the normal.
                &vec![[0f32; 4]; MAX_SHOOTERS as usize * SUB_CELL_ROWS * SUB_CELL_COUNT],
                wgpu::BufferUsages::UNIFORM,
            ),
            depth_view: depth.create_view(&Default::default()),
        }
    }
}

/// Receivers a row of the receiver texture holds at least: 1 << this.
const MIN_ROW_SHIFT: u32 = 12;

/// The row width of the receiver texture, as a shift: the narrowest power of
/// two from 4,096 whose rows for `count` receivers fit in `max_dimension`.
fn receiver_row_shift(count: u32, max_dimension: u32) -> u32 {
    let mut shift = MIN_ROW_SHIFT;
    while (count >> shift) >= max_dimension && (2u64 << shift) <= max_dimension as u64 {
        shift += 1;
    }
    shift
}

/// Every receiver texel as the gather reads it (`load_receiver` in
/// include/bounce.wgsl): four layers of 4-word records, receiver i at
/// (i mod width, i / width) of each, width = 1 << `row_shift`: its position
/// and area, shading normal and atlas index, face normal and share of the
/// bouncing area, albedo and patch. A CPU driver fetches texels several
/// times faster than it reads a storage buffer's elements, and the gather
/// reads every receiver every batch.
fn receiver_records(texels: &[Texel], shares: &[f32], texel_patch: &[u32], row_shift: u32) -> Vec<[u32; 4]> {
    let width = 1usize << row_shift;
    let layer = texels.len().div_ceil(width).max(1) * width;
    let mut records = vec![[0u32; 4]; 4 * layer];
    let bits = |v: [f32; 3], w: u32| [v[0].to_bits(), v[1].to_bits(), v[2].to_bits(), w];
    for (i, t) in texels.iter().enumerate() {
        records[i] = bits(t.position, t.area.to_bits());
        records[layer + i] = bits(t.normal, t.index);
        records[2 * layer + i] = bits(t.face_normal, shares[i].to_bits());
        records[3 * layer + i] = bits(t.albedo, texel_patch[i]);
    }
    records
}

fn receiver_texture(gpu: &Gpu, inputs: &Inputs, row_shift: u32) -> wgpu::Texture {
    let records = receiver_records(&inputs.texels.texels, inputs.shares, &inputs.patches.texel_patch, row_shift);
    let width = 1u32 << row_shift;
    gpu.records_texture("solve_shoot receivers", &records, width, records.len() as u32 / (4 * width), 4)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::Shader;
    use crate::gpu::mirror::assert_mirrors;

    #[test]
    fn receiver_rows_are_4096_wide_until_their_count_would_pass_the_adapter_s_limit() {
        assert_eq!(receiver_row_shift(1, 8192), 12);
        assert_eq!(receiver_row_shift(4096 * 8192 - 1, 8192), 12);
        // One more would need row 8,192: rows twice as wide instead.
        assert_eq!(receiver_row_shift(4096 * 8192, 8192), 13);
        assert_eq!(receiver_row_shift(u32::MAX, 16384), 14);
        // Never wider than the adapter allows.
        assert_eq!(receiver_row_shift(u32::MAX, 8192), 13);
    }

    #[test]
    fn each_receiver_s_four_records_sit_at_its_index_in_four_layers() {
        let texel = |k: f32| Texel {
            position: [k, k + 0.1, k + 0.2],
            area: k + 0.3,
            normal: [k + 0.4, 0.0, 0.0],
            index: 100 + k as u32,
            face_normal: [0.0, k + 0.5, 0.0],
            albedo: [0.0, 0.0, k + 0.6],
            ..Default::default()
        };
        let texels = [texel(0.0), texel(1.0), texel(2.0)];
        let records = receiver_records(&texels, &[1.0, 0.5, 0.25], &[7, 8, 9], 12);
        // One row of 4,096 per layer, receiver i at column i.
        assert_eq!(records.len(), 4 * 4096);
        let floats = |r: [u32; 4]| r.map(f32::from_bits);
        assert_eq!(floats(records[2]), [2.0, 2.1, 2.2, 2.3]);
        assert_eq!(floats(records[4096 + 2])[0], 2.4);
        assert_eq!(records[4096 + 2][3], 102);
        assert_eq!(floats(records[2 * 4096 + 2]), [0.0, 2.5, 0.0, 0.25]);
        assert_eq!(floats(records[3 * 4096 + 2])[2], 2.6);
        assert_eq!(records[3 * 4096 + 2][3], 9);
        // Past the last receiver, nothing.
        assert_eq!(records[3], [0; 4]);
    }

    #[test]
    fn the_bounce_params_mirror_bounce_wgsl() {
        assert_mirrors!(
            Shader::SolveShoot,
            "BounceParams",
            BounceParams {
                texel_count,
                patch_count,
                shooter_count,
                row_stride,
                face_size,
                tiles_per_row,
                far,
                near,
                receiver_offset,
                max_slope,
                chunk_count,
                atlas_width,
                cell,
                in_plane,
                receiver_row_shift,
                measure_coverage,
                overshoot,
            }
        );
    }
}
