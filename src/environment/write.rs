//! Writing environment maps, for fixtures and round-trip tests: OpenEXR (half or float,
//! scanline or tiled, lossless ZIP) through the `exr` crate and Radiance RGBE through the
//! `image` crate. Output is deterministic: the same map gives the same bytes.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

use anyhow::Context;

use super::EnvironmentMap;

/// Sample precision of a written OpenEXR file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExrPrecision {
    /// 16-bit half floats (relative precision ≈ 5e-4; finite values beyond ±65 504 are clamped
    /// to ±65 504 because half cannot store them, so never use it for suns).
    Half,
    /// 32-bit floats: exact.
    Float,
}

/// Writes `map` as an RGB OpenEXR file: ZIP-compressed (lossless), scanlines or 64×64 tiles,
/// increasing line order, no extra attributes. The pixel layout is the map's own (row 0 at the
/// top = zenith).
pub fn write_exr(
    map: &EnvironmentMap,
    path: impl AsRef<Path>,
    precision: ExrPrecision,
    tiled: bool,
) -> anyhow::Result<()> {
    use exr::prelude::*;
    let path = path.as_ref();
    let (w, h) = (map.width as usize, map.height as usize);
    anyhow::ensure!(
        w > 0 && h > 0 && map.texels.len() == w * h,
        "cannot write '{}': map size {}×{} does not match its {} texels",
        path.display(),
        w,
        h,
        map.texels.len()
    );
    let encoding = Encoding {
        compression: Compression::ZIP16,
        blocks: if tiled { Blocks::Tiles(Vec2(64, 64)) } else { Blocks::ScanLines },
        line_order: LineOrder::Increasing,
    };
    let texels = &map.texels;
    let result = match precision {
        ExrPrecision::Float => {
            let channels = SpecificChannels::rgb(|p: Vec2<usize>| {
                let t = texels[p.y() * w + p.x()];
                (t[0], t[1], t[2])
            });
            let layer = Layer::new((w, h), LayerAttributes::default(), encoding, channels);
            Image::from_layer(layer).write().to_file(path)
        }
        ExrPrecision::Half => {
            let half = |v: f32| f16::from_f32(if v.is_finite() { v.clamp(-65504.0, 65504.0) } else { v });
            let channels = SpecificChannels::rgb(|p: Vec2<usize>| {
                let t = texels[p.y() * w + p.x()];
                (half(t[0]), half(t[1]), half(t[2]))
            });
            let layer = Layer::new((w, h), LayerAttributes::default(), encoding, channels);
            Image::from_layer(layer).write().to_file(path)
        }
    };
    result.with_context(|| format!("cannot write OpenEXR '{}'", path.display()))
}

/// Smallest largest-channel value RGBE stores (2⁻¹²⁷; the exponent byte is then 1).
const MIN_RGBE: f32 = 5.877_472e-39;
/// Largest value RGBE stores (just below 2¹²⁷).
const MAX_RGBE: f32 = 1.7e38;

/// Writes `map` as a Radiance RGBE (`.hdr`) file with the `image` crate's encoder (standard
/// `-Y H +X W` orientation, run-length encoded scanlines). RGBE keeps about 1 % relative
/// precision per pixel (relative to the pixel's largest channel, truncated); negative and NaN
/// values become 0, pixels darker than 2⁻¹²⁷ black, values above 1.7e38 1.7e38.
pub fn write_hdr(map: &EnvironmentMap, path: impl AsRef<Path>) -> anyhow::Result<()> {
    let path = path.as_ref();
    let (w, h) = (map.width as usize, map.height as usize);
    anyhow::ensure!(
        w > 0 && h > 0 && map.texels.len() == w * h,
        "cannot write '{}': map size {}×{} does not match its {} texels",
        path.display(),
        w,
        h,
        map.texels.len()
    );
    // RGBE holds non-negative values with a shared exponent in 2^-128 … 2^127; pixels whose
    // largest channel is below that range are written black (the encoder would wrap its
    // exponent), negative / NaN channels as 0, larger values as the largest RGBE value.
    let representable = |t: &[f32; 3]| {
        let mx = t[0].max(t[1]).max(t[2]);
        t.iter().all(|v| *v >= 0.0) && (mx == 0.0 || (MIN_RGBE..=MAX_RGBE).contains(&mx))
    };
    let fixed: Option<Vec<[f32; 3]>> = (!map.texels.iter().all(representable)).then(|| {
        map.texels
            .iter()
            .map(|t| {
                let t = t.map(|v| if v > 0.0 { v.min(MAX_RGBE) } else { 0.0 });
                if t[0].max(t[1]).max(t[2]) < MIN_RGBE { [0.0; 3] } else { t }
            })
            .collect()
    });
    let texels = fixed.as_deref().unwrap_or(&map.texels);
    let write = || -> anyhow::Result<()> {
        use image::ImageEncoder;
        let mut out = BufWriter::new(File::create(path)?);
        image::codecs::hdr::HdrEncoder::new(&mut out).write_image(
            bytemuck::cast_slice(texels),
            map.width,
            map.height,
            image::ExtendedColorType::Rgb32F,
        )?;
        out.flush()?;
        Ok(())
    };
    write().with_context(|| format!("cannot write Radiance HDR '{}'", path.display()))
}
