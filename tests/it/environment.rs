//! Integration tests of the environment stage: loading and sanitising EXR / Radiance maps,
//! writers, and light extraction (energy, orientation, rotation, the sun).

// RGB triples and xyz vectors read best with explicit channel indices.

use std::f64::consts::PI;
use std::path::{Path, PathBuf};
use std::time::Instant;

use bake::colour::luminance;
use bake::environment::{
    EnvLoadOptions, EnvironmentMap, ExrPrecision, Light, LightMode, LightSet, write_exr, write_hdr,
};

// ---------------------------------------------------------------------------------------------
// helpers

/// A fresh path in cargo's per-target temp folder (no extra dependency needed).
fn tmp(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("environment-tests");
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(name);
    let _ = std::fs::remove_file(&p);
    p
}

fn default_opts() -> EnvLoadOptions {
    EnvLoadOptions::default()
}

fn load_err(path: &Path, opts: &EnvLoadOptions) -> String {
    match EnvironmentMap::load(path, opts) {
        Ok(_) => panic!("{} loaded but should not", path.display()),
        Err(e) => format!("{e:#}"),
    }
}

/// The one-line, path-first error format every load error must have.
fn assert_error_format(msg: &str, path: &Path) {
    let prefix = format!("environment '{}': ", path.display());
    assert!(msg.starts_with(&prefix), "error does not start with {prefix:?}: {msg}");
    assert!(!msg.contains('\n'), "error is not one line: {msg:?}");
}

fn dot(a: [f32; 3], b: [f32; 3]) -> f64 {
    a[0] as f64 * b[0] as f64 + a[1] as f64 * b[1] as f64 + a[2] as f64 * b[2] as f64
}

fn norm(v: [f64; 3]) -> [f64; 3] {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    v.map(|x| x / l)
}

fn angle_deg(a: [f64; 3], b: [f64; 3]) -> f64 {
    let (a, b) = (norm(a), norm(b));
    (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]).clamp(-1.0, 1.0).acos().to_degrees()
}

fn light_energy(l: &Light) -> [f64; 3] {
    l.radiance.map(|r| r as f64 * l.solid_angle as f64)
}

fn light_lum_energy(l: &Light) -> f64 {
    luminance(l.radiance) * l.solid_angle as f64
}

/// Luminance-energy-weighted mean light direction.
fn mean_direction(set: &LightSet) -> [f64; 3] {
    let mut s = [0.0f64; 3];
    for l in &set.lights {
        let w = light_lum_energy(l);
        for c in 0..3 {
            s[c] += w * l.direction[c] as f64;
        }
    }
    norm(s)
}

fn brightest(set: &LightSet) -> &Light {
    set.lights.iter().max_by(|a, b| light_lum_energy(a).total_cmp(&light_lum_energy(b))).expect("no lights")
}

fn rel_err(a: f64, b: f64) -> f64 {
    if b == 0.0 { a.abs() } else { ((a - b) / b).abs() }
}

/// Every invariant a light set must satisfy, plus energy conservation to `tol`.
fn check_light_set(set: &LightSet, what: &str, tol: f64) {
    for c in 0..3 {
        let e = rel_err(set.captured[c], set.map_integral[c]);
        assert!(
            e <= tol,
            "{what}: channel {c}: captured {} vs integral {} (rel {e:e})",
            set.captured[c],
            set.map_integral[c]
        );
    }
    // `captured` is what it says: Σ L Ω over the stored f32 values.
    let mut sum = [0.0f64; 3];
    for l in &set.lights {
        let e = light_energy(l);
        for c in 0..3 {
            sum[c] += e[c];
        }
        let len = dot(l.direction, l.direction).sqrt();
        assert!((len - 1.0).abs() < 1e-5, "{what}: direction not unit: {:?}", l.direction);
        assert!(l.solid_angle > 0.0 && l.solid_angle.is_finite(), "{what}: bad Ω {l:?}");
        assert!(l.radiance.iter().all(|r| r.is_finite() && *r >= 0.0), "{what}: {l:?}");
        assert!(l.radiance != [0.0; 3], "{what}: zero-energy light kept");
    }
    for c in 0..3 {
        assert!(rel_err(sum[c], set.captured[c]) < 1e-12, "{what}: captured field mismatch");
    }
    let omega: f64 = set.lights.iter().map(|l| l.solid_angle as f64).sum();
    assert!(omega <= 4.0 * PI * (1.0 + 1e-5), "{what}: lights cover {omega} sr > 4π");
    let requested = set.mode.requested_lights();
    assert!(set.lights.len() <= requested, "{what}: {} lights > {requested}", set.lights.len());
    if let LightMode::Cube { .. } = set.mode {
        assert_eq!(set.lights.len() + set.dropped, requested, "{what}: cube light count");
    }
}

const ALL_MODES: [&str; 9] = ["cube:4", "cube:8", "cube:16", "cube:32", "1", "8", "64", "256", "1024"];

fn modes() -> Vec<LightMode> {
    ALL_MODES.iter().map(|s| s.parse().unwrap()).collect()
}

/// A map with a wide but finite dynamic range, 1e-3 … 3e4, different per channel.
fn wide_range_map() -> EnvironmentMap {
    let (w, h) = (64u32, 32u32);
    let decades = 3e4f64.log10() + 3.0;
    let mut texels = Vec::new();
    for i in 0..w * h {
        // Low-discrepancy spread of exponents, different per channel.
        let v = |k: f64| {
            let t = (i as f64 * 0.618_033_988_7 + k).fract();
            10f64.powf(-3.0 + t * decades) as f32
        };
        texels.push([v(0.0), v(0.33), v(0.71)]);
    }
    // Make sure both ends of the range are present.
    texels[0] = [1e-3, 3e4, 1.0];
    texels[1] = [3e4, 1e-3, 12.5];
    EnvironmentMap { width: w, height: h, texels }
}

fn cap_map(axis: [f32; 3], radius_deg: f64) -> EnvironmentMap {
    let cos_r = radius_deg.to_radians().cos();
    EnvironmentMap::from_fn(256, 128, move |d| if dot(d, axis) >= cos_r { [3.0, 2.0, 1.0] } else { [0.0; 3] })
}

const SKY: [f32; 3] = [0.4, 0.6, 1.0];

fn sun_dir() -> [f32; 3] {
    let d = norm([0.45, 0.55, -0.7]);
    d.map(|v| v as f32)
}

