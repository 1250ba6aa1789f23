//! Which caster triangles lie on an open surface (a sheet: a wall or floor
//! of zero thickness, a leaf) and which on a closed one (a solid's skin, or
//! a sealed room of inward-facing walls). The depth maps mark the former,
//! so that the direct pass lets shadow rays through the open space behind
//! a sheet, while the space inside a closed surface stays sealed.
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
    let (vertex_ids, count) = welded_ids(positions);
    let mut pieces = Pieces::new(count);
    // Every edge once per triangle it borders, as one sortable key.
    let mut edges = Vec::with_capacity(indices.len());
    for t in indices.chunks_exact(3) {
        let [a, b, c] = [t[0], t[1], t[2]].map(|i| vertex_ids[i as usize]);
        // A triangle with two corners welded (a sphere's pole) has no area
        // and would count one edge twice.
        if a == b || b == c || c == a {
            continue;
        }
        for (p, q) in [(a, b), (b, c), (c, a)] {
            pieces.join(p, q);
            edges.push((p.min(q) as u64) << 32 | p.max(q) as u64);
        }
    }
    edges.sort_unstable();
    let mut open_piece = vec![false; count];
    for run in edges.chunk_by(|x, y| x == y) {
        if run.len() < 2 {
            let root = pieces.root((run[0] >> 32) as u32);
            open_piece[root as usize] = true;
        }
    }
    vertex_ids.iter().map(|&id| open_piece[pieces.root(id) as usize]).collect()
}

/// An id for each position, equal for positions within a millionth of the
/// bounding box's diagonal of each other (and some up to three millionths
/// apart: the first position in a cell twice that wide stands for all in
/// it), and the number of ids.
fn welded_ids(positions: &[[f32; 3]]) -> (Vec<u32>, usize) {
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
    (ids, count as usize)
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
