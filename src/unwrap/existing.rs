//! Reusing the input's own lightmap UVs (`--keep-uv1`): an [`Atlas`] of one
//! page built from every mesh's existing TEXCOORD_1, if those UVs can hold a
//! lightmap.
//!
//! The checks, in this order, for each mesh in input order:
//! 1. one UV per vertex, each finite and inside `[0, 1]²`;
//! 2. the mesh's triangles with surface area have UV area;
//! 3. no two triangles with surface area (of the same mesh or of different ones) overlap: each is
//!    rasterized at the page resolution and a texel centre strictly inside two triangles is an
//!    overlap (triangles that merely share an edge never both hold a centre).
//!
//! Charts, which the solver's patches need, are the groups of triangles connected through shared
//! vertices or identical UVs. Triangles without surface area get no chart and collapse onto one
//! UV, as the unwrap backends do with them.

use super::{Atlas, AtlasVertex, MeshInput, UnwrapOptions, UnwrappedMesh, check, triangle_area};

/// Why the existing UVs cannot be used. Meshes are numbered in input order.
#[derive(Clone, Debug, PartialEq)]
pub enum ExistingUvError {
    /// Options or meshes that no unwrap accepts either.
    Invalid(String),
    CountMismatch {
        mesh: usize,
        uvs: usize,
        vertices: usize,
    },
    OutOfRange {
        mesh: usize,
        vertex: usize,
        uv: [f32; 2],
    },
    /// `triangles` of the mesh's triangles with surface area have none in UV space.
    NoArea {
        mesh: usize,
        triangles: usize,
    },
    /// `mesh` overlaps `other` (the same mesh for a self-overlap); `texels` counts every texel
    /// centre covered twice on the `size`² page, whichever meshes cover it.
    Overlap {
        mesh: usize,
        other: usize,
        texels: u64,
        size: u32,
    },
}

impl ExistingUvError {
    /// The problem in words, with `name(i)` naming mesh `i`.
    pub fn describe(&self, name: impl Fn(usize) -> String) -> String {
        match *self {
            ExistingUvError::Invalid(ref why) => why.clone(),
            ExistingUvError::CountMismatch { mesh, uvs, vertices } => {
                format!("{}: {uvs} UVs for {vertices} vertices", name(mesh))
            }
            ExistingUvError::OutOfRange { mesh, vertex, uv } => {
                format!("{}: vertex {vertex} has UV ({}, {}), outside [0, 1]", name(mesh), uv[0], uv[1])
            }
            ExistingUvError::NoArea { mesh, triangles } => {
                format!("{}: {triangles} triangles with surface area have no UV area", name(mesh))
            }
            ExistingUvError::Overlap { mesh, other, texels, size } => format!(
                "{} overlaps {} in UV space ({texels} texel centres covered twice on a {size}×{size} page)",
                name(mesh),
                if other == mesh { "itself".to_string() } else { name(other) }
            ),
        }
    }
}

impl std::fmt::Display for ExistingUvError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.describe(|i| format!("mesh {i}")))
    }
}

impl std::error::Error for ExistingUvError {}

