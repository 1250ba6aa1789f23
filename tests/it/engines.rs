//! The lightmap as three.js and Babylon.js show it, in a real browser: a
//! baked fixture is loaded with each engine's snippet from docs/engines.md
//! (taken from the markdown by pipeline/engines.mjs, so the docs are what is
//! tested) in headless Chromium, and the `pbr+lightmap` form (the input's
//! PBR material lit by `MOZ_lightmap` alone) is drawn from the same camera as
//! the unlit `baked` preview and compared with it pixel by pixel.
//!
//! Tolerance, per pixel and channel, in linear light: the lit value lies
//! between 0.88 times the preview's and the preview's, each widened by the
//! 8-bit steps on the way (the preview texture's and the output's rounding,
//! a code each, and half a code step of the lightmap, intensity/510 of
//! irradiance, times an albedo of at most 1, over π). The lower end is the
//! engines' PBR diffuse, which gives the light a dielectric reflects
//! specularly (F0 = 0.04) to a specular term the lightmap does not feed:
//! Babylon's `LEGACY_SPECULAR_ENERGY_CONSERVATION` takes 4 % everywhere,
//! three.js (r155 on) its multiple-scattering share, more at grazing angles.
//! The same file with its `intensity` ignored (1), with π wrong (the
//! intensity π times too large, as a reader that takes the texture as L_lm),
//! or with its texture written in sRGB must fail the check in both engines.
//!
//! The browser is Debian's `chromium` and the npm packages are those
//! `pipeline/setup.sh` installs; without them this test fails, it never skips.

use std::path::{Path, PathBuf};

use serde_json::Value;

use crate::common::{bake_file, fixture, node};

/// The lit form may be this much darker than the preview in linear light.
const SPECULAR_SHARE_FLOOR: f64 = 0.88;
/// The share of covered pixel channels allowed outside the bounds.
const OUTLIERS: f64 = 0.001;

fn srgb_to_linear(code: f64) -> f64 {
    let c = (code / 255.0).clamp(0.0, 1.0);
    if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
}

/// How a lit picture compares with the preview drawn from the same camera.
#[derive(Debug)]
struct Comparison {
    /// Channels where either picture is not black.
    covered: usize,
    /// Of those, the ones outside the bounds.
    outside: usize,
    /// Median and extremes of lit / preview in linear light, over channels
    /// the preview shows between codes 20 and 250 (away from black and clipping).
    ratios: [f64; 3],
    mean_code_difference: f64,
}

impl Comparison {
    fn passes(&self) -> bool {
        self.covered > 10_000 && self.outside as f64 <= OUTLIERS * self.covered as f64
    }
}

/// Compares `lit` with `preview` (module documentation), `intensity` being
/// MOZ_lightmap's.
fn compare(preview: &image::RgbImage, lit: &image::RgbImage, intensity: f64) -> Comparison {
    assert_eq!(preview.dimensions(), lit.dimensions());
    let lightmap_step = intensity / 510.0 / std::f64::consts::PI;
    let (mut covered, mut outside, mut ratios, mut difference) = (0, 0, Vec::new(), 0.0);
    for (p, l) in preview.pixels().zip(lit.pixels()) {
        for c in 0..3 {
            let (a, b) = (p[c] as f64, l[c] as f64);
            if a == 0.0 && b == 0.0 {
                continue;
            }
            covered += 1;
            difference += (a - b).abs();
            let low = SPECULAR_SHARE_FLOOR * srgb_to_linear(a - 1.0) - lightmap_step;
            let high = srgb_to_linear(a + 1.0) + lightmap_step;
            if srgb_to_linear(b + 0.5) < low || srgb_to_linear(b - 0.5) > high {
                outside += 1;
            }
            if (20.0..=250.0).contains(&a) {
                ratios.push(srgb_to_linear(b) / srgb_to_linear(a));
            }
        }
    }
    ratios.sort_by(f64::total_cmp);
    let ratios = match ratios.len() {
        0 => [f64::NAN; 3],
        n => [ratios[0], ratios[n / 2], ratios[n - 1]],
    };
    Comparison { covered, outside, ratios, mean_code_difference: difference / covered.max(1) as f64 }
}

/// A copy of the GLB at `from`, written to `to`, with its JSON and binary
/// chunk changed by `change`.
fn mutate(from: &Path, to: &Path, change: impl FnOnce(&mut Value, &mut Vec<u8>)) {
    let bytes = std::fs::read(from).unwrap();
    let glb = gltf::binary::Glb::from_slice(&bytes).unwrap();
    let mut json: Value = serde_json::from_slice(&glb.json).unwrap();
    let mut bin = glb.bin.unwrap().into_owned();
    change(&mut json, &mut bin);
    json["buffers"][0]["byteLength"] = bin.len().into();
    std::fs::write(to, bake::export::glb::encode(&serde_json::to_vec(&json).unwrap(), &bin)).unwrap();
}

/// A change to a GLB's JSON and binary chunk.
type Change = Box<dyn Fn(&mut Value, &mut Vec<u8>)>;

