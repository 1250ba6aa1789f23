//! Bounds on what a bake accepts, so that nothing it computes in f32 can
//! overflow, and the default budget of work one input may ask for. README
//! "Bad input" states them; each refusal names the value, where it is and
//! the bound.
//!
//! # Why these bounds (f32 headroom)
//!
//! f32 holds values up to 3.4·10³⁸. The largest figures the solve forms are
//! a texel's power π·L·A and sums of it over the scene, and squared distances
//! r². With the scene within [`MAX_SCENE_EXTENT`] = 10⁷ m on every axis
//! (positions are stored relative to an origin at most 4.5 extents away,
//! `scene::choose_origin`), r² < 3·10¹⁵ m² and one triangle's area is under
//! 5·10¹³ m². With every radiance and punctual intensity at most
//! [`MAX_LIGHT`] = 10¹², one triangle's power is under π·10¹²·5·10¹³ ≈
//! 1.6·10²⁶, and a billion such triangles sum to 1.6·10³⁵: still 2000 times
//! under f32's largest value. Lightmap values stay near the lights' radiance
//! (L_lm = E/π, amplified by interreflection at most 1/(1 − albedo)).
//!
//! Neither bound is near a real scene: 10⁷ m is 10 000 km, most of the
//! Earth's diameter; the sun's luminance is 1.6·10⁹ cd/m², a stadium
//! floodlight about 10⁶ cd, sunlight 1.2·10⁵ lux.
//!
//! At the other end, the form factors divide by terms of the fourth power of
//! a distance (r²·(πr² + A)), which leave f32's normal range (10⁻³⁸) for
//! distances under about 10⁻¹⁰ m: a scene whose longest side is under
//! [`MIN_SCENE_EXTENT`] = 10⁻⁶ m is refused rather than baked dark. No real
//! scene is that small either: a chair exported in kilometres is still 10⁻³.

/// The largest extent of a scene along any world axis, in metres.
pub const MAX_SCENE_EXTENT: f64 = 1e7;

/// The smallest a scene's longest extent along a world axis may be, in metres.
pub const MIN_SCENE_EXTENT: f64 = 1e-6;

/// The largest radiance an environment texel (times `--env-intensity`) or
/// an emissive material (factor × KHR_materials_emissive_strength) may
/// have, and the largest colour × intensity of a punctual light (candela,
/// or lux for a directional light).
pub const MAX_LIGHT: f64 = 1e12;

/// The default of `--max-triangles`: the most triangles one input may draw
/// once node and GPU instances are expanded. Past most game levels, short
/// of what a small file drawing one mesh from thousands of nodes asks for,
/// and an unwrap of well under a minute and a GB on a 2-core build machine.
pub const DEFAULT_MAX_TRIANGLES: u64 = 4_000_000;

/// The side of the largest square material image bake decodes: an image
/// with more texels is baked as absent, with a notice. An 8192² image's
/// decoded copies (RGBA8, then linear f32) take 1.25 GiB, where a small file
/// can declare far more (a 1-bit PNG of 16,000² texels is 31 KB).
pub const MAX_IMAGE_SQUARE: u64 = 8192;

/// Whether `value` is a usable light figure: finite, ≥ 0 and at most [`MAX_LIGHT`].
pub fn light_in_range(value: f64) -> bool {
    (0.0..=MAX_LIGHT).contains(&value)
}

/// `value` for a message: plain between 10⁻³ and 10⁶, else in scientific
/// notation to four digits, trailing zeros dropped (`1.5e38`, `1e300`).
pub fn figure(value: f64) -> String {
    if reads_plainly(value) {
        return format!("{value}");
    }
    let text = format!("{value:.3e}");
    match text.split_once('e') {
        Some((mantissa, exponent)) if mantissa.contains('.') => {
            format!("{}e{exponent}", mantissa.trim_end_matches('0').trim_end_matches('.'))
        }
        _ => text,
    }
}

/// [`figure`] for a value a file gave as an f32: plain as it was written
/// (0.1, not the 0.10000000149011612 it widens to).
pub fn figure_f32(value: f32) -> String {
    if reads_plainly(value.into()) { value.to_string() } else { figure(value.into()) }
}

fn reads_plainly(value: f64) -> bool {
    value == 0.0 || (1e-3..1e6).contains(&value.abs())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn figures_read_plainly_or_in_scientific_notation() {
        assert_eq!(figure(1.0), "1");
        assert_eq!(figure(-5.0), "-5");
        assert_eq!(figure(1e38), "1e38");
        assert_eq!(figure(f64::from(1e38f32)), "1e38");
        assert_eq!(figure(1.4953815e38), "1.495e38");
        assert_eq!(figure(-5e30), "-5e30");
        assert_eq!(figure(2.5e-7), "2.5e-7");
        assert_eq!(figure(f64::NAN), "NaN");
        assert_eq!(figure_f32(0.1), "0.1");
        assert_eq!(figure_f32(1e-30), "1e-30");
    }
}
