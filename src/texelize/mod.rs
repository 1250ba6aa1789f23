//! Texelize stage: Scene + Atlas in, `TexelSet` out. Every lightmap texel a
//! triangle touches becomes a radiosity element with world position, normal,
//! world area, albedo and emission (design notes, algorithm step 1).
//!
//! The GPU rasterizes each triangle into the atlas in TEXCOORD_1 space
//! (`raster.rs`); texels at chart borders whose centre lies outside every
//! triangle still get the data of the nearest point of the nearest triangle.

mod raster;

use anyhow::{Result, bail};
use bytemuck::{Pod, Zeroable};
use glam::Vec3;

use crate::gpu::Gpu;
use crate::scene::Scene;
use crate::unwrap::Atlas;

/// One covered texel. Mirrors `struct Texel` in `shaders/include/texel.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct Texel {
    /// Position in scene coordinates (metres, world − `Scene::origin`): the
    /// texel centre's nearest point on its triangle.
    pub position: [f32; 3],
    /// World area (m²) of the surface inside the texel's square; zero for
    /// texels that only border a chart.
    pub area: f32,
    /// Unit shading normal.
    pub normal: [f32; 3],
    /// x + y · atlas width.
    pub index: u32,
    /// Unit geometric normal of the texel's triangle, on the shading normal's side.
    pub face_normal: [f32; 3],
    /// Global triangle id (primitives in scene order, triangles in order,
    /// repeated triangles left out).
    pub triangle: u32,
    /// Diffuse albedo, linear RGB.
    pub albedo: [f32; 3],
    /// Global chart id from the unwrap.
    pub chart: u32,
    /// Emitted radiance, linear RGB.
    pub emission: [f32; 3],
    /// Index into `Scene::primitives`.
    pub primitive: u32,
}

impl Texel {
    pub fn position(&self) -> Vec3 {
        Vec3::from(self.position)
    }
    pub fn normal(&self) -> Vec3 {
        Vec3::from(self.normal)
    }
    pub fn x(&self, width: u32) -> u32 {
        self.index % width
    }
    pub fn y(&self, width: u32) -> u32 {
        self.index / width
    }
    /// Whether it is surface (has area) that emits light.
    pub fn emits(&self) -> bool {
        self.area > 0.0 && self.emission.iter().any(|&e| e > 0.0)
    }
}

/// The radiosity elements of one atlas page.
#[derive(Clone, Debug)]
pub struct TexelSet {
    pub width: u32,
    pub height: u32,
    /// Covered texels in row-major atlas order.
    pub texels: Vec<Texel>,
    /// Per texel, the vertex colour (COLOR_0, clamped to [0, 1]) its albedo
    /// was multiplied by; empty when no primitive has one (all white).
    pub tint: Vec<[f32; 3]>,
}

impl TexelSet {
    /// Total world area covered by texels (m²): equals the baked surface area.
    pub fn total_area(&self) -> f64 {
        self.texels.iter().map(|t| t.area as f64).sum()
    }
}

/// Per-vertex data the GPU interpolates. Mirrors `struct Vertex` in texelize_attributes.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct GpuVertex {
    position: [f32; 3],
    _pad0: f32,
    normal: [f32; 3],
    _pad1: f32,
    uv0: [f32; 2],
    uv1: [f32; 2],
}

/// Mirrors `struct Triangle` in texelize_attributes.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct GpuTriangle {
    corners: [u32; 3],
    material: u32,
    face_normal: [f32; 3],
    /// Bit k set: edge k → k+1 is on its chart's border (no other triangle
    /// of the chart shares it).
    border_edges: u32,
}

/// The whole scene flattened for the GPU, with per-triangle facts the CPU keeps.
struct Mesh {
    vertices: Vec<GpuVertex>,
    triangles: Vec<GpuTriangle>,
    /// Three corners per triangle in texel units.
    corners: Vec<[f32; 2]>,
    /// World area per texel² of UV area, per triangle.
    area_ratio: Vec<f32>,
    triangle_primitive: Vec<u32>,
    triangle_chart: Vec<u32>,
    /// COLOR_0 at each triangle's three corners (white where a primitive
    /// has none); empty when no primitive has one.
    triangle_colors: Vec<[[f32; 3]; 3]>,
}

