//! Light extraction: an equirectangular environment map becomes a set of distant area lights.
//!
//! References:
//! * Kim & Hong (the seed paper of this baker): the environment is resampled into a cube map
//!   whose texels (one level of its mip chain) are used as directional lights —
//!   [`LightMode::Cube`]. Here every equirect (sub)pixel's energy is assigned to the cube texel
//!   its direction falls in, so no energy is lost or double counted by resampling.
//! * P. Debevec, "A Median Cut Algorithm for Light Probe Sampling", SIGGRAPH 2005 poster:
//!   recursively split the equirect image, in solid-angle-weighted luminance, into regions that
//!   become one light each at their energy centroid — [`LightMode::Budget`].
//! * K. Viriyothai & P. Debevec, "Variance Minimization Light Probe Sampling", SIGGRAPH 2009
//!   poster: choose each cut to minimise the summed energy-weighted angular variance of the two
//!   halves instead of halving the energy. Cutting at the energy median puts the cut through a
//!   bright sun; the variance-minimising cut runs along the sun's edge instead.
//!
//! # Budget mode in detail
//! Regions are rectangles of a working grid (the map itself; nearest-upsampled when the map is
//! coarse for the budget, block-downsampled above 2²¹ cells so the tables stay small). A summed
//! area table of `w = max(lum, 0)·Ω` and `w·d` gives, for any rectangle, its energy `E`, its
//! centroid and its energy-weighted angular variance `σ² = 1 − |Σ w d|²/E²` (rad²) in O(1).
//! Regions are refined greedily, the one with the largest error first, until `K` regions hold
//! energy. The error of standing for a region with one light is `E · max(σ², Ω/6)`: its energy
//! times the larger of its true angular variance and the variance the light appears to have
//! when its energy is spread uniformly over the region's solid angle Ω (a square has Ω = 6σ²).
//! * A region whose border strips are dark (mean luminance ≤ 5 % of the region's, at most 2 %
//!   of its energy per side, together ≥ 20 % of its solid angle on one side) is first *trimmed*
//!   there, so a light never claims a large dark solid angle (a sun's light shrinks to the sun,
//!   the sky's lights stop at a black ground). Trims that split off a region without any energy
//!   cost no light and are made even once the budget is spent.
//! * A region that is *point-like* — its energy lies within an RMS radius
//!   `σ ≤ 0.25 · √(4π/K)`, a quarter of the mean light spacing — and *tight* (`Ω ≤ 24 σ²`, i.e.
//!   its energy fills its solid angle rather than sitting in a corner of it) is final: splitting
//!   it would not change the lighting but would take lights from elsewhere. This is what keeps
//!   a tiny sun 10⁴–10⁵× brighter than the sky as one small, bright light, while a sun inside a
//!   bright glow is still carved out of the glow.
//! * Any other region is cut, along whichever axis and at whichever cell boundary minimises the
//!   children's summed `E·σ²` (Viriyothai & Debevec).
//!
//! Regions never get smaller than one grid cell; a budget larger than the map can resolve
//! yields fewer lights (the `LightSet` says so in `notes`).
//!
//! The cut seam in longitude is placed at the darkest column boundary, so a sun on the map's
//! seam is not split by it. Afterwards one pass over the map sums every region's exact RGB
//! energy (f64) and luminance centroid; each light's radiance is energy / solid angle of its
//! region, so `Σ L Ω` equals the map's integral up to f32 rounding.

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::f64::consts::PI;

use super::{EnvironmentMap, Light, LightMode, LightSet, cos_diff, normalize3, rotate_direction};
use crate::colour::luminance;

/// Grid cells at most, for the budget mode's tables (≈ 2 M cells: 64 MiB of f64 sums).
const MAX_GRID_CELLS: usize = 1 << 21;
/// Fine samples at most for the cube mode when it has to upsample a coarse map.
const MAX_CUBE_SAMPLES: usize = 1 << 25;
/// Cube mode: fine rows per cube texel row: even a corner texel gets ~100 samples, so a constant
/// map gives every texel its radiance to ≈6 %.
const CUBE_ROWS_PER_TEXEL: usize = 32;
/// Budget mode: a region is point-like below `KAPPA · √(4π/K)` RMS radius.
const KAPPA: f64 = 0.25;
/// A point-like region is final only if it is tight: `Ω ≤ TIGHT_TAU · σ²` (a uniform square
/// has Ω = 6σ², a disc 2πσ²); a sun inside a much larger region of glow is not.
const TIGHT_TAU: f64 = 24.0;
/// Trim: a border strip is dark if its mean luminance is ≤ `TRIM_ALPHA` × the region's.
const TRIM_ALPHA: f64 = 0.05;
/// Trim: at most this fraction of the region's energy is cut off on one side.
const TRIM_BETA: f64 = 0.02;
/// Trim: only when the dark margin on one side is at least this fraction of the solid angle.
const TRIM_GAMMA: f64 = 0.2;

