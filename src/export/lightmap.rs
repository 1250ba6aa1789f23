//! Lightmap images from the solution: the HDR lightmap (L_lm per texel), the
//! "baked" beauty image (albedo·L_lm + emission) a viewer shows, dilation
//! into chart padding, and their encodings (EXR, 8-bit sRGB PNG, RGBM PNG).
//!
//! RGBM (8-bit RGBA PNG, raw codes, no sRGB transfer), with the atlas-wide
//! range `R` recorded beside it:
//!
//! ```text
//! L_lm = R · (A / 255) · (RGB / 255)
//! ```
//!
//! `A` is the smallest code with `R·A/255 ≥ max(r, g, b)`, so nothing clips,
//! and each channel is rounded to the nearest code: a decoded channel is
//! within half a step, `R·A / (2·255²)`, of the float value, which is at most
//! `(max(r, g, b) + R/255) / 510`: 8-bit precision relative to the texel's
//! brightest channel down to R/255, an absolute `R/65025` below that.

use anyhow::{Context, Result};

use super::seams::{self, SeamEdge, StitchStats};
use crate::texelize::TexelSet;

/// An RGB f32 image, row-major, with a per-texel "written" mask and the
/// chart each written texel belongs to.
#[derive(Clone, Debug)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f32; 3]>,
    pub written: Vec<bool>,
    /// Chart id of each written texel (`NO_CHART` elsewhere).
    pub chart: Vec<u32>,
}

/// `Image::chart` of a texel no chart wrote.
pub const NO_CHART: u32 = u32::MAX;

impl Image {
    pub(crate) fn blank(width: u32, height: u32) -> Image {
        let n = (width * height) as usize;
        Image { width, height, pixels: vec![[0.0; 3]; n], written: vec![false; n], chart: vec![NO_CHART; n] }
    }

    /// Places `value(texel index)` at every covered texel.
    pub fn from_texels(texels: &TexelSet, value: impl Fn(usize) -> [f32; 3]) -> Image {
        let mut image = Image::blank(texels.width, texels.height);
        for (i, texel) in texels.texels.iter().enumerate() {
            image.pixels[texel.index as usize] = value(i);
            image.written[texel.index as usize] = true;
            image.chart[texel.index as usize] = texel.chart;
        }
        image
    }

    /// Grows written regions by `rings` texels, chart by chart: each
    /// unwritten texel next to written ones joins the chart most of them
    /// belong to (the lower id on a tie) and takes the mean of that chart's
    /// neighbours, so bilinear filtering at a chart's edge reads only that
    /// chart, never black or a neighbour chart (the unwrap keeps charts `2 ·
    /// padding` texels apart). Returns how many texels were filled.
    pub fn dilate(&mut self, rings: u32) -> usize {
        let (w, h) = (self.width as i64, self.height as i64);
        let mut filled = 0;
        for _ in 0..rings {
            let mut updates = Vec::new();
            for y in 0..h {
                for x in 0..w {
                    let i = (y * w + x) as usize;
                    if self.written[i] {
                        continue;
                    }
                    let neighbours = [(-1, -1), (0, -1), (1, -1), (-1, 0), (1, 0), (-1, 1), (0, 1), (1, 1)]
                        .into_iter()
                        .map(|(dx, dy)| (x + dx, y + dy))
                        .filter(|&(nx, ny)| nx >= 0 && ny >= 0 && nx < w && ny < h)
                        .map(|(nx, ny)| (ny * w + nx) as usize)
                        .filter(|&j| self.written[j]);
                    // The chart with the most written neighbours (few: a texel has 8).
                    let mut counts: Vec<(u32, usize)> = Vec::new();
                    for j in neighbours.clone() {
                        match counts.iter_mut().find(|(c, _)| *c == self.chart[j]) {
                            Some(entry) => entry.1 += 1,
                            None => counts.push((self.chart[j], 1)),
                        }
                    }
                    let Some(&(chart, count)) = counts.iter().max_by(|a, b| a.1.cmp(&b.1).then(b.0.cmp(&a.0))) else {
                        continue;
                    };
                    let mut sum = [0.0f32; 3];
                    for j in neighbours.filter(|&j| self.chart[j] == chart) {
                        for (s, v) in sum.iter_mut().zip(self.pixels[j]) {
                            *s += v;
                        }
                    }
                    updates.push((i, chart, sum.map(|s| s / count as f32)));
                }
            }
            if updates.is_empty() {
                break;
            }
            filled += updates.len();
            for (i, chart, value) in updates {
                self.pixels[i] = value;
                self.written[i] = true;
                self.chart[i] = chart;
            }
        }
        filled
    }

