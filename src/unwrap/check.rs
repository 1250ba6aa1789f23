//! Measuring an atlas: overlaps, flips, padding and texel-density error, by rasterizing every
//! charted triangle conservatively at the page resolution.

use super::{Atlas, AtlasVertex, MeshInput, triangle_area};

/// What [`inspect`] measured. Texel distances are Chebyshev (diagonal neighbours are 1 apart).
#[derive(Clone, Debug, PartialEq)]
pub struct Quality {
    /// Texels touched (with positive area) by triangles of two or more different charts.
    pub overlap_texels: u64,
    /// Texel centres strictly inside two triangles of the same chart (a chart folding over
    /// itself, or duplicate faces sharing UVs).
    pub self_overlap_texels: u64,
    /// Per chart, the number of triangles of its less common UV winding (mirrored triangles).
    pub flipped_triangles: u64,
    /// Triangles with a corner outside `[0, 1]²`, an index out of range, an `xref` out of range
    /// or corners in different charts, plus output triangles (or meshes) missing or in excess.
    pub malformed_triangles: u64,
    /// Fewest empty texels between texels of two different charts, if any two are closer than
    /// the `gap_limit` given to [`inspect`].
    pub min_chart_gap: Option<u32>,
    /// Fewest texels between a chart texel and the page border.
    pub min_border_gap: Option<u32>,
    /// Per chart, `max(r, 1/r)` with `r` = UV area in texels / (world area × texels_per_unit²):
    /// the largest over all charts (1 = exact density).
    pub max_chart_distortion: f64,
    /// Per triangle `max(r, 1/r)` as above, averaged with world-area weights.
    pub mean_triangle_distortion: f64,
    /// Total UV area of charted triangles over the page area.
    pub utilization: f64,
}

impl Quality {
    /// No overlap (between or within charts), no flip, nothing malformed, and at least `2·padding` texels between charts
    /// and `padding` to the border.
    pub fn is_valid(&self, padding: u32) -> bool {
        self.overlap_texels == 0
            && self.self_overlap_texels == 0
            && self.flipped_triangles == 0
            && self.malformed_triangles == 0
            && self.min_chart_gap.is_none_or(|g| g >= 2 * padding)
            && self.min_border_gap.is_none_or(|g| g >= padding)
    }
}

/// Signed area of a UV triangle (in UV units²; positive when counter-clockwise with v up).
pub(crate) fn uv_area(a: [f32; 2], b: [f32; 2], c: [f32; 2]) -> f64 {
    let [a, b, c] = [a, b, c].map(|p| p.map(f64::from));
    0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]))
}

const EMPTY: u32 = u32::MAX;
const CONFLICT: u32 = u32::MAX - 1;

/// Measures `atlas`, made from `meshes`. Chart gaps are searched up to `gap_limit` texels
/// (pass at least `2·padding + 1` to verify padding). Cost: one pass over the page's texels
/// plus `(2·gap_limit + 1)²` per chart texel.
pub fn inspect(meshes: &[MeshInput], atlas: &Atlas, gap_limit: u32) -> Quality {
    let mut tally = Tally::new(atlas);
    // Missing meshes or triangles count as malformed.
    let missing = |n: usize, m: usize| (n.max(m) - n.min(m)) as u64;
    tally.malformed += missing(meshes.len(), atlas.meshes.len());
    for (m, out) in meshes.iter().zip(&atlas.meshes) {
        tally.malformed += missing(m.indices.len() / 3, out.indices.len() / 3);
        for t in out.indices.chunks_exact(3) {
            match t.iter().map(|&i| out.vertices.get(i as usize).copied()).collect::<Option<Vec<_>>>() {
                Some(v) => tally.triangle(m, [v[0], v[1], v[2]]),
                None => tally.malformed += 1,
            }
        }
    }
    let gaps = Gaps::measure(&tally.grid, tally.w, tally.h, gap_limit);
    Quality {
        overlap_texels: gaps.overlap,
        self_overlap_texels: tally.self_overlap,
        flipped_triangles: tally.flipped(),
        malformed_triangles: tally.malformed,
        min_chart_gap: gaps.min_gap,
        min_border_gap: gaps.min_border,
        max_chart_distortion: tally.max_chart_distortion(),
        mean_triangle_distortion: if tally.weight > 0.0 { tally.weighted / tally.weight } else { 1.0 },
        utilization: tally.covered,
    }
}

