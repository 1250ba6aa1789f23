//! The scene's triangles and their hierarchy laid out for GPU passes that
//! cast rays (`shaders/include/trace.wgsl` reads it): one `Rgba32Uint` texture,
//! since a CPU driver fetches texels far faster than storage buffers, in
//! regions of 4-word records:
//!
//! - nodes, depth-first with escape links (`bvh::FlatNode`), two records each:
//!   `[lo.xyz, escape]`, `[hi.xyz, leaf]`, `leaf` = first triangle | count << 28,
//!   or `NO_LEAF`;
//! - triangles in the leaves' order, three records each: `[v0.xyz, id]`,
//!   `[v1.xyz, material | CUT_OUT]`, `[v2.xyz, first cut-out UV record]`;
//! - per node, two more: a bounding sphere `[centre.xyz, radius]` and, where
//!   the node's triangles tile a convex polygon in one plane, `[normal.xyz,
//!   first vertex record]` (0: none);
//! - the polygons' corners `[xyz, 0]`, four each (a triangle repeats its
//!   last), counter-clockwise about the normal;
//! - a cut-out triangle's UV sets at its corners `[uv0, uv1]`.
//!
//! Floats are stored as their bits; boxes are rounded outwards to f32.

use glam::{DVec2, DVec3};

use super::bvh::{FlatNode, Tree};
use crate::gpu::{Gpu, Materials};
use crate::scene::Scene;

/// Triangles per leaf (up to twice as many where a split costs more; at
/// most 15 fit the leaf word).
const LEAF: usize = 4;
/// Records per texture row (`ROW_SHIFT` in trace.wgsl).
pub const ROW: u32 = 4096;
/// `leaf` of an interior node.
pub const NO_LEAF: u32 = u32::MAX;
/// The triangle id of a triangle no texel lies on (a repeat).
pub const NO_ID: u32 = u32::MAX;
/// Bit of a triangle's material word: its material cuts out holes.
pub const CUT_OUT: u32 = 1 << 31;
/// Corners of a polygon kept for a planar node (a triangle repeats its
/// last): the GPU tests four edges, without a loop.
const POLYGON_CORNERS: usize = 4;
/// Largest subtree checked for a polygon (bigger flat areas are covered by
/// polygons of their subtrees).
const MAX_POLYGON_TRIANGLES: u32 = 256;

/// Mirrors `SceneLayout` in trace.wgsl: where each region starts.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct SceneLayout {
    pub node_count: u32,
    pub triangle_base: u32,
    pub extra_base: u32,
    pub uv_base: u32,
    /// Largest absolute coordinate of any vertex, metres (ray offsets are
    /// relative to it).
    pub scale: f32,
    pub _pad: [u32; 3],
}

/// One triangle of the scene as the GPU traces it.
struct SceneTriangle {
    corners: [DVec3; 3],
    /// The texel triangle id (`texelize::Texel::triangle`), or `NO_ID`.
    id: u32,
    material: u32,
    cut_out: bool,
    uv: [[f32; 4]; 3],
}

/// The scene on the GPU for ray casts: what its bind group binds.
pub struct GpuScene {
    /// The records; held for as long as the view is bound.
    _records: wgpu::Texture,
    view: wgpu::TextureView,
    layout_buffer: wgpu::Buffer,
    materials: Materials,
    /// Whether any triangle's material cuts out holes.
    cut_outs: bool,
}

