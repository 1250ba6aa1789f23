//! The `Scene`: what import hands to the rest of the pipeline. Static
//! triangle geometry in world space (glTF's: right-handed, +Y up, metres)
//! with the material facts the solver needs, plus the source asset that
//! export rewrites.
//!
//! Positions are stored relative to `Scene::origin` (world = origin +
//! position), so a scene far from glTF's origin keeps f32 precision; every
//! stage after import works in these scene coordinates.

use std::sync::Arc;

use glam::{DVec3, Vec3};

use crate::asset::SourceAsset;
use crate::repeats::Repeat;

/// One glTF primitive as drawn by one node: the unit that gets lightmap space.
#[derive(Clone, Debug)]
pub struct ScenePrimitive {
    /// Index of the node that draws it.
    pub node: usize,
    /// Which of the node's EXT_mesh_gpu_instancing instances it is (each
    /// instance is baked as a mesh of its own); `None` for a plain node.
    pub instance: Option<usize>,
    /// Index of the glTF mesh and of the primitive within it.
    pub mesh: usize,
    pub primitive: usize,
    /// Positions in scene coordinates (metres, world minus `Scene::origin`),
    /// one per source vertex, in source order.
    pub positions: Vec<[f32; 3]>,
    /// World-space unit normals, one per source vertex, if the source has them
    /// (otherwise flat normals are used, as glTF prescribes).
    pub normals: Option<Vec<[f32; 3]>>,
    /// TEXCOORD_0, one per source vertex, if present.
    pub uv0: Option<Vec<[f32; 2]>>,
    /// The source's own TEXCOORD_1, if present (textures may sample it; the
    /// lightmap UVs replace it in the output).
    pub uv1: Option<Vec<[f32; 2]>>,
    /// COLOR_0's RGB (linear, as glTF stores it), one per source vertex, if
    /// present: it multiplies the base colour (its alpha is not read).
    pub colors: Option<Vec<[f32; 3]>>,
    /// Triangle list in source vertex numbering (strips and fans converted),
    /// in the source's winding.
    pub indices: Vec<u32>,
    /// Triangles that repeat an earlier one of this primitive (same corners,
    /// same facing), in order: they share its lightmap texels (see `repeats`).
    pub repeats: Vec<Repeat>,
    /// The node's transform has a negative determinant, so the winding that
    /// faces front is reversed in world space.
    pub mirrored: bool,
    /// Index into `Scene::materials`; `None` means glTF's default material.
    /// In a file bake wrote, the primitive's own material (its `pbr+lightmap`
    /// variant's), not the baked one it is drawn with.
    pub material: Option<usize>,
    /// The material the file draws it with by default (`material` but in a
    /// file bake wrote): what a viewer shows.
    pub drawn_material: Option<usize>,
}

/// What names a baked primitive in the input: its node, the node's GPU
/// instance where it has them, its mesh and its index in the mesh.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PrimitiveKey {
    pub node: usize,
    pub instance: Option<usize>,
    pub mesh: usize,
    pub primitive: usize,
}

impl ScenePrimitive {
    pub fn key(&self) -> PrimitiveKey {
        PrimitiveKey { node: self.node, instance: self.instance, mesh: self.mesh, primitive: self.primitive }
    }

    /// The corners of triangle `t` wound counter-clockwise about its front
    /// side's world-space normal: the source's order, reversed under a
    /// mirroring transform.
    pub fn front_corners(&self, t: usize) -> [u32; 3] {
        let [a, b, c] = [0, 1, 2].map(|k| self.indices[3 * t + k]);
        if self.mirrored { [a, c, b] } else { [a, b, c] }
    }

    /// The world-space normal of triangle `t` from its winding (front side), or
    /// zero for a degenerate triangle.
    pub fn face_normal(&self, t: usize) -> Vec3 {
        let [a, b, c] = self.front_corners(t).map(|i| Vec3::from(self.positions[i as usize]));
        (b - a).cross(c - a).try_normalize().unwrap_or(Vec3::ZERO)
    }

    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }
}

/// A texture a material samples.
#[derive(Clone, Debug, PartialEq)]
pub struct TextureRef {
    /// Index of the glTF image (into `Scene::images`).
    pub image: usize,
    /// Which TEXCOORD_n set it reads (0 or 1; KHR_texture_transform's override applied).
    pub tex_coord: u32,
    /// uv' = M · (u, v, 1) with M = [[a, b, c], [d, e, f]]: KHR_texture_transform's
    /// translation · rotation · scale, the identity without it.
    pub transform: [[f32; 3]; 2],
    /// Sampler wrap modes for u and v (glTF codes: 33071 clamp, 33648 mirror, 10497 repeat).
    pub wrap: [u32; 2],
}

impl TextureRef {
    pub const IDENTITY: [[f32; 3]; 2] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
}

