//! Environment stage: an equirectangular HDR map (OpenEXR or Radiance `.hdr`) in, a set of
//! distant area lights out.
//!
//! # Conventions (binding for the whole crate)
//!
//! * World space is glTF's: right-handed, +Y up. Directions are unit vectors pointing **from the
//!   scene towards the sky** (the direction light arrives from, reversed).
//! * An [`EnvironmentMap`] holds linear, scene-referred radiance (W·sr⁻¹·m⁻² or any consistent
//!   unit; the baker never assumes an absolute scale) in an equirectangular layout, row 0 at the
//!   zenith (+Y). A unit direction `d` maps to column `u = 0.5 + atan2(d.z, d.x)/(2π)` and
//!   row-from-top `t = acos(d.y)/π` (both as fractions of the image size). The centre of pixel
//!   `(col, row)` of a `W×H` map is `φ = ((col+0.5)/W − 0.5)·2π`, `θ = (row+0.5)/H·π`,
//!   `d = (sin θ cos φ, cos θ, sin θ sin φ)`. So the image centre looks along +X, a quarter
//!   width to its right (`u = 0.75`) looks along +Z, the left/right edges (the seam) along −X.
//! * Pixel row `r` subtends `Ω_r = (2π/W)(cos θ_top − cos θ_bottom)` steradians with
//!   `θ_top = rπ/H`, `θ_bottom = (r+1)π/H`; the whole image sums to exactly 4π.
//! * The map's integral is `Σ_pixels L_p Ω_p` per RGB channel, in f64 (units: radiance × sr).
//! * Radiance is stored as f32 (never f16: captured suns exceed 65 504).
//! * Environment rotation (`--env-rotation DEG`) turns the environment about +Y:
//!   `d_world = R_y(DEG) · d_map` with the usual right-handed matrix
//!   `R_y(a) = [[cos a, 0, sin a], [0, 1, 0], [−sin a, 0, cos a]]`. A positive angle turns the
//!   content counter-clockwise seen from above (looking down −Y); +90° takes the map's +X to
//!   world −Z and the map's +Z to world +X. See [`rotation_matrix`].
//! * Environment intensity (`--env-intensity X`) multiplies all radiance by `X` (≥ 0).
//!
//! # Parts
//!
//! * [`EnvironmentMap::load`] (in `load.rs`) reads and sanitises EXR / Radiance files.
//! * [`LightSet::extract`] (in `lights.rs`) turns a map into lights, either the seed paper's
//!   cube-map texel lights ([`LightMode::Cube`]) or an energy-driven budget
//!   ([`LightMode::Budget`], median-cut family).
//! * [`write_exr`] / [`write_hdr`] (in `write.rs`) write maps, for fixtures and tests.

#![warn(missing_docs)]

mod lights;
mod load;
#[cfg(feature = "internals")]
mod write;

use std::f64::consts::PI;
use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

pub use load::EnvLoadError;
pub(crate) use load::check_exr_size;
#[cfg(feature = "internals")]
pub use write::{ExrPrecision, write_exr, write_hdr};

/// Linear, scene-referred radiance in an equirectangular layout, row 0 at the zenith (+Y).
///
/// See the module documentation for the direction ↔ pixel convention. Maps read from files are
/// always 2:1 (`width == 2·height`) or 1×1; maps built in code ([`EnvironmentMap::from_fn`]) may
/// have any size ≥ 1×1 and every function here treats columns as equal steps of φ over 2π and
/// rows as equal steps of θ over π.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvironmentMap {
    /// Number of columns (steps of longitude φ).
    pub width: u32,
    /// Number of rows (steps of polar angle θ from the zenith).
    pub height: u32,
    /// Row-major linear RGB radiance, `width * height` entries, row 0 at the zenith.
    pub texels: Vec<[f32; 3]>,
}

/// Options for [`EnvironmentMap::load`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EnvLoadOptions {
    /// Non-finite texel values (NaN, ±∞) are an error unless this is set; when set, NaN and −∞
    /// become 0 and +∞ becomes the largest finite value in the map, with a warning notice.
    pub clamp_nonfinite: bool,
}

