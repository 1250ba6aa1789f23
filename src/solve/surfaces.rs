//! Which caster triangles lie on an open surface (a sheet: a wall or floor
//! of zero thickness, a leaf) and which on a closed one (a solid's skin, or
//! a sealed room of inward-facing walls). The depth maps mark the former,
//! so that the direct pass lets shadow rays through the open space behind
//! a sheet, while the space inside a closed surface stays sealed. The
//! bounce pass's cull leaves out the far side of closed, consistently wound
//! pieces seen from outside their bounds (`solids`).
//!
//! Triangles connect through shared positions (welded within millionths of
//! the scene's size, so that UV seams, rounding and separate primitives
//! meeting at the same corners join); a connected piece is closed when every
//! edge in it borders at least two triangles.

use std::collections::HashMap;

use glam::{IVec3, Vec3};

/// For each vertex of `positions`, whether the triangles `indices` join it
/// into an open surface. Vertices no triangle uses count as closed.
pub fn open_vertices(positions: &[[f32; 3]], indices: &[u32]) -> Vec<bool> {
    let mut joined = Joined::new(positions, indices);
    let mut open_piece = vec![false; joined.pieces.parent.len()];
    for run in joined.edges.chunk_by(|x, y| x.key == y.key) {
        if run.len() < 2 {
            let root = joined.pieces.root(run[0].from);
            open_piece[root as usize] = true;
        }
    }
    joined.vertex_ids.iter().map(|&id| open_piece[joined.pieces.root(id) as usize]).collect()
}

/// `Solids::triangle_solid` of a triangle on no solid.
pub const NOT_SOLID: u32 = u32::MAX;

/// A closed piece whose every edge borders exactly two triangles wound in
/// opposite directions along it, and which encloses a volume. Every ray from
/// outside it meets it first on the side its winding makes the outside:
/// the front where `outward`, the back for a sealed room of inward-facing
/// walls.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Solid {
    /// Its bounds, widened a little over rounding: an eye outside them is
    /// outside the solid.
    pub lo: Vec3,
    pub hi: Vec3,
    pub outward: bool,
}

/// The solids among the pieces, and each triangle's.
#[derive(Debug, Default)]
pub struct Solids {
    /// Per triangle of `indices`: its solid, or `NOT_SOLID`.
    pub triangle_solid: Vec<u32>,
    pub solids: Vec<Solid>,
}

/// The solids the triangles `indices` form (see `Solid`).
pub fn solids(positions: &[[f32; 3]], indices: &[u32]) -> Solids {
    let mut joined = Joined::new(positions, indices);
    let count = joined.pieces.parent.len();
    let mut sealed = vec![true; count];
    for run in joined.edges.chunk_by(|x, y| x.key == y.key) {
        // Open, more than two triangles on an edge, or two wound alike.
        if run.len() != 2 || run[0].from == run[1].from {
            let root = joined.pieces.root(run[0].from);
            sealed[root as usize] = false;
        }
    }
    // Volume (six times, about the scene's centre to keep the digits),
    // area and bounds of each piece.
    let centre = joined.bounds.0.as_dvec3().midpoint(joined.bounds.1.as_dvec3());
    let (mut volume, mut area) = (vec![0.0f64; count], vec![0.0f64; count]);
    let mut bounds = vec![(Vec3::MAX, Vec3::MIN); count];
    let mut triangle_root = Vec::with_capacity(indices.len() / 3);
    for t in indices.chunks_exact(3) {
        let Some([first, _, _]) = joined.corners(t) else {
            triangle_root.push(None);
            continue;
        };
        let root = joined.pieces.root(first) as usize;
        triangle_root.push(Some(root));
        let p = [t[0], t[1], t[2]].map(|i| Vec3::from(positions[i as usize]));
        let [a, b, c] = p.map(|v| v.as_dvec3() - centre);
        volume[root] += a.dot(b.cross(c));
        area[root] += 0.5 * (b - a).cross(c - a).length();
        for v in p {
            bounds[root] = (bounds[root].0.min(v), bounds[root].1.max(v));
        }
    }
    let margin = 1e-6 * (joined.bounds.1 - joined.bounds.0).length();
    let mut solid_of_root = HashMap::new();
    let mut solids = Solids::default();
    for root in triangle_root {
        let id = root.filter(|&r| sealed[r] && volume[r].abs() > 1e-6 * area[r].powf(1.5)).map(|r| {
            *solid_of_root.entry(r).or_insert_with(|| {
                let (lo, hi) = bounds[r];
                // So that an eye inside the solid, on or near its skin,
                // never rounds to outside.
                let widen = margin + 1e-3 * (hi - lo).length();
                solids.solids.push(Solid { lo: lo - widen, hi: hi + widen, outward: volume[r] > 0.0 });
                solids.solids.len() as u32 - 1
            })
        });
        solids.triangle_solid.push(id.unwrap_or(NOT_SOLID));
    }
    solids
}