fn real_captures() -> Vec<PathBuf> {
    let mut out = Vec::new();
    for name in ["courtyard.exr", "sunrise.exr", "interior.exr"] {
        let p = Path::new("/work/shared/env").join(name);
        if p.is_file() {
            out.push(p);
        } else {
            println!("skipped real capture {} (not present on this machine)", p.display());
        }
    }
    out
}

// ---------------------------------------------------------------------------------------------
// round trips and writers

fn assert_round_trip(original: &EnvironmentMap, path: &Path, rel_tol: f32, what: &str) {
    let loaded = EnvironmentMap::load(path, &default_opts()).unwrap_or_else(|e| panic!("{what}: {e:#}"));
    let m = &loaded.map;
    assert_eq!((m.width, m.height), (original.width, original.height), "{what}: size");
    let mut worst = 0.0f32;
    for (a, b) in original.texels.iter().zip(&m.texels) {
        // RGBE shares one exponent per pixel: its error is relative to the pixel's largest
        // channel. EXR errors are per channel.
        let scale_px = a.iter().copied().fold(0.0f32, f32::max);
        for c in 0..3 {
            let scale = if rel_tol >= 0.005 { scale_px } else { a[c].abs() };
            let e = if scale == 0.0 { b[c].abs() } else { (a[c] - b[c]).abs() / scale };
            worst = worst.max(e);
        }
    }
    assert!(worst <= rel_tol, "{what}: worst relative error {worst:e} > {rel_tol:e}");
}

#[test]
fn round_trip_float_exr_is_exact() {
    let map = wide_range_map();
    let p = tmp("rt_float.exr");
    write_exr(&map, &p, ExrPrecision::Float, false).unwrap();
    assert_round_trip(&map, &p, 0.0, "float scanline EXR");
}

#[test]
fn round_trip_tiled_exr_float_exact_and_half_within_precision() {
    let map = wide_range_map();
    let p = tmp("rt_float_tiled.exr");
    write_exr(&map, &p, ExrPrecision::Float, true).unwrap();
    assert_round_trip(&map, &p, 0.0, "float tiled EXR");
    let p = tmp("rt_half_tiled.exr");
    write_exr(&map, &p, ExrPrecision::Half, true).unwrap();
    assert_round_trip(&map, &p, 1e-3, "half tiled EXR");
}

#[test]
fn round_trip_half_exr_within_half_precision() {
    let map = wide_range_map();
    let p = tmp("rt_half.exr");
    write_exr(&map, &p, ExrPrecision::Half, false).unwrap();
    assert_round_trip(&map, &p, 1e-3, "half EXR");
}

#[test]
fn round_trip_radiance_hdr_within_rgbe_precision() {
    let map = wide_range_map();
    let p = tmp("rt.hdr");
    write_hdr(&map, &p).unwrap();
    assert_round_trip(&map, &p, 0.01, "Radiance RGBE");
}

#[test]
fn writers_are_deterministic() {
    let map = wide_range_map();
    for (i, write) in [
        &(|p: &Path| write_exr(&wide_range_map(), p, ExrPrecision::Float, false))
            as &dyn Fn(&Path) -> anyhow::Result<()>,
        &|p: &Path| write_exr(&wide_range_map(), p, ExrPrecision::Half, true),
        &|p: &Path| write_hdr(&wide_range_map(), p),
    ]
    .iter()
    .enumerate()
    {
        let (a, b) = (tmp(&format!("det_{i}_a")), tmp(&format!("det_{i}_b")));
        write(&a).unwrap();
        write(&b).unwrap();
        assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap(), "writer {i}");
    }
    let _ = map;
}

#[test]
fn half_exr_clamps_values_beyond_half_range() {
    let map = EnvironmentMap::from_fn(2, 1, |_| [1e5, 1.0, 0.5]);
    let p = tmp("half_clamp.exr");
    write_exr(&map, &p, ExrPrecision::Half, false).unwrap();
    let m = EnvironmentMap::load(&p, &default_opts()).unwrap().map;
    assert_eq!(m.texels[0], [65504.0, 1.0, 0.5]);
}

#[test]
fn hdr_writer_handles_values_rgbe_cannot_store() {
    let texels = vec![[1e-40, 0.0, 0.0], [-1.0, 2.0, f32::NAN], [3e38, 1.0, 1.0], [0.5, 0.25, 0.125]];
    let map = EnvironmentMap { width: 4, height: 1, texels };
    let p = tmp("rgbe_range.hdr");
    write_hdr(&map, &p).unwrap();
    let bytes = std::fs::read(&p).unwrap();
    // Back through the image crate directly: the map is 4×1, not an environment.
    let img = image::load_from_memory_with_format(&bytes, image::ImageFormat::Hdr).unwrap().into_rgb32f();
    let px: Vec<[f32; 3]> = img.pixels().map(|p| p.0).collect();
    assert_eq!(px[0], [0.0; 3]);
    assert_eq!(px[1][0], 0.0);
    assert!((px[1][1] - 2.0).abs() < 0.02 && px[1][2] == 0.0, "{:?}", px[1]);
    assert!(px[2][0] > 1e38 && px[2][0].is_finite(), "{:?}", px[2]);
    assert_eq!(px[3], [0.5, 0.25, 0.125]);
}

#[test]
fn format_is_chosen_by_content_not_extension() {
    let map = wide_range_map();
    let exr_as_hdr = tmp("really_exr.hdr");
    write_exr(&map, &exr_as_hdr, ExrPrecision::Float, false).unwrap();
    assert_round_trip(&map, &exr_as_hdr, 0.0, "EXR named .hdr");
    let hdr_as_exr = tmp("really_hdr.exr");
    write_hdr(&map, &hdr_as_exr).unwrap();
    assert_round_trip(&map, &hdr_as_exr, 0.01, "HDR named .exr");
}

#[test]
fn radiance_exposure_header_is_divided_out() {
    let map = EnvironmentMap::from_fn(8, 4, |_| [2.0, 4.0, 8.0]);
    let p = tmp("exposure.hdr");
    write_hdr(&map, &p).unwrap();
    let bytes = std::fs::read(&p).unwrap();
    let text_end = bytes.windows(2).position(|w| w == b"\n\n").unwrap();
    let mut patched = bytes[..text_end + 1].to_vec();
    patched.extend_from_slice(b"EXPOSURE=2\n");
    patched.extend_from_slice(&bytes[text_end + 1..]);
    std::fs::write(&p, patched).unwrap();
    let loaded = EnvironmentMap::load(&p, &default_opts()).unwrap();
    assert_eq!(loaded.map.texels[0], [1.0, 2.0, 4.0]);
    assert!(loaded.notices.iter().any(|n| n.contains("EXPOSURE")), "{:?}", loaded.notices);
}