/// What [`inspect`]'s pass over the output triangles accumulates.
struct Tally {
    w: usize,
    h: usize,
    /// Page area in texels: UV area to texels.
    texel_area: f64,
    /// Texels per world unit, squared: world area to texels.
    tpu2: f64,
    /// Per texel: `EMPTY`, the one chart touching it, or `CONFLICT`.
    grid: Vec<u32>,
    /// Triangle (running number) whose interior holds each texel centre, for self-overlap.
    centres: Vec<u32>,
    self_overlap: u64,
    tri_id: u32,
    malformed: u64,
    /// Per chart: |UV| area sum, world area sum.
    uv_sum: Vec<f64>,
    world_sum: Vec<f64>,
    /// Sums of world area × per-triangle distortion and of world area.
    weighted: f64,
    weight: f64,
    covered: f64,
    /// (chart, signed area) of each charted triangle, for the flip count.
    tris: Vec<(usize, f64)>,
}

impl Tally {
    fn new(atlas: &Atlas) -> Self {
        let (w, h) = (atlas.width as usize, atlas.height as usize);
        let n = atlas.chart_count as usize;
        Tally {
            w,
            h,
            texel_area: w as f64 * h as f64,
            tpu2: (atlas.texels_per_unit as f64).powi(2),
            grid: vec![EMPTY; w * h],
            centres: vec![EMPTY; w * h],
            self_overlap: 0,
            tri_id: 0,
            malformed: 0,
            uv_sum: vec![0.0; n],
            world_sum: vec![0.0; n],
            weighted: 0.0,
            weight: 0.0,
            covered: 0.0,
            tris: Vec::new(),
        }
    }

    /// Checks one output triangle of mesh `m` and adds it to the sums and the grid.
    fn triangle(&mut self, m: &MeshInput, v: [AtlasVertex; 3]) {
        let in_range = |uv: [f32; 2]| uv.iter().all(|c| (0.0..=1.0).contains(c));
        if v.iter().any(|x| !in_range(x.uv) || x.xref as usize >= m.positions.len()) {
            self.malformed += 1;
            return;
        }
        let chart = v[0].chart;
        if v.iter().any(|x| x.chart != chart) {
            self.malformed += 1;
            return;
        }
        let a = uv_area(v[0].uv, v[1].uv, v[2].uv);
        if chart == u32::MAX {
            // Uncharted (ignored) triangles must cover nothing.
            if a.abs() * self.texel_area > 1e-9 {
                self.malformed += 1;
            }
            return;
        }
        let c = chart as usize;
        if c >= self.uv_sum.len() {
            self.malformed += 1;
            return;
        }
        let world = triangle_area([0, 1, 2].map(|k| m.positions[v[k].xref as usize]));
        self.uv_sum[c] += a.abs();
        self.world_sum[c] += world;
        self.covered += a.abs();
        self.tris.push((c, a));
        let texels = a.abs() * self.texel_area;
        if world > 0.0 && texels > 0.0 && self.tpu2 > 0.0 {
            let r = texels / (world * self.tpu2);
            self.weighted += world * r.max(1.0 / r);
            self.weight += world;
        }
        if texels > 1e-9 {
            let (w, h) = (self.w, self.h);
            let p = v.map(|x| [x.uv[0] as f64 * w as f64, x.uv[1] as f64 * h as f64]);
            self.cover(p, chart);
        }
    }