impl LightSet {
    /// Turns `map` into distant lights.
    ///
    /// * `mode`: [`LightMode::Cube`] (6·N² cube texel lights) or [`LightMode::Budget`] (at most
    ///   K lights where the energy is); see the file documentation for the methods.
    /// * `rotation_deg`: the environment rotation about +Y in degrees, `d_world = R_y · d_map`
    ///   (see [`super::rotation_matrix`]); it rotates the light directions exactly (the image is
    ///   not resampled, so the light set is a rigid rotation of the unrotated one).
    /// * `intensity`: multiplies all radiance (and `map_integral`).
    ///
    /// Lights with zero energy are left out and counted in `dropped`. `Σ L_k Ω_k` over the kept
    /// lights equals the map's integral × intensity to ≈1e-7 relative per channel (f32 rounding).
    /// Directions are unit vectors in glTF world space; solid angles are in steradians. A light
    /// whose energy has no preferred direction (one light for a uniform sphere) points up (+Y).
    ///
    /// The map should be non-negative (loaded maps are); negative values count towards energy
    /// but not towards the luminance weights that place directions and cuts.
    ///
    /// # Panics
    /// If `intensity` is negative or not finite, `rotation_deg` is not finite, the map is empty
    /// or its texel count does not match its size, or the mode has N = 0 / K = 0.
    pub fn extract(map: &EnvironmentMap, mode: LightMode, rotation_deg: f32, intensity: f32) -> LightSet {
        assert!(
            intensity.is_finite() && intensity >= 0.0,
            "environment intensity must be finite and ≥ 0, got {intensity}"
        );
        assert!(rotation_deg.is_finite(), "environment rotation must be finite");
        assert!(
            map.width > 0 && map.height > 0 && map.texels.len() == map.width as usize * map.height as usize,
            "environment map size {}×{} does not match its {} texels",
            map.width,
            map.height,
            map.texels.len()
        );
        let (accs, mut notes) = match mode {
            LightMode::Cube { face_size } => {
                assert!(face_size > 0, "cube face size must be ≥ 1");
                cube_lights(map, face_size as usize)
            }
            LightMode::Budget { count } => {
                assert!(count > 0, "light budget must be ≥ 1");
                budget_lights(map, count as usize)
            }
        };
        let intensity = intensity as f64;
        let rotation = rotation_deg as f64;
        let mut lights = Vec::with_capacity(accs.len());
        let mut dropped = 0usize;
        let mut captured = [0.0f64; 3];
        for acc in &accs {
            let omega = acc.omega as f32;
            let radiance = acc.e.map(|e| (e * intensity / omega as f64).clamp(f32::MIN as f64, f32::MAX as f64) as f32);
            if radiance == [0.0; 3] || omega.is_nan() || omega <= 0.0 {
                dropped += 1;
                continue;
            }
            let wd_len = (acc.wd[0].powi(2) + acc.wd[1].powi(2) + acc.wd[2].powi(2)).sqrt();
            let dir = if acc.w > 0.0 && wd_len > 1e-9 * acc.w { normalize3(acc.wd) } else { acc.fallback };
            let d = normalize3(rotate_direction(dir, rotation));
            for c in 0..3 {
                captured[c] += radiance[c] as f64 * omega as f64;
            }
            lights.push(Light { direction: d.map(|v| v as f32), solid_angle: omega, radiance });
        }
        let integral = map.integral();
        let map_integral = integral.map(|v| v * intensity);
        if let LightMode::Budget { count } = mode
            && lights.len() < count as usize
            && intensity > 0.0
        {
            notes.push(format!(
                "light budget {count}: the map yields only {} lights with energy ({} regions \
                 without energy dropped); its energy is concentrated in fewer, smaller areas \
                 than the budget could resolve",
                lights.len(),
                dropped
            ));
        }
        if intensity > 0.0 && integral.iter().all(|&v| v == 0.0) {
            notes.push("the environment is black: no lights".into());
        }
        LightSet { lights, mode, map_integral, captured, dropped, notes }
    }
}

