//! Procedural test meshes for the unwrap stage, shared by `tests/unwrap.rs` and the
//! `unwrap_compare` example. World space, metres, triangle lists.
#![allow(dead_code)]

use std::f32::consts::{PI, TAU};

/// An owned triangle mesh.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    pub positions: Vec<[f32; 3]>,
    pub indices: Vec<u32>,
}

impl Mesh {
    pub fn input(&self) -> bake::unwrap::MeshInput<'_> {
        bake::unwrap::MeshInput::new(&self.positions, &self.indices)
    }

    pub fn translated(mut self, d: [f32; 3]) -> Mesh {
        for p in &mut self.positions {
            for k in 0..3 {
                p[k] += d[k];
            }
        }
        self
    }

    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }
}

/// A UV sphere of `radius` with `segments` around and `rings` from pole to pole; the seam and
/// the poles have duplicated vertices, the pole rows are single triangles (no degenerate ones).
pub fn uv_sphere(segments: u32, rings: u32, radius: f32) -> Mesh {
    let mut m = Mesh::default();
    for r in 0..=rings {
        let theta = PI * r as f32 / rings as f32;
        for s in 0..=segments {
            let phi = TAU * s as f32 / segments as f32;
            m.positions.push([
                radius * theta.sin() * phi.cos(),
                radius * theta.cos(),
                radius * theta.sin() * phi.sin(),
            ]);
        }
    }
    let row = segments + 1;
    for r in 0..rings {
        for s in 0..segments {
            let (a, b) = (r * row + s, r * row + s + 1);
            let (c, d) = ((r + 1) * row + s, (r + 1) * row + s + 1);
            if r != 0 {
                m.indices.extend([a, b, c]);
            }
            if r != rings - 1 {
                m.indices.extend([b, d, c]);
            }
        }
    }
    // Exact poles and seam: identical positions for duplicated vertices.
    for s in 0..=segments {
        m.positions[s as usize] = [0.0, radius, 0.0];
        m.positions[(rings * row + s) as usize] = [0.0, -radius, 0.0];
    }
    for r in 0..=rings {
        m.positions[(r * row + segments) as usize] = m.positions[(r * row) as usize];
    }
    m
}

/// An axis-aligned cube of side `size` centred at the origin: 24 vertices (split per face),
/// 12 outward-facing triangles.
pub fn cube(size: f32) -> Mesh {
    let h = 0.5 * size;
    let mut m = Mesh::default();
    // (normal axis, sign)
    for axis in 0..3 {
        for sign in [1.0f32, -1.0] {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            let base = m.positions.len() as u32;
            for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                let mut p = [0.0; 3];
                p[axis] = sign * h;
                p[u] = a * h;
                p[v] = b * h;
                m.positions.push(p);
            }
            if sign > 0.0 {
                m.indices.extend([base, base + 1, base + 2, base, base + 2, base + 3]);
            } else {
                m.indices.extend([base, base + 2, base + 1, base, base + 3, base + 2]);
            }
        }
    }
    m
}

/// A horizontal square of side `size` at y = 0, centred at the origin, two triangles, facing +y.
pub fn ground(size: f32) -> Mesh {
    let h = 0.5 * size;
    Mesh { positions: vec![[-h, 0.0, -h], [h, 0.0, -h], [h, 0.0, h], [-h, 0.0, h]], indices: vec![0, 2, 1, 0, 3, 2] }
}

/// A torus around the y axis: ring radius `major`, tube radius `minor`, `segments` × `sides`
/// quads, seams duplicated.
pub fn torus(segments: u32, sides: u32, major: f32, minor: f32) -> Mesh {
    let mut m = Mesh::default();
    for i in 0..=segments {
        let u = TAU * (i % segments) as f32 / segments as f32;
        for j in 0..=sides {
            let v = TAU * (j % sides) as f32 / sides as f32;
            let r = major + minor * v.cos();
            m.positions.push([r * u.cos(), minor * v.sin(), r * u.sin()]);
        }
    }
    let row = sides + 1;
    for i in 0..segments {
        for j in 0..sides {
            let (a, b) = (i * row + j, i * row + j + 1);
            let (c, d) = ((i + 1) * row + j, (i + 1) * row + j + 1);
            m.indices.extend([a, c, b, b, c, d]);
        }
    }
    m
}