/// How a material's alpha is used (glTF `alphaMode`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AlphaMode {
    Opaque,
    /// Cut out where alpha < cutoff: light passes there.
    Mask(f32),
    /// Blended transparency: with a base colour texture, light passes where
    /// alpha < [`BLEND_CUTOFF`] (see [`Material::cutoff`]); without one, its
    /// constant alpha makes it opaque (import leaves out one under 0.5).
    Blend,
}

/// Where a blend's texture lets light through: an alpha under one half.
/// The bake's shadows are binary, so a blend is cut where it is mostly
/// clear, as engines' lightmappers treat a transparent surface's alpha.
pub const BLEND_CUTOFF: f32 = 0.5;

/// What a surface does with light, in linear RGB.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    pub name: Option<String>,
    /// baseColorFactor RGB (diffuse albedo) and alpha.
    pub base_color: [f32; 4],
    /// Multiplies `base_color`, sampled through its UV set.
    pub base_color_texture: Option<TextureRef>,
    /// emissiveFactor × KHR_materials_emissive_strength, radiance in the
    /// scene's units (W·sr⁻¹·m⁻² up to the environment's scale).
    pub emission: [f32; 3],
    /// Multiplies `emission`.
    pub emissive_texture: Option<TextureRef>,
    pub alpha: AlphaMode,
    pub double_sided: bool,
}

impl Material {
    /// The alpha under which light passes the surface, `None` for a surface
    /// whose alpha never lets it through: a MASK's cut-off, and
    /// [`BLEND_CUTOFF`] for a blend whose base colour texture varies its
    /// alpha (foliage, fences and decals are often exported blended). The
    /// export already keeps both kinds' holes in viewers.
    pub fn cutoff(&self) -> Option<f32> {
        match self.alpha {
            AlphaMode::Mask(cutoff) => Some(cutoff),
            AlphaMode::Blend if self.base_color_texture.is_some() => Some(BLEND_CUTOFF),
            _ => None,
        }
    }
}

impl Default for Material {
    /// glTF's default material: white, not emissive, opaque, single-sided.
    fn default() -> Self {
        Material {
            name: None,
            base_color: [1.0; 4],
            base_color_texture: None,
            emission: [0.0; 3],
            emissive_texture: None,
            alpha: AlphaMode::Opaque,
            double_sided: false,
        }
    }
}

/// A decoded texture in linear RGB with linear alpha, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct LinearImage {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f32; 4]>,
}

/// The shape of a punctual light's beam (KHR_lights_punctual's types).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightKind {
    /// Parallel light along the light's direction, from infinitely far away;
    /// its intensity is illuminance (lux) on a surface facing it.
    Directional,
    /// Light from a point in every direction; intensity in candela.
    Point,
    /// A point's light within a cone about the light's direction, full up to
    /// `inner_cone` (radians off its axis) and falling to 0 at `outer_cone`.
    Spot { inner_cone: f64, outer_cone: f64 },
}

/// A KHR_lights_punctual light where its node places it: a light source
/// the bake's punctual pass traces (`solve::punctual`).
#[derive(Clone, Debug, PartialEq)]
pub struct PunctualLight {
    /// The node that places it, and its index in the extension's list.
    pub node: usize,
    pub light: usize,
    /// How notices name it: its index and name and its node's
    /// ("light 1 'bulb' on node 2 'hall'").
    pub label: String,
    pub kind: LightKind,
    /// In scene coordinates (world − `Scene::origin`); unused by a
    /// directional light.
    pub position: DVec3,
    /// Unit direction the light shines along: its node's −Z in world space.
    pub direction: DVec3,
    /// Colour × intensity, linear RGB: candela for a point or spot light,
    /// lux for a directional one.
    pub intensity: DVec3,
    /// Distance at which a point or spot light's influence ends, if any.
    pub range: Option<f64>,
}

/// Light from a punctual light arriving at a point (`PunctualLight::towards`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Incident {
    /// Unit direction from the point towards the light.
    pub direction: DVec3,
    /// Distance to the light (infinite for a directional one).
    pub distance: f64,
    /// Irradiance on a surface facing the light, before visibility:
    /// intensity × attenuation / distance² (the intensity itself for a
    /// directional light).
    pub irradiance: DVec3,
}

impl PunctualLight {
    /// The light arriving at `p` (scene coordinates), as KHR_lights_punctual
    /// defines it: inverse-square falloff, the recommended range window
    /// max(min(1 − (d/range)⁴, 1), 0), and a spot's angular attenuation
    /// clamp((cos − cos outer) / (cos inner − cos outer), 0, 1)². `None`
    /// where none arrives (outside a spot's cone, past the range, or at the
    /// light's own position).
    pub fn towards(&self, p: DVec3) -> Option<Incident> {
        if self.kind == LightKind::Directional {
            return Some(Incident { direction: -self.direction, distance: f64::INFINITY, irradiance: self.intensity });
        }
        let to_light = self.position - p;
        let distance = to_light.length();
        if !(distance > 0.0 && distance.is_finite()) {
            return None;
        }
        let direction = to_light / distance;
        let mut attenuation = 1.0 / (distance * distance);
        if let Some(range) = self.range {
            attenuation *= (1.0 - (distance / range).powi(4)).clamp(0.0, 1.0);
        }
        if let LightKind::Spot { inner_cone, outer_cone } = self.kind {
            let (cos_inner, cos_outer) = (inner_cone.cos(), outer_cone.cos());
            let scale = 1.0 / (cos_inner - cos_outer).max(1e-3);
            let cone = ((self.direction.dot(-direction) - cos_outer) * scale).clamp(0.0, 1.0);
            attenuation *= cone * cone;
        }
        (attenuation > 0.0).then_some(Incident { direction, distance, irradiance: self.intensity * attenuation })
    }
}