impl GpuScene {
    /// Lays out `scene` (every triangle with area, repeats left out) and
    /// uploads it. Fails when it does not fit the adapter's largest texture.
    pub fn new(gpu: &Gpu, scene: &Scene) -> anyhow::Result<GpuScene> {
        let materials = Materials::upload(gpu, scene);
        let triangles = scene_triangles(scene, &materials);
        if triangles.len() >= 1 << 28 {
            anyhow::bail!("the scene has {} triangles; ray casts take at most {}", triangles.len(), (1u32 << 28) - 1);
        }
        let boxes: Vec<(DVec3, DVec3)> = triangles.iter().map(|t| bounds(&t.corners)).collect();
        let tree = Tree::build(&boxes, LEAF);
        let flat = tree.flatten();
        let ordered: Vec<&SceneTriangle> = tree.order.iter().map(|&i| &triangles[i as usize]).collect();
        let records = Records::new(&flat, &ordered);
        let rows = (records.data.len() as u32).div_ceil(ROW).max(1);
        if rows > gpu.limits.max_texture_dimension_2d {
            anyhow::bail!(
                "the scene's {} triangles need a {ROW}×{rows} ray-tracing texture; this adapter's limit is {}",
                triangles.len(),
                gpu.limits.max_texture_dimension_2d
            );
        }
        let mut data = records.data;
        data.resize((rows * ROW) as usize, [0; 4]);
        let texture = gpu.records_texture("trace scene", &data, ROW, rows, 1);
        let view = texture.create_view(&Default::default());
        let scale = triangles
            .iter()
            .flat_map(|t| t.corners)
            .map(|v| v.abs().max_element())
            .fold(0.0f64, f64::max)
            .max(f64::MIN_POSITIVE);
        let layout = SceneLayout {
            node_count: flat.len() as u32,
            triangle_base: records.triangle_base,
            extra_base: records.extra_base,
            uv_base: records.uv_base,
            scale: scale as f32,
            _pad: [0; 3],
        };
        let layout_buffer = gpu.uniform_buffer("trace scene layout", &layout);
        let cut_outs = triangles.iter().any(|t| t.cut_out);
        Ok(GpuScene { _records: texture, view, layout_buffer, materials, cut_outs })
    }

    /// The `CUT_OUTS` override of trace.wgsl: whether pipelines need the alpha test.
    pub fn cut_out_constant(&self) -> f64 {
        if self.cut_outs { 1.0 } else { 0.0 }
    }

    /// The layout of the scene's bind group (group 1 of the passes that cast
    /// rays): the records, their layout, the materials, their textures and
    /// sampler (cut-outs).
    pub fn bind_group_layout(gpu: &Gpu) -> wgpu::BindGroupLayout {
        let compute = wgpu::ShaderStages::COMPUTE;
        let entries = [
            // 0: the records (nodes, leaves, triangles), ROW texels to a row
            wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: compute,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Uint,
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
                count: None,
            },
            // 1: SceneLayout (where each kind of record starts)
            crate::gpu::uniform_entry(1, compute),
            // 2: the materials (their alpha cut-outs)
            crate::gpu::storage_entry(2, true, compute),
            // 3, 4: the material textures and their sampler
            crate::gpu::texture_array_entry(3, compute, crate::gpu::FILTERABLE),
            crate::gpu::sampler_entry(4, compute),
        ];
        gpu.bind_group_layout("trace scene", &entries)
    }

    /// The scene's bind group (`bind_group_layout`).
    pub fn bind_group(&self, gpu: &Gpu, layout: &wgpu::BindGroupLayout) -> wgpu::BindGroup {
        let entries = [
            wgpu::BindGroupEntry { binding: 0, resource: wgpu::BindingResource::TextureView(&self.view) },
            wgpu::BindGroupEntry { binding: 1, resource: self.layout_buffer.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 2, resource: self.materials.buffer.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 3, resource: wgpu::BindingResource::TextureView(&self.materials.textures) },
            wgpu::BindGroupEntry { binding: 4, resource: wgpu::BindingResource::Sampler(&self.materials.sampler) },
        ];
        gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("trace scene"),
            layout,
            entries: &entries,
        })
    }
}

/// The records of every region, and where each starts.
struct Records {
    data: Vec<[u32; 4]>,
    triangle_base: u32,
    extra_base: u32,
    uv_base: u32,
}