/// Triangles joined into pieces through welded positions, with their edges.
struct Joined {
    vertex_ids: Vec<u32>,
    pieces: Pieces,
    /// Every edge once per triangle it borders, sorted by `key`.
    edges: Vec<Edge>,
    /// The positions' bounding box.
    bounds: (Vec3, Vec3),
}

#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
struct Edge {
    /// The welded ends, lower first, as one sortable number.
    key: u64,
    /// The end the triangle runs along it from.
    from: u32,
}

impl Joined {
    fn new(positions: &[[f32; 3]], indices: &[u32]) -> Joined {
        let (vertex_ids, count, bounds) = welded_ids(positions);
        let mut joined =
            Joined { vertex_ids, pieces: Pieces::new(count), edges: Vec::with_capacity(indices.len()), bounds };
        for t in indices.chunks_exact(3) {
            let Some([a, b, c]) = joined.corners(t) else { continue };
            for (p, q) in [(a, b), (b, c), (c, a)] {
                joined.pieces.join(p, q);
                joined.edges.push(Edge { key: (p.min(q) as u64) << 32 | p.max(q) as u64, from: p });
            }
        }
        joined.edges.sort_unstable();
        joined
    }

    /// A triangle's welded corners; None where two of them weld (a sphere's
    /// pole), as the triangle has no area and would count one edge twice.
    fn corners(&self, t: &[u32]) -> Option<[u32; 3]> {
        let [a, b, c] = [t[0], t[1], t[2]].map(|i| self.vertex_ids[i as usize]);
        (a != b && b != c && c != a).then_some([a, b, c])
    }
}

/// An id for each position, equal for positions within a millionth of the
/// bounding box's diagonal of each other (and some up to three millionths
/// apart: the first position in a cell twice that wide stands for all in
/// it), the number of ids and the bounding box.
fn welded_ids(positions: &[[f32; 3]]) -> (Vec<u32>, usize, (Vec3, Vec3)) {
    let points: Vec<Vec3> = positions.iter().map(|&p| Vec3::from(p)).collect();
    let (lo, hi) = points.iter().fold((Vec3::MAX, Vec3::MIN), |(lo, hi), &p| (lo.min(p), hi.max(p)));
    let tolerance = (1e-6 * (hi - lo).length()).max(f32::MIN_POSITIVE);
    // Cells twice the tolerance wide: a match lies in at most two per axis.
    let cell_of = |p: Vec3| (p / (2.0 * tolerance)).floor().as_ivec3();
    let mut cells: HashMap<IVec3, u32> = HashMap::with_capacity(points.len());
    let mut count = 0u32;
    let ids = points
        .iter()
        .map(|&p| {
            let own = cell_of(p);
            if let Some(&id) = cells.get(&own) {
                return id;
            }
            // The neighbouring cells the tolerance reaches into.
            let (first, last) = (cell_of(p - tolerance), cell_of(p + tolerance));
            for x in first.x..=last.x {
                for y in first.y..=last.y {
                    for z in first.z..=last.z {
                        if let Some(&id) = cells.get(&IVec3::new(x, y, z)) {
                            return id;
                        }
                    }
                }
            }
            cells.insert(own, count);
            count += 1;
            count - 1
        })
        .collect();
    (ids, count as usize, (lo, hi))
}

/// Disjoint sets of position ids (union by size, with path halving).
struct Pieces {
    parent: Vec<u32>,
    size: Vec<u32>,
}

impl Pieces {
    fn new(count: usize) -> Pieces {
        Pieces { parent: (0..count as u32).collect(), size: vec![1; count] }
    }

    fn root(&mut self, mut i: u32) -> u32 {
        while self.parent[i as usize] != i {
            let grandparent = self.parent[self.parent[i as usize] as usize];
            self.parent[i as usize] = grandparent;
            i = grandparent;
        }
        i
    }