/// A map read from a file, with the human-readable notices loading produced (layer chosen,
/// negative texels clamped, non-finite values replaced, …). Notices are single lines meant for
/// the user; none of them is an error.
#[derive(Clone, Debug)]
pub struct LoadedEnvironment {
    /// The sanitised map: finite, non-negative radiance.
    pub map: EnvironmentMap,
    /// One line per notice, in the order they arose.
    pub notices: Vec<String>,
}

/// How the map becomes lights (CLI syntax: `cube:N` or a plain integer `K`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LightMode {
    /// The seed paper's scheme (Kim & Hong): every texel of a cube map with `face_size`×`face_size`
    /// texels per face is one light (6·N² lights: N = 32 gives 6144, 16 gives 1536, 8 gives 384,
    /// 4 gives 96). CLI: `cube:N`.
    Cube {
        /// Texels along one edge of a cube face (N ≥ 1).
        face_size: u32,
    },
    /// Energy-driven: at most `count` lights placed where the energy is (variance-minimising
    /// median cut, see `lights.rs`). CLI: the plain integer `K`.
    Budget {
        /// Maximum number of lights (K ≥ 1).
        count: u32,
    },
}

/// Largest accepted cube face size (6·512² ≈ 1.6 M lights).
pub const MAX_CUBE_FACE_SIZE: u32 = 512;
/// Largest accepted light budget.
pub const MAX_LIGHT_BUDGET: u32 = 1 << 20;

impl Default for LightMode {
    /// `Budget { count: 1024 }`.
    ///
    /// Why: the direct-lighting cost of a bake is linear in the number of lights (one visibility
    /// pass each), so the default should be the fewest lights that still resolve a captured
    /// environment. A budget spends them where the energy is: a sun or a lamp becomes one small,
    /// bright light of the right size, windows and bright sky get many lights, dark ground few.
    /// 1024 lights leave a typical light ≈ 6° across (√(4π/1024) rad), finer than the penumbra
    /// detail a lightmap texel resolves, at two thirds of the cost of the paper's `cube:16`
    /// (1536 lights, which spends as many lights on a black floor as on the sky).
    fn default() -> Self {
        LightMode::Budget { count: 1024 }
    }
}

impl LightMode {
    /// The number of lights this mode asks for: 6·N² for `cube:N`, K for a budget. The light set
    /// may hold fewer (zero-energy lights are dropped; a budget may not be fillable).
    pub fn requested_lights(&self) -> usize {
        match *self {
            LightMode::Cube { face_size } => 6 * (face_size as usize).pow(2),
            LightMode::Budget { count } => count as usize,
        }
    }
}

impl fmt::Display for LightMode {
    /// The CLI spelling: `cube:N` or `K`; it parses back to the same mode.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LightMode::Cube { face_size } => write!(f, "cube:{face_size}"),
            LightMode::Budget { count } => write!(f, "{count}"),
        }
    }
}

/// Why a string is not a [`LightMode`].
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "invalid light mode '{input}': {reason}; expected 'cube:N' (a cube map with N×N texels per \
     face, 6·N² lights, 1 ≤ N ≤ {MAX_CUBE_FACE_SIZE}) or a light budget K (an integer, \
     1 ≤ K ≤ {MAX_LIGHT_BUDGET})"
)]
pub struct LightModeParseError {
    /// The string as given.
    pub input: String,
    /// What is wrong with it.
    pub reason: String,
}

impl FromStr for LightMode {
    type Err = LightModeParseError;

    /// Parses `cube:N` (the prefix is case-insensitive) or a plain positive integer `K`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let err = |reason: &str| LightModeParseError { input: s.to_string(), reason: reason.to_string() };
        let t = s.trim();
        let parse_int = |digits: &str, what: &str, max: u32| -> Result<u32, LightModeParseError> {
            if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
                return Err(err(&format!("{what} is not a whole number")));
            }
            match digits.parse::<u64>() {
                Ok(0) => Err(err(&format!("{what} must be at least 1"))),
                Ok(v) if v <= max as u64 => Ok(v as u32),
                _ => Err(err(&format!("{what} is larger than {max}"))),
            }
        };
        if t.len() >= 5 && t[..5].eq_ignore_ascii_case("cube:") {
            let n = parse_int(&t[5..], "the cube face size", MAX_CUBE_FACE_SIZE)?;
            Ok(LightMode::Cube { face_size: n })
        } else if !t.is_empty() && t.bytes().all(|b| b.is_ascii_digit()) {
            let k = parse_int(t, "the light budget", MAX_LIGHT_BUDGET)?;
            Ok(LightMode::Budget { count: k })
        } else {
            Err(err("not recognised"))
        }
    }
}