/// Every material's MOZ_lightmap extension.
fn lightmaps(json: &mut Value) -> Vec<&mut Value> {
    let materials = json["materials"].as_array_mut().unwrap();
    materials.iter_mut().filter_map(|m| m.pointer_mut("/extensions/MOZ_lightmap")).collect()
}

/// The MOZ_lightmap texture's PNG codes re-encoded as sRGB colour, appended
/// to `bin` as the image's new bytes: a lightmap written as a colour picture.
fn lightmap_as_srgb(json: &mut Value, bin: &mut Vec<u8>) {
    let texture = lightmaps(json)[0]["index"].as_u64().unwrap() as usize;
    let image = json["textures"][texture]["source"].as_u64().unwrap() as usize;
    let view = &json["bufferViews"][json["images"][image]["bufferView"].as_u64().unwrap() as usize];
    let start = view["byteOffset"].as_u64().unwrap_or(0) as usize;
    let png = &bin[start..start + view["byteLength"].as_u64().unwrap() as usize];
    let mut codes = image::load_from_memory(png).unwrap().to_rgb8();
    for c in codes.iter_mut() {
        *c = bake::export::lightmap::linear_to_srgb8(*c as f32 / 255.0);
    }
    let mut encoded = std::io::Cursor::new(Vec::new());
    codes.write_to(&mut encoded, image::ImageFormat::Png).unwrap();
    let encoded = encoded.into_inner();
    bin.resize(bin.len().next_multiple_of(4), 0);
    let views = json["bufferViews"].as_array_mut().unwrap();
    views.push(serde_json::json!({ "buffer": 0, "byteOffset": bin.len(), "byteLength": encoded.len() }));
    json["images"][image]["bufferView"] = (views.len() - 1).into();
    bin.extend_from_slice(&encoded);
}

#[test]
fn three_and_babylon_draw_the_lightmapped_pbr_form_as_the_preview() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("baked");
    bake_file(
        &fixture("sphere_on_ground.glb"),
        &out,
        &["--max-atlas-size", "128", "--lights", "256", "--material", "engine", "-q"],
    );
    let baked = out.join("sphere_on_ground.glb");
    let mut json: Value =
        serde_json::from_slice(&gltf::binary::Glb::from_slice(&std::fs::read(&baked).unwrap()).unwrap().json).unwrap();
    let intensity = lightmaps(&mut json)[0]["intensity"].as_f64().unwrap();
    let mutations: [(&str, Change); 3] = [
        (
            "intensity_ignored",
            Box::new(|json, _| lightmaps(json).into_iter().for_each(|l| l["intensity"] = 1.0.into())),
        ),
        (
            "pi_wrong",
            Box::new(move |json, _| {
                let wrong = intensity * std::f64::consts::PI;
                lightmaps(json).into_iter().for_each(|l| l["intensity"] = wrong.into())
            }),
        ),
        ("srgb_texture", Box::new(lightmap_as_srgb)),
    ];
    let mut files: Vec<PathBuf> = vec![baked.clone()];
    for (name, change) in &mutations {
        let file = dir.path().join(format!("{name}.glb"));
        mutate(&baked, &file, change);
        files.push(file);
    }

    let pictures = dir.path().join("pictures");
    std::fs::create_dir(&pictures).unwrap();
    let mut args: Vec<&std::ffi::OsStr> = vec![pictures.as_os_str()];
    args.extend(files.iter().map(|f| f.as_os_str()));
    let start = std::time::Instant::now();
    node("pipeline/engines.mjs", &args);
    eprintln!("drawn in {:.1} s", start.elapsed().as_secs_f64());
    // BAKE_KEEP_ENGINE_PICTURES=DIR keeps them for a look (docs/engines-*.png are two of them).
    if let Some(keep) = std::env::var_os("BAKE_KEEP_ENGINE_PICTURES") {
        for entry in std::fs::read_dir(&pictures).unwrap() {
            let path = entry.unwrap().path();
            std::fs::copy(&path, Path::new(&keep).join(path.file_name().unwrap())).unwrap();
        }
    }

    let load = |stem: &str, engine: &str, variant: &str| {
        let path = pictures.join(format!("{stem}.{engine}.{variant}.png"));
        image::open(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display())).to_rgb8()
    };
    for engine in ["three", "babylon"] {
        for file in &files {
            let stem = file.file_stem().unwrap().to_str().unwrap();
            let comparison = compare(&load(stem, engine, "baked"), &load(stem, engine, "pbr+lightmap"), intensity);
            eprintln!("{engine} {stem}: {comparison:?}");
            assert_eq!(
                comparison.passes(),
                file == &baked,
                "{engine}, {stem}: {} of {} channels outside the bounds (lit/preview in linear light: min, median, \
                 max {:?}; mean difference {:.2} codes)",
                comparison.outside,
                comparison.covered,
                comparison.ratios,
                comparison.mean_code_difference,
            );
        }
    }
}