    /// Refuses an image holding a NaN, infinite or negative texel, naming the
    /// first and the count: bake never ships one. The import's bounds
    /// (`limits`) keep every figure inside f32, so reaching this is a bug.
    pub fn check_shippable(&self) -> Result<()> {
        let bad = |p: &[f32; 3]| p.iter().any(|c| !c.is_finite() || *c < 0.0);
        let Some(first) = self.pixels.iter().position(bad) else { return Ok(()) };
        let count = self.pixels.iter().filter(|p| bad(p)).count();
        let (x, y) = (first % self.width as usize, first / self.width as usize);
        anyhow::bail!(
            "the lightmap holds {count} NaN, infinite or negative texel(s), the first at ({x}, {y}): {:?}; nothing \
             written, since bake never ships such a texel (a bug in bake: please report it with the input)",
            self.pixels[first]
        )
    }

    /// A float RGB OpenEXR file (ZIP-compressed, lossless), as bytes.
    pub fn encode_exr(&self) -> Result<Vec<u8>> {
        use exr::prelude::*;
        let width = self.width as usize;
        let channels = SpecificChannels::rgb(|position: Vec2<usize>| {
            let p = self.pixels[position.y() * width + position.x()];
            (p[0], p[1], p[2])
        });
        let mut layer = Layer::new(
            (self.width as usize, self.height as usize),
            LayerAttributes::named("lightmap"),
            Encoding::SMALL_LOSSLESS,
            channels,
        );
        layer.encoding.line_order = LineOrder::Increasing;
        let image = exr::image::Image::from_layer(layer);
        let mut bytes = std::io::Cursor::new(Vec::new());
        image.write().non_parallel().to_buffered(&mut bytes).context("encoding the EXR lightmap")?;
        Ok(bytes.into_inner())
    }

    /// An 8-bit sRGB PNG of `value × exposure`, clamped to [0, 1].
    pub fn encode_png(&self, exposure: f32) -> Result<Vec<u8>> {
        let mut rgb = Vec::with_capacity(self.pixels.len() * 3);
        for p in &self.pixels {
            for c in p {
                rgb.push(linear_to_srgb8(c * exposure));
            }
        }
        let mut bytes = Vec::new();
        let encoder = image::codecs::png::PngEncoder::new(&mut bytes);
        image::ImageEncoder::write_image(encoder, &rgb, self.width, self.height, image::ExtendedColorType::Rgb8)
            .context("encoding the PNG lightmap")?;
        Ok(bytes)
    }
}

/// The RGBM range for an image whose brightest channel is `peak`: `peak`
/// rounded up to 4 significant digits (so the JSON number is short and
/// exact), 1 for a black or non-finite image.
pub fn rgbm_range(peak: f32) -> f64 {
    if !(peak.is_finite() && peak > 0.0) {
        return 1.0;
    }
    let peak = peak as f64;
    let step = 10f64.powi(peak.log10().floor() as i32 - 3);
    let range = (peak / step).ceil() * step;
    // Rounding the decimal may land a hair under `peak`: step up once more.
    if range < peak { range + step } else { range }
}

/// One texel as RGBM codes under `range` (module documentation).
pub fn rgbm_encode(value: [f32; 3], range: f64) -> [u8; 4] {
    let v = value.map(|c| if c.is_finite() { (c as f64).clamp(0.0, range) } else { 0.0 });
    let peak = v[0].max(v[1]).max(v[2]);
    let a = (peak / range * 255.0).ceil().clamp(0.0, 255.0);
    if a == 0.0 {
        return [0; 4];
    }
    let scale = range * a / 255.0;
    let code = |c: f64| (c / scale * 255.0).round().clamp(0.0, 255.0) as u8;
    [code(v[0]), code(v[1]), code(v[2]), a as u8]
}