    /// Marks the texels triangle `p` (texel units) of `chart` touches, and counts texel
    /// centres already inside another triangle of the same chart.
    fn cover(&mut self, p: [[f64; 2]; 3], chart: u32) {
        let (w, h) = (self.w, self.h);
        let grid = &mut self.grid;
        rasterize(p, w, h, |x, y| {
            let cell = &mut grid[y * w + x];
            if *cell == EMPTY {
                *cell = chart;
            } else if *cell != chart {
                *cell = CONFLICT;
            }
        });
        self.tri_id = self.tri_id.wrapping_add(1);
        let (grid, centres, tri_id, self_overlap) =
            (&self.grid, &mut self.centres, self.tri_id, &mut self.self_overlap);
        inside_centres(p, w, h, |x, y| {
            let cell = &mut centres[y * w + x];
            if *cell != EMPTY && grid[y * w + x] == chart {
                *self_overlap += 1;
            }
            *cell = tri_id;
        });
    }

    /// Per chart, the triangles of the less common winding (non-degenerate ones).
    fn flipped(&self) -> u64 {
        let mut windings = vec![[0u64; 2]; self.uv_sum.len()];
        for &(c, a) in &self.tris {
            if a.abs() * self.texel_area > 1e-9 {
                windings[c][usize::from(a > 0.0)] += 1;
            }
        }
        windings.iter().map(|w| w[0].min(w[1])).sum()
    }

    fn max_chart_distortion(&self) -> f64 {
        (0..self.uv_sum.len())
            .filter(|&c| self.world_sum[c] > 0.0 && self.uv_sum[c] > 0.0 && self.tpu2 > 0.0)
            .map(|c| {
                let r = self.uv_sum[c] * self.texel_area / (self.world_sum[c] * self.tpu2);
                r.max(1.0 / r)
            })
            .fold(1.0, f64::max)
    }
}

/// Overlaps and distances between charts and to the border, on the chart grid.
struct Gaps {
    overlap: u64,
    min_gap: Option<u32>,
    min_border: Option<u32>,
}

impl Gaps {
    fn measure(grid: &[u32], w: usize, h: usize, gap_limit: u32) -> Gaps {
        let mut gaps = Gaps { overlap: 0, min_gap: None, min_border: None };
        for y in 0..h {
            for x in 0..w {
                let c = grid[y * w + x];
                if c == EMPTY {
                    continue;
                }
                if c == CONFLICT {
                    gaps.overlap += 1;
                    gaps.min_gap = Some(0);
                    continue;
                }
                let border = x.min(y).min(w - 1 - x).min(h - 1 - y) as u32;
                gaps.min_border = Some(gaps.min_border.map_or(border, |b| b.min(border)));
                // Only texels on a chart's outline can be nearest to another chart.
                let interior = (y > 0 && y + 1 < h && x > 0 && x + 1 < w)
                    && [(-1i64, -1i64), (0, -1), (1, -1), (-1, 0), (1, 0), (-1, 1), (0, 1), (1, 1)]
                        .iter()
                        .all(|&(dx, dy)| grid[(y as i64 + dy) as usize * w + (x as i64 + dx) as usize] == c);
                if !interior {
                    gaps.nearest_other(grid, w, h, (x, y), gap_limit);
                }
            }
        }
        gaps
    }

    /// Lowers `min_gap` to the distance from chart texel `(x, y)` to the nearest texel of
    /// another chart, searching no further than the current best.
    fn nearest_other(&mut self, grid: &[u32], w: usize, h: usize, (x, y): (usize, usize), gap_limit: u32) {
        let c = grid[y * w + x];
        let reach = self.min_gap.map_or(gap_limit as i64, |g| (g as i64).min(gap_limit as i64));
        for d in 1..=reach {
            for (dx, dy) in ring(d) {
                let (xx, yy) = (x as i64 + dx, y as i64 + dy);
                if xx < 0 || yy < 0 || xx >= w as i64 || yy >= h as i64 {
                    continue;
                }
                let o = grid[yy as usize * w + xx as usize];
                if o != EMPTY && o != c {
                    let gap = (d - 1) as u32;
                    self.min_gap = Some(self.min_gap.map_or(gap, |g| g.min(gap)));
                    return;
                }
            }
        }
    }
}

