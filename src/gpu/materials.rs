//! The scene's materials on the GPU: one record per material (factors,
//! texture references, alpha cut-off) and every texture a baked material
//! samples, resampled to one size in a 2-D array with a full mip chain in
//! linear RGB (Rgba16Float, so mips average light, not sRGB codes).
//!
//! Material index `scene.materials.len()` is glTF's default material.

use bytemuck::{Pod, Zeroable};
use image::{ImageBuffer, Rgba};

use super::Gpu;
use crate::scene::{LinearImage, Scene, TextureRef};

/// Largest texture side kept: a lightmap texel covers many texture texels,
/// so more detail would only be averaged away.
const MAX_TEXTURE_SIZE: u32 = 1024;
/// `GpuTexture::info[0]` of a material without that texture.
pub const NO_TEXTURE: u32 = u32::MAX;

/// Mirrors `TextureRef` in include/materials.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuTexture {
    /// First row of the UV transform (a, b, c, unused).
    row0: [f32; 4],
    /// Second row (d, e, f, unused).
    row1: [f32; 4],
    /// Array layer (NO_TEXTURE if none), TEXCOORD set, wrap s, wrap t.
    info: [u32; 4],
}

impl GpuTexture {
    const NONE: GpuTexture =
        GpuTexture { row0: [1.0, 0.0, 0.0, 0.0], row1: [0.0, 1.0, 0.0, 0.0], info: [NO_TEXTURE, 0, 10497, 10497] };
}

/// Mirrors `Material` in include/materials.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuMaterial {
    pub base_color: [f32; 4],
    /// Emission rgb; w: alpha cut-off of a MASK material, −1 otherwise.
    pub emission: [f32; 4],
    pub base_texture: GpuTexture,
    pub emissive_texture: GpuTexture,
}

/// Materials and textures uploaded once for the passes that sample them.
pub struct Materials {
    pub records: Vec<GpuMaterial>,
    pub buffer: wgpu::Buffer,
    pub textures: wgpu::TextureView,
    pub sampler: wgpu::Sampler,
}

impl Materials {
    /// Whether material `m` cuts out texels (alphaMode MASK).
    pub fn is_masked(&self, m: usize) -> bool {
        self.records.get(m).is_some_and(|r| r.emission[3] >= 0.0)
    }

    pub fn upload(gpu: &Gpu, scene: &Scene) -> Materials {
        // Layers: the decoded images, in image order.
        let mut layer_of = vec![NO_TEXTURE; scene.images.len()];
        let mut decoded: Vec<&LinearImage> = Vec::new();
        for (i, image) in scene.images.iter().enumerate() {
            if let Some(image) = image {
                layer_of[i] = decoded.len() as u32;
                decoded.push(image.as_ref());
            }
        }
        let size = decoded
            .iter()
            .map(|i| i.width.max(i.height))
            .max()
            .unwrap_or(1)
            .next_power_of_two()
            .min(MAX_TEXTURE_SIZE)
            .min(gpu.limits.max_texture_dimension_2d);
        let records = material_records(scene, &layer_of);
        let buffer = gpu.storage_buffer("materials", &records, wgpu::BufferUsages::empty());
        let texture = upload_layers(gpu, &decoded, size);
        let textures = texture.create_view(&wgpu::TextureViewDescriptor {
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        });
        // Clamp and mirror are applied to the coordinates in the shader
        // (wrap_coordinate in include/materials.wgsl); the sampler repeats.
        let sampler = gpu.device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("material textures"),
            address_mode_u: wgpu::AddressMode::Repeat,
            address_mode_v: wgpu::AddressMode::Repeat,
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            mipmap_filter: wgpu::MipmapFilterMode::Linear,
            ..Default::default()
        });
        Materials { records, buffer, textures, sampler }
    }
}

/// One record per material of `scene`, then glTF's default material; `layer_of` maps an
/// image to its array layer (`NO_TEXTURE` for one not decoded).
fn material_records(scene: &Scene, layer_of: &[u32]) -> Vec<GpuMaterial> {
    let texture_ref = |t: &Option<TextureRef>| match t {
        Some(t) if layer_of.get(t.image).is_some_and(|&l| l != NO_TEXTURE) => GpuTexture {
            row0: [t.transform[0][0], t.transform[0][1], t.transform[0][2], 0.0],
            row1: [t.transform[1][0], t.transform[1][1], t.transform[1][2], 0.0],
            info: [layer_of[t.image], t.tex_coord.min(1), t.wrap[0], t.wrap[1]],
        },
        _ => GpuTexture::NONE,
    };
    let default = crate::scene::Material::default();
    scene
        .materials
        .iter()
        .chain(std::iter::once(&default))
        .map(|m| GpuMaterial {
            base_color: m.base_color,
            emission: [m.emission[0], m.emission[1], m.emission[2], m.cutoff().unwrap_or(-1.0)],
            base_texture: texture_ref(&m.base_color_texture),
            emissive_texture: texture_ref(&m.emissive_texture),
        })
        .collect()
}

/// A `size`² array texture (at least one layer) with a full mip chain, holding each of
/// `decoded` resampled in a layer of its own.
fn upload_layers(gpu: &Gpu, decoded: &[&LinearImage], size: u32) -> wgpu::Texture {
    let layers = (decoded.len() as u32).max(1);
    let mip_levels = size.ilog2() + 1;
    let texture = gpu.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("material textures"),
        size: wgpu::Extent3d { width: size, height: size, depth_or_array_layers: layers },
        mip_level_count: mip_levels,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba16Float,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    for (layer, image) in decoded.iter().enumerate() {
        for (level, mip) in mip_chain(image, size).into_iter().enumerate() {
            let side = mip.width();
            let halves: Vec<half::f16> = mip.as_raw().iter().map(|&v| half::f16::from_f32(v)).collect();
            gpu.queue.write_texture(
                wgpu::TexelCopyTextureInfo {
                    texture: &texture,
                    mip_level: level as u32,
                    origin: wgpu::Origin3d { x: 0, y: 0, z: layer as u32 },
                    aspect: wgpu::TextureAspect::All,
                },
                bytemuck::cast_slice(&halves),
                wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(side * 8), rows_per_image: Some(side) },
                wgpu::Extent3d { width: side, height: side, depth_or_array_layers: 1 },
            );
        }
    }
    texture
}

/// The image resampled to `size`² and halved down to 1×1, in linear light.
fn mip_chain(image: &LinearImage, size: u32) -> Vec<ImageBuffer<Rgba<f32>, Vec<f32>>> {
    let flat: Vec<f32> = image.pixels.iter().flatten().copied().collect();
    let source: ImageBuffer<Rgba<f32>, Vec<f32>> =
        ImageBuffer::from_raw(image.width, image.height, flat).expect("pixel count matches the size");
    let mut levels = vec![image::imageops::resize(&source, size, size, image::imageops::FilterType::Triangle)];
    while levels.last().unwrap().width() > 1 {
        let side = levels.last().unwrap().width() / 2;
        let next = image::imageops::resize(levels.last().unwrap(), side, side, image::imageops::FilterType::Triangle);
        levels.push(next);
    }
    levels
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::Shader;
    use crate::gpu::mirror::assert_mirrors;

    #[test]
    fn the_material_records_mirror_materials_wgsl() {
        assert_mirrors!(Shader::TexelizeAttributes, "TextureRef", GpuTexture { row0, row1, info });
        assert_mirrors!(
            Shader::TexelizeAttributes,
            "Material",
            GpuMaterial { base_color, emission, base_texture, emissive_texture }
        );
    }
}