#[test]
fn radiance_with_rgbe_signature_loads() {
    let map = EnvironmentMap::from_fn(8, 4, |_| [0.5, 1.0, 2.0]);
    let p = tmp("rgbe_sig.hdr");
    write_hdr(&map, &p).unwrap();
    let bytes = std::fs::read(&p).unwrap();
    let mut patched = b"#?RGBE".to_vec();
    patched.extend_from_slice(&bytes[b"#?RADIANCE".len()..]);
    std::fs::write(&p, patched).unwrap();
    let m = EnvironmentMap::load(&p, &default_opts()).unwrap().map;
    assert_eq!(m.texels[5], [0.5, 1.0, 2.0]);
}

// ---------------------------------------------------------------------------------------------
// EXR variants written with the exr crate directly

mod exr_files {
    use super::*;
    use exr::prelude::*;

    pub fn write_channels(path: &Path, size: (usize, usize), channels: Vec<AnyChannel<FlatSamples>>) {
        let layer = Layer::new(
            size,
            LayerAttributes::default(),
            Encoding::SMALL_LOSSLESS,
            AnyChannels::sort(SmallVec::from_vec(channels)),
        );
        Image::from_layer(layer).write().to_file(path).unwrap();
    }

    pub fn ramp(n: usize, scale: f32) -> Vec<f32> {
        (0..n).map(|i| (i % 97) as f32 * scale + 0.25).collect()
    }

    #[test]
    fn single_channel_y_loads_as_grey_with_notice() {
        let p = tmp("grey_y.exr");
        let y = ramp(16 * 8, 0.5);
        write_channels(&p, (16, 8), vec![AnyChannel::new("Y", FlatSamples::F32(y.clone()))]);
        let l = EnvironmentMap::load(&p, &default_opts()).unwrap();
        for (t, v) in l.map.texels.iter().zip(&y) {
            assert_eq!(*t, [*v; 3]);
        }
        assert!(l.notices.iter().any(|n| n.contains("'Y'") && n.contains("grey")), "{:?}", l.notices);
    }

    #[test]
    fn any_single_channel_loads_as_grey() {
        let p = tmp("grey_z.exr");
        let z = ramp(8 * 4, 2.0);
        write_channels(
            &p,
            (8, 4),
            vec![AnyChannel::new("L", FlatSamples::F16(z.iter().map(|&v| f16::from_f32(v)).collect()))],
        );
        let l = EnvironmentMap::load(&p, &default_opts()).unwrap();
        assert_eq!(l.map.texels[3], [z[3]; 3]);
        let p = tmp("grey_custom.exr");
        write_channels(&p, (8, 4), vec![AnyChannel::new("intensity", FlatSamples::F32(z.clone()))]);
        let l = EnvironmentMap::load(&p, &default_opts()).unwrap();
        assert_eq!(l.map.texels[7], [z[7]; 3]);
    }

    #[test]
    fn rgba_half_ignores_alpha_and_u32_channels_load() {
        let p = tmp("rgba.exr");
        let n = 16 * 8;
        let h = |s: f32| FlatSamples::F16(ramp(n, s).into_iter().map(f16::from_f32).collect());
        write_channels(
            &p,
            (16, 8),
            vec![
                AnyChannel::new("R", h(1.0)),
                AnyChannel::new("G", h(2.0)),
                AnyChannel::new("B", h(3.0)),
                AnyChannel::new("A", FlatSamples::F32(vec![0.0; n])),
            ],
        );
        let m = EnvironmentMap::load(&p, &default_opts()).unwrap().map;
        assert_eq!(m.texels[10], [ramp(n, 1.0)[10], ramp(n, 2.0)[10], ramp(n, 3.0)[10]]);

        let p = tmp("u32.exr");
        let u = |k: u32| FlatSamples::U32((0..n as u32).map(|i| i * k).collect());
        write_channels(
            &p,
            (16, 8),
            vec![AnyChannel::new("R", u(1)), AnyChannel::new("G", u(2)), AnyChannel::new("B", u(3))],
        );
        let m = EnvironmentMap::load(&p, &default_opts()).unwrap().map;
        assert_eq!(m.texels[5], [5.0, 10.0, 15.0]);
    }

    #[test]
    fn multi_layer_file_uses_first_rgb_layer_and_names_it() {
        let p = tmp("layers.exr");
        let n = 16 * 8;
        write_channels(
            &p,
            (16, 8),
            vec![
                AnyChannel::new("depth.Z", FlatSamples::F32(vec![9.0; n])),
                AnyChannel::new("diffuse.R", FlatSamples::F32(vec![1.0; n])),
                AnyChannel::new("diffuse.G", FlatSamples::F32(vec![2.0; n])),
                AnyChannel::new("diffuse.B", FlatSamples::F32(vec![3.0; n])),
                AnyChannel::new("specular.R", FlatSamples::F32(vec![7.0; n])),
                AnyChannel::new("specular.G", FlatSamples::F32(vec![7.0; n])),
                AnyChannel::new("specular.B", FlatSamples::F32(vec![7.0; n])),
            ],
        );
        let l = EnvironmentMap::load(&p, &default_opts()).unwrap();
        assert_eq!(l.map.texels[0], [1.0, 2.0, 3.0]);
        assert!(l.notices.iter().any(|s| s.contains("'diffuse'")), "{:?}", l.notices);
    }

    #[test]
    fn multi_part_file_uses_first_part_with_rgb() {
        let p = tmp("parts.exr");
        let size = (16usize, 8usize);
        let n = size.0 * size.1;
        let depth = Layer::new(
            size,
            LayerAttributes::named("depth"),
            Encoding::SMALL_LOSSLESS,
            AnyChannels::sort(SmallVec::from_vec(vec![AnyChannel::new("Z", FlatSamples::F32(vec![5.0; n]))])),
        );
        let beauty = Layer::new(
            size,
            LayerAttributes::named("beauty"),
            Encoding::SMALL_LOSSLESS,
            AnyChannels::sort(SmallVec::from_vec(vec![
                AnyChannel::new("R", FlatSamples::F32(vec![0.5; n])),
                AnyChannel::new("G", FlatSamples::F32(vec![0.25; n])),
                AnyChannel::new("B", FlatSamples::F32(vec![0.125; n])),
            ])),
        );
        let image = Image::from_layers(ImageAttributes::with_size(size), vec![depth, beauty]);
        image.write().to_file(&p).unwrap();
        let l = EnvironmentMap::load(&p, &default_opts()).unwrap();
        assert_eq!(l.map.texels[3], [0.5, 0.25, 0.125]);
        assert!(l.notices.iter().any(|s| s.contains("'beauty'")), "{:?}", l.notices);
    }