impl Serialize for LightMode {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_str(self)
    }
}

impl<'de> Deserialize<'de> for LightMode {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let s = String::deserialize(deserializer)?;
        s.parse().map_err(serde::de::Error::custom)
    }
}

/// One distant light: uniform radiance `radiance` over a cone-like patch of `solid_angle`
/// steradians centred on `direction`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Light {
    /// Unit vector from the scene towards the light, glTF world space (rotation applied). It is
    /// the energy (luminance) centroid of the part of the map the light stands for.
    pub direction: [f32; 3],
    /// Solid angle of the part of the sphere the light stands for, in steradians (> 0).
    pub solid_angle: f32,
    /// Mean linear RGB radiance over that solid angle (intensity applied), so that
    /// `radiance · solid_angle` is the light's energy (irradiance at normal incidence).
    pub radiance: [f32; 3],
}

/// Lights extracted from an environment map by [`LightSet::extract`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LightSet {
    /// The lights with non-zero energy.
    pub lights: Vec<Light>,
    /// The mode they were made with.
    pub mode: LightMode,
    /// The map's integral `Σ L_p Ω_p` per channel, times the intensity (radiance × sr).
    pub map_integral: [f64; 3],
    /// `Σ_k L_k Ω_k` over `lights`, in f64 from the stored f32 values; equals `map_integral`
    /// to about 1e-7 relative.
    pub captured: [f64; 3],
    /// How many lights (cube texels or budget regions) had zero energy and were left out.
    pub dropped: usize,
    /// Human-readable remarks, e.g. why a budget could not be filled. Empty when there is
    /// nothing to say.
    pub notes: Vec<String>,
}

/// The environment rotation as a matrix: `d_world = rotation_matrix(deg) · d_map`
/// (right-handed rotation about +Y; see the module documentation). To look up the map for a
/// world direction, use the transpose.
#[cfg(any(test, feature = "internals"))]
pub fn rotation_matrix(rotation_deg: f32) -> glam::Mat3 {
    glam::Mat3::from_rotation_y((rotation_deg as f64).to_radians() as f32)
}

/// [`rotation_matrix`] in f64, applied to one direction.
pub fn rotate_direction(d: [f64; 3], rotation_deg: f64) -> [f64; 3] {
    let (s, c) = rotation_deg.to_radians().sin_cos();
    [c * d[0] + s * d[2], d[1], -s * d[0] + c * d[2]]
}

/// `cos a − cos b` without cancellation for nearby angles.
pub(crate) fn cos_diff(a: f64, b: f64) -> f64 {
    2.0 * ((a + b) * 0.5).sin() * ((b - a) * 0.5).sin()
}

/// The unit direction for longitude `phi` and polar angle `theta` (radians).
pub(crate) fn dir_from_angles(phi: f64, theta: f64) -> [f64; 3] {
    let (st, ct) = theta.sin_cos();
    let (sp, cp) = phi.sin_cos();
    [st * cp, ct, st * sp]
}

impl EnvironmentMap {
    /// The index and value of the largest channel value of any texel (`None` for an empty map);
    /// NaN is passed over.
    pub fn brightest(&self) -> Option<(usize, f32)> {
        let mut brightest: Option<(usize, f32)> = None;
        for (i, texel) in self.texels.iter().enumerate() {
            for &v in texel {
                // Of equal values the last, as `Iterator::max_by` would give.
                if !v.is_nan() && brightest.is_none_or(|(_, b)| v.total_cmp(&b).is_ge()) {
                    brightest = Some((i, v));
                }
            }
        }
        brightest
    }