/// Offsets at Chebyshev distance exactly `d`.
fn ring(d: i64) -> impl Iterator<Item = (i64, i64)> {
    (-d..=d).flat_map(move |dy| {
        let step = if dy.abs() == d { 1 } else { 2 * d };
        (-d..=d).step_by(step as usize).map(move |dx| (dx, dy))
    })
}

/// Calls `f(x, y)` for every texel of a `w × h` grid that the triangle `p` (in texel units)
/// overlaps with positive area (conservative rasterization, shrunk by a tiny epsilon so that
/// merely touching an edge doesn't count).
pub(crate) fn rasterize(p: [[f64; 2]; 3], w: usize, h: usize, mut f: impl FnMut(usize, usize)) {
    const EPS: f64 = 1e-4;
    let ymin = p.iter().map(|q| q[1]).fold(f64::INFINITY, f64::min);
    let ymax = p.iter().map(|q| q[1]).fold(f64::NEG_INFINITY, f64::max);
    if !(ymin.is_finite() && ymax.is_finite()) {
        return;
    }
    let r0 = (ymin + EPS).floor().max(0.0) as usize;
    let r1 = ((ymax - EPS).ceil() as i64).min(h as i64);
    for r in r0 as i64..r1 {
        let (y0, y1) = (r as f64 + EPS, r as f64 + 1.0 - EPS);
        let Some((xmin, xmax)) = slab_extent(&p, y0, y1) else {
            continue;
        };
        let c0 = (xmin + EPS).floor().max(0.0) as i64;
        let c1 = ((xmax - EPS).ceil() as i64).min(w as i64);
        for c in c0..c1 {
            f(c as usize, r as usize);
        }
    }
}

/// Calls `f(x, y)` for every texel whose centre lies inside the triangle `p` (texel units) by
/// more than a small margin, so that triangles sharing an edge never both claim a centre.
pub(super) fn inside_centres(p: [[f64; 2]; 3], w: usize, h: usize, mut f: impl FnMut(usize, usize)) {
    const MARGIN: f64 = 1e-3;
    let area2 = (p[1][0] - p[0][0]) * (p[2][1] - p[0][1]) - (p[2][0] - p[0][0]) * (p[1][1] - p[0][1]);
    if area2 == 0.0 || !area2.is_finite() {
        return;
    }
    let s = area2.signum();
    let ys = p.map(|q| q[1]);
    let y_lo = ys.iter().copied().fold(f64::INFINITY, f64::min);
    let y_hi = ys.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let y0 = (y_lo - 0.5).ceil().max(0.0) as usize;
    let y1 = ((y_hi - 0.5).floor() + 1.0).clamp(0.0, h as f64) as usize;
    for y in y0..y1 {
        let cy = y as f64 + 0.5;
        // Each edge k, as a function of the centre's x: s·(e × (c − a)) = a0 + b·x, and the
        // centre is inside when that exceeds MARGIN·|e| for all three edges.
        let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
        for k in 0..3 {
            let (a, b) = (p[k], p[(k + 1) % 3]);
            let e = [b[0] - a[0], b[1] - a[1]];
            let m = MARGIN * (e[0] * e[0] + e[1] * e[1]).sqrt();
            let slope = -s * e[1];
            let offset = s * (e[0] * (cy - a[1]) + e[1] * a[0]);
            if slope > 0.0 {
                lo = lo.max((m - offset) / slope);
            } else if slope < 0.0 {
                hi = hi.min((m - offset) / slope);
            } else if offset <= m {
                lo = f64::INFINITY;
            }
        }
        // (NaN bounds fail this too.)
        if lo.partial_cmp(&hi) != Some(std::cmp::Ordering::Less) {
            continue;
        }
        // Columns whose centre x + 0.5 lies strictly inside (lo, hi).
        let x0 = ((lo - 0.5).floor() + 1.0).max(0.0);
        let x1 = ((hi - 0.5).ceil()).min(w as f64);
        if x0.partial_cmp(&x1) != Some(std::cmp::Ordering::Less) {
            continue;
        }
        for x in x0 as usize..x1 as usize {
            f(x, y);
        }
    }
}

