//! Triangles listed more than once in a primitive: the same three corner
//! positions with the same facing (a mesh exported twice over itself, or a
//! merge gone wrong). Each copy would need lightmap space of its own, and
//! copies overlap in space, so the unwrap cannot keep them in one chart: a
//! plane listed twice became one chart per triangle at an eighth of the
//! density. Instead a repeat shares the lightmap texels of the first copy:
//! it is left out of the unwrap and of texelization, and written back with
//! the first copy's lightmap UVs. Copies facing the other way are not
//! repeats: their other side gets other light.

use std::collections::HashMap;

use crate::unwrap::{AtlasVertex, UnwrappedMesh};

/// Triangle `triangle` repeats the earlier triangle `original`: its corner k
/// is at the position of the original's corner (k + `rotation`) mod 3.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Repeat {
    pub triangle: u32,
    pub original: u32,
    pub rotation: u8,
}

/// The repeats of a triangle list, by triangle, in order. Triangles without
/// area are never repeats (they get no lightmap space anyway).
pub fn find(positions: &[[f32; 3]], indices: &[u32]) -> Vec<Repeat> {
    let mut first: HashMap<[[u32; 3]; 3], (u32, usize)> = HashMap::new();
    let mut repeats = Vec::new();
    for (t, corners) in indices.chunks_exact(3).enumerate() {
        let bits = [0, 1, 2].map(|k| positions[corners[k] as usize].map(f32::to_bits));
        if bits[0] == bits[1] || bits[1] == bits[2] || bits[0] == bits[2] {
            continue;
        }
        // The same triangle in any of its three rotations: start at the smallest corner.
        let start = (0..3).min_by_key(|&k| bits[k]).unwrap_or(0);
        let key = [0, 1, 2].map(|k| bits[(start + k) % 3]);
        match first.get(&key) {
            Some(&(original, original_start)) => {
                let rotation = ((original_start + 3 - start) % 3) as u8;
                repeats.push(Repeat { triangle: t as u32, original, rotation });
            }
            None => {
                first.insert(key, (t as u32, start));
            }
        }
    }
    repeats
}

/// Per triangle: is it a repeat?
pub fn mask(repeats: &[Repeat], triangles: usize) -> Vec<bool> {
    let mut mask = vec![false; triangles];
    for r in repeats {
        mask[r.triangle as usize] = true;
    }
    mask
}

/// The triangle list without its repeats.
pub fn without(indices: &[u32], repeats: &[Repeat]) -> Vec<u32> {
    let mask = mask(repeats, indices.len() / 3);
    indices.chunks_exact(3).zip(&mask).filter(|(_, repeat)| !**repeat).flat_map(|(t, _)| t.iter().copied()).collect()
}

/// Puts the repeats back into `unwrapped`, an unwrap of `without(indices,
/// repeats)`: each repeat's corners get the lightmap UVs of the original's
/// matching corners, on vertices that refer to the repeat's own source
/// vertices (so export copies the repeat's own attributes).
pub fn restore(indices: &[u32], repeats: &[Repeat], unwrapped: UnwrappedMesh) -> UnwrappedMesh {
    if repeats.is_empty() {
        return unwrapped;
    }
    let UnwrappedMesh { mut vertices, indices: unique } = unwrapped;
    let mask = mask(repeats, indices.len() / 3);
    // Where each original triangle landed in the unwrapped list.
    let mut position_in_unique = vec![u32::MAX; mask.len()];
    let mut next = 0u32;
    for (t, &repeat) in mask.iter().enumerate() {
        if !repeat {
            position_in_unique[t] = next;
            next += 1;
        }
    }
    let mut by_triangle: HashMap<u32, Repeat> = repeats.iter().map(|r| (r.triangle, *r)).collect();
    let mut shared: HashMap<(u32, u32), u32> = HashMap::new();
    let mut out = Vec::with_capacity(indices.len());
    for (t, source) in indices.chunks_exact(3).enumerate() {
        match by_triangle.remove(&(t as u32)) {
            None => {
                let u = position_in_unique[t] as usize;
                out.extend_from_slice(&unique[3 * u..3 * u + 3]);
            }
            Some(r) => {
                let u = position_in_unique[r.original as usize] as usize;
                for (k, &source_vertex) in source.iter().enumerate() {
                    let of_original = unique[3 * u + (k + r.rotation as usize) % 3];
                    let v = vertices[of_original as usize];
                    let index = if v.xref == source_vertex {
                        of_original
                    } else {
                        *shared.entry((of_original, source_vertex)).or_insert_with(|| {
                            vertices.push(AtlasVertex { xref: source_vertex, ..v });
                            (vertices.len() - 1) as u32
                        })
                    };
                    out.push(index);
                }
            }
        }
    }
    UnwrappedMesh { vertices, indices: out }
}

#[cfg(test)]
mod tests {
    use super::*;

    const QUAD: [[f32; 3]; 4] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 1.0], [0.0, 0.0, 1.0]];

    #[test]
    fn a_repeat_is_found_in_any_rotation_but_not_facing_the_other_way() {
        // 0: original; 1: rotated copy; 2: the other facing; 3: the other half of the quad.
        let indices = [0, 1, 2, 1, 2, 0, 0, 2, 1, 0, 2, 3];
        let repeats = find(&QUAD, &indices);
        assert_eq!(repeats, [Repeat { triangle: 1, original: 0, rotation: 1 }]);
    }

    #[test]
    fn repeats_on_their_own_vertices_are_found_and_restored_onto_them() {
        // The quad listed twice, the second time on copies of its vertices (4..8).
        let mut positions = QUAD.to_vec();
        positions.extend_from_slice(&QUAD);
        let indices = [0, 1, 2, 0, 2, 3, 6, 4, 5, 4, 6, 7];
        let repeats = find(&positions, &indices);
        assert_eq!(repeats.len(), 2);
        let unique = without(&indices, &repeats);
        assert_eq!(unique, [0, 1, 2, 0, 2, 3]);
        // A stand-in unwrap: one atlas vertex per source vertex, uv from x and z.
        let vertices =
            (0..4).map(|i| AtlasVertex { xref: i, uv: [QUAD[i as usize][0], QUAD[i as usize][2]], chart: 0 });
        let unwrapped = UnwrappedMesh { vertices: vertices.collect(), indices: unique };
        let full = restore(&indices, &repeats, unwrapped);
        assert_eq!(full.indices.len(), indices.len());
        for (k, &v) in full.indices.iter().enumerate() {
            let vertex = full.vertices[v as usize];
            assert_eq!(vertex.xref, indices[k], "corner {k} refers to its own source vertex");
            let p = positions[indices[k] as usize];
            assert_eq!(vertex.uv, [p[0], p[2]], "corner {k} has the uv of its position");
        }
    }
}