/// A scene ready to unwrap and bake.
pub struct Scene {
    /// Output stem (the input's file name without extension).
    pub name: String,
    pub source: SourceAsset,
    /// Where scene coordinates are zero, in world coordinates (metres): every
    /// position (of primitives, texels, reference points) is world − origin.
    /// Zero for a scene near the world origin (see `choose_origin`).
    pub origin: [f64; 3],
    pub primitives: Vec<ScenePrimitive>,
    /// One per glTF material, index for index.
    pub materials: Vec<Material>,
    /// One per glTF image, index for index: decoded when a baked material
    /// samples it (`None` otherwise, or when it could not be decoded).
    /// Shared, not copied, by the CPU scenes (`reference`): a 4096² image
    /// holds 256 MB.
    pub images: Vec<Option<Arc<LinearImage>>>,
    /// The KHR_lights_punctual lights the default scene's nodes place, each
    /// with light in it: the bake's light sources besides the environment
    /// and emissive surfaces.
    pub lights: Vec<PunctualLight>,
    /// Things left out or changed, one line each, for the user and the report.
    pub notices: Vec<String>,
}

impl Scene {
    pub fn material(&self, primitive: &ScenePrimitive) -> Material {
        primitive.material.and_then(|m| self.materials.get(m).cloned()).unwrap_or_default()
    }

    /// Axis-aligned bounds of all baked geometry in scene coordinates, or `None` when there is none.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let mut points = self.primitives.iter().flat_map(|p| p.positions.iter().map(|&v| Vec3::from(v)));
        let first = points.next()?;
        Some(points.fold((first, first), |(lo, hi), p| (lo.min(p), hi.max(p))))
    }

    pub fn triangle_count(&self) -> usize {
        self.primitives.iter().map(ScenePrimitive::triangle_count).sum()
    }
}

/// The scene origin for geometry whose world bounds are `lo`..`hi`.
///
/// A scene within a few of its sizes of the world origin keeps it (scene
/// coordinates are world coordinates, and f32 loses at most 3 bits there).
/// A farther one gets its bounds' centre rounded to a multiple of a power of
/// two at least twice its largest side: exact in f32 and f64, and every
/// position ends up within 2.5 sizes of zero.
pub fn choose_origin(lo: DVec3, hi: DVec3) -> DVec3 {
    /// How many sizes from the world origin a scene's centre may be and keep it.
    const NEAR: f64 = 4.0;
    let centre = (lo + hi) * 0.5;
    let size = (hi - lo).max_element();
    if !centre.is_finite() || !size.is_finite() {
        return DVec3::ZERO;
    }
    if centre.abs().max_element() <= NEAR * size {
        return DVec3::ZERO;
    }
    if size <= 0.0 {
        return centre;
    }
    let step = (2.0 * size).log2().ceil().exp2();
    (centre / step).round() * step
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scene_near_the_world_origin_keeps_it() {
        assert_eq!(choose_origin(DVec3::new(-0.1, 0.0, -2.0), DVec3::new(3.0, 1.0, 0.5)), DVec3::ZERO);
        // A 2 m sphere 2 m up: not around the origin, but near it.
        assert_eq!(choose_origin(DVec3::new(-1.0, 1.0, -1.0), DVec3::new(1.0, 3.0, 1.0)), DVec3::ZERO);
    }

    #[test]
    fn a_far_scene_gets_an_origin_near_its_centre() {
        let (lo, hi) = (DVec3::new(1e5 - 2.0, 0.3, -1e5 - 2.0), DVec3::new(1e5 + 2.3, 2.0, -1e5 + 2.0));
        let origin = choose_origin(lo, hi);
        let size = (hi - lo).max_element();
        for corner in [lo, hi] {
            assert!((corner - origin).abs().max_element() <= 2.5 * size, "{corner} from {origin}");
        }
        // A multiple of a power of two: exact in f64 and f32.
        assert_eq!(origin, DVec3::new(1e5, 0.0, -1e5));
    }

    #[test]
    fn a_point_far_away_is_its_own_origin_and_overflow_falls_back_to_zero() {
        let p = DVec3::new(1e7, 3.5, -2.25);
        assert_eq!(choose_origin(p, p), p);
        assert_eq!(choose_origin(DVec3::splat(-f64::MAX), DVec3::splat(f64::MAX)), DVec3::ZERO);
    }
}