    fn join(&mut self, a: u32, b: u32) {
        let (a, b) = (self.root(a), self.root(b));
        if a == b {
            return;
        }
        let (big, small) = if self.size[a as usize] >= self.size[b as usize] { (a, b) } else { (b, a) };
        self.parent[small as usize] = big;
        self.size[big as usize] += self.size[small as usize];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures::MeshData;

    fn open_of(mesh: &MeshData) -> Vec<bool> {
        open_vertices(&mesh.positions, &mesh.indices)
    }

    #[test]
    fn a_plane_is_open() {
        assert!(open_of(&MeshData::plane(2.0, 2.0, 3)).iter().all(|&open| open));
    }

    #[test]
    fn a_box_and_a_room_are_closed_though_their_faces_share_no_vertex() {
        // Each face has its own four vertices: the faces join by position.
        assert!(open_of(&MeshData::cuboid([1.0, 2.0, 3.0])).iter().all(|&open| !open));
        assert!(open_of(&MeshData::room([4.0, 3.0, 4.0])).iter().all(|&open| !open));
        // Welded at the seam and the poles, whose triangles have no area.
        assert!(open_of(&MeshData::sphere(0.5, 16, 8)).iter().all(|&open| !open));
        assert!(open_of(&MeshData::statue(4, 1)).iter().all(|&open| !open));
    }

    fn solids_of(mesh: &MeshData) -> Solids {
        solids(&mesh.positions, &mesh.indices)
    }

    #[test]
    fn a_box_a_sphere_and_a_statue_are_outward_solids_and_a_room_an_inward_one() {
        for (mesh, outward) in [
            (MeshData::cuboid([1.0, 2.0, 3.0]), true),
            (MeshData::sphere(0.5, 16, 8), true),
            (MeshData::statue(4, 1), true),
            (MeshData::room([4.0, 3.0, 4.0]), false),
        ] {
            let s = solids_of(&mesh);
            assert_eq!(s.solids.len(), 1);
            assert_eq!(s.solids[0].outward, outward);
            // Every triangle with area is on it (the sphere's poles have none).
            let on = s.triangle_solid.iter().filter(|&&id| id == 0).count();
            let total = mesh.indices.len() / 3;
            assert!(on + 32 >= total && on > 0, "{on} of {total} triangles");
            // The bounds hold every corner, with room to spare.
            let (lo, hi) = (s.solids[0].lo, s.solids[0].hi);
            assert!(mesh.positions.iter().all(|&p| Vec3::from(p).cmpgt(lo).all() && Vec3::from(p).cmplt(hi).all()));
        }
    }

    #[test]
    fn open_inconsistently_wound_and_flat_closed_pieces_are_not_solids() {
        let not_solid = |positions: &[[f32; 3]], indices: &[u32]| {
            let s = solids(positions, indices);
            s.solids.is_empty() && s.triangle_solid.iter().all(|&id| id == NOT_SOLID)
        };
        let plane = MeshData::plane(2.0, 2.0, 3);
        assert!(not_solid(&plane.positions, &plane.indices));
        // A box with one triangle wound the other way.
        let cube = MeshData::cuboid([1.0, 1.0, 1.0]);
        let mut flipped = cube.indices.clone();
        flipped.swap(1, 2);
        assert!(not_solid(&cube.positions, &flipped));
        // A two-sided plane: closed (each edge borders two triangles, wound
        // oppositely), but it encloses nothing.
        let mut two_sided = plane.indices.clone();
        two_sided.extend(plane.indices.chunks_exact(3).flat_map(|t| [t[0], t[2], t[1]]));
        assert!(not_solid(&plane.positions, &two_sided));
    }

    #[test]
    fn a_room_missing_a_wall_is_open_and_a_closed_piece_beside_it_stays_closed() {
        let room = MeshData::room([4.0, 3.0, 4.0]);
        // The last face's two triangles left out.
        let walls = &room.indices[..room.indices.len() - 6];
        let mut positions = room.positions.clone();
        let cube = MeshData::cuboid([1.0, 1.0, 1.0]);
        let base = positions.len() as u32;
        positions.extend(cube.positions.iter().map(|p| [p[0] + 10.0, p[1], p[2]]));
        let mut indices = walls.to_vec();
        indices.extend(cube.indices.iter().map(|i| i + base));
        let open = open_vertices(&positions, &indices);
        assert!(open[..20].iter().all(|&o| o), "the room's used vertices are open");
        assert!(open[base as usize..].iter().all(|&o| !o), "the cube beside it is closed");
    }
}
