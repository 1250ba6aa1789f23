//! The paper's per-vertex comparison (its Fig. 14: incremental radiosity at
//! the vertices against its texels), for the direct light: the same direct
//! pass and shadow rays evaluated at the meshes' vertices and interpolated
//! across each triangle (Gouraud), against the pass at the texels. Both are
//! compared with the CPU reference of the direct light alone at the same
//! texel centres. The bounce pass has no per-vertex form: it shoots from
//! patches of atlas cells to texels, and a vertex version would be a second
//! solver.

use std::sync::Arc;
use std::time::Instant;

use anyhow::{Result, bail};
use glam::Vec3;

use bake::config::BakeOptions;
use bake::environment::{EnvironmentMap, LightSet};
use bake::gpu::Gpu;
use bake::reference::{ReferenceCheck, reference_probes_within};
use bake::scene::Scene;
use bake::texelize::{Texel, TexelSet};

/// One atlas size's comparison.
pub struct Comparison {
    pub texels: usize,
    pub vertices: usize,
    pub texel_seconds: f64,
    pub vertex_seconds: f64,
    pub texel_error: f64,
    pub vertex_error: f64,
    /// The direct-only reference's own noise (relative).
    pub noise: f64,
}

/// What to compare: probe texels and paths per probe for the reference.
pub struct Setup<'a> {
    pub gpu: &'a Gpu,
    pub environment: &'a Arc<EnvironmentMap>,
    pub lights: &'a LightSet,
    pub probes: usize,
    pub samples: u32,
}

/// Bakes the direct light of `scene` at the texels of an atlas of `options`
/// and at its vertices, and measures both against the reference.
pub fn compare(setup: &Setup, scene: &Scene, options: &BakeOptions) -> Result<Comparison> {
    let atlas = crate::unwrap(scene, options)?;
    let texels = bake::texelize::run(setup.gpu, scene, &atlas)?;
    let gpu = setup.gpu;

    let (vertices, first_vertex) = vertex_points(scene);
    let at_vertices = || {
        let start = Instant::now();
        let direct = bake::solve::direct::run(gpu, scene, &vertices, setup.lights, &options.solve, &mut |_, _| {})?;
        anyhow::Ok((direct.irradiance, start.elapsed().as_secs_f64()))
    };
    // Before the texels too, so that neither pays for the pipelines' first use.
    let (_, first_seconds) = at_vertices()?;
    let start = Instant::now();
    let (at_texels, _) = bake::solve::direct_light(
        gpu,
        scene,
        &texels,
        setup.lights,
        atlas.texels_per_unit,
        &options.solve,
        &mut |_, _| {},
    )?;
    let texel_seconds = start.elapsed().as_secs_f64();

    let (at_vertices, second_seconds) = at_vertices()?;
    let vertex_seconds = first_seconds.min(second_seconds);

    // The reference of the direct light alone, at the grid's probe texels.
    let check = ReferenceCheck {
        texels: setup.probes,
        samples: setup.samples,
        environment: Some(setup.environment.clone()),
        env_rotation_degrees: 0.0,
        env_intensity: 1.0,
    };
    let (probes, noise) = reference_probes_within(scene, &texels, &check, 0);
    let lightmap = |e: [f32; 3]| e.map(|c| c as f64 / std::f64::consts::PI);
    let texel_error = probes.relative_rmse(probes.texels.iter().map(|&i| lightmap(at_texels.irradiance[i as usize])));
    let mut interpolated = Vec::with_capacity(probes.texels.len());
    for &i in &probes.texels {
        interpolated.push(lightmap(gouraud(scene, &first_vertex, &at_vertices, &texels.texels[i as usize])?));
    }
    let vertex_error = probes.relative_rmse(interpolated.into_iter());
    Ok(Comparison {
        texels: texels.texels.len(),
        vertices: vertices.texels.len(),
        texel_seconds,
        vertex_seconds,
        texel_error,
        vertex_error,
        noise,
    })
}