    #[test]
    fn mip_mapped_file_loads_full_resolution() {
        let p = tmp("mips.exr");
        let full = Vec2(32usize, 16usize);
        let levels: Vec<(usize, Vec2<usize>)> =
            exr::meta::mip_map_levels(exr::math::RoundingMode::Down, full).collect();
        let chan = |name: &str, v: f32| {
            AnyChannel::new(
                name,
                Levels::Mip {
                    level_data: levels
                        .iter()
                        .map(|(i, s)| FlatSamples::F32(vec![v + *i as f32 * 100.0; s.area()]))
                        .collect(),
                    rounding_mode: exr::math::RoundingMode::Down,
                },
            )
        };
        let layer = Layer::new(
            full,
            LayerAttributes::default(),
            Encoding {
                compression: Compression::ZIP16,
                blocks: Blocks::Tiles(Vec2(8, 8)),
                line_order: LineOrder::Increasing,
            },
            AnyChannels::sort(SmallVec::from_vec(vec![chan("R", 1.0), chan("G", 2.0), chan("B", 3.0)])),
        );
        Image::from_layer(layer).write().to_file(&p).unwrap();
        let m = EnvironmentMap::load(&p, &default_opts()).unwrap().map;
        assert_eq!((m.width, m.height), (32, 16));
        assert_eq!(m.texels[100], [1.0, 2.0, 3.0]);
    }

    #[test]
    fn file_without_colour_channels_is_rejected() {
        let p = tmp("no_colour.exr");
        let n = 16 * 8;
        write_channels(&p, (16, 8), vec![AnyChannel::new("A", FlatSamples::F32(vec![1.0; n]))]);
        let msg = load_err(&p, &default_opts());
        assert_error_format(&msg, &p);
        assert!(msg.contains("no colour channels"), "{msg}");
        let p = tmp("two_odd_channels.exr");
        write_channels(
            &p,
            (16, 8),
            vec![
                AnyChannel::new("U", FlatSamples::F32(vec![1.0; n])),
                AnyChannel::new("V", FlatSamples::F32(vec![1.0; n])),
            ],
        );
        let msg = load_err(&p, &default_opts());
        assert_error_format(&msg, &p);
        assert!(msg.contains("no colour channels"), "{msg}");
    }

    fn rgb_f32(path: &Path, w: usize, h: usize, f: impl Fn(usize) -> [f32; 3]) {
        let px: Vec<[f32; 3]> = (0..w * h).map(f).collect();
        let ch = |c: usize| FlatSamples::F32(px.iter().map(|p| p[c]).collect());
        write_channels(
            path,
            (w, h),
            vec![AnyChannel::new("R", ch(0)), AnyChannel::new("G", ch(1)), AnyChannel::new("B", ch(2))],
        );
    }

    #[test]
    fn nonfinite_texels_are_rejected_with_count_and_positions() {
        let p = tmp("nan.exr");
        rgb_f32(&p, 16, 8, |i| match i {
            3 => [f32::NAN, 1.0, 1.0],
            17 => [1.0, f32::INFINITY, f32::NAN],
            40 => [1.0, 1.0, f32::NEG_INFINITY],
            _ => [1.0, 2.0, 3.0],
        });
        let msg = load_err(&p, &default_opts());
        assert_error_format(&msg, &p);
        assert!(msg.contains("4 non-finite"), "{msg}");
        assert!(msg.contains("(3,0)") && msg.contains("(1,1)") && msg.contains("(8,2)"), "{msg}");
    }

    #[test]
    fn nonfinite_texels_are_clamped_with_warning_when_asked() {
        let p = tmp("nan_clamp.exr");
        rgb_f32(&p, 16, 8, |i| match i {
            3 => [f32::NAN, 1.0, 1.0],
            17 => [1.0, f32::INFINITY, f32::NAN],
            40 => [1.0, 1.0, f32::NEG_INFINITY],
            41 => [500.0, 1.0, 1.0],
            _ => [1.0, 2.0, 3.0],
        });
        let l = EnvironmentMap::load(&p, &EnvLoadOptions { clamp_nonfinite: true }).unwrap();
        assert_eq!(l.map.texels[3], [0.0, 1.0, 1.0]);
        assert_eq!(l.map.texels[17], [1.0, 500.0, 0.0]);
        assert_eq!(l.map.texels[40], [1.0, 1.0, 0.0]);
        assert!(l.notices.iter().any(|n| n.starts_with("warning") && n.contains("4 non-finite")), "{:?}", l.notices);
    }

    #[test]
    fn negative_texels_are_clamped_with_count_and_energy() {
        let p = tmp("negative.exr");
        rgb_f32(&p, 16, 8, |i| match i {
            5 => [-0.5, 1.0, 1.0],
            6 => [-1e-4, -2e-4, 1.0],
            70 => [1.0, 1.0, -3.0],
            _ => [1.0, 1.0, 1.0],
        });
        let l = EnvironmentMap::load(&p, &default_opts()).unwrap();
        assert_eq!(l.map.texels[5], [0.0, 1.0, 1.0]);
        assert_eq!(l.map.texels[6], [0.0, 0.0, 1.0]);
        assert_eq!(l.map.texels[70], [1.0, 1.0, 0.0]);
        assert!(l.map.texels.iter().flatten().all(|v| *v >= 0.0));
        let n = l.notices.iter().find(|n| n.contains("negative")).expect("no notice");
        assert!(n.contains("4 negative"), "{n}");
        assert!(n.contains("energy removed"), "{n}");
    }