/// L_lm from RGBM codes under `range`: `range · (A/255) · (RGB/255)`.
pub fn rgbm_decode(code: [u8; 4], range: f64) -> [f32; 3] {
    let scale = range * code[3] as f64 / 255.0;
    [0, 1, 2].map(|c| (scale * code[c] as f64 / 255.0) as f32)
}

impl Image {
    /// The brightest channel of any texel (finite values only).
    pub fn peak(&self) -> f32 {
        self.pixels.iter().flatten().copied().filter(|c| c.is_finite()).fold(0.0, f32::max)
    }

    /// An 8-bit RGBA PNG of the RGBM codes under `range` (see the module documentation).
    pub fn encode_rgbm_png(&self, range: f64) -> Result<Vec<u8>> {
        let rgba: Vec<u8> = self.pixels.iter().flat_map(|&p| rgbm_encode(p, range)).collect();
        let mut bytes = Vec::new();
        let encoder = image::codecs::png::PngEncoder::new(&mut bytes);
        image::ImageEncoder::write_image(encoder, &rgba, self.width, self.height, image::ExtendedColorType::Rgba8)
            .context("encoding the RGBM lightmap")?;
        Ok(bytes)
    }
}

/// Linear [0, 1] to an 8-bit sRGB code (IEC 61966-2-1), rounding to nearest.
pub fn linear_to_srgb8(linear: f32) -> u8 {
    let v = if linear.is_nan() { 0.0 } else { linear.clamp(0.0, 1.0) };
    let s = if v <= 0.003_130_8 { 12.92 * v } else { 1.055 * v.powf(1.0 / 2.4) - 0.055 };
    (s * 255.0 + 0.5) as u8
}

/// The HDR lightmap (L_lm per texel) and the baked beauty image
/// (albedo·L_lm + emission), both dilated by `rings` texels, then stitched
/// along `seams`; with what dilation and stitching did. `values` holds L_lm
/// per texel of `texels`; `as_emission[p]` says that primitive `p`'s baked
/// material shows the image as emission.
pub fn images(
    texels: &TexelSet,
    values: &[[f32; 3]],
    as_emission: &[bool],
    rings: u32,
    seams: &[SeamEdge],
) -> (Image, Image, Fixups) {
    let mut lightmap = Image::from_texels(texels, |i| values[i]);
    // A viewer multiplies a base colour texture by the primitive's COLOR_0,
    // so there the texture holds the albedo without it (and the emission
    // divided by it, where it is not near black). Emission it leaves alone.
    let mut beauty = Image::from_texels(texels, |i| {
        let t = &texels.texels[i];
        let l = values[i];
        let multiplied = !as_emission.get(t.primitive as usize).copied().unwrap_or(false);
        let tint = texels.tint.get(i).copied().filter(|_| multiplied).unwrap_or([1.0; 3]);
        [0, 1, 2].map(|c| {
            let shown = tint[c].max(1.0 / 255.0);
            t.albedo[c] / shown * l[c] + t.emission[c] / shown
        })
    });
    let dilated = lightmap.dilate(rings);
    beauty.dilate(rings);
    let stitch = seams::stitch(&mut lightmap, seams);
    seams::stitch(&mut beauty, seams);
    (lightmap, beauty, Fixups { dilated, stitch })
}

/// What the export's fix-ups did to the lightmap.
#[derive(Clone, Debug, Default)]
pub struct Fixups {
    /// Padding texels filled by dilation.
    pub dilated: usize,
    pub stitch: StitchStats,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unshippable_texels_are_refused_naming_the_first() {
        let mut image = Image::blank(4, 2);
        image.check_shippable().unwrap();
        image.pixels[6] = [1.0, f32::INFINITY, 0.0];
        image.pixels[7] = [-1.0, 0.0, 0.0];
        let error = image.check_shippable().unwrap_err().to_string();
        assert!(error.contains("2 NaN, infinite or negative texel(s), the first at (2, 1)"), "{error}");
        image.pixels[6] = [f32::NAN; 3];
        image.pixels[7] = [0.0; 3];
        assert!(image.check_shippable().is_err());
    }