/// What one light gathered, before intensity and rotation.
#[derive(Clone, Copy, Debug, Default)]
struct Acc {
    /// RGB energy Σ L Ω (radiance × sr).
    e: [f64; 3],
    /// Luminance-weighted direction sum Σ max(lum,0) Ω d.
    wd: [f64; 3],
    /// Σ max(lum,0) Ω.
    w: f64,
    /// Solid angle of the light's patch, sr.
    omega: f64,
    /// Direction when there is no luminance to weight by: the patch's geometric centre.
    fallback: [f64; 3],
}

impl Acc {
    #[inline]
    fn add(&mut self, e: [f64; 3], w: f64, d: [f64; 3]) {
        for c in 0..3 {
            self.e[c] += e[c];
            self.wd[c] += w * d[c];
        }
        self.w += w;
    }
}

/// The map nearest-upsampled by `ux`×`uy`: "fine samples" with exact sub-pixel solid angles
/// (equal Δφ columns, equal Δθ rows, so each row keeps the `(2π/W)(cos θ_top − cos θ_bottom)`
/// formula and a pixel's sub-samples sum exactly to the pixel's solid angle).
struct Fine<'a> {
    map: &'a EnvironmentMap,
    ux: usize,
    uy: usize,
    wf: usize,
    hf: usize,
    /// (cos φ, sin φ) of each fine column centre.
    cols: Vec<(f64, f64)>,
    /// (sin θ, cos θ) of each fine row centre and the solid angle of one fine sample there.
    rows: Vec<(f64, f64, f64)>,
}

impl<'a> Fine<'a> {
    fn new(map: &'a EnvironmentMap, ux: usize, uy: usize) -> Self {
        let wf = map.width as usize * ux;
        let hf = map.height as usize * uy;
        let cols = (0..wf)
            .map(|fc| {
                let phi = ((fc as f64 + 0.5) / wf as f64 - 0.5) * 2.0 * PI;
                (phi.cos(), phi.sin())
            })
            .collect();
        let dphi = 2.0 * PI / wf as f64;
        let rows = (0..hf)
            .map(|fr| {
                let theta = (fr as f64 + 0.5) / hf as f64 * PI;
                let a = fr as f64 * PI / hf as f64;
                let b = (fr as f64 + 1.0) * PI / hf as f64;
                (theta.sin(), theta.cos(), dphi * cos_diff(a, b))
            })
            .collect();
        Fine { map, ux, uy, wf, hf, cols, rows }
    }

    /// Calls `f(fine_row, fine_col, radiance, energy L·Ω, weight max(lum,0)·Ω, direction)` for
    /// every fine sample with non-zero radiance, row by row.
    #[inline]
    fn for_each_lit(&self, mut f: impl FnMut(usize, usize, [f64; 3], f64, [f64; 3])) {
        let w = self.map.width as usize;
        for fr in 0..self.hf {
            let r = fr / self.uy;
            let (st, ct, om) = self.rows[fr];
            let texels = &self.map.texels[r * w..(r + 1) * w];
            for (c, &l) in texels.iter().enumerate() {
                if l == [0.0; 3] {
                    continue;
                }
                // Not `l.map`: an array map called per sample is not inlined without LTO.
                let e = [l[0] as f64 * om, l[1] as f64 * om, l[2] as f64 * om];
                let lw = luminance(l).max(0.0) * om;
                for fc in c * self.ux..(c + 1) * self.ux {
                    let (cp, sp) = self.cols[fc];
                    f(fr, fc, e, lw, [st * cp, ct, st * sp]);
                }
            }
        }
    }
}

/// Upsampling multipliers that make fine samples roughly square for any map aspect
/// (1×1 maps: 2×1).
fn aspect_factors(map: &EnvironmentMap) -> (usize, usize) {
    let (w, h) = (map.width as f64, map.height as f64);
    let ax = ((2.0 * h / w).round() as usize).max(1);
    let ay = ((w / (2.0 * h)).round() as usize).max(1);
    (ax, ay)
}

// ---------------------------------------------------------------------------------------------
// Cube mode

/// Cube face order: +X, −X, +Y, −Y, +Z, −Z. Face coordinates (sc, tc) ∈ [−1, 1]² follow the
/// OpenGL cube map convention; texel (i, j) of face f is light `f·N² + j·N + i`.
#[inline]
fn cube_texel(d: [f64; 3], n: usize) -> usize {
    let [x, y, z] = d;
    let (ax, ay, az) = (x.abs(), y.abs(), z.abs());
    let (face, sc, tc, ma) = if ax >= ay && ax >= az {
        if x > 0.0 { (0, -z, -y, ax) } else { (1, z, -y, ax) }
    } else if ay >= az {
        if y > 0.0 { (2, x, z, ay) } else { (3, x, -z, ay) }
    } else if z > 0.0 {
        (4, x, -y, az)
    } else {
        (5, -x, -y, az)
    };
    let nf = n as f64;
    let i = (((sc / ma + 1.0) * 0.5 * nf) as usize).min(n - 1);
    let j = (((tc / ma + 1.0) * 0.5 * nf) as usize).min(n - 1);
    face * n * n + j * n + i
}

