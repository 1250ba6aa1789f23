//! Lightmap images from the solution: the HDR lightmap (L_lm per texel), the
//! "baked" beauty image (albedo·L_lm + emission) a viewer shows, dilation
//! into chart padding, and their encodings (EXR, 8-bit sRGB PNG).

use anyhow::{Context, Result};

use crate::solve::Solution;
use crate::texelize::TexelSet;

/// An RGB f32 image, row-major, with a per-texel "written" mask.
#[derive(Clone, Debug)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f32; 3]>,
    pub written: Vec<bool>,
}

impl Image {
    fn blank(width: u32, height: u32) -> Image {
        let n = (width * height) as usize;
        Image { width, height, pixels: vec![[0.0; 3]; n], written: vec![false; n] }
    }

    /// Places `value(texel index)` at every covered texel.
    pub fn from_texels(texels: &TexelSet, value: impl Fn(usize) -> [f32; 3]) -> Image {
        let mut image = Image::blank(texels.width, texels.height);
        for (i, texel) in texels.texels.iter().enumerate() {
            image.pixels[texel.index as usize] = value(i);
            image.written[texel.index as usize] = true;
        }
        image
    }

    /// Grows written regions by `rings` texels: each unwritten texel next to
    /// written ones takes their mean, so bilinear filtering at chart edges
    /// never pulls in black. Returns how many texels were filled.
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
                    let mut sum = [0.0f32; 3];
                    let mut count = 0;
                    for (dx, dy) in [(-1, -1), (0, -1), (1, -1), (-1, 0), (1, 0), (-1, 1), (0, 1), (1, 1)] {
                        let (nx, ny) = (x + dx, y + dy);
                        if nx < 0 || ny < 0 || nx >= w || ny >= h {
                            continue;
                        }
                        let j = (ny * w + nx) as usize;
                        if self.written[j] {
                            for (s, v) in sum.iter_mut().zip(self.pixels[j]) {
                                *s += v;
                            }
                            count += 1;
                        }
                    }
                    if count > 0 {
                        updates.push((i, sum.map(|s| s / count as f32)));
                    }
                }
            }
            if updates.is_empty() {
                break;
            }
            filled += updates.len();
            for (i, value) in updates {
                self.pixels[i] = value;
                self.written[i] = true;
            }
        }
        filled
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

/// Linear [0, 1] to an 8-bit sRGB code (IEC 61966-2-1), rounding to nearest.
pub fn linear_to_srgb8(linear: f32) -> u8 {
    let v = if linear.is_nan() { 0.0 } else { linear.clamp(0.0, 1.0) };
    let s = if v <= 0.003_130_8 { 12.92 * v } else { 1.055 * v.powf(1.0 / 2.4) - 0.055 };
    (s * 255.0 + 0.5) as u8
}

/// The HDR lightmap (L_lm per texel) and the baked beauty image
/// (albedo·L_lm + emission), both dilated by `rings` texels.
pub fn images(texels: &TexelSet, solution: &Solution, rings: u32) -> (Image, Image, usize) {
    let mut lightmap = Image::from_texels(texels, |i| solution.lightmap[i]);
    let mut beauty = Image::from_texels(texels, |i| {
        let t = &texels.texels[i];
        let l = solution.lightmap[i];
        [0, 1, 2].map(|c| t.albedo[c] * l[c] + t.emission[c])
    });
    let filled = lightmap.dilate(rings);
    beauty.dilate(rings);
    (lightmap, beauty, filled)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_endpoints_and_midpoint() {
        assert_eq!(linear_to_srgb8(0.0), 0);
        assert_eq!(linear_to_srgb8(1.0), 255);
        assert_eq!(linear_to_srgb8(4.0), 255);
        assert_eq!(linear_to_srgb8(0.5), 188);
        assert_eq!(linear_to_srgb8(0.002), 7);
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
}