    /// Builds a `width×height` map by evaluating `f` at every pixel centre direction (unit
    /// vector, map space). Any size ≥ 1×1 is accepted (files must be 2:1 or 1×1).
    ///
    /// # Panics
    /// If `width` or `height` is zero.
    pub fn from_fn(width: u32, height: u32, f: impl Fn([f32; 3]) -> [f32; 3]) -> Self {
        assert!(width > 0 && height > 0, "an environment map needs at least one pixel");
        let mut texels = Vec::with_capacity(width as usize * height as usize);
        for row in 0..height {
            for col in 0..width {
                texels.push(f(Self::direction_of(width, height, col, row)));
            }
        }
        EnvironmentMap { width, height, texels }
    }

    /// A uniform map (8×4) of `radiance` everywhere; its integral is `4π · radiance`.
    pub fn constant(radiance: [f32; 3]) -> Self {
        EnvironmentMap { width: 8, height: 4, texels: vec![radiance; 32] }
    }

    /// 64×32 map with `radiance` in the upper hemisphere (rows 0..16, y > 0) and black below;
    /// the horizon is a row boundary, so the integral is exactly `2π · radiance`.
    pub fn horizon(radiance: [f32; 3]) -> Self {
        let (w, h) = (64u32, 32u32);
        let mut texels = vec![[0.0f32; 3]; (w * h) as usize];
        for t in &mut texels[..(w * h / 2) as usize] {
            *t = radiance;
        }
        EnvironmentMap { width: w, height: h, texels }
    }

    /// A uniform sky of `sky_radiance` with a disc-shaped sun of radiance
    /// `sky_radiance × sun_radiance_ratio` (per channel) centred on `sun_direction` (map space,
    /// normalised here) with angular radius `sun_angular_radius` **radians**.
    ///
    /// A texel belongs to the sun iff the angle between its centre direction and the sun
    /// direction is ≤ the radius; sun texels hold the sun radiance *instead of* the sky's. The
    /// sun's energy is therefore exactly `ratio · sky · Σ_{sun texels} Ω` (see
    /// [`EnvironmentMap::sun_texels`]), and the integral is `sky · 4π + (ratio − 1) · sky · Ω_sun`.
    /// The resolution is 2H×H with H the smallest power of two ≥ 256 for which a pixel is at
    /// most half the sun radius tall (capped at H = 2048, so radii below ≈ 0.18° cover few
    /// pixels).
    pub fn sun_and_sky(
        sky_radiance: [f32; 3],
        sun_direction: [f32; 3],
        sun_radiance_ratio: f32,
        sun_angular_radius: f32,
    ) -> Self {
        let r = (sun_angular_radius as f64).max(1e-6);
        let mut h = 256u32;
        while h < 2048 && PI / h as f64 > r / 2.0 {
            h *= 2;
        }
        let sun = normalize3(sun_direction.map(|v| v as f64));
        let cos_r = r.cos();
        let sun_l = sky_radiance.map(|v| v * sun_radiance_ratio);
        Self::from_fn(2 * h, h, |d| {
            let c = d[0] as f64 * sun[0] + d[1] as f64 * sun[1] + d[2] as f64 * sun[2];
            if c >= cos_r { sun_l } else { sky_radiance }
        })
    }

    /// The texels `(col, row)` whose centre lies within `angular_radius` radians of
    /// `direction` (the sun of [`EnvironmentMap::sun_and_sky`]).
    pub fn sun_texels(&self, direction: [f32; 3], angular_radius: f32) -> Vec<(u32, u32)> {
        let sun = normalize3(direction.map(|v| v as f64));
        let cos_r = (angular_radius as f64).max(1e-6).cos();
        let mut out = Vec::new();
        for row in 0..self.height {
            for col in 0..self.width {
                let d = self.pixel_direction(col, row);
                let c = d[0] as f64 * sun[0] + d[1] as f64 * sun[1] + d[2] as f64 * sun[2];
                if c >= cos_r {
                    out.push((col, row));
                }
            }
        }
        out
    }

    fn direction_of(width: u32, height: u32, col: u32, row: u32) -> [f32; 3] {
        let phi = ((col as f64 + 0.5) / width as f64 - 0.5) * 2.0 * PI;
        let theta = (row as f64 + 0.5) / height as f64 * PI;
        let [x, y, z] = dir_from_angles(phi, theta);
        [x as f32, y as f32, z as f32]
    }

