//! Environment stage: an equirectangular HDR map (EXR or Radiance .hdr) in,
//! a set of distant area lights out.
//!
//! Conventions (design notes): a unit direction d in glTF world space maps to
//! column u = 0.5 + atan2(d.z, d.x)/(2π) and row-from-top t = acos(d.y)/π.
//! Pixel row r of H rows, width W, has solid angle
//! Ω = (2π/W)(cos θ_top − cos θ_bottom); the image sums to exactly 4π.
//!
//! STUB: the interface below is fixed; the implementation is being written.

use std::path::Path;

/// Linear, scene-referred radiance in an equirectangular layout, row 0 at the zenith.
#[derive(Clone, Debug)]
pub struct EnvironmentMap {
    pub width: u32,
    pub height: u32,
    /// Row-major RGB radiance, `width * height` entries.
    pub texels: Vec<[f32; 3]>,
}

/// How the map becomes lights.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightMode {
    /// The paper's scheme: every texel of a cube map with faces of `face_size`² texels (6·N² lights).
    Cube { face_size: u32 },
}

/// One distant light: radiance `radiance` over solid angle `solid_angle` around `direction`
/// (unit vector from the scene towards the light, glTF world space).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    pub direction: [f32; 3],
    pub solid_angle: f32,
    pub radiance: [f32; 3],
}

#[derive(Clone, Debug)]
pub struct LightSet {
    pub lights: Vec<Light>,
    pub mode: LightMode,
}

impl EnvironmentMap {
    pub fn load(_path: &Path) -> anyhow::Result<EnvironmentMap> {
        todo!()
    }
}