/// An atlas from existing lightmap UVs: `uvs[i]` holds one UV per vertex of `meshes[i]`
/// (normalized page coordinates, the module conventions of [`super`]).
///
/// The page is square: `max_atlas_size` texels wide, or with `texels_per_unit` the side that
/// gives that mean density (world area against UV area), capped at `max_atlas_size` with a
/// notice. Vertex `i` of each output mesh is input vertex `i` with its own UV; triangles keep
/// their order. Padding is whatever the UVs have (dilation at export fills what it can).
pub fn from_existing(
    meshes: &[MeshInput],
    uvs: &[&[[f32; 2]]],
    options: &UnwrapOptions,
) -> Result<Atlas, ExistingUvError> {
    super::validate(meshes, options).map_err(|e| ExistingUvError::Invalid(e.to_string()))?;
    if uvs.len() != meshes.len() {
        return Err(ExistingUvError::Invalid(format!("{} UV sets for {} meshes", uvs.len(), meshes.len())));
    }
    let mut world_area = 0.0f64;
    let mut uv_area = 0.0f64;
    for (mesh, (m, uv)) in meshes.iter().zip(uvs).enumerate() {
        if uv.len() != m.positions.len() {
            return Err(ExistingUvError::CountMismatch { mesh, uvs: uv.len(), vertices: m.positions.len() });
        }
        for &i in m.indices {
            let p = uv[i as usize];
            if !p.iter().all(|c| (0.0..=1.0).contains(c)) {
                return Err(ExistingUvError::OutOfRange { mesh, vertex: i as usize, uv: p });
            }
        }
        let mut no_area = 0;
        for t in m.indices.chunks_exact(3) {
            let world = triangle_area([0, 1, 2].map(|k| m.positions[t[k] as usize]));
            let area = check::uv_area(uv[t[0] as usize], uv[t[1] as usize], uv[t[2] as usize]).abs();
            if world > 0.0 && area == 0.0 {
                no_area += 1;
            }
            world_area += world;
            uv_area += area;
        }
        if no_area > 0 {
            return Err(ExistingUvError::NoArea { mesh, triangles: no_area });
        }
    }

    let mut notices = Vec::new();
    let size = match options.texels_per_unit {
        None => options.max_atlas_size,
        Some(t) if world_area > 0.0 && uv_area > 0.0 => {
            let wanted = (t as f64 * (world_area / uv_area).sqrt()).ceil();
            if wanted > options.max_atlas_size as f64 {
                notices.push(format!(
                    "--texels-per-unit {t} on the input's TEXCOORD_1 needs a {wanted}² page; \
                     capped at {0}² (max_atlas_size)",
                    options.max_atlas_size
                ));
            }
            (wanted as u32).clamp(1, options.max_atlas_size)
        }
        Some(_) => options.max_atlas_size,
    };

    // Overlaps: the first triangle holding each texel centre, as (mesh, triangle).
    let n = size as usize;
    let mut owner: Vec<Option<(usize, usize)>> = vec![None; n * n];
    let mut first: Option<(usize, usize)> = None;
    let mut overlapping = 0u64;
    for (mesh, (m, uv)) in meshes.iter().zip(uvs).enumerate() {
        for (t, tri) in m.indices.chunks_exact(3).enumerate() {
            if triangle_area([0, 1, 2].map(|k| m.positions[tri[k] as usize])) == 0.0 {
                continue; // collapsed below: it covers nothing
            }
            let p = [0, 1, 2].map(|k| uv[tri[k] as usize].map(|c| c as f64 * n as f64));
            check::inside_centres(p, n, n, |x, y| match owner[y * n + x] {
                None => owner[y * n + x] = Some((mesh, t)),
                Some((other, _)) => {
                    overlapping += 1;
                    first.get_or_insert((other, mesh));
                }
            });
        }
    }
    if let Some((mesh, other)) = first {
        return Err(ExistingUvError::Overlap { mesh, other, texels: overlapping, size });
    }

    let mut chart_count = 0u32;
    let out = meshes.iter().zip(uvs).map(|(m, uv)| charted(m, uv, &mut chart_count)).collect();
    Ok(Atlas {
        width: size,
        height: size,
        texels_per_unit: if world_area > 0.0 { (size as f64 * (uv_area / world_area).sqrt()) as f32 } else { 0.0 },
        chart_count,
        utilization: uv_area.min(1.0) as f32,
        meshes: out,
        notices,
    })
}