impl Records {
    fn new(flat: &[FlatNode], triangles: &[&SceneTriangle]) -> Records {
        let mut data: Vec<[u32; 4]> = Vec::with_capacity(4 * flat.len() + 4 * triangles.len());
        for node in flat {
            let leaf = if node.leaf { node.first | node.count << 28 } else { NO_LEAF };
            data.push(word(round_down(node.lo), node.escape));
            data.push(word(round_up(node.hi), leaf));
        }
        let triangle_base = data.len() as u32;
        let mut uvs = Vec::new();
        for t in triangles {
            let material = t.material | if t.cut_out { CUT_OUT } else { 0 };
            let uv_index = if t.cut_out { uvs.len() as u32 } else { u32::MAX };
            if t.cut_out {
                uvs.extend(t.uv.iter().map(|uv| uv.map(f32::to_bits)));
            }
            data.push(word(t.corners[0].as_vec3().to_array(), t.id));
            data.push(word(t.corners[1].as_vec3().to_array(), material));
            data.push(word(t.corners[2].as_vec3().to_array(), uv_index));
        }
        let extra_base = data.len() as u32;
        // Polygon vertices follow the two extra records of every node.
        let vertex_base = extra_base + 2 * flat.len() as u32;
        let mut vertices = Vec::new();
        for node in flat {
            let members = &triangles[node.first as usize..(node.first + node.count) as usize];
            let (centre, radius) = bounding_sphere(node, members);
            data.push(word(centre, radius.to_bits()));
            match (node.count <= MAX_POLYGON_TRIANGLES).then(|| planar_polygon(members)).flatten() {
                Some((normal, corners)) => {
                    let first = vertex_base + vertices.len() as u32;
                    let last = *corners.last().expect("three corners or more");
                    let padded = corners.iter().chain(std::iter::repeat(&last)).take(POLYGON_CORNERS);
                    vertices.extend(padded.map(|c| word(c.as_vec3().to_array(), 0)));
                    data.push(word(normal.as_vec3().to_array(), first));
                }
                None => data.push([0; 4]),
            }
        }
        data.extend(vertices);
        let uv_base = data.len() as u32;
        data.extend(uvs);
        Records { data, triangle_base, extra_base, uv_base }
    }
}

/// A record of three floats and a word.
fn word(v: [f32; 3], w: u32) -> [u32; 4] {
    [v[0].to_bits(), v[1].to_bits(), v[2].to_bits(), w]
}

fn round_down(v: DVec3) -> [f32; 3] {
    v.to_array().map(|c| {
        let f = c as f32;
        if f as f64 > c { f.next_down() } else { f }
    })
}

fn round_up(v: DVec3) -> [f32; 3] {
    v.to_array().map(|c| {
        let f = c as f32;
        if (f as f64) < c { f.next_up() } else { f }
    })
}

fn bounds(corners: &[DVec3; 3]) -> (DVec3, DVec3) {
    (corners[0].min(corners[1]).min(corners[2]), corners[0].max(corners[1]).max(corners[2]))
}

/// A sphere around the node's triangles: centred on its box, as small as
/// their corners allow (a box's half-diagonal is up to √3 times wider).
fn bounding_sphere(node: &FlatNode, members: &[&SceneTriangle]) -> ([f32; 3], f32) {
    let centre = (node.lo + node.hi) * 0.5;
    let radius = members.iter().flat_map(|t| t.corners).map(|c| (c - centre).length()).fold(0.0f64, f64::max);
    let centre32 = centre.as_vec3();
    // Widened by the centre's rounding and a few ulps, so it stays a bound in f32.
    let slack =
        (centre32.as_dvec3() - centre).length() + 4.0 * f32::EPSILON as f64 * (radius + centre.abs().max_element());
    (centre32.to_array(), (radius + slack) as f32)
}

/// The plane and convex outline (counter-clockwise about the normal) of
/// `members` where they are opaque, lie in one plane, and tile a convex
/// polygon of at most `POLYGON_CORNERS` corners without overlap: then a ray
/// meets one of them exactly where it meets the polygon.
fn planar_polygon(members: &[&SceneTriangle]) -> Option<(DVec3, Vec<DVec3>)> {
    if members.len() < 2 || members.iter().any(|t| t.cut_out) {
        return None;
    }
    let [a, b, c] = members[0].corners;
    let normal = (b - a).cross(c - a).try_normalize()?;
    let offset = normal.dot(a);
    let scale = members.iter().flat_map(|t| t.corners).map(|v| v.abs().max_element()).fold(0.0, f64::max);
    let tolerance = 1e-6 * scale.max(f64::MIN_POSITIVE);
    if members.iter().flat_map(|t| t.corners).any(|v| (normal.dot(v) - offset).abs() > tolerance) {
        return None;
    }
    let (u, v) = normal.any_orthonormal_pair();
    let flat = |p: DVec3| DVec2::new(u.dot(p), v.dot(p));
    let points: Vec<DVec2> = members.iter().flat_map(|t| t.corners).map(flat).collect();
    let hull = convex_hull(points);
    if hull.len() < 3 || hull.len() > POLYGON_CORNERS {
        return None;
    }
    let hull_area = polygon_area(&hull);
    let area: f64 = members
        .iter()
        .map(|t| {
            let [a, b, c] = t.corners.map(flat);
            0.5 * (b - a).perp_dot(c - a).abs()
        })
        .sum();
    if (hull_area - area).abs() > 1e-9 * hull_area || !tiles_without_overlap(members, &flat, &hull) {
        return None;
    }
    let lift = normal * offset;
    Some((normal, hull.iter().map(|p| lift + u * p.x + v * p.y).collect()))
}