    /// Unit direction (map space) of the centre of pixel `(col, row)`:
    /// `φ = ((col+0.5)/W − 0.5)·2π`, `θ = (row+0.5)/H·π`, `d = (sin θ cos φ, cos θ, sin θ sin φ)`.
    pub fn pixel_direction(&self, col: u32, row: u32) -> [f32; 3] {
        Self::direction_of(self.width, self.height, col, row)
    }

    /// Solid angle in steradians of one pixel of row `row`:
    /// `(2π/W)(cos(rπ/H) − cos((r+1)π/H))`. Summed over all pixels this is 4π.
    pub fn row_solid_angle(&self, row: u32) -> f64 {
        let h = self.height as f64;
        let a = row as f64 * PI / h;
        let b = (row as f64 + 1.0) * PI / h;
        2.0 * PI / self.width as f64 * cos_diff(a, b)
    }

    /// The pixel `(col, row)` containing direction `d` (map space; need not be normalised).
    /// Inverse of [`EnvironmentMap::pixel_direction`]. A zero or non-finite `d` gives (0, 0).
    pub fn pixel_of(&self, d: [f32; 3]) -> (u32, u32) {
        let d = [d[0] as f64, d[1] as f64, d[2] as f64];
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        if !(len > 0.0 && len.is_finite()) {
            return (0, 0);
        }
        let u = 0.5 + d[2].atan2(d[0]) / (2.0 * PI);
        let t = (d[1] / len).clamp(-1.0, 1.0).acos() / PI;
        let col = ((u * self.width as f64).floor() as i64).rem_euclid(self.width as i64) as u32;
        let row = ((t * self.height as f64).floor() as i64).clamp(0, self.height as i64 - 1) as u32;
        (col, row)
    }

    /// Nearest-pixel radiance in direction `d` (map space; need not be normalised).
    pub fn sample(&self, d: [f32; 3]) -> [f32; 3] {
        let (col, row) = self.pixel_of(d);
        self.texels[row as usize * self.width as usize + col as usize]
    }

    /// The map's integral `Σ_pixels L_p Ω_p` per channel (radiance × sr), computed in f64.
    pub fn integral(&self) -> [f64; 3] {
        let w = self.width as usize;
        let mut total = [0.0f64; 3];
        for (row, texels) in self.texels.chunks_exact(w).enumerate() {
            let mut sum = [0.0f64; 3];
            for t in texels {
                for c in 0..3 {
                    sum[c] += t[c] as f64;
                }
            }
            let omega = self.row_solid_angle(row as u32);
            for c in 0..3 {
                total[c] += sum[c] * omega;
            }
        }
        total
    }

    /// Largest texel channel value.
    pub fn peak(&self) -> f32 {
        self.texels.iter().flat_map(|t| t.iter().copied()).fold(0.0f32, f32::max)
    }
}

pub(crate) fn normalize3(v: [f64; 3]) -> [f64; 3] {
    let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if len > 0.0 && len.is_finite() { v.map(|x| x / len) } else { [0.0, 1.0, 0.0] }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn light_mode_round_trips() {
        for s in ["cube:4", "cube:32", "1", "1024"] {
            let m: LightMode = s.parse().unwrap();
            assert_eq!(m.to_string(), s);
        }
        assert_eq!("CUBE:8".parse::<LightMode>().unwrap(), LightMode::Cube { face_size: 8 });
        for bad in ["", "cube:", "cube:0", "0", "-3", "1.5", "abc", "cube:x", "cube:9999"] {
            assert!(bad.parse::<LightMode>().is_err(), "{bad:?} parsed");
        }
    }

    #[test]
    fn rotation_matrix_matches_rotate_direction() {
        let m = rotation_matrix(90.0);
        let v = m * glam::Vec3::X;
        assert!((v - glam::Vec3::NEG_Z).length() < 1e-6, "{v}");
        let d = rotate_direction([1.0, 0.0, 0.0], 90.0);
        assert!((d[2] + 1.0).abs() < 1e-12 && d[0].abs() < 1e-12);
    }

    #[test]
    fn solid_angles_sum_to_four_pi() {
        let m = EnvironmentMap::from_fn(6, 3, |_| [1.0; 3]);
        let s: f64 = (0..3).map(|r| m.row_solid_angle(r) * 6.0).sum();
        assert!((s - 4.0 * PI).abs() < 1e-12);
    }
}