/// The (unnormalised) direction of face coordinates (sc, tc) on `face`.
fn cube_dir(face: usize, sc: f64, tc: f64) -> [f64; 3] {
    match face {
        0 => [1.0, -tc, -sc],
        1 => [-1.0, -tc, sc],
        2 => [sc, 1.0, tc],
        3 => [sc, -1.0, -tc],
        4 => [sc, -tc, 1.0],
        _ => [-sc, -tc, -1.0],
    }
}

/// Exact solid angle of the face rectangle [x0,x1]×[y0,y1] (face coordinates): sum of the
/// corner terms `atan2(x y, √(x² + y² + 1))`.
fn cube_rect_solid_angle(x0: f64, x1: f64, y0: f64, y1: f64) -> f64 {
    let a = |x: f64, y: f64| (x * y).atan2((x * x + y * y + 1.0).sqrt());
    a(x1, y1) - a(x0, y1) - a(x1, y0) + a(x0, y0)
}

fn cube_lights(map: &EnvironmentMap, n: usize) -> (Vec<Acc>, Vec<String>) {
    let (ax, ay) = aspect_factors(map);
    let (w, h) = (map.width as usize, map.height as usize);
    let base = w * ax * h * ay;
    let want = (CUBE_ROWS_PER_TEXEL * n).div_ceil(h * ay).max(1);
    let cap = ((MAX_CUBE_SAMPLES / base) as f64).sqrt().floor().max(1.0) as usize;
    let s = want.min(cap);
    let fine = Fine::new(map, ax * s, ay * s);

    let mut accs = vec![Acc::default(); 6 * n * n];
    for (f, face) in accs.chunks_exact_mut(n * n).enumerate() {
        for j in 0..n {
            for i in 0..n {
                let x0 = -1.0 + 2.0 * i as f64 / n as f64;
                let x1 = -1.0 + 2.0 * (i + 1) as f64 / n as f64;
                let y0 = -1.0 + 2.0 * j as f64 / n as f64;
                let y1 = -1.0 + 2.0 * (j + 1) as f64 / n as f64;
                let a = &mut face[j * n + i];
                a.omega = cube_rect_solid_angle(x0, x1, y0, y1);
                a.fallback = normalize3(cube_dir(f, 0.5 * (x0 + x1), 0.5 * (y0 + y1)));
            }
        }
    }
    fine.for_each_lit(|_, _, e, lw, d| accs[cube_texel(d, n)].add(e, lw, d));
    let mut notes = Vec::new();
    if s < want {
        notes.push(format!(
            "cube:{n}: the map is coarse for this cube; sampled it {}×{} per pixel (capped), so \
             some small texels may get no energy",
            ax * s,
            ay * s
        ));
    }
    (accs, notes)
}

// ---------------------------------------------------------------------------------------------
// Budget mode

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Rect {
    x0: u32,
    x1: u32,
    y0: u32,
    y1: u32,
}

impl Rect {
    fn cells(&self) -> u64 {
        (self.x1 - self.x0) as u64 * (self.y1 - self.y0) as u64
    }
}

#[derive(Clone, Copy, Debug, Default)]
struct Stats {
    /// Σ w (luminance energy).
    e: f64,
    /// Σ w d.
    s: [f64; 3],
    /// Number of fine samples with non-zero radiance (exact, integer).
    nz: u32,
}

impl Stats {
    fn minus(&self, o: &Stats) -> Stats {
        Stats {
            e: self.e - o.e,
            s: [self.s[0] - o.s[0], self.s[1] - o.s[1], self.s[2] - o.s[2]],
            nz: self.nz.wrapping_sub(o.nz),
        }
    }
    /// `|Σ w d|² / Σ w`: the part of the energy that is "coherent"; E − this = E·σ².
    fn coherent(&self) -> f64 {
        if self.nz == 0 || self.e <= 0.0 {
            0.0
        } else {
            (self.s[0] * self.s[0] + self.s[1] * self.s[1] + self.s[2] * self.s[2]) / self.e
        }
    }
    /// Energy-weighted angular variance σ² (rad² for small regions), in [0, 1].
    fn sigma2(&self) -> f64 {
        if self.e <= 0.0 { 0.0 } else { (1.0 - self.coherent() / self.e).clamp(0.0, 1.0) }
    }
}

