//! Lightmap images from the solution: the HDR lightmap (L_lm per texel), the
//! "baked" beauty image (albedo·L_lm + emission) a viewer shows, dilation
//! into chart padding, and their encodings (EXR, 8-bit sRGB PNG, and the
//! 8-bit linear irradiance PNG `MOZ_lightmap` points at).
//!
//! The `MOZ_lightmap` texture is written the way its readers read it (README,
//! "Using the lightmap in an engine"): Hubs' `GLTFHubsLightMapExtension`
//! (mozilla/hubs `src/components/gltf-model-plus.js`) and three.js's
//! `GLTFLightMapLoaderExtension` addon
//! (`examples/jsm/loaders/GLTFLightMapLoaderExtension.js`) take the texture
//! as linear RGB into `material.lightMap` and `intensity` as
//! `lightMapIntensity`; three.js shades `lightMap` as irradiance E (× albedo/π).
//! Its `GLTFLightMapExporterExtension`
//! (`examples/jsm/exporters/GLTFLightMapExporterExtension.js`) writes a float
//! light map the same way as here: each channel divided by the map's largest
//! value s and rounded to an 8-bit code, s in `intensity` (it starts s at 1;
//! here s is the peak itself, so a dim map keeps its 8 bits):
//!
//! ```text
//! E = π · L_lm = intensity · RGB / 255
//! ```
//!
//! s is the atlas's brightest channel of E rounded up to 4 significant digits
//! (`irradiance_scale`), so nothing clips and the JSON number is short and
//! reproducible. Each channel is within half a code, `s / 510`, of E.

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

/// `peak` rounded up to 4 significant digits (so the JSON number is short and
/// exact), 1 for a black or non-finite image: the scale s of the irradiance
/// PNG for a map whose brightest channel of E is `peak`.
pub fn irradiance_scale(peak: f64) -> f64 {
    if !(peak.is_finite() && peak > 0.0) {
        return 1.0;
    }
    let step = 10f64.powi(peak.log10().floor() as i32 - 3);
    let scale = (peak / step).ceil() * step;
    // Rounding the decimal may land a hair under `peak`: step up once more.
    if scale < peak { scale + step } else { scale }
}

/// One texel of L_lm as the codes of E/s, E = π·L_lm (module documentation).
pub fn irradiance_encode(value: [f32; 3], scale: f64) -> [u8; 3] {
    value.map(|c| {
        let e = if c.is_finite() { std::f64::consts::PI * c as f64 } else { 0.0 };
        (e / scale * 255.0).round().clamp(0.0, 255.0) as u8
    })
}

impl Image {
    /// The brightest channel of any texel (finite values only).
    pub fn peak(&self) -> f32 {
        self.pixels.iter().flatten().copied().filter(|c| c.is_finite()).fold(0.0, f32::max)
    }

    /// The scale s of this lightmap's irradiance PNG: its peak E = π·L_lm, rounded up.
    pub fn irradiance_scale(&self) -> f64 {
        irradiance_scale(std::f64::consts::PI * self.peak() as f64)
    }

    /// An 8-bit RGB PNG of E/s, E = π·L_lm, with no colour space chunk: raw
    /// linear codes (see the module documentation).
    pub fn encode_irradiance_png(&self, scale: f64) -> Result<Vec<u8>> {
        let rgb: Vec<u8> = self.pixels.iter().flat_map(|&p| irradiance_encode(p, scale)).collect();
        let mut bytes = Vec::new();
        let encoder = image::codecs::png::PngEncoder::new(&mut bytes);
        image::ImageEncoder::write_image(encoder, &rgb, self.width, self.height, image::ExtendedColorType::Rgb8)
            .context("encoding the irradiance lightmap")?;
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
    fn irradiance_scale_rounds_up_to_four_digits() {
        assert_eq!(irradiance_scale(0.0), 1.0);
        assert_eq!(irradiance_scale(f64::NAN), 1.0);
        assert_eq!(irradiance_scale(1.0), 1.0);
        assert!((irradiance_scale(1.23456) - 1.235).abs() < 1e-12);
        assert!((irradiance_scale(12345.6) - 12350.0).abs() < 1e-9);
        for peak in [1e-3, 0.7, 2.5, 99.99, 1e5, std::f64::consts::PI * 2.417] {
            let scale = irradiance_scale(peak);
            assert!(scale >= peak && scale <= peak * 1.001, "{peak}");
        }
    }

    #[test]
    fn irradiance_codes_are_within_half_a_step_of_pi_times_the_lightmap() {
        let mut image = Image::blank(2000, 1);
        for (i, p) in image.pixels.iter_mut().enumerate() {
            let t = i as f32 / 1999.0;
            *p = [2.5 * t * t, 0.8 * t, 0.01 + 0.5 * t * t * t];
        }
        let scale = image.irradiance_scale();
        let peak = std::f64::consts::PI * 2.5;
        assert!((peak..=peak * 1.001).contains(&scale), "{scale}");
        for p in &image.pixels {
            let code = irradiance_encode(*p, scale);
            for c in 0..3 {
                let decoded = scale * code[c] as f64 / 255.0;
                let e = std::f64::consts::PI * p[c] as f64;
                assert!((decoded - e).abs() <= scale / 510.0 * (1.0 + 1e-9), "{p:?} → {code:?}");
            }
        }
        assert_eq!(irradiance_encode([0.0, f32::NAN, 100.0], scale), [0, 0, 255]);
        let png = image.encode_irradiance_png(scale).unwrap();
        assert_eq!(image::load_from_memory(&png).unwrap().color(), image::ColorType::Rgb8);
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