/// Whether the triangles share each inner edge between exactly two of them
/// with opposite windings in the plane (no edge used twice the same way: no
/// doubled or folded triangle), and every edge only one of them uses lies
/// on the hull's outline (no gap inside). With equal areas the hull is
/// then covered once.
fn tiles_without_overlap(members: &[&SceneTriangle], flat: &impl Fn(DVec3) -> DVec2, hull: &[DVec2]) -> bool {
    // Directed edge (by its ends' bits) → how often it is used, and its ends in the plane.
    type EdgeUses = std::collections::HashMap<([u64; 3], [u64; 3]), (i32, DVec2, DVec2)>;
    let mut edges = EdgeUses::new();
    let key = |p: DVec3| p.to_array().map(f64::to_bits);
    for t in members {
        let [a, b, c] = t.corners.map(flat);
        let ccw = (b - a).perp_dot(c - a) > 0.0;
        for k in 0..3 {
            let (p, q) = (t.corners[k], t.corners[(k + 1) % 3]);
            let (from, to) = if ccw { (p, q) } else { (q, p) };
            edges.entry((key(from), key(to))).or_insert((0, flat(from), flat(to))).0 += 1;
        }
    }
    let span = hull.iter().map(|p| p.abs().max_element()).fold(0.0, f64::max);
    let on_outline = |p: DVec2| {
        (0..hull.len()).any(|i| {
            let (a, b) = (hull[i], hull[(i + 1) % hull.len()]);
            let along = (p - a).dot(b - a) / (b - a).length_squared();
            (b - a).perp_dot(p - a).abs() <= 1e-9 * span * (b - a).length() && (-1e-9..=1.0 + 1e-9).contains(&along)
        })
    };
    edges.iter().all(|(&(from, to), &(count, p, q))| {
        let shared = edges.contains_key(&(to, from));
        count == 1 && (shared || (on_outline(p) && on_outline(q)))
    })
}