fn flatten(scene: &Scene, atlas: &Atlas) -> Mesh {
    let size = [atlas.width as f32, atlas.height as f32];
    let mut mesh = Mesh {
        vertices: Vec::new(),
        triangles: Vec::new(),
        corners: Vec::new(),
        area_ratio: Vec::new(),
        triangle_primitive: Vec::new(),
        triangle_chart: Vec::new(),
        triangle_colors: Vec::new(),
    };
    let coloured = scene.primitives.iter().any(|p| p.colors.is_some());
    let default_material = scene.materials.len() as u32;
    for (p, (primitive, unwrapped)) in scene.primitives.iter().zip(&atlas.meshes).enumerate() {
        let base = mesh.vertices.len() as u32;
        for v in &unwrapped.vertices {
            let source = v.xref as usize;
            mesh.vertices.push(GpuVertex {
                position: primitive.positions[source],
                normal: primitive.normals.as_ref().map_or([0.0; 3], |n| n[source]),
                uv0: primitive.uv0.as_ref().map_or([0.0; 2], |uv| uv[source]),
                uv1: primitive.uv1.as_ref().map_or([0.0; 2], |uv| uv[source]),
                ..Default::default()
            });
        }
        let material = primitive.material.map_or(default_material, |m| m as u32);
        // Edges used by one triangle only are chart borders (the unwrap splits
        // vertices along seams, so a shared edge shares its vertex indices).
        // Repeated triangles share their first copy's texels: they are left out here.
        let repeat = crate::repeats::mask(&primitive.repeats, unwrapped.indices.len() / 3);
        let triangles = || unwrapped.indices.chunks_exact(3).enumerate().filter(|(t, _)| !repeat[*t]);
        let mut edge_uses: std::collections::HashMap<(u32, u32), u32> = std::collections::HashMap::new();
        for (_, corner) in triangles() {
            for k in 0..3 {
                let (a, b) = (corner[k], corner[(k + 1) % 3]);
                *edge_uses.entry((a.min(b), a.max(b))).or_default() += 1;
            }
        }
        for (t, corner) in triangles() {
            let border_edges = (0..3)
                .filter(|&k| {
                    let (a, b) = (corner[k], corner[(k + 1) % 3]);
                    edge_uses[&(a.min(b), a.max(b))] == 1
                })
                .fold(0u32, |mask, k| mask | 1 << k);
            let face_normal = primitive.face_normal(t);
            let [a, b, c] = [0, 1, 2]
                .map(|k| Vec3::from(primitive.positions[unwrapped.vertices[corner[k] as usize].xref as usize]));
            let world_area = 0.5 * (b - a).cross(c - a).length();
            let uv = [0, 1, 2].map(|k| {
                let v = unwrapped.vertices[corner[k] as usize].uv;
                [v[0] * size[0], v[1] * size[1]]
            });
            let uv_area = 0.5
                * ((uv[1][0] - uv[0][0]) * (uv[2][1] - uv[0][1]) - (uv[2][0] - uv[0][0]) * (uv[1][1] - uv[0][1])).abs();
            mesh.corners.extend_from_slice(&uv);
            mesh.area_ratio.push(if uv_area > 1e-12 { world_area / uv_area } else { 0.0 });
            mesh.triangles.push(GpuTriangle {
                corners: [base + corner[0], base + corner[1], base + corner[2]],
                material,
                face_normal: face_normal.to_array(),
                border_edges,
            });
            mesh.triangle_primitive.push(p as u32);
            mesh.triangle_chart.push(unwrapped.vertices[corner[0] as usize].chart);
            if coloured {
                let source = |k: usize| unwrapped.vertices[corner[k] as usize].xref as usize;
                let color = |k: usize| primitive.colors.as_ref().map_or([1.0; 3], |c| c[source(k)]);
                mesh.triangle_colors.push([0, 1, 2].map(color));
            }
        }
    }
    mesh
}

