//! UV seams and their stitching. A seam is a surface edge the unwrap cut:
//! the same two world points, on a smooth surface, at two places of the
//! atlas. Each side is filtered from its own texels, so a viewer shows a
//! line wherever the two sides' bilinear values differ.
//!
//! Stitching (least squares, as in Iwanicki 2013 and the seam optimisers of
//! Lightmapper and Unity's Progressive Lightmapper): sample both sides of
//! every seam at a few points per texel of its length, and move the texels
//! the samples read by the least total amount that makes each pair agree:
//!
//! ```text
//! min Σ_samples (bilinear_A(x) − bilinear_B(x))² + λ Σ_texels (x − x₀)²
//! ```
//!
//! solved per channel by conjugate gradients (the system is symmetric
//! positive definite). Hard edges (normals that differ by more than
//! `SMOOTH_COS`) are not seams: their two sides are lit differently.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::lightmap::Image;
use crate::scene::Scene;
use crate::unwrap::Atlas;

/// Normals at a shared edge's ends within about 18° of each other make it
/// smooth, so a seam to stitch.
const SMOOTH_COS: f32 = 0.95;
/// Samples along a seam per texel of its length on the longer side.
const SAMPLES_PER_TEXEL: f32 = 2.0;
/// Weight of staying near the solved values against closing the seam.
const LAMBDA: f64 = 0.02;
const MAX_ITERATIONS: usize = 200;

/// One seam edge: the same world edge at two places of the atlas, as the
/// two ends' page coordinates on side `a` and side `b` (end k of `a` is the
/// same world point as end k of `b`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SeamEdge {
    pub a: [[f32; 2]; 2],
    pub b: [[f32; 2]; 2],
}

/// What stitching found and did, for the report.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct StitchStats {
    /// Seam edges found (hard edges excluded).
    pub edges: usize,
    /// Texels the stitch moved.
    pub texels: usize,
    /// Relative difference of the two sides' bilinear values along the seams
    /// (luminance, mean and max over the samples) before and after.
    pub error_before: SeamError,
    pub error_after: SeamError,
}

#[derive(Clone, Copy, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct SeamError {
    pub mean: f64,
    pub max: f64,
}

/// The seam edges of the atlas: triangle edges with the same world end
/// points, smooth normals and different page coordinates.
pub fn find(scene: &Scene, atlas: &Atlas) -> Vec<SeamEdge> {
    // World end points (exact bits, smaller first) → the edges' sides.
    let mut sides: BTreeMap<([u32; 3], [u32; 3]), Vec<EdgeSide>> = BTreeMap::new();
    for (primitive, mesh) in scene.primitives.iter().zip(&atlas.meshes) {
        // A repeated triangle lies on its first copy's texels: one side, not two.
        let repeat = crate::repeats::mask(&primitive.repeats, mesh.indices.len() / 3);
        for (_, triangle) in mesh.indices.chunks_exact(3).enumerate().filter(|(t, _)| !repeat[*t]) {
            let corners = [0, 1, 2].map(|k| mesh.vertices[triangle[k] as usize]);
            if corners.iter().any(|v| v.chart == u32::MAX) {
                continue;
            }
            let position = |k: usize| primitive.positions[corners[k].xref as usize];
            let face = face_normal(position(0), position(1), position(2));
            let normal = |k: usize| primitive.normals.as_ref().map_or(face, |n| n[corners[k].xref as usize]);
            for (i, j) in [(0, 1), (1, 2), (2, 0)] {
                let (pi, pj) = (position(i).map(f32::to_bits), position(j).map(f32::to_bits));
                let (first, second) = if pi <= pj { (i, j) } else { (j, i) };
                let key = (position(first).map(f32::to_bits), position(second).map(f32::to_bits));
                if key.0 == key.1 {
                    continue;
                }
                let uv = [corners[first].uv, corners[second].uv];
                sides.entry(key).or_default().push((uv, [normal(first), normal(second)]));
            }
        }
    }
    let mut seams = Vec::new();
    for list in sides.values() {
        // An edge with more than two sides is not a manifold seam.
        let [(uv_a, n_a), (uv_b, n_b)] = list.as_slice() else {
            continue;
        };
        let same_place = (0..2).all(|k| (0..2).all(|c| (uv_a[k][c] - uv_b[k][c]).abs() < 1e-7));
        let smooth = (0..2).all(|k| dot(n_a[k], n_b[k]) >= SMOOTH_COS);
        if !same_place && smooth {
            seams.push(SeamEdge { a: *uv_a, b: *uv_b });
        }
    }
    seams
}

