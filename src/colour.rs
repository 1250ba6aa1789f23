//! Colour maths every stage shares, defined once, so that light extraction,
//! the solve's convergence test, the seam error, the reference's sampling and
//! the report's statistics all weigh red, green and blue alike.

/// Rec. 709 / sRGB-primaries luminance of linear RGB, `0.2126 R + 0.7152 G +
/// 0.0722 B`, in f64 whether the RGB is f32 or f64 (f32 converts exactly, so
/// either gives the same bits for the same values).
#[inline]
pub fn luminance<T: Into<f64>>(rgb: [T; 3]) -> f64 {
    // Not `rgb.map`: an array map is not inlined into hot loops without LTO.
    let [r, g, b] = rgb;
    let (r, g, b): (f64, f64, f64) = (r.into(), g.into(), b.into());
    0.2126 * r + 0.7152 * g + 0.0722 * b
}

#[cfg(test)]
mod tests {
    use super::luminance;

    #[test]
    fn white_has_unit_luminance_and_green_weighs_most() {
        assert!((luminance([1.0f32; 3]) - 1.0).abs() < 1e-12);
        assert_eq!(luminance([0.0, 1.0f64, 0.0]), 0.7152);
        assert_eq!(luminance([0.5f32, 0.25, 2.0]), luminance([0.5f64, 0.25, 2.0]));
    }
}