    #[test]
    fn cropped_data_window_is_placed_in_the_display_window() {
        let p = tmp("cropped.exr");
        let (w, h) = (8usize, 4usize);
        let mut layer = Layer::new(
            (w, h),
            LayerAttributes::default(),
            Encoding::SMALL_LOSSLESS,
            AnyChannels::sort(SmallVec::from_vec(vec![
                AnyChannel::new("R", FlatSamples::F32(vec![1.0; w * h])),
                AnyChannel::new("G", FlatSamples::F32(vec![2.0; w * h])),
                AnyChannel::new("B", FlatSamples::F32(vec![3.0; w * h])),
            ])),
        );
        layer.attributes.layer_position = Vec2(4, 2);
        let display = exr::meta::attribute::IntegerBounds::new((0, 0), (32, 16));
        Image::new(ImageAttributes::new(display), layer).write().to_file(&p).unwrap();
        let l = EnvironmentMap::load(&p, &default_opts()).unwrap();
        assert_eq!((l.map.width, l.map.height), (32, 16));
        assert_eq!(l.map.texels[0], [0.0; 3]);
        assert_eq!(l.map.texels[2 * 32 + 4], [1.0, 2.0, 3.0]);
        assert_eq!(l.map.texels[5 * 32 + 11], [1.0, 2.0, 3.0]);
        assert_eq!(l.map.texels[6 * 32 + 11], [0.0; 3]);
        assert!(l.notices.iter().any(|n| n.contains("display window")), "{:?}", l.notices);
    }

    #[test]
    fn declared_primaries_are_converted_to_rec709() {
        let p = tmp("aces.exr");
        let n = 16 * 8;
        let layer = Layer::new(
            (16, 8),
            LayerAttributes::default(),
            Encoding::SMALL_LOSSLESS,
            AnyChannels::sort(SmallVec::from_vec(vec![
                AnyChannel::new("R", FlatSamples::F32(vec![1.0; n])),
                AnyChannel::new("G", FlatSamples::F32(vec![1.0; n])),
                AnyChannel::new("B", FlatSamples::F32(vec![1.0; n])),
            ])),
        );
        let mut image = Image::from_layer(layer);
        // ACES 2065-1 (AP0, D60 white).
        image.attributes.chromaticities = Some(exr::meta::attribute::Chromaticities {
            red: Vec2(0.7347, 0.2653),
            green: Vec2(0.0, 1.0),
            blue: Vec2(0.0001, -0.0770),
            white: Vec2(0.32168, 0.33767),
        });
        image.write().to_file(&p).unwrap();
        let l = EnvironmentMap::load(&p, &default_opts()).unwrap();
        let t = l.map.texels[0];
        // AP0 white is D60: same luminance, slightly warmer than Rec. 709's D65 white.
        assert!((luminance(t) - 1.0).abs() < 2e-3, "{t:?}");
        assert!(t[0] > t[2], "{t:?}");
        assert!(l.notices.iter().any(|n| n.contains("Rec. 709")), "{:?}", l.notices);
    }

    #[test]
    fn non_equirectangular_exr_is_rejected_with_its_size() {
        let p = tmp("300x200.exr");
        rgb_f32(&p, 300, 200, |_| [1.0; 3]);
        let msg = load_err(&p, &default_opts());
        assert_error_format(&msg, &p);
        assert!(msg.contains("300×200") && msg.contains("2:1"), "{msg}");
    }
}

// ---------------------------------------------------------------------------------------------
// bad files

#[test]
fn missing_file_error_names_file_and_os_error() {
    let p = tmp("does_not_exist.exr");
    let msg = load_err(&p, &default_opts());
    assert_error_format(&msg, &p);
    assert!(msg.contains("os error"), "{msg}");
}

#[test]
fn text_file_is_not_an_environment() {
    let p = tmp("notes.exr");
    std::fs::write(&p, "just some text\nnothing to see\n").unwrap();
    let msg = load_err(&p, &default_opts());
    assert_error_format(&msg, &p);
    assert!(msg.contains("not an OpenEXR or Radiance HDR file") && msg.contains("text"), "{msg}");
}

#[test]
fn png_is_not_an_environment() {
    let p = tmp("picture.hdr");
    image::RgbImage::from_pixel(8, 4, image::Rgb([10, 20, 30])).save_with_format(&p, image::ImageFormat::Png).unwrap();
    let msg = load_err(&p, &default_opts());
    assert_error_format(&msg, &p);
    assert!(msg.contains("PNG"), "{msg}");
}

#[test]
fn empty_file_and_directory_are_rejected() {
    let p = tmp("empty.exr");
    std::fs::write(&p, b"").unwrap();
    let msg = load_err(&p, &default_opts());
    assert_error_format(&msg, &p);
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("environment-tests");
    std::fs::create_dir_all(&d).unwrap();
    let msg = load_err(&d, &default_opts());
    assert_error_format(&msg, &d);
}

#[test]
fn truncated_exr_gives_one_line_error() {
    let p = tmp("truncated.exr");
    write_exr(&wide_range_map(), &p, ExrPrecision::Float, false).unwrap();
    let bytes = std::fs::read(&p).unwrap();
    std::fs::write(&p, &bytes[..bytes.len() / 3]).unwrap();
    let msg = load_err(&p, &default_opts());
    assert_error_format(&msg, &p);
}

#[test]
fn non_equirectangular_hdr_is_rejected() {
    let p = tmp("square.hdr");
    write_hdr(&EnvironmentMap::from_fn(16, 16, |_| [1.0; 3]), &p).unwrap();
    let msg = load_err(&p, &default_opts());
    assert_error_format(&msg, &p);
    assert!(msg.contains("16×16 is not 2:1"), "{msg}");
}

#[test]
fn one_by_one_maps_load_and_light() {
    let map = EnvironmentMap::from_fn(1, 1, |_| [0.25, 0.5, 1.0]);
    for (name, write) in [
        (
            "one.exr",
            Box::new(|p: &Path| write_exr(&map, p, ExrPrecision::Float, false))
                as Box<dyn Fn(&Path) -> anyhow::Result<()>>,
        ),
        ("one.hdr", Box::new(|p: &Path| write_hdr(&map, p))),
    ] {
        let p = tmp(name);
        write(&p).unwrap();
        let l = EnvironmentMap::load(&p, &default_opts()).unwrap();
        assert_eq!((l.map.width, l.map.height), (1, 1));
        assert_eq!(l.map.texels[0], [0.25, 0.5, 1.0]);
        let set = LightSet::extract(&l.map, LightMode::default(), 0.0, 1.0);
        check_light_set(&set, name, 1e-5);
    }
}

// ---------------------------------------------------------------------------------------------
// real captures

#[test]
fn real_captures_load_with_negative_texel_notice() {
    for p in real_captures() {
        let l = EnvironmentMap::load(&p, &default_opts()).unwrap_or_else(|e| panic!("{e:#}"));
        assert_eq!((l.map.width, l.map.height), (1024, 512), "{}", p.display());
        assert!(l.map.texels.iter().flatten().all(|v| v.is_finite() && *v >= 0.0));
        assert!(l.notices.iter().any(|n| n.contains("negative texel")), "{}: {:?}", p.display(), l.notices);
        assert!(l.map.peak() > 10.0, "{}: implausible peak {}", p.display(), l.map.peak());
    }
}

