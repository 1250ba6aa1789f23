//! Texture look-ups with glTF's sampler semantics, in f64: the
//! KHR_texture_transform matrix, a wrap mode per axis and bilinear filtering
//! at the image's full resolution.
//!
//! The GPU bake filters mip levels over each lightmap texel's footprint; the
//! reference needs no mips, because its Monte Carlo integral already averages
//! the texture over everything a ray can land on. Bilinear filtering between
//! texel centres is the continuous surface that those mips average.
//!
//! Coordinates follow glTF: (0, 0) is the top-left corner of the image (row 0
//! of a [`LinearImage`]), u grows to the right and v downwards, and texel
//! (i, j) of a W×H image has its centre at ((i + ½)/W, (j + ½)/H).

use glam::{DVec2, DVec4};

use std::sync::Arc;

use crate::scene::{LinearImage, TextureRef};

/// glTF sampler codes (OpenGL enums) of the wrap modes other than repeat.
const CLAMP_TO_EDGE: u32 = 33071;
const MIRRORED_REPEAT: u32 = 33648;

/// How texel indices outside the image fold back into it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Wrap {
    Repeat,
    ClampToEdge,
    MirroredRepeat,
}

impl Wrap {
    /// The mode of a glTF wrap code; unknown codes repeat, as the sampler
    /// the bake uses does (`wrap_coordinate` in include/materials.wgsl
    /// leaves them alone).
    pub(crate) fn from_gl(code: u32) -> Wrap {
        match code {
            CLAMP_TO_EDGE => Wrap::ClampToEdge,
            MIRRORED_REPEAT => Wrap::MirroredRepeat,
            _ => Wrap::Repeat,
        }
    }

    /// Texel index `i` (any integer) of an axis of `n` ≥ 1 texels, folded
    /// into 0..n. Folding the indices rather than the coordinate keeps the
    /// bilinear neighbours right across the edge: repeat blends the last
    /// texel with the first, clamp and mirror blend the edge texel with itself.
    fn fold(self, i: i64, n: u32) -> usize {
        let n = n as i64;
        let folded = match self {
            Wrap::Repeat => i.rem_euclid(n),
            Wrap::ClampToEdge => i.clamp(0, n - 1),
            Wrap::MirroredRepeat => {
                // Period 2n: 0..n forwards, then n..2n backwards.
                let m = i.rem_euclid(2 * n);
                if m < n { m } else { 2 * n - 1 - m }
            }
        };
        folded as usize
    }
}

/// A material's texture ready to sample: an image of the surfaces' table,
/// the UV set it reads, its transform and wrap modes.
#[derive(Clone, Debug)]
pub(crate) struct Texture {
    /// Index into the surfaces' images (shared between materials).
    pub image: usize,
    /// TEXCOORD set: 0 or 1 (the bake reads set 1 for any index above 0).
    set: usize,
    /// uv' = M · (u, v, 1).
    transform: [[f64; 3]; 2],
    wrap: [Wrap; 2],
}

impl Texture {
    /// `texture` reading image `image` of the surfaces' table.
    pub(crate) fn new(texture: &TextureRef, image: usize) -> Texture {
        Texture {
            image,
            set: texture.tex_coord.min(1) as usize,
            transform: texture.transform.map(|row| row.map(f64::from)),
            wrap: texture.wrap.map(Wrap::from_gl),
        }
    }

    /// The linear RGBA at a point whose TEXCOORD_0 and TEXCOORD_1 are `uv`.
    pub(crate) fn sample(&self, images: &[Arc<LinearImage>], uv: [DVec2; 2]) -> DVec4 {
        bilinear(&images[self.image], self.coordinates(uv[self.set]), self.wrap)
    }

    /// The texture coordinates (KHR_texture_transform applied) of UV `uv`.
    fn coordinates(&self, uv: DVec2) -> DVec2 {
        let [a, b] = self.transform;
        DVec2::new(a[0] * uv.x + a[1] * uv.y + a[2], b[0] * uv.x + b[1] * uv.y + b[2])
    }
}

/// Whether `image` can be sampled: non-empty, with one pixel per texel.
pub(crate) fn is_usable(image: &LinearImage) -> bool {
    image.width > 0 && image.height > 0 && image.pixels.len() == image.width as usize * image.height as usize
}