/// One triangle's copy of an edge: its ends' page coordinates and normals.
type EdgeSide = ([[f32; 2]; 2], [[f32; 3]; 2]);

fn face_normal(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> [f32; 3] {
    let (a, b, c) = (glam::Vec3::from(a), glam::Vec3::from(b), glam::Vec3::from(c));
    (b - a).cross(c - a).normalize_or_zero().to_array()
}

fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// One sample pair: the texels (image index) the two sides' bilinear
/// lookups read, side a's with positive and side b's with negative weight.
type Row = Vec<(usize, f64)>;

/// The bilinear taps (image index, weight) at page coordinates `uv`, as a
/// viewer filters: texel centres at (x + ½)/width; `None` where a tap
/// falls on an unwritten texel.
fn taps(image: &Image, uv: [f32; 2]) -> Option<[(usize, f64); 4]> {
    let x = uv[0] as f64 * image.width as f64 - 0.5;
    let y = uv[1] as f64 * image.height as f64 - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let mut out = [(0usize, 0.0f64); 4];
    for (k, (dx, dy, w)) in
        [(0, 0, (1.0 - fx) * (1.0 - fy)), (1, 0, fx * (1.0 - fy)), (0, 1, (1.0 - fx) * fy), (1, 1, fx * fy)]
            .into_iter()
            .enumerate()
    {
        // Clamped to the page's edge, as a clamping sampler reads.
        let tx = (x0 as i64 + dx).clamp(0, image.width as i64 - 1);
        let ty = (y0 as i64 + dy).clamp(0, image.height as i64 - 1);
        let index = (ty * image.width as i64 + tx) as usize;
        if !image.written[index] && w > 0.0 {
            return None;
        }
        out[k] = (index, w);
    }
    Some(out)
}

/// Sample pairs along every seam.
fn rows(image: &Image, seams: &[SeamEdge]) -> Vec<Row> {
    let size = [image.width as f32, image.height as f32];
    let texels = |e: [[f32; 2]; 2]| ((e[1][0] - e[0][0]) * size[0]).hypot((e[1][1] - e[0][1]) * size[1]);
    let mut rows = Vec::new();
    for seam in seams {
        let n = (texels(seam.a).max(texels(seam.b)) * SAMPLES_PER_TEXEL).ceil().max(1.0) as usize;
        for s in 0..n {
            let t = (s as f32 + 0.5) / n as f32;
            let at = |e: [[f32; 2]; 2]| [0, 1].map(|c| e[0][c] + (e[1][c] - e[0][c]) * t);
            let (Some(a), Some(b)) = (taps(image, at(seam.a)), taps(image, at(seam.b))) else {
                continue;
            };
            let mut row: Row = Vec::with_capacity(8);
            for (index, w) in a.into_iter().chain(b.into_iter().map(|(i, w)| (i, -w))) {
                if w == 0.0 {
                    continue;
                }
                match row.iter_mut().find(|(i, _)| *i == index) {
                    Some(entry) => entry.1 += w,
                    None => row.push((index, w)),
                }
            }
            rows.push(row);
        }
    }
    rows
}

/// Relative luminance difference of the two sides over the sample pairs.
fn error(image: &Image, rows: &[Row]) -> SeamError {
    let luminance = |i: usize| crate::colour::luminance(image.pixels[i]);
    let (mut sum, mut max, mut count) = (0.0, 0.0f64, 0usize);
    for row in rows {
        let difference: f64 = row.iter().map(|&(i, w)| w * luminance(i)).sum();
        let level: f64 = row.iter().map(|&(i, w)| w.abs() * luminance(i)).sum::<f64>() / 2.0;
        if level <= 1e-12 {
            continue;
        }
        let relative = difference.abs() / level;
        sum += relative;
        max = max.max(relative);
        count += 1;
    }
    SeamError { mean: if count > 0 { sum / count as f64 } else { 0.0 }, max }
}

/// The seam error of `image` along `seams` (see [`StitchStats`]).
#[cfg(feature = "internals")]
pub fn seam_error(image: &Image, seams: &[SeamEdge]) -> SeamError {
    error(image, &rows(image, seams))
}

/// Stitches `image` along `seams` (module documentation).
pub fn stitch(image: &mut Image, seams: &[SeamEdge]) -> StitchStats {
    let rows = rows(image, seams);
    let error_before = error(image, &rows);
    // The texels the samples read, as unknowns 0..n in image order.
    let mut unknown = vec![u32::MAX; image.pixels.len()];
    let mut texels: Vec<usize> = rows.iter().flatten().map(|&(i, _)| i).collect();
    texels.sort_unstable();
    texels.dedup();
    for (k, &i) in texels.iter().enumerate() {
        unknown[i] = k as u32;
    }
    let local: Vec<Vec<(usize, f64)>> =
        rows.iter().map(|row| row.iter().map(|&(i, w)| (unknown[i] as usize, w)).collect()).collect();
    let mut moved = vec![false; texels.len()];
    for channel in 0..3 {
        let start: Vec<f64> = texels.iter().map(|&i| image.pixels[i][channel] as f64).collect();
        let solved = solve(&local, &start);
        for (k, &i) in texels.iter().enumerate() {
            let value = solved[k].max(0.0) as f32;
            if value != image.pixels[i][channel] {
                moved[k] = true;
            }
            image.pixels[i][channel] = value;
        }
    }
    StitchStats {
        edges: seams.len(),
        texels: moved.iter().filter(|m| **m).count(),
        error_before,
        error_after: error(image, &rows),
    }
}

/// (MᵀM + λI) x = λ x₀ by conjugate gradients, from x = x₀; M's rows are `rows`.
fn solve(rows: &[Vec<(usize, f64)>], start: &[f64]) -> Vec<f64> {
    let apply = |x: &[f64]| -> Vec<f64> {
        let mut y: Vec<f64> = x.iter().map(|v| LAMBDA * v).collect();
        for row in rows {
            let r: f64 = row.iter().map(|&(k, w)| w * x[k]).sum();
            for &(k, w) in row {
                y[k] += w * r;
            }
        }
        y
    };
    let mut x = start.to_vec();
    let ax = apply(&x);
    let mut r: Vec<f64> = start.iter().zip(&ax).map(|(s, a)| LAMBDA * s - a).collect();
    let mut p = r.clone();
    let mut rr: f64 = r.iter().map(|v| v * v).sum();
    let scale: f64 = start.iter().map(|v| v * v).sum::<f64>().max(1e-300);
    for _ in 0..MAX_ITERATIONS {
        if rr <= 1e-20 * LAMBDA * LAMBDA * scale {
            break;
        }
        let ap = apply(&p);
        let pap: f64 = p.iter().zip(&ap).map(|(a, b)| a * b).sum();
        if pap <= 0.0 {
            break;
        }
        let alpha = rr / pap;
        for k in 0..x.len() {
            x[k] += alpha * p[k];
            r[k] -= alpha * ap[k];
        }
        let next: f64 = r.iter().map(|v| v * v).sum();
        let beta = next / rr;
        rr = next;
        for k in 0..p.len() {
            p[k] = r[k] + beta * p[k];
        }
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(width: u32, values: &[f32]) -> Image {
        let mut image = Image::blank(width, 1);
        image.pixels = values.iter().map(|&v| [v; 3]).collect();
        image.written.iter_mut().for_each(|w| *w = true);
        image
    }

    #[test]
    fn a_stitched_seam_agrees_and_the_rest_stays() {
        // Two one-row "charts": texels 0–3 and 6–9, the seam at their middles.
        let mut img = image(10, &[1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 2.0, 2.0, 2.0, 2.0]);
        let y = 0.5;
        let seams = [SeamEdge { a: [[0.15, y], [0.35, y]], b: [[0.65, y], [0.85, y]] }];
        let stats = stitch(&mut img, &seams);
        assert!(stats.error_before.mean > 0.6, "{stats:?}");
        assert!(stats.error_after.mean < 0.05, "{stats:?}");
        // Both sides meet near the middle; texels the seam does not read stay.
        let left = img.pixels[2][0];
        let right = img.pixels[7][0];
        assert!(left > 1.3 && right < 1.7, "{left} {right}");
        assert_eq!(img.pixels[4], [0.0; 3]);
    }
}