#[test]
fn real_captures_conserve_energy_in_every_mode() {
    for p in real_captures() {
        let map = EnvironmentMap::load(&p, &default_opts()).unwrap().map;
        for mode in modes() {
            let set = LightSet::extract(&map, mode, 0.0, 1.0);
            check_light_set(&set, &format!("{} {mode}", p.display()), 1e-5);
            if let LightMode::Budget { count } = mode {
                assert_eq!(set.lights.len(), count as usize, "{} {mode}", p.display());
            }
        }
    }
}

#[test]
fn real_sunrise_sun_is_one_small_light() {
    let p = Path::new("/work/shared/env/sunrise.exr");
    if !p.is_file() {
        println!("skipped: {} not present", p.display());
        return;
    }
    let map = EnvironmentMap::load(p, &default_opts()).unwrap().map;
    let set = LightSet::extract(&map, LightMode::Budget { count: 256 }, 0.0, 1.0);
    let sun = brightest(&set);
    let frac = light_lum_energy(sun) / luminance(set.map_integral);
    // The sun holds about half of this capture's energy; its light must be a few pixels big.
    assert!(frac > 0.4, "sun light holds only {frac}");
    assert!(sun.solid_angle < 1e-3, "sun light Ω {}", sun.solid_angle);
}
#[test]
fn extraction_is_fast_on_a_1024_map() {
    // Not a benchmark: catches accidental per-light passes over the image (those take minutes).
    let map = match real_captures().first() {
        Some(p) => EnvironmentMap::load(p, &default_opts()).unwrap().map,
        None => EnvironmentMap::from_fn(1024, 512, |d| [d[1].max(0.0) * 3.0 + 0.1; 3]),
    };
    for mode in ["cube:32", "1024"] {
        let t = Instant::now();
        let set = LightSet::extract(&map, mode.parse().unwrap(), 0.0, 1.0);
        let dt = t.elapsed();
        println!("{mode}: {} lights in {dt:?}", set.lights.len());
        assert!(dt.as_secs_f64() < 10.0, "{mode} took {dt:?}");
    }
}

// ---------------------------------------------------------------------------------------------
// map geometry

#[test]
fn pixel_direction_and_sample_invert_each_other() {
    let (w, h) = (64u32, 32u32);
    let map = EnvironmentMap { width: w, height: h, texels: (0..w * h).map(|i| [i as f32, 0.0, 0.0]).collect() };
    for row in 0..h {
        for col in 0..w {
            let d = map.pixel_direction(col, row);
            assert!((dot(d, d) - 1.0).abs() < 1e-6);
            assert_eq!(map.pixel_of(d), (col, row));
            assert_eq!(map.sample(d)[0], (row * w + col) as f32);
        }
    }
}

#[test]
fn direction_convention_matches_the_design() {
    let map = EnvironmentMap::from_fn(8, 4, |_| [0.0; 3]);
    // u = 0.5 + atan2(z, x)/2π, t = acos(y)/π
    assert_eq!(map.pixel_of([1.0, 0.01, 0.01]), (4, 1)); // +X, just above the horizon: centre column
    assert_eq!(map.pixel_of([-0.01, 0.0, 1.0]).0, 6); // +Z: u = 0.75 (column boundary 5|6)
    assert_eq!(map.pixel_of([0.01, 0.0, -1.0]).0, 2); // -Z: u = 0.25
    assert_eq!(map.pixel_of([-1.0, 0.0, -0.01]).0, 0); // -X: seam
    assert_eq!(map.pixel_of([0.0, 1.0, 0.0]).1, 0); // zenith: top row
    assert_eq!(map.pixel_of([0.0, -1.0, 0.0]).1, 3); // nadir: bottom row
    // The formula itself, on many directions and an odd-sized map.
    let map = EnvironmentMap::from_fn(37, 19, |_| [0.0; 3]);
    for i in 0..2000 {
        let a = i as f64 * 2.399_963;
        let y = 1.0 - 2.0 * (i as f64 + 0.5) / 2000.0;
        let r = (1.0 - y * y).sqrt();
        let d = [r * a.cos(), y, r * a.sin()];
        let u = 0.5 + d[2].atan2(d[0]) / (2.0 * PI);
        let t = d[1].acos() / PI;
        let expect = (((u * 37.0).floor() as u32) % 37, ((t * 19.0).floor() as u32).min(18));
        assert_eq!(map.pixel_of(d.map(|v| v as f32)), expect, "{d:?}");
    }
    let map = EnvironmentMap::from_fn(8, 4, |_| [0.0; 3]);
    let d = map.pixel_direction(4, 1);
    let theta = (1.5f64 / 4.0) * PI;
    let phi = (4.5f64 / 8.0 - 0.5) * 2.0 * PI;
    let expect = [theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin()];
    for c in 0..3 {
        assert!((d[c] as f64 - expect[c]).abs() < 1e-6);
    }
}

#[test]
fn solid_angles_and_integrals_are_exact() {
    for (w, h) in [(1u32, 1u32), (8, 4), (64, 32), (1000, 500)] {
        let map = EnvironmentMap::from_fn(w, h, |_| [1.0, 2.0, 0.5]);
        let total: f64 = (0..h).map(|r| map.row_solid_angle(r) * w as f64).sum();
        assert!((total - 4.0 * PI).abs() < 1e-9, "{w}×{h}: {total}");
        let i = map.integral();
        assert!(rel_err(i[1], 8.0 * PI) < 1e-12, "{w}×{h}: {i:?}");
    }
    let c = EnvironmentMap::constant([1.0, 1.0, 1.0]);
    assert!(rel_err(c.integral()[0], 4.0 * PI) < 1e-12);
    let hz = EnvironmentMap::horizon([3.0, 2.0, 1.0]);
    assert!(rel_err(hz.integral()[0], 6.0 * PI) < 1e-12);
    assert!(rel_err(hz.integral()[2], 2.0 * PI) < 1e-12);
}