/// A 4×4 grid (1 m cells) with trouble added: triangles with a repeated index, collinear
/// (zero-area) ones, a zero-length edge from coincident vertices, exact duplicates of existing
/// faces (same and reversed winding), needle triangles, and unused vertices.
pub fn troublesome() -> Mesh {
    let n = 4u32;
    let mut m = Mesh::default();
    for y in 0..=n {
        for x in 0..=n {
            m.positions.push([x as f32, 0.0, y as f32]);
        }
    }
    for y in 0..n {
        for x in 0..n {
            let a = y * (n + 1) + x;
            m.indices.extend([a, a + n + 1, a + 1, a + 1, a + n + 1, a + n + 2]);
        }
    }
    // Repeated index.
    m.indices.extend([0, 0, 1, 7, 8, 7]);
    // Collinear: three points of one grid row.
    m.indices.extend([0, 1, 2]);
    // Coincident vertex: a copy of vertex 6 used in a triangle with a zero-length edge.
    let copy = m.positions.len() as u32;
    m.positions.push(m.positions[6]);
    m.indices.extend([6, copy, 12]);
    // Duplicates of existing faces.
    let dup: Vec<u32> = m.indices[0..6].to_vec();
    m.indices.extend(&dup);
    m.indices.extend([m.indices[8], m.indices[7], m.indices[6]]);
    // Needles: a sliver 4 m long and 1e-4 m wide standing above the grid, and one 1e-6 wide.
    for (k, width) in [1e-4f32, 1e-6].into_iter().enumerate() {
        let b = m.positions.len() as u32;
        let z = 0.5 + k as f32;
        m.positions.extend([[0.0, 1.0, z], [4.0, 1.0, z], [2.0, 1.0 + width, z]]);
        m.indices.extend([b, b + 1, b + 2]);
    }
    // Unused vertices.
    m.positions.extend([[100.0, 100.0, 100.0], [-5.0, 3.0, 2.0]]);
    m
}

/// An icosphere with `subdivisions` levels (20·4^s triangles, 10·4^s + 2 vertices), radius 1.
fn icosphere(subdivisions: u32) -> Mesh {
    let t = (1.0 + 5.0f32.sqrt()) / 2.0;
    let mut p: Vec<[f32; 3]> = vec![
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ];
    let mut tris: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    let norm = |v: [f32; 3]| {
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        [v[0] / l, v[1] / l, v[2] / l]
    };
    for v in &mut p {
        *v = norm(*v);
    }
    for _ in 0..subdivisions {
        let mut mid = std::collections::HashMap::new();
        let mut next = Vec::with_capacity(tris.len() * 4);
        let mut midpoint = |a: u32, b: u32, p: &mut Vec<[f32; 3]>| {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let (x, y) = (p[a as usize], p[b as usize]);
                p.push(norm([x[0] + y[0], x[1] + y[1], x[2] + y[2]]));
                (p.len() - 1) as u32
            })
        };
        for [a, b, c] in tris {
            let ab = midpoint(a, b, &mut p);
            let bc = midpoint(b, c, &mut p);
            let ca = midpoint(c, a, &mut p);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        tris = next;
    }
    Mesh { positions: p, indices: tris.into_iter().flatten().collect() }
}

/// A statue-like stand-in for a scanned model: an icosphere (5 subdivisions: 10242 vertices,
/// 20480 triangles) pushed into a lumpy, bunny-ish body (stretched, with two ear-like bulges
/// and deterministic multi-frequency bumps), about 1 m tall, standing on y = 0.
pub fn statue() -> Mesh {
    statue_of(5)
}

/// The statue on an icosphere of `level` subdivisions (20·4^level triangles).
pub fn statue_of(level: u32) -> Mesh {
    let mut m = icosphere(level);
    for p in &mut m.positions {
        let [x, y, z] = *p;
        let bumps = 0.06 * (7.0 * x + 1.3).sin() * (5.0 * y).cos() * (6.0 * z + 0.7).sin()
            + 0.03 * (13.0 * x + 17.0 * y).sin() * (11.0 * z).cos()
            + 0.012 * (31.0 * y + 29.0 * z).sin() * (23.0 * x).cos();
        // Ears: bulges around two directions on the upper side.
        let ear = |dx: f32| {
            let d = (x - dx) * (x - dx) + (y - 0.8) * (y - 0.8) + z * z;
            0.55 * (-d * 9.0).exp()
        };
        let r = 1.0 + bumps + ear(0.35) + ear(-0.35);
        *p = [0.42 * r * x, 0.5 * r * y * 0.9 + 0.5, 0.35 * r * z];
    }
    m
}

/// The scenes of the comparison: name and meshes.
pub fn scenes() -> Vec<(&'static str, Vec<Mesh>)> {
    vec![
        ("sphere", vec![uv_sphere(48, 24, 1.0)]),
        ("cube", vec![cube(1.0)]),
        ("torus", vec![torus(48, 24, 1.0, 0.3)]),
        ("ground", vec![ground(10.0)]),
        ("sphere on ground", vec![uv_sphere(48, 24, 1.0).translated([0.0, 1.0, 0.0]), ground(10.0)]),
        ("statue", vec![statue()]),
    ]
}