/// Rasterizes the scene's triangles into the atlas and returns every texel they touch.
pub fn run(gpu: &Gpu, scene: &Scene, atlas: &Atlas) -> Result<TexelSet> {
    if atlas.meshes.len() != scene.primitives.len() {
        bail!("texelize: the atlas has {} meshes for {} primitives", atlas.meshes.len(), scene.primitives.len());
    }
    let max = gpu.limits.max_texture_dimension_2d;
    if atlas.width > max || atlas.height > max {
        bail!(
            "texelize: the atlas is {}×{} texels but adapter {} allows at most {max}²; lower --max-atlas-size",
            atlas.width,
            atlas.height,
            gpu.adapter.name
        );
    }
    let mesh = flatten(scene, atlas);
    let materials = crate::gpu::Materials::upload(gpu, scene);
    let mut texels = raster::texelize(gpu, &mesh, &materials, atlas.width, atlas.height)?;
    for texel in &mut texels {
        texel.primitive = mesh.triangle_primitive[texel.triangle as usize];
        texel.chart = mesh.triangle_chart[texel.triangle as usize];
    }
    gpu.check("texelize")?;
    let tint = tint_by_vertex_colors(&mesh, &mut texels);
    Ok(TexelSet { width: atlas.width, height: atlas.height, texels, tint })
}

/// Multiplies each texel's albedo by COLOR_0 interpolated at its position
/// (glTF: base colour = factor · texture · COLOR_0) and returns the factors.
fn tint_by_vertex_colors(mesh: &Mesh, texels: &mut [Texel]) -> Vec<[f32; 3]> {
    if mesh.triangle_colors.is_empty() {
        return Vec::new();
    }
    texels
        .iter_mut()
        .map(|texel| {
            let t = texel.triangle as usize;
            let corners = mesh.triangles[t].corners.map(|v| Vec3::from(mesh.vertices[v as usize].position));
            let w = barycentric(texel.position(), corners);
            let colors = mesh.triangle_colors[t].map(Vec3::from);
            let tint = (w[0] * colors[0] + w[1] * colors[1] + w[2] * colors[2]).clamp(Vec3::ZERO, Vec3::ONE);
            let tint = if tint.is_finite() { tint } else { Vec3::ONE };
            texel.albedo = (Vec3::from(texel.albedo) * tint).to_array();
            tint.to_array()
        })
        .collect()
}

/// Barycentric weights of `p` (a point on the triangle's plane) in triangle
/// `[a, b, c]`, clamped to the triangle; a third each for a degenerate one.
fn barycentric(p: Vec3, [a, b, c]: [Vec3; 3]) -> [f32; 3] {
    let (e1, e2, d) = (b - a, c - a, p - a);
    let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let det = d11 * d22 - d12 * d12;
    if det <= f32::EPSILON * d11 * d22 || det <= 0.0 {
        return [1.0 / 3.0; 3];
    }
    let (d1, d2) = (d.dot(e1), d.dot(e2));
    let v = ((d22 * d1 - d12 * d2) / det).max(0.0);
    let w = ((d11 * d2 - d12 * d1) / det).max(0.0);
    let u = (1.0 - v - w).max(0.0);
    let sum = u + v + w;
    [u / sum, v / sum, w / sum]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_rust_structs_mirror_the_shaders() {
        use crate::gpu::{Shader, mirror::assert_mirrors};
        assert_mirrors!(
            Shader::TexelizeAttributes,
            "Texel",
            Texel { position, area, normal, index, face_normal, triangle, albedo, chart, emission, primitive }
        );
        assert_mirrors!(Shader::TexelizeAttributes, "Vertex", GpuVertex { position, normal, uv0, uv1 });
        assert_mirrors!(
            Shader::TexelizeAttributes,
            "Triangle",
            GpuTriangle { corners, material, face_normal, border_edges }
        );
    }
}