#[test]
fn sun_and_sky_has_the_documented_sun() {
    let r = 1.5f32.to_radians();
    let map = EnvironmentMap::sun_and_sky(SKY, sun_dir(), 1e5, r);
    assert_eq!(map.width, 2 * map.height);
    let sun = map.sun_texels(sun_dir(), r);
    assert!(sun.len() >= 7, "sun covers only {} pixels", sun.len());
    let omega_sun: f64 = sun.iter().map(|&(_, row)| map.row_solid_angle(row)).sum();
    let expect = SKY[1] as f64 * 4.0 * PI + (1e5 - 1.0) * SKY[1] as f64 * omega_sun;
    assert!(rel_err(map.integral()[1], expect) < 1e-6);
    // The pixel solid angles of the disc approximate the disc's own solid angle.
    let disc = 2.0 * PI * (1.0 - (r as f64).cos());
    assert!(rel_err(omega_sun, disc) < 0.25, "{omega_sun} vs {disc}");
}

// ---------------------------------------------------------------------------------------------
// light sets: energy

fn energy_maps() -> Vec<(&'static str, EnvironmentMap, Option<[f64; 3]>)> {
    let l = [0.3f32, 0.5, 0.9];
    let four_pi = l.map(|v| v as f64 * 4.0 * PI);
    vec![
        ("constant 1×1", EnvironmentMap::from_fn(1, 1, |_| l), Some(four_pi)),
        ("constant 8×4", EnvironmentMap::constant(l), Some(four_pi)),
        ("horizon", EnvironmentMap::horizon(l), Some(l.map(|v| v as f64 * 2.0 * PI))),
        ("sun and sky 1e5", EnvironmentMap::sun_and_sky(SKY, sun_dir(), 1e5, 1.5f32.to_radians()), None),
    ]
}

#[test]
fn energy_is_conserved_for_every_mode_and_map() {
    for (name, map, exact) in energy_maps() {
        for mode in modes() {
            let set = LightSet::extract(&map, mode, 0.0, 1.0);
            let what = format!("{name}, {mode}");
            check_light_set(&set, &what, 1e-5);
            if let Some(exact) = exact {
                for c in 0..3 {
                    assert!(rel_err(set.map_integral[c], exact[c]) < 1e-9, "{what}: integral");
                }
            }
        }
    }
}

#[test]
fn budgets_fill_even_on_tiny_constant_maps() {
    for map in [EnvironmentMap::from_fn(1, 1, |_| [1.0; 3]), EnvironmentMap::constant([1.0; 3])] {
        for k in [1u32, 8, 64, 256, 1024] {
            let set = LightSet::extract(&map, LightMode::Budget { count: k }, 0.0, 1.0);
            assert_eq!(set.lights.len(), k as usize, "{}×{} K={k}", map.width, map.height);
            assert!(set.notes.is_empty(), "{:?}", set.notes);
            // A uniform sphere split into K lights: none should be huge.
            let max_omega = set.lights.iter().map(|l| l.solid_angle).fold(0.0, f32::max) as f64;
            assert!(max_omega < 8.0 * 4.0 * PI / k as f64, "K={k}: largest light {max_omega} sr");
        }
    }
}

#[test]
fn cube_lights_on_a_constant_map_have_its_radiance() {
    for map in [EnvironmentMap::from_fn(1, 1, |_| [2.0; 3]), EnvironmentMap::constant([2.0; 3])] {
        for n in [4u32, 16, 32] {
            let set = LightSet::extract(&map, LightMode::Cube { face_size: n }, 0.0, 1.0);
            assert_eq!(set.lights.len(), 6 * (n * n) as usize);
            assert_eq!(set.dropped, 0);
            for l in &set.lights {
                let r = l.radiance[0];
                assert!((r - 2.0).abs() < 0.2, "cube:{n}: texel radiance {r} (Ω {})", l.solid_angle);
            }
        }
    }
}

#[test]
fn horizon_lights_stay_above_the_horizon() {
    let map = EnvironmentMap::horizon([1.0; 3]);
    for mode in modes() {
        let set = LightSet::extract(&map, mode, 0.0, 1.0);
        for l in &set.lights {
            assert!(l.direction[1] > 0.0, "{mode}: light below the horizon {l:?}");
        }
        let omega: f64 = set.lights.iter().map(|l| l.solid_angle as f64).sum();
        if mode != (LightMode::Budget { count: 1 }) {
            // Lights do not claim the black ground: they cover the sky's 2π.
            assert!(rel_err(omega, 2.0 * PI) < 1e-5, "{mode}: lights cover {omega} sr");
        }
        if let LightMode::Cube { face_size } = mode {
            assert_eq!(set.dropped, 3 * (face_size * face_size) as usize, "{mode}");
        }
    }
}

#[test]
fn black_map_gives_no_lights() {
    let map = EnvironmentMap::constant([0.0; 3]);
    for mode in modes() {
        let set = LightSet::extract(&map, mode, 0.0, 1.0);
        assert!(set.lights.is_empty());
        assert_eq!(set.captured, [0.0; 3]);
    }
}

// ---------------------------------------------------------------------------------------------
// light sets: orientation, rotation, intensity

#[test]
fn cap_lights_point_at_their_axis() {
    let axes: [[f32; 3]; 6] =
        [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]];
    for axis in axes {
        let map = cap_map(axis, 10.0);
        for mode in modes() {
            let set = LightSet::extract(&map, mode, 0.0, 1.0);
            check_light_set(&set, &format!("cap {axis:?} {mode}"), 1e-5);
            let a = angle_deg(mean_direction(&set), axis.map(|v| v as f64));
            assert!(a < 2.0, "cap {axis:?}, {mode}: mean light direction {a:.2}° off");
            // No light may point away from a 10° cap.
            for l in &set.lights {
                let off = angle_deg(l.direction.map(|v| v as f64), axis.map(|v| v as f64));
                assert!(off < 11.0, "cap {axis:?}, {mode}: light {off:.1}° off axis");
            }
        }
    }
}

#[test]
fn rotation_by_90_degrees_turns_plus_x_to_minus_z() {
    // d_world = R_y(90°) · d_map: +X → −Z (counter-clockwise seen from above).
    let map = cap_map([1.0, 0.0, 0.0], 3.0);
    for mode in modes() {
        let set0 = LightSet::extract(&map, mode, 0.0, 1.0);
        let set = LightSet::extract(&map, mode, 90.0, 1.0);
        let d = brightest(&set).direction.map(|v| v as f64);
        assert!(angle_deg(d, [0.0, 0.0, -1.0]) < 2.0, "{mode}: rotated sun at {d:?}");
        let d = mean_direction(&set);
        assert!(angle_deg(d, [0.0, 0.0, -1.0]) < 1.0, "{mode}: rotated mean at {d:?}");
        // A rigid rotation of the unrotated set: same energies, rotated directions.
        assert_eq!(set0.lights.len(), set.lights.len());
        for (a, b) in set0.lights.iter().zip(&set.lights) {
            assert_eq!(a.radiance, b.radiance);
            assert_eq!(a.solid_angle, b.solid_angle);
            let expect = [a.direction[2], a.direction[1], -a.direction[0]];
            for c in 0..3 {
                assert!((b.direction[c] - expect[c]).abs() < 1e-6, "{mode}");
            }
        }
    }
    // −90° takes +X to +Z, 180° to −X.
    let set = LightSet::extract(&map, LightMode::Budget { count: 64 }, -90.0, 1.0);
    assert!(angle_deg(mean_direction(&set), [0.0, 0.0, 1.0]) < 1.0);
    let set = LightSet::extract(&map, LightMode::Budget { count: 64 }, 180.0, 1.0);
    assert!(angle_deg(mean_direction(&set), [-1.0, 0.0, 0.0]) < 1.0);
}