/// The working grid with summed-area tables.
struct Grid {
    wg: usize,
    /// Longitude of cell column boundaries, radians from the seam (len wg+1).
    phi_b: Vec<f64>,
    /// Polar angle of cell row boundaries (len hg+1).
    theta_b: Vec<f64>,
    /// Longitude of the seam (grid column 0's left edge) in map φ.
    phi_seam: f64,
    /// Inclusive prefix sums of [w, w dx, w dy, w dz], (wg+1)×(hg+1).
    sat: Vec<[f64; 4]>,
    /// Prefix counts of non-zero fine samples, (wg+1)×(hg+1), wrapping arithmetic.
    nz: Vec<u32>,
    /// Fine column (unshifted) → grid column.
    fc_to_gx: Vec<u32>,
    /// Fine row → grid row.
    fr_to_gy: Vec<u32>,
}

/// `n_cells` boundaries spread evenly over `n_fine` fine units: `[floor(j·n_fine/n_cells)]`.
fn boundaries(n_fine: usize, n_cells: usize) -> Vec<usize> {
    (0..=n_cells).map(|j| j * n_fine / n_cells).collect()
}

fn lookup(bounds: &[usize]) -> Vec<u32> {
    let mut out = Vec::with_capacity(*bounds.last().unwrap());
    for j in 0..bounds.len() - 1 {
        out.extend(std::iter::repeat_n(j as u32, bounds[j + 1] - bounds[j]));
    }
    out
}

impl Grid {
    fn build(fine: &Fine, wg: usize, hg: usize) -> Grid {
        let map = fine.map;
        let (w, h) = (map.width as usize, map.height as usize);
        // Seam: the column boundary whose two neighbouring columns hold the least energy.
        let mut col_e = vec![0.0f64; w];
        for r in 0..h {
            let om = map.row_solid_angle(r as u32);
            for (c, &l) in map.texels[r * w..(r + 1) * w].iter().enumerate() {
                col_e[c] += luminance(l).max(0.0) * om;
            }
        }
        let seam = (0..w)
            .min_by(|&a, &b| {
                let ea = col_e[a] + col_e[(a + w - 1) % w];
                let eb = col_e[b] + col_e[(b + w - 1) % w];
                ea.total_cmp(&eb)
            })
            .unwrap_or(0);
        let shift = seam * fine.ux;
        let col_b = boundaries(fine.wf, wg);
        let row_b = boundaries(fine.hf, hg);
        let gx_of_shifted = lookup(&col_b);
        let fc_to_gx: Vec<u32> = (0..fine.wf).map(|fc| gx_of_shifted[(fc + fine.wf - shift) % fine.wf]).collect();
        let fr_to_gy = lookup(&row_b);
        let phi_b = col_b.iter().map(|&b| b as f64 * 2.0 * PI / fine.wf as f64).collect();
        let theta_b = row_b.iter().map(|&b| b as f64 * PI / fine.hf as f64).collect();
        let phi_seam = (shift as f64 / fine.wf as f64 - 0.5) * 2.0 * PI;

        let stride = wg + 1;
        let mut sat = vec![[0.0f64; 4]; stride * (hg + 1)];
        let mut nz = vec![0u32; stride * (hg + 1)];
        fine.for_each_lit(|fr, fc, _e, lw, d| {
            let k = (fr_to_gy[fr] as usize + 1) * stride + fc_to_gx[fc] as usize + 1;
            let cell = &mut sat[k];
            cell[0] += lw;
            cell[1] += lw * d[0];
            cell[2] += lw * d[1];
            cell[3] += lw * d[2];
            nz[k] = nz[k].wrapping_add(1);
        });
        for y in 1..=hg {
            for x in 1..=wg {
                let (l, u, ul) = (y * stride + x - 1, (y - 1) * stride + x, (y - 1) * stride + x - 1);
                let k = y * stride + x;
                let (left, up, upleft) = (sat[l], sat[u], sat[ul]);
                for (c, v) in sat[k].iter_mut().enumerate() {
                    *v += left[c] + up[c] - upleft[c];
                }
                nz[k] = nz[k].wrapping_add(nz[l]).wrapping_add(nz[u]).wrapping_sub(nz[ul]);
            }
        }
        Grid { wg, phi_b, theta_b, phi_seam, sat, nz, fc_to_gx, fr_to_gy }
    }