/// Andrew's monotone chain: the convex hull counter-clockwise, collinear
/// points left out.
fn convex_hull(mut points: Vec<DVec2>) -> Vec<DVec2> {
    points.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    points.dedup();
    if points.len() < 3 {
        return points;
    }
    let turn = |o: DVec2, a: DVec2, b: DVec2| (a - o).perp_dot(b - o);
    let mut hull: Vec<DVec2> = Vec::with_capacity(points.len() + 1);
    for pass in [&points[..], &points.iter().rev().copied().collect::<Vec<_>>()[..]] {
        let start = hull.len();
        for &p in pass {
            while hull.len() >= start + 2 && turn(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0 {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull
}

fn polygon_area(points: &[DVec2]) -> f64 {
    let n = points.len();
    0.5 * (0..n).map(|i| points[i].perp_dot(points[(i + 1) % n])).sum::<f64>()
}

/// Every triangle with area of every primitive, with the id its texels name
/// (`texelize`: primitives in order, repeats left out).
fn scene_triangles(scene: &Scene, materials: &Materials) -> Vec<SceneTriangle> {
    let default_material = scene.materials.len();
    let mut triangles = Vec::with_capacity(scene.triangle_count());
    let mut next_id = 0u32;
    for primitive in &scene.primitives {
        let material = primitive.material.unwrap_or(default_material);
        let cut_out = materials.is_masked(material);
        let repeat = crate::repeats::mask(&primitive.repeats, primitive.triangle_count());
        for (t, &repeated) in repeat.iter().enumerate().take(primitive.triangle_count()) {
            let id = if repeated { NO_ID } else { next_id };
            next_id += u32::from(!repeated);
            let corners = primitive.front_corners(t);
            let positions = corners.map(|i| primitive.positions[i as usize]);
            let corners3 = positions.map(|p| DVec3::from(p.map(|c| c as f64)));
            let area = (corners3[1] - corners3[0]).cross(corners3[2] - corners3[0]).length();
            if repeated || !(area > 0.0 && area.is_finite()) {
                continue;
            }
            let uv = corners.map(|i| {
                let uv0 = primitive.uv0.as_ref().map_or([0.0; 2], |uv| uv[i as usize]);
                let uv1 = primitive.uv1.as_ref().map_or([0.0; 2], |uv| uv[i as usize]);
                [uv0[0], uv0[1], uv1[0], uv1[1]]
            });
            triangles.push(SceneTriangle { corners: corners3, id, material: material as u32, cut_out, uv });
        }
    }
    triangles
}

#[cfg(test)]
mod tests {
    use super::*;

    fn triangle(corners: [[f64; 3]; 3]) -> SceneTriangle {
        SceneTriangle { corners: corners.map(DVec3::from), id: 0, material: 0, cut_out: false, uv: [[0.0; 4]; 3] }
    }

    /// A w × h grid of unit squares in the y = 0 plane, two triangles each.
    fn grid(w: usize, h: usize) -> Vec<SceneTriangle> {
        let mut out = Vec::new();
        for i in 0..w {
            for j in 0..h {
                let (x, z) = (i as f64, j as f64);
                out.push(triangle([[x, 0.0, z], [x, 0.0, z + 1.0], [x + 1.0, 0.0, z]]));
                out.push(triangle([[x + 1.0, 0.0, z], [x, 0.0, z + 1.0], [x + 1.0, 0.0, z + 1.0]]));
            }
        }
        out
    }

    #[test]
    fn a_tiled_rectangle_is_one_polygon() {
        let tiles = grid(4, 3);
        let members: Vec<&SceneTriangle> = tiles.iter().collect();
        let (normal, corners) = planar_polygon(&members).expect("a rectangle");
        assert!((normal.y.abs() - 1.0).abs() < 1e-12);
        assert_eq!(corners.len(), 4);
    }

    #[test]
    fn an_l_shape_a_hole_or_a_doubled_tile_is_not() {
        let mut l_shape = grid(2, 2);
        l_shape.truncate(6);
        let members: Vec<&SceneTriangle> = l_shape.iter().collect();
        assert!(planar_polygon(&members).is_none(), "L shape");
        // A ring of 3 × 3 squares with the middle one missing.
        let ring: Vec<SceneTriangle> =
            grid(3, 3).into_iter().enumerate().filter(|(i, _)| i / 2 != 4).map(|(_, t)| t).collect();
        let members: Vec<&SceneTriangle> = ring.iter().collect();
        assert!(planar_polygon(&members).is_none(), "hole");
        // A triangle listed twice.
        let doubled = [
            triangle([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]),
            triangle([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]),
        ];
        let members: Vec<&SceneTriangle> = doubled.iter().collect();
        assert!(planar_polygon(&members).is_none(), "doubled");
        // The ring again with a corner square listed twice: the areas add up
        // to the hull's, and only the edges tell the overlap and the hole.
        let mut ring_doubled = ring;
        ring_doubled.extend(grid(3, 3).into_iter().take(2));
        let members: Vec<&SceneTriangle> = ring_doubled.iter().collect();
        assert!(planar_polygon(&members).is_none(), "a hole and a doubled square");
    }

    #[test]
    fn a_bent_or_cut_out_pair_is_not() {
        let bent = [
            triangle([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]),
            triangle([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.1, 1.0]]),
        ];
        let members: Vec<&SceneTriangle> = bent.iter().collect();
        assert!(planar_polygon(&members).is_none());
        let mut cut = grid(1, 1);
        cut[0].cut_out = true;
        let members: Vec<&SceneTriangle> = cut.iter().collect();
        assert!(planar_polygon(&members).is_none());
    }

    #[test]
    fn rounding_keeps_boxes_outside() {
        let v = DVec3::new(0.1, -0.3, 1e7 + 0.3);
        let (lo, hi) = (round_down(v), round_up(v));
        for k in 0..3 {
            assert!((lo[k] as f64) <= v[k] && (hi[k] as f64) >= v[k]);
        }
    }

    #[test]
    fn the_scene_layout_mirrors_trace_wgsl() {
        use crate::gpu::{Shader, mirror::assert_mirrors};
        assert_mirrors!(
            Shader::SolveDirect,
            "SceneLayout",
            SceneLayout { node_count, triangle_base, extra_base, uv_base, scale }
        );
    }
}