/// Every vertex of every primitive as a receiver point, with its normal
/// (the source's, else the area-weighted mean of its triangles'), and the
/// index of each primitive's first vertex among them.
fn vertex_points(scene: &Scene) -> (TexelSet, Vec<usize>) {
    let mut points = Vec::new();
    let mut first = Vec::new();
    for (p, primitive) in scene.primitives.iter().enumerate() {
        first.push(points.len());
        let material = scene.material(primitive);
        let normals = primitive.normals.clone().unwrap_or_else(|| {
            // A mirroring transform turns the winding, and so the normals, around.
            let side = if primitive.mirrored { -1.0 } else { 1.0 };
            let area_weighted = bake::fixtures::vertex_normals(&primitive.positions, &primitive.indices);
            area_weighted.into_iter().map(|n| n.map(|c| side * c)).collect()
        });
        for (v, position) in primitive.positions.iter().enumerate() {
            let normal = Vec3::from(normals[v]).normalize_or_zero();
            let index = points.len() as u32;
            points.push(Texel {
                position: *position,
                area: 0.0,
                normal: normal.to_array(),
                index,
                face_normal: normal.to_array(),
                triangle: 0,
                albedo: [material.base_color[0], material.base_color[1], material.base_color[2]],
                chart: 0,
                emission: [0.0; 3],
                primitive: p as u32,
            });
        }
    }
    (TexelSet { width: points.len() as u32, height: 1, texels: points, tint: Vec::new() }, first)
}

/// The vertices' irradiance interpolated to `texel`'s position across its
/// triangle (barycentric weights of the nearest point on it).
fn gouraud(scene: &Scene, first_vertex: &[usize], at_vertices: &[[f32; 3]], texel: &Texel) -> Result<[f32; 3]> {
    // Global triangle ids run through the primitives in order (the statues repeat no triangle).
    let mut id = texel.triangle as usize;
    for (p, primitive) in scene.primitives.iter().enumerate() {
        if !primitive.repeats.is_empty() {
            bail!("per-vertex baseline: primitive {p} repeats triangles");
        }
        if id >= primitive.triangle_count() {
            id -= primitive.triangle_count();
            continue;
        }
        let corners = [0, 1, 2].map(|k| primitive.indices[3 * id + k] as usize);
        let [a, b, c] = corners.map(|v| Vec3::from(primitive.positions[v]));
        let [u, v] = barycentric(texel.position(), a, b, c);
        // The texel's point lies on its triangle: a wrong id would land elsewhere.
        let off = (a + u * (b - a) + v * (c - a)).distance(texel.position());
        if off > 1e-3 * (b - a).length().max((c - a).length()).max(1e-6) {
            bail!("per-vertex baseline: texel {} lies {off} m off its triangle {}", texel.index, texel.triangle);
        }
        let w = [1.0 - u - v, u, v];
        let mut sum = [0.0f32; 3];
        for (corner, weight) in corners.iter().zip(w) {
            let e = at_vertices[first_vertex[p] + corner];
            for (s, e) in sum.iter_mut().zip(e) {
                *s += weight * e;
            }
        }
        return Ok(sum);
    }
    bail!("per-vertex baseline: texel {} names triangle {} past the scene's last", texel.index, texel.triangle)
}

/// Barycentric weights of b and c for the point of triangle abc nearest `p`'s
/// projection onto its plane, clamped into the triangle.
fn barycentric(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> [f32; 2] {
    let (e1, e2, d) = (b - a, c - a, p - a);
    let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let det = (d11 * d22 - d12 * d12).max(f32::MIN_POSITIVE);
    let (d1, d2) = (d.dot(e1), d.dot(e2));
    let u = ((d22 * d1 - d12 * d2) / det).clamp(0.0, 1.0);
    let v = ((d11 * d2 - d12 * d1) / det).clamp(0.0, 1.0 - u);
    [u, v]
}