/// The bilinear blend of the four texels whose centres surround texture
/// coordinates `st`, indices folded per axis by `wrap`.
pub(crate) fn bilinear(image: &LinearImage, st: DVec2, wrap: [Wrap; 2]) -> DVec4 {
    let (x0, x1, fx) = neighbours(st.x, image.width, wrap[0]);
    let (y0, y1, fy) = neighbours(st.y, image.height, wrap[1]);
    let texel = |x: usize, y: usize| DVec4::from(image.pixels[y * image.width as usize + x].map(f64::from));
    let top = texel(x0, y0).lerp(texel(x1, y0), fx);
    let bottom = texel(x0, y1).lerp(texel(x1, y1), fx);
    top.lerp(bottom, fy)
}

/// Along an axis of `n` texels: the two texels whose centres bracket
/// coordinate `c`, wrapped, and the weight of the second. A non-finite
/// coordinate reads as 0 (some texel, rather than a NaN that would poison
/// the whole estimate).
fn neighbours(c: f64, n: u32, wrap: Wrap) -> (usize, usize, f64) {
    let c = if c.is_finite() { c } else { 0.0 };
    // In texel units with texel i's centre at i.
    let x = c * n as f64 - 0.5;
    let first = x.floor();
    // `as` saturates, so absurdly large coordinates still give valid indices.
    let i = first as i64;
    (wrap.fold(i, n), wrap.fold(i.saturating_add(1), n), x - first)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `width`×`height` image whose texel (i, j) is (i, j, 10 i + j, 1).
    fn ramp(width: u32, height: u32) -> LinearImage {
        let pixels =
            (0..height).flat_map(|j| (0..width).map(move |i| [i as f32, j as f32, (10 * i + j) as f32, 1.0])).collect();
        LinearImage { width, height, pixels }
    }

    fn at(image: &LinearImage, s: f64, t: f64, wrap: Wrap) -> DVec4 {
        bilinear(image, DVec2::new(s, t), [wrap; 2])
    }

    fn close(a: DVec4, b: DVec4) -> bool {
        (a - b).abs().max_element() < 1e-12
    }

    #[test]
    fn texel_centres_return_the_texel_and_midpoints_the_mean() {
        let image = ramp(4, 2);
        for wrap in [Wrap::Repeat, Wrap::ClampToEdge, Wrap::MirroredRepeat] {
            // Texel (2, 1)'s centre.
            assert!(close(at(&image, 2.5 / 4.0, 1.5 / 2.0, wrap), DVec4::new(2.0, 1.0, 21.0, 1.0)));
            // Halfway between the centres of texels 1 and 2 of row 0.
            assert!(close(at(&image, 0.5, 0.25, wrap), DVec4::new(1.5, 0.0, 15.0, 1.0)));
            // A quarter of the way from (0, 0) to (1, 1) in both axes.
            let p = at(&image, 0.75 / 4.0, 0.75 / 2.0, wrap);
            assert!(close(p, DVec4::new(0.25, 0.25, 2.75, 1.0)), "{wrap:?}: {p}");
        }
    }

    #[test]
    fn v_grows_downwards_from_row_0() {
        // glTF's (0, 0) is the top-left corner: small v reads row 0.
        let image = ramp(1, 4);
        assert_eq!(at(&image, 0.5, 0.5 / 4.0, Wrap::ClampToEdge).y, 0.0);
        assert_eq!(at(&image, 0.5, 3.5 / 4.0, Wrap::ClampToEdge).y, 3.0);
    }

    #[test]
    fn clamp_holds_the_edge_texel_at_and_past_the_edges() {
        let image = ramp(4, 1);
        for s in [-3.0, -0.01, 0.0, 0.5 / 4.0] {
            assert_eq!(at(&image, s, 0.5, Wrap::ClampToEdge).x, 0.0, "s {s}");
        }
        for s in [3.5 / 4.0, 1.0, 1.01, 7.0] {
            assert_eq!(at(&image, s, 0.5, Wrap::ClampToEdge).x, 3.0, "s {s}");
        }
    }

    #[test]
    fn repeat_blends_across_the_seam_and_is_periodic() {
        let image = ramp(4, 1);
        // On the edge: halfway between the last texel and the first.
        for s in [0.0, 1.0, -2.0] {
            assert!((at(&image, s, 0.5, Wrap::Repeat).x - 1.5).abs() < 1e-12, "s {s}");
        }
        for s in [0.1, 0.37, 0.9] {
            let base = at(&image, s, 0.5, Wrap::Repeat);
            for shift in [-5.0, -1.0, 1.0, 3.0] {
                assert!(close(at(&image, s + shift, 0.5, Wrap::Repeat), base), "s {s} + {shift}");
            }
        }
    }

    #[test]
    fn mirrored_repeat_reflects_at_each_edge() {
        let image = ramp(4, 1);
        // At an edge the edge texel meets its own mirror image.
        assert_eq!(at(&image, 0.0, 0.5, Wrap::MirroredRepeat).x, 0.0);
        assert_eq!(at(&image, 1.0, 0.5, Wrap::MirroredRepeat).x, 3.0);
        assert_eq!(at(&image, 2.0, 0.5, Wrap::MirroredRepeat).x, 0.0);
        for s in [0.1, 0.37, 0.9] {
            let base = at(&image, s, 0.5, Wrap::MirroredRepeat);
            // Mirrored about 0 and about 1, and periodic over 2.
            assert!(close(at(&image, -s, 0.5, Wrap::MirroredRepeat), base), "s {s}");
            assert!(close(at(&image, 2.0 - s, 0.5, Wrap::MirroredRepeat), base), "s {s}");
            assert!(close(at(&image, s + 2.0, 0.5, Wrap::MirroredRepeat), base), "s {s}");
            assert!(close(at(&image, s - 4.0, 0.5, Wrap::MirroredRepeat), base), "s {s}");
        }
        // Texel indices: 0 1 2 3 | 3 2 1 0 | 0 1 …
        let folded: Vec<usize> = (-5..10).map(|i| Wrap::MirroredRepeat.fold(i, 4)).collect();
        assert_eq!(folded, [3, 3, 2, 1, 0, 0, 1, 2, 3, 3, 2, 1, 0, 0, 1]);
    }

    #[test]
    fn odd_and_unknown_coordinates_and_codes() {
        let image = ramp(4, 4);
        for wrap in [Wrap::Repeat, Wrap::ClampToEdge, Wrap::MirroredRepeat] {
            for s in [f64::NAN, f64::INFINITY, 1e300, -1e300] {
                assert!(at(&image, s, 0.3, wrap).is_finite(), "{wrap:?} at {s}");
            }
        }
        assert_eq!(Wrap::from_gl(10497), Wrap::Repeat);
        assert_eq!(Wrap::from_gl(33071), Wrap::ClampToEdge);
        assert_eq!(Wrap::from_gl(33648), Wrap::MirroredRepeat);
        assert_eq!(Wrap::from_gl(0), Wrap::Repeat);
    }

    #[test]
    fn texture_applies_its_transform_and_reads_its_uv_set() {
        let images = [Arc::new(ramp(4, 4))];
        let reference = TextureRef {
            image: 7,
            tex_coord: 1,
            // uv' = (0.5 u + 0.25, v + 0.125) after a swap of u and v.
            transform: [[0.0, 0.5, 0.25], [1.0, 0.0, 0.125]],
            wrap: [CLAMP_TO_EDGE, 10497],
        };
        let texture = Texture::new(&reference, 0);
        let uv = [DVec2::new(0.9, 0.9), DVec2::new(0.3, 0.5)];
        // Set 1's (0.3, 0.5) → (0.5·0.5 + 0.25, 0.3 + 0.125) = (0.5, 0.425).
        let expected = at(&images[0], 0.5, 0.425, Wrap::Repeat);
        assert!(close(texture.sample(&images, uv), expected));
        // Any set above 1 reads set 1, as the bake does.
        let texture = Texture::new(&TextureRef { tex_coord: 3, ..reference.clone() }, 0);
        assert!(close(texture.sample(&images, uv), expected));
        // With set 0 the same transform reads (0.7, 1.025): clamped in u, wrapped in v.
        let texture = Texture::new(&TextureRef { tex_coord: 0, ..reference }, 0);
        let expected = bilinear(&images[0], DVec2::new(0.7, 0.025), [Wrap::ClampToEdge, Wrap::Repeat]);
        assert!(close(texture.sample(&images, uv), expected));
    }
}
