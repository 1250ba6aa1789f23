//! The `Scene`: what import hands to the rest of the pipeline. Static
//! triangle geometry in world space (glTF's: right-handed, +Y up, metres)
//! with the material facts the solver needs, plus the source asset that
//! export rewrites.

use glam::Vec3;

use crate::asset::SourceAsset;

/// One glTF primitive as drawn by one node: the unit that gets lightmap space.
#[derive(Clone, Debug)]
pub struct ScenePrimitive {
    /// Index of the node that draws it.
    pub node: usize,
    /// Index of the glTF mesh and of the primitive within it.
    pub mesh: usize,
    pub primitive: usize,
    /// World-space positions (metres), one per source vertex, in source order.
    pub positions: Vec<[f32; 3]>,
    /// World-space unit normals, one per source vertex, if the source has them
    /// (otherwise flat normals are used, as glTF prescribes).
    pub normals: Option<Vec<[f32; 3]>>,
    /// TEXCOORD_0, one per source vertex, if present.
    pub uv0: Option<Vec<[f32; 2]>>,
    /// Triangle list in source vertex numbering (strips and fans converted),
    /// in the source's winding.
    pub indices: Vec<u32>,
    /// The node's transform has a negative determinant, so the winding that
    /// faces front is reversed in world space.
    pub mirrored: bool,
    /// Index into `Scene::materials`; `None` means glTF's default material.
    pub material: Option<usize>,
}

impl ScenePrimitive {
    /// The world-space normal of triangle `t` from its winding (front side), or
    /// zero for a degenerate triangle.
    pub fn face_normal(&self, t: usize) -> Vec3 {
        let [a, b, c] = [0, 1, 2].map(|k| Vec3::from(self.positions[self.indices[3 * t + k] as usize]));
        let n = (b - a).cross(c - a);
        let n = if self.mirrored { -n } else { n };
        n.try_normalize().unwrap_or(Vec3::ZERO)
    }

    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }
}

/// What a surface does with light, in linear RGB.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    pub name: Option<String>,
    /// baseColorFactor RGB (diffuse albedo) and alpha.
    pub base_color: [f32; 4],
    /// emissiveFactor × KHR_materials_emissive_strength, radiance in the
    /// scene's units (W·sr⁻¹·m⁻² up to the environment's scale).
    pub emission: [f32; 3],
    pub double_sided: bool,
}

impl Default for Material {
    /// glTF's default material: white, not emissive, single-sided.
    fn default() -> Self {
        Material { name: None, base_color: [1.0; 4], emission: [0.0; 3], double_sided: false }
    }
}

/// A scene ready to unwrap and bake.
pub struct Scene {
    /// Output stem (the input's file name without extension).
    pub name: String,
    pub source: SourceAsset,
    pub primitives: Vec<ScenePrimitive>,
    /// One per glTF material, index for index.
    pub materials: Vec<Material>,
    /// Things left out or changed, one line each, for the user and the report.
    pub notices: Vec<String>,
}

impl Scene {
    pub fn material(&self, primitive: &ScenePrimitive) -> Material {
        primitive.material.and_then(|m| self.materials.get(m).cloned()).unwrap_or_default()
    }

    /// Axis-aligned bounds of all baked geometry, or `None` when there is none.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let mut points = self.primitives.iter().flat_map(|p| p.positions.iter().map(|&v| Vec3::from(v)));
        let first = points.next()?;
        Some(points.fold((first, first), |(lo, hi), p| (lo.min(p), hi.max(p))))
    }

    pub fn triangle_count(&self) -> usize {
        self.primitives.iter().map(ScenePrimitive::triangle_count).sum()
    }
}