/// X range of a triangle clipped to the horizontal slab `y0 <= y <= y1`.
fn slab_extent(p: &[[f64; 2]; 3], y0: f64, y1: f64) -> Option<(f64, f64)> {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    let mut add = |x: f64| {
        lo = lo.min(x);
        hi = hi.max(x);
    };
    for i in 0..3 {
        let (a, b) = (p[i], p[(i + 1) % 3]);
        if a[1] >= y0 && a[1] <= y1 {
            add(a[0]);
        }
        for y in [y0, y1] {
            if (a[1] - y) * (b[1] - y) < 0.0 {
                let t = (y - a[1]) / (b[1] - a[1]);
                add(a[0] + t * (b[0] - a[0]));
            }
        }
    }
    (lo <= hi).then_some((lo, hi))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::unwrap::{AtlasVertex, UnwrappedMesh};

    /// An atlas of two unit right triangles (world) given their UVs and charts.
    fn atlas(uvs: [[[f32; 2]; 3]; 2], charts: [u32; 2], size: u32) -> Atlas {
        let vertices =
            (0..6).map(|i| AtlasVertex { xref: (i % 3) as u32, uv: uvs[i / 3][i % 3], chart: charts[i / 3] }).collect();
        Atlas {
            width: size,
            height: size,
            texels_per_unit: 4.0,
            chart_count: charts.iter().max().unwrap() + 1,
            utilization: 0.0,
            meshes: vec![UnwrappedMesh { vertices, indices: (0..6).collect() }],
            notices: Vec::new(),
        }
    }

    const P: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    const I: [u32; 6] = [0, 1, 2, 0, 1, 2];

    /// A triangle of 4×4 texels at texel (x, y) on a 32² page (exact density 4 texels/m).
    fn tri(x: f32, y: f32) -> [[f32; 2]; 3] {
        [[x, y], [x + 4.0, y], [x, y + 4.0]].map(|p| [p[0] / 32.0, p[1] / 32.0])
    }

    #[test]
    fn measures_gaps_overlaps_and_flips() {
        let mesh = [MeshInput::new(&P, &I)];
        // Two charts 3 texels apart, 2 from the border.
        let q = inspect(&mesh, &atlas([tri(2.0, 2.0), tri(9.0, 2.0)], [0, 1], 32), 8);
        assert_eq!((q.min_chart_gap, q.min_border_gap), (Some(3), Some(2)));
        assert!(q.is_valid(1) && !q.is_valid(2));
        assert!((q.max_chart_distortion - 1.0).abs() < 1e-6);
        // Overlapping charts.
        let q = inspect(&mesh, &atlas([tri(2.0, 2.0), tri(3.0, 3.0)], [0, 1], 32), 8);
        assert!(q.overlap_texels > 0 && q.min_chart_gap == Some(0) && !q.is_valid(0));
        // The same, within one chart.
        let q = inspect(&mesh, &atlas([tri(2.0, 2.0), tri(3.0, 3.0)], [0, 0], 32), 8);
        assert!(q.self_overlap_texels > 0 && q.overlap_texels == 0 && !q.is_valid(0));
        // A mirrored triangle in a chart.
        let mut m = tri(12.0, 2.0);
        m.swap(1, 2);
        let q = inspect(&mesh, &atlas([tri(2.0, 2.0), m], [0, 0], 32), 8);
        assert_eq!(q.flipped_triangles, 1);
        // Twice the density's area.
        let big = [[2.0, 2.0], [2.0 + 5.657, 2.0], [2.0, 2.0 + 5.657]].map(|p| [p[0] / 32.0, p[1] / 32.0]);
        let q = inspect(&mesh, &atlas([big, tri(20.0, 20.0)], [0, 1], 32), 8);
        assert!((q.max_chart_distortion - 2.0).abs() < 0.01, "{q:?}");
    }
}