/// One mesh with its UVs and charts numbered from `*next` on (advanced past them).
fn charted(m: &MeshInput, uv: &[[f32; 2]], next: &mut u32) -> UnwrappedMesh {
    // Union-find over vertices: corners of a triangle, and vertices with bit-identical UVs.
    let mut parent: Vec<usize> = (0..m.positions.len()).collect();
    fn root(parent: &mut [usize], mut v: usize) -> usize {
        while parent[v] != v {
            parent[v] = parent[parent[v]];
            v = parent[v];
        }
        v
    }
    let union = |parent: &mut Vec<usize>, a: usize, b: usize| {
        let (ra, rb) = (root(parent, a), root(parent, b));
        if ra != rb {
            parent[ra.max(rb)] = ra.min(rb);
        }
    };
    let surface: Vec<bool> =
        m.indices.chunks_exact(3).map(|t| triangle_area([0, 1, 2].map(|k| m.positions[t[k] as usize])) > 0.0).collect();
    let mut by_uv = std::collections::HashMap::new();
    for (t, tri) in m.indices.chunks_exact(3).enumerate() {
        if !surface[t] {
            continue;
        }
        union(&mut parent, tri[0] as usize, tri[1] as usize);
        union(&mut parent, tri[0] as usize, tri[2] as usize);
        for &v in tri {
            let key = uv[v as usize].map(f32::to_bits);
            let same = *by_uv.entry(key).or_insert(v as usize);
            union(&mut parent, same, v as usize);
        }
    }
    // Chart ids in order of first use.
    let mut chart_of_root = std::collections::HashMap::new();
    let mut vertices: Vec<AtlasVertex> =
        (0..m.positions.len()).map(|i| AtlasVertex { xref: i as u32, uv: uv[i], chart: u32::MAX }).collect();
    let mut indices = Vec::with_capacity(m.indices.len());
    for (t, tri) in m.indices.chunks_exact(3).enumerate() {
        if surface[t] {
            let r = root(&mut parent, tri[0] as usize);
            let chart = *chart_of_root.entry(r).or_insert_with(|| {
                *next += 1;
                *next - 1
            });
            for &v in tri {
                vertices[v as usize].chart = chart;
            }
            indices.extend_from_slice(tri);
        } else {
            // No surface: its own corners, collapsed onto one UV, in no chart.
            let collapsed = uv[tri[0] as usize];
            for &v in tri {
                indices.push(vertices.len() as u32);
                vertices.push(AtlasVertex { xref: v, uv: collapsed, chart: u32::MAX });
            }
        }
    }
    UnwrappedMesh { vertices, indices }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::unwrap::inspect;

    /// A unit quad (two triangles) in the XY plane at `z`.
    const QUAD: [[f32; 3]; 4] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
    const QUAD_INDICES: [u32; 6] = [0, 1, 2, 0, 2, 3];

    fn square(x: f32, y: f32, side: f32) -> [[f32; 2]; 4] {
        [[x, y], [x + side, y], [x + side, y + side], [x, y + side]]
    }

    fn options(size: u32) -> UnwrapOptions {
        UnwrapOptions { max_atlas_size: size, ..UnwrapOptions::default() }
    }

    #[test]
    fn disjoint_squares_make_a_valid_atlas_with_their_own_uvs() {
        let meshes = [MeshInput::new(&QUAD, &QUAD_INDICES), MeshInput::new(&QUAD, &QUAD_INDICES)];
        let (a, b) = (square(0.05, 0.05, 0.4), square(0.55, 0.05, 0.4));
        let atlas = from_existing(&meshes, &[&a, &b], &options(64)).unwrap();
        assert_eq!((atlas.width, atlas.height, atlas.chart_count), (64, 64, 2));
        assert_eq!(atlas.meshes[1].vertices[2].uv, b[2]);
        assert_eq!(atlas.meshes[1].vertices[2].chart, 1);
        assert_eq!(atlas.meshes[0].indices, QUAD_INDICES);
        // 0.4 of the page per metre: 25.6 texels per metre on a 64² page.
        assert!((atlas.texels_per_unit - 25.6).abs() < 1e-3, "{}", atlas.texels_per_unit);
        let quality = inspect(&meshes, &atlas, 1);
        assert_eq!((quality.overlap_texels, quality.self_overlap_texels, quality.malformed_triangles), (0, 0, 0));
    }

    #[test]
    fn overlapping_meshes_are_named() {
        let meshes = [MeshInput::new(&QUAD, &QUAD_INDICES), MeshInput::new(&QUAD, &QUAD_INDICES)];
        let (a, b) = (square(0.05, 0.05, 0.4), square(0.3, 0.3, 0.4));
        match from_existing(&meshes, &[&a, &b], &options(64)) {
            Err(ExistingUvError::Overlap { mesh: 0, other: 1, texels, size: 64 }) => {
                // (0.45 − 0.3) × 64 ≈ 9.6 texels square: 9 or 10 texel centres a side.
                assert!((81..=100).contains(&texels), "{texels}");
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn a_mesh_folding_over_itself_overlaps_itself() {
        let uv = [[0.1, 0.1], [0.9, 0.1], [0.9, 0.9], [0.1, 0.9]];
        // Both triangles use the same three UV corners' region: the second one mirrors the first.
        let folded = [uv[0], uv[1], uv[2], [0.9, 0.1]];
        let meshes = [MeshInput::new(&QUAD, &QUAD_INDICES)];
        let error = from_existing(&meshes, &[&folded], &options(32)).unwrap_err();
        assert!(matches!(error, ExistingUvError::Overlap { mesh: 0, other: 0, .. }), "{error:?}");
        assert!(error.to_string().contains("overlaps itself"), "{error}");
    }

    #[test]
    fn uvs_outside_the_page_and_missing_area_are_refused() {
        let meshes = [MeshInput::new(&QUAD, &QUAD_INDICES)];
        let outside = square(0.8, 0.1, 0.4);
        let error = from_existing(&meshes, &[&outside], &options(32)).unwrap_err();
        assert_eq!(error, ExistingUvError::OutOfRange { mesh: 0, vertex: 1, uv: [1.2, 0.1] });
        let flat = [[0.5, 0.5]; 4];
        let error = from_existing(&meshes, &[&flat], &options(32)).unwrap_err();
        assert_eq!(error, ExistingUvError::NoArea { mesh: 0, triangles: 2 });
        let short = [[0.5, 0.5]; 3];
        assert!(matches!(
            from_existing(&meshes, &[&short], &options(32)),
            Err(ExistingUvError::CountMismatch { uvs: 3, vertices: 4, .. })
        ));
    }

    #[test]
    fn a_requested_density_sets_the_page_size() {
        let meshes = [MeshInput::new(&QUAD, &QUAD_INDICES)];
        let uv = square(0.0, 0.0, 0.5);
        let options = UnwrapOptions { texels_per_unit: Some(16.0), ..options(1024) };
        let atlas = from_existing(&meshes, &[&uv], &options).unwrap();
        // 1 m² on a quarter of the page at 16 texels/m: a 32² page.
        assert_eq!(atlas.width, 32);
        assert!((atlas.texels_per_unit - 16.0).abs() < 1e-4);
    }

    #[test]
    fn triangles_without_surface_get_no_chart() {
        let positions = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [2.0, 0.0, 0.0]];
        // The second triangle is degenerate (collinear corners).
        let indices = [0, 1, 2, 0, 1, 3];
        let uv = [[0.1, 0.1], [0.5, 0.1], [0.5, 0.5], [0.9, 0.9]];
        let atlas = from_existing(&[MeshInput::new(&positions, &indices)], &[&uv], &options(32)).unwrap();
        let mesh = &atlas.meshes[0];
        assert_eq!(atlas.chart_count, 1);
        let corners: Vec<AtlasVertex> = mesh.indices[3..].iter().map(|&i| mesh.vertices[i as usize]).collect();
        assert!(corners.iter().all(|v| v.chart == u32::MAX && v.uv == uv[0]));
        assert_eq!(corners.iter().map(|v| v.xref).collect::<Vec<_>>(), [0, 1, 3]);
    }
}