    fn stats(&self, r: &Rect) -> Stats {
        let stride = self.wg + 1;
        let i = |x: u32, y: u32| y as usize * stride + x as usize;
        let (a, b, c, d) = (i(r.x1, r.y1), i(r.x0, r.y1), i(r.x1, r.y0), i(r.x0, r.y0));
        let v = |k: usize| self.sat[a][k] - self.sat[b][k] - self.sat[c][k] + self.sat[d][k];
        let nz = self.nz[a].wrapping_sub(self.nz[b]).wrapping_sub(self.nz[c]).wrapping_add(self.nz[d]);
        if nz == 0 {
            return Stats::default();
        }
        Stats { e: v(0).max(0.0), s: [v(1), v(2), v(3)], nz }
    }

    fn omega(&self, r: &Rect) -> f64 {
        (self.phi_b[r.x1 as usize] - self.phi_b[r.x0 as usize])
            * cos_diff(self.theta_b[r.y0 as usize], self.theta_b[r.y1 as usize])
    }

    /// The solid-angle centroid of a rectangle (map space, normalised; +Y if degenerate).
    fn geometric_centre(&self, r: &Rect) -> [f64; 3] {
        let p0 = self.phi_b[r.x0 as usize] + self.phi_seam;
        let p1 = self.phi_b[r.x1 as usize] + self.phi_seam;
        let t0 = self.theta_b[r.y0 as usize];
        let t1 = self.theta_b[r.y1 as usize];
        // ∫∫ d sinθ dθ dφ over the rectangle.
        let s2 = |t: f64| t / 2.0 - (2.0 * t).sin() / 4.0; // ∫ sin²θ
        let sc = |t: f64| t.sin().powi(2) / 2.0; // ∫ sinθ cosθ
        let i_sin2 = s2(t1) - s2(t0);
        let x = (p1.sin() - p0.sin()) * i_sin2;
        let z = (p0.cos() - p1.cos()) * i_sin2;
        let y = (p1 - p0) * (sc(t1) - sc(t0));
        let v = [x, y, z];
        let len = (x * x + y * y + z * z).sqrt();
        if len > 1e-9 * self.omega(r).max(1e-300) { normalize3(v) } else { [0.0, 1.0, 0.0] }
    }

    /// Strip `k` (0-based, counted inward) of `r` along `side`: 0 left, 1 right, 2 top, 3 bottom.
    fn strip(r: &Rect, side: u8, k: u32) -> Rect {
        match side {
            0 => Rect { x0: r.x0 + k, x1: r.x0 + k + 1, ..*r },
            1 => Rect { x0: r.x1 - k - 1, x1: r.x1 - k, ..*r },
            2 => Rect { y0: r.y0 + k, y1: r.y0 + k + 1, ..*r },
            _ => Rect { y0: r.y1 - k - 1, y1: r.y1 - k, ..*r },
        }
    }

    /// A cut that separates a dark border margin from `r`, if there is a worthwhile one.
    fn find_trim(&self, r: &Rect, st: &Stats, omega: f64) -> Option<Cut> {
        if st.e <= 0.0 || omega <= 0.0 {
            return None;
        }
        let mean = st.e / omega;
        let mut best: Option<(f64, Cut)> = None;
        for side in 0..4u8 {
            let len = if side < 2 { r.x1 - r.x0 } else { r.y1 - r.y0 };
            let mut k = 0;
            let mut cum = 0.0;
            while k + 1 < len {
                let s = Self::strip(r, side, k);
                let se = self.stats(&s).e;
                let so = self.omega(&s);
                if se > TRIM_ALPHA * mean * so || cum + se > TRIM_BETA * st.e {
                    break;
                }
                cum += se;
                k += 1;
            }
            if k == 0 {
                continue;
            }
            let (margin, cut) = match side {
                0 => (Rect { x1: r.x0 + k, ..*r }, Cut { vertical: true, at: r.x0 + k }),
                1 => (Rect { x0: r.x1 - k, ..*r }, Cut { vertical: true, at: r.x1 - k }),
                2 => (Rect { y1: r.y0 + k, ..*r }, Cut { vertical: false, at: r.y0 + k }),
                _ => (Rect { y0: r.y1 - k, ..*r }, Cut { vertical: false, at: r.y1 - k }),
            };
            let mo = self.omega(&margin);
            if mo >= TRIM_GAMMA * omega && best.is_none_or(|(b, _)| mo > b) {
                best = Some((mo, cut));
            }
        }
        best.map(|(_, c)| c)
    }