#[test]
fn intensity_scales_energy() {
    let map = EnvironmentMap::sun_and_sky(SKY, sun_dir(), 1e4, 2f32.to_radians());
    for mode in modes() {
        let one = LightSet::extract(&map, mode, 0.0, 1.0);
        let two = LightSet::extract(&map, mode, 0.0, 2.0);
        for c in 0..3 {
            assert!(rel_err(two.captured[c], 2.0 * one.captured[c]) < 1e-6, "{mode}");
            assert!(rel_err(two.map_integral[c], 2.0 * one.map_integral[c]) < 1e-12, "{mode}");
        }
        check_light_set(&two, &format!("intensity 2, {mode}"), 1e-5);
        let zero = LightSet::extract(&map, mode, 0.0, 0.0);
        assert!(zero.lights.is_empty() && zero.captured == [0.0; 3], "{mode}");
    }
}

// ---------------------------------------------------------------------------------------------
// the sun

fn sun_energy(map: &EnvironmentMap, dir: [f32; 3], radius: f32) -> f64 {
    map.sun_texels(dir, radius)
        .iter()
        .map(|&(c, r)| luminance(map.texels[(r * map.width + c) as usize]) * map.row_solid_angle(r))
        .sum()
}

#[test]
fn budget_64_keeps_the_sun_as_one_light_and_cube_4_cannot() {
    let radius = 1.5f32.to_radians();
    let map = EnvironmentMap::sun_and_sky(SKY, sun_dir(), 1e5, radius);
    let e_sun = sun_energy(&map, sun_dir(), radius);
    let set = LightSet::extract(&map, LightMode::Budget { count: 64 }, 0.0, 1.0);
    check_light_set(&set, "sun, 64", 1e-5);
    let sun = brightest(&set);
    let e = light_lum_energy(sun);
    assert!(e >= 0.99 * e_sun && e <= 1.01 * e_sun, "sun light holds {} of the sun", e / e_sun);
    let off = angle_deg(sun.direction.map(|v| v as f64), sun_dir().map(|v| v as f64));
    assert!(off <= radius.to_degrees() as f64, "sun light {off}° from the sun");
    let disc = 2.0 * PI * (1.0 - (radius as f64).cos());
    assert!((sun.solid_angle as f64) < 3.0 * disc, "sun light Ω {} vs disc {disc}", sun.solid_angle);

    let cube = LightSet::extract(&map, LightMode::Cube { face_size: 4 }, 0.0, 1.0);
    let csun = brightest(&cube);
    let ratio = csun.solid_angle / sun.solid_angle;
    assert!(ratio > 10.0, "cube:4's brightest light is only {ratio}× the budget's sun light");
}

#[test]
fn sun_stays_one_light_anywhere_on_the_sphere() {
    let radius = 1.5f32.to_radians();
    // On the map's seam (−X), near the zenith, at the zenith, below the horizon.
    for dir in [[-1.0f32, 0.1, 0.02], [0.05, 1.0, 0.1], [0.0, 1.0, 0.0], [0.3, -0.4, 0.8]] {
        let d = norm(dir.map(|v| v as f64)).map(|v| v as f32);
        let map = EnvironmentMap::sun_and_sky(SKY, d, 1e5, radius);
        let e_sun = sun_energy(&map, d, radius);
        for k in [64u32, 1024] {
            let set = LightSet::extract(&map, LightMode::Budget { count: k }, 0.0, 1.0);
            let sun = brightest(&set);
            let frac = light_lum_energy(sun) / e_sun;
            assert!((0.99..=1.01).contains(&frac), "sun at {d:?}, K={k}: light holds {frac}");
            let off = angle_deg(sun.direction.map(|v| v as f64), d.map(|v| v as f64));
            assert!(off <= radius.to_degrees() as f64, "sun at {d:?}, K={k}: {off}° off");
        }
    }
}

#[test]
fn dim_uniform_sky_gets_large_lights_around_a_bright_sun() {
    let radius = 1.5f32.to_radians();
    let map = EnvironmentMap::sun_and_sky(SKY, sun_dir(), 1e5, radius);
    let set = LightSet::extract(&map, LightMode::Budget { count: 64 }, 0.0, 1.0);
    let sun = brightest(&set);
    let sky_lights: Vec<&Light> = set.lights.iter().filter(|l| !std::ptr::eq(*l, sun)).collect();
    let mean_sky_omega: f64 = sky_lights.iter().map(|l| l.solid_angle as f64).sum::<f64>() / sky_lights.len() as f64;
    assert!(mean_sky_omega > 50.0 * sun.solid_angle as f64, "sky lights too small");
}

// ---------------------------------------------------------------------------------------------
// light mode strings

#[test]
fn light_mode_parses_from_cli_strings_and_displays_back() {
    for (s, m) in [
        ("cube:32", LightMode::Cube { face_size: 32 }),
        ("cube:4", LightMode::Cube { face_size: 4 }),
        ("1024", LightMode::Budget { count: 1024 }),
        ("1", LightMode::Budget { count: 1 }),
    ] {
        assert_eq!(s.parse::<LightMode>().unwrap(), m);
        assert_eq!(m.to_string(), s);
    }
    for bad in ["", "cube", "cube:", "cube:0", "cube:-1", "0", "-8", "12.5", "1e3", "auto", "sphere:8"] {
        let e = bad.parse::<LightMode>().unwrap_err().to_string();
        assert!(e.contains(&format!("'{bad}'")) && e.contains("cube:N"), "{bad:?}: {e}");
    }
    assert_eq!(LightMode::default(), LightMode::Budget { count: 1024 });
    assert_eq!(LightMode::default().to_string().parse::<LightMode>().unwrap(), LightMode::default());
}