    #[test]
    fn srgb_endpoints_and_midpoint() {
        assert_eq!(linear_to_srgb8(0.0), 0);
        assert_eq!(linear_to_srgb8(1.0), 255);
        assert_eq!(linear_to_srgb8(4.0), 255);
        assert_eq!(linear_to_srgb8(0.5), 188);
        assert_eq!(linear_to_srgb8(0.002), 7);
    }

    #[test]
    fn rgbm_range_rounds_up_to_four_digits() {
        assert_eq!(rgbm_range(0.0), 1.0);
        assert_eq!(rgbm_range(f32::NAN), 1.0);
        assert_eq!(rgbm_range(1.0), 1.0);
        assert!((rgbm_range(1.23456) - 1.235).abs() < 1e-12);
        assert!((rgbm_range(12345.6) - 12350.0).abs() < 1e-9);
        for peak in [1e-3f32, 0.7, 2.5, 99.99, 1e5] {
            assert!(rgbm_range(peak) >= peak as f64 && rgbm_range(peak) <= peak as f64 * 1.001, "{peak}");
        }
    }

    #[test]
    fn rgbm_round_trips_within_half_a_step() {
        let range = 8.0;
        let mut worst_relative: f64 = 0.0;
        for i in 0..2000 {
            let t = i as f32 / 1999.0;
            let value = [8.0 * t * t, 3.0 * t, 0.01 + 0.5 * t * t * t].map(|c: f32| c.min(8.0));
            let code = rgbm_encode(value, range);
            let back = rgbm_decode(code, range);
            let half_step = range * code[3] as f64 / (2.0 * 255.0 * 255.0);
            let peak = value.iter().copied().fold(0.0f32, f32::max) as f64;
            for c in 0..3 {
                let error = (back[c] as f64 - value[c] as f64).abs();
                assert!(error <= half_step * (1.0 + 1e-6), "{value:?} → {code:?} → {back:?}");
                if peak > range / 255.0 {
                    worst_relative = worst_relative.max(error / peak);
                }
            }
        }
        assert!(worst_relative <= 1.0 / 255.0, "{worst_relative}");
        assert_eq!(rgbm_encode([0.0; 3], range), [0; 4]);
        assert_eq!(rgbm_encode([100.0, 0.0, f32::NAN], range), [255, 0, 0, 255]);
    }

    #[test]
    fn dilation_fills_neighbours_with_their_mean() {
        let mut image = Image::blank(3, 1);
        image.pixels[0] = [1.0, 2.0, 3.0];
        image.written[0] = true;
        assert_eq!(image.dilate(1), 1);
        assert_eq!(image.pixels[1], [1.0, 2.0, 3.0]);
        assert!(!image.written[2]);
    }

    #[test]
    fn dilation_takes_the_majority_chart_only() {
        // Chart 0 on the left column, chart 1 at the right; the middle
        // column's texels each touch both but more of one.
        let mut image = Image::blank(3, 3);
        for (i, value, chart) in [(0, 1.0, 0), (3, 1.0, 0), (6, 1.0, 0), (5, 9.0, 1)] {
            image.pixels[i] = [value; 3];
            image.written[i] = true;
            image.chart[i] = chart;
        }
        image.dilate(1);
        // (1,0) sees chart 0 twice, chart 1 once: chart 0's value alone.
        assert_eq!((image.pixels[1], image.chart[1]), ([1.0; 3], 0));
        // (1,1) sees chart 0 three times, chart 1 once.
        assert_eq!((image.pixels[4], image.chart[4]), ([1.0; 3], 0));
        // (2,0) sees only chart 1.
        assert_eq!((image.pixels[2], image.chart[2]), ([9.0; 3], 1));
    }
}