    /// The cut minimising the children's summed `E·σ²`, if it reduces it at all.
    fn variance_cut(&self, r: &Rect, st: &Stats) -> Option<Cut> {
        let base = st.coherent();
        let mut best: Option<(f64, Cut)> = None;
        let mut consider = |a: Stats, cut: Cut| {
            let b = st.minus(&a);
            let q = a.coherent() + if b.e > 0.0 { b.coherent() } else { 0.0 };
            if best.is_none_or(|(bq, _)| q > bq) {
                best = Some((q, cut));
            }
        };
        for x in r.x0 + 1..r.x1 {
            let a = self.stats(&Rect { x1: x, ..*r });
            consider(a, Cut { vertical: true, at: x });
        }
        for y in r.y0 + 1..r.y1 {
            let a = self.stats(&Rect { y1: y, ..*r });
            consider(a, Cut { vertical: false, at: y });
        }
        match best {
            Some((q, cut)) if q - base > 1e-14 * st.e => Some(cut),
            _ => None,
        }
    }
}

/// A cut of a rectangle at grid column (`vertical`) or row boundary `at`.
#[derive(Clone, Copy, Debug)]
struct Cut {
    vertical: bool,
    at: u32,
}

impl Cut {
    fn apply(&self, r: &Rect) -> (Rect, Rect) {
        if self.vertical {
            (Rect { x1: self.at, ..*r }, Rect { x0: self.at, ..*r })
        } else {
            (Rect { y1: self.at, ..*r }, Rect { y0: self.at, ..*r })
        }
    }
}

#[derive(Clone, Copy, Debug)]
enum Action {
    /// Leave as one light.
    Final,
    /// Cut here (a dark-margin trim, or the variance cut of a point-like region).
    Cut(Cut),
    /// Find the variance-minimising cut when popped.
    Split,
}

struct Node {
    rect: Rect,
    nonempty: bool,
    priority: f64,
    action: Action,
}

fn evaluate(grid: &Grid, rect: Rect, floor2: f64) -> Node {
    let st = grid.stats(&rect);
    let node = |priority, action| Node { rect, nonempty: st.nz > 0, priority, action };
    if st.nz == 0 || st.e <= 0.0 || rect.cells() <= 1 {
        return node(0.0, Action::Final);
    }
    let omega = grid.omega(&rect);
    let sigma2 = st.sigma2();
    // The error of standing for this region with one light: its energy times the larger of
    // its true angular variance and the variance the light appears to have (uniform over Ω).
    let priority = st.e * sigma2.max(omega / 6.0);
    if let Some(cut) = grid.find_trim(&rect, &st, omega) {
        return node(priority, Action::Cut(cut));
    }
    if sigma2 <= floor2 && omega <= TIGHT_TAU * sigma2 {
        // Point-like and tight: a compact source (a sun, a lamp) that one light describes.
        return node(0.0, Action::Final);
    }
    node(priority, Action::Split)
}

fn budget_lights(map: &EnvironmentMap, k: usize) -> (Vec<Acc>, Vec<String>) {
    let (ax, ay) = aspect_factors(map);
    let (w, h) = (map.width as usize, map.height as usize);
    let floor = KAPPA * (4.0 * PI / k as f64).sqrt();
    let base = w * ax * h * ay;
    let (fine, wg, hg) = if base > MAX_GRID_CELLS {
        // Large map: cells are blocks of pixels.
        let fine = Fine::new(map, ax, ay);
        let b = (base as f64 / MAX_GRID_CELLS as f64).sqrt().ceil() as usize;
        let (wg, hg) = (fine.wf.div_ceil(b), fine.hf.div_ceil(b));
        (fine, wg, hg)
    } else {
        // Cells are pixels, or sub-pixels when the map is coarse for the budget: a cell at most
        // half the point-like radius tall.
        let want = ((PI / (h * ay) as f64) / (0.5 * floor)).ceil().max(1.0) as usize;
        let cap = ((MAX_GRID_CELLS / base) as f64).sqrt().floor().max(1.0) as usize;
        let s = want.min(cap);
        let fine = Fine::new(map, ax * s, ay * s);
        let (wg, hg) = (fine.wf, fine.hf);
        (fine, wg, hg)
    };
    let grid = Grid::build(&fine, wg, hg);

    let floor2 = floor * floor;
    let mut nodes: Vec<Node> = Vec::new();
    let mut heap: BinaryHeap<(OrdF64, Reverse<usize>)> = BinaryHeap::new();
    let mut finals: Vec<usize> = Vec::new();
    let push = |node: Node, nodes: &mut Vec<Node>, heap: &mut BinaryHeap<_>, finals: &mut Vec<usize>| {
        let id = nodes.len();
        match node.action {
            Action::Final => finals.push(id),
            _ => heap.push((OrdF64(node.priority), Reverse(id))),
        }
        nodes.push(node);
    };
    let root = evaluate(&grid, Rect { x0: 0, x1: wg as u32, y0: 0, y1: hg as u32 }, floor2);
    let mut count = root.nonempty as usize;
    debug_assert!(count <= k);
    push(root, &mut nodes, &mut heap, &mut finals);
    // Refine the worst region first. Once the budget is spent, only cuts that split off a
    // region without energy (trimming black margins) are still made: they cost no light.
    while let Some((_, Reverse(id))) = heap.pop() {
        let rect = nodes[id].rect;
        let full = count >= k;
        let cut = match nodes[id].action {
            Action::Cut(c) => Some(c),
            Action::Split if !full => grid.variance_cut(&rect, &grid.stats(&rect)),
            Action::Split => None,
            Action::Final => unreachable!("final regions are never queued"),
        };
        let Some(cut) = cut else {
            finals.push(id);
            continue;
        };
        let (a, b) = cut.apply(&rect);
        let lit = |r: &Rect| (grid.stats(r).nz > 0) as usize;
        let after = count + lit(&a) + lit(&b) - 1;
        if after > k {
            finals.push(id);
            continue;
        }
        count = after;
        push(evaluate(&grid, a, floor2), &mut nodes, &mut heap, &mut finals);
        push(evaluate(&grid, b, floor2), &mut nodes, &mut heap, &mut finals);
    }
    finals.sort_unstable();

    // Exact pass: every fine sample's energy goes to the region holding its cell.
    let mut region_of = vec![0u32; wg * hg];
    let mut accs = Vec::with_capacity(finals.len());
    for (i, &id) in finals.iter().enumerate() {
        let r = nodes[id].rect;
        for y in r.y0..r.y1 {
            let row = y as usize * wg;
            region_of[row + r.x0 as usize..row + r.x1 as usize].fill(i as u32);
        }
        accs.push(Acc { omega: grid.omega(&r), fallback: grid.geometric_centre(&r), ..Acc::default() });
    }
    fine.for_each_lit(|fr, fc, e, lw, d| {
        let cell = grid.fr_to_gy[fr] as usize * wg + grid.fc_to_gx[fc] as usize;
        accs[region_of[cell] as usize].add(e, lw, d);
    });
    (accs, Vec::new())
}

/// f64 ordered by `total_cmp`, for the priority queue.
#[derive(Clone, Copy, Debug, PartialEq)]
struct OrdF64(f64);
impl Eq for OrdF64 {}
impl PartialOrd for OrdF64 {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for OrdF64 {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&other.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cube_texel_solid_angles_sum_to_four_pi() {
        for n in [1usize, 3, 16] {
            let mut sum = 0.0;
            for j in 0..n {
                for i in 0..n {
                    let x0 = -1.0 + 2.0 * i as f64 / n as f64;
                    let x1 = -1.0 + 2.0 * (i + 1) as f64 / n as f64;
                    let y0 = -1.0 + 2.0 * j as f64 / n as f64;
                    let y1 = -1.0 + 2.0 * (j + 1) as f64 / n as f64;
                    sum += 6.0 * cube_rect_solid_angle(x0, x1, y0, y1);
                }
            }
            assert!((sum - 4.0 * PI).abs() < 1e-12, "n={n}: {sum}");
        }
    }

    #[test]
    fn cube_texel_of_texel_centre_is_that_texel() {
        let n = 5;
        for f in 0..6 {
            for j in 0..n {
                for i in 0..n {
                    let sc = -1.0 + (2 * i + 1) as f64 / n as f64;
                    let tc = -1.0 + (2 * j + 1) as f64 / n as f64;
                    let d = normalize3(cube_dir(f, sc, tc));
                    assert_eq!(cube_texel(d, n), f * n * n + j * n + i);
                }
            }
        }
    }

    #[test]
    fn geometric_centre_of_polar_cap_is_the_pole() {
        let map = EnvironmentMap::from_fn(16, 8, |_| [1.0; 3]);
        let fine = Fine::new(&map, 1, 1);
        let grid = Grid::build(&fine, 16, 8);
        let c = grid.geometric_centre(&Rect { x0: 0, x1: 16, y0: 0, y1: 2 });
        assert!((c[1] - 1.0).abs() < 1e-9, "{c:?}");
        // A quarter wedge around the seam offset still points to the right longitude.
        let r = Rect { x0: 0, x1: 1, y0: 3, y1: 5 };
        let c = grid.geometric_centre(&r);
        let phi = c[2].atan2(c[0]);
        let expect = grid.phi_seam + 0.5 * (grid.phi_b[0] + grid.phi_b[1]);
        let diff = (phi - expect).rem_euclid(2.0 * PI);
        assert!(diff < 1e-9 || (2.0 * PI - diff) < 1e-9, "{phi} vs {expect}");
    }
}
