//! The KTX2 lightmap (`NAME.lightmap0.ktx2`), read back as Bevy reads it:
//! the `ktx2` crate's Reader for the container (E5B9G9R9, the EXR's size,
//! one level, Zstandard, a basic linear RGB descriptor), ruzstd for the
//! level, and every texel equal to the EXR's at the same place within
//! E5B9G9R9's precision; a file with its rows flipped, its values × π or
//! sRGB-encoded fails that comparison. Each node that draws baked
//! primitives names the file, its UV set, `uv_rect` and primitives, and the
//! camera EV100 matching the preview, in `extras.bake`.

use crate::common::{bake_file, fixture, read_exr, read_ktx2};
use bake::asset::SourceAsset;
use bake::export::ktx2::pack_e5b9g9r9;
use serde_json::json;

/// Tiny bakes: the file and its values are checked here, not the light.
const TINY: [&str; 7] = ["--max-atlas-size", "64", "--lights", "64", "--max-shots", "64", "-q"];

/// The first texel of `ktx2` farther from the EXR's `exr` than E5B9G9R9's
/// rounding allows (half a mantissa step: 2^-9 of the texel's largest
/// channel, or of the smallest exponent's step), as a message; else the
/// worst error relative to the texel's largest channel.
fn compare(ktx2: &[[f32; 3]], exr: &[[f32; 3]]) -> Result<f64, String> {
    if ktx2.len() != exr.len() {
        return Err(format!("{} texels for the EXR's {}", ktx2.len(), exr.len()));
    }
    let mut worst = 0.0f64;
    for (i, (k, e)) in ktx2.iter().zip(exr).enumerate() {
        let largest = f64::from(e.iter().copied().fold(0.0f32, f32::max));
        let allowed = largest * 2f64.powi(-9) * (1.0 + 2f64.powi(-9)) + 2f64.powi(-25);
        for c in 0..3 {
            let error = (f64::from(k[c]) - f64::from(e[c])).abs();
            if error > allowed {
                return Err(format!("texel {i}: {k:?} for the EXR's {e:?}"));
            }
            if largest > 0.0 {
                worst = worst.max(error / largest);
            }
        }
    }
    Ok(worst)
}

/// `pixels` with rows in the opposite order.
fn flipped(pixels: &[[f32; 3]], width: usize) -> Vec<[f32; 3]> {
    pixels.chunks_exact(width).rev().flatten().copied().collect()
}

#[test]
fn the_ktx2_lightmap_holds_the_exrs_texels_in_place() {
    let dir = tempfile::tempdir().unwrap();
    // Under the sun, L_lm reaches far above 1; the ground's shadow makes rows differ.
    let report = bake_file(&fixture("sphere_on_ground.glb"), dir.path(), &TINY);
    let path = dir.path().join("sphere_on_ground.lightmap0.ktx2");
    assert!(report.scenes[0].outputs.iter().any(|o| o.ends_with("sphere_on_ground.lightmap0.ktx2")));
    let bytes = std::fs::read(&path).unwrap();
    let (width, height, depth, pixels) = read_ktx2(&bytes);
    assert_eq!(depth, 0, "a 2D image");
    let (exr_width, exr) = read_exr(&dir.path().join("sphere_on_ground.lightmap0.exr"));
    assert_eq!((width, height), (exr_width, exr.len() / exr_width), "the EXR's size");
    let worst = compare(&pixels, &exr).unwrap_or_else(|e| panic!("{e}"));
    let peak = exr.iter().flatten().copied().fold(0.0f32, f32::max);
    assert!(peak > 1.0, "the sun makes L_lm exceed 1 ({peak})");
    assert!(exr.iter().filter(|p| p.iter().any(|&c| c > 0.0)).count() > width * height / 4);
    // The texel with the peak lands where the EXR has it.
    let at = exr.iter().position(|p| p.contains(&peak)).unwrap();
    assert_eq!(pack_e5b9g9r9(pixels[at]), pack_e5b9g9r9(exr[at]), "texel ({}, {})", at % width, at / width);
    eprintln!(
        "{width}×{height} KTX2 lightmap, {} bytes (EXR {} bytes), peak L_lm {peak}: worst error {worst:.3e} of the \
         texel's largest channel (bound 2^-9 = {:.3e})",
        bytes.len(),
        std::fs::metadata(dir.path().join("sphere_on_ground.lightmap0.exr")).unwrap().len(),
        2f64.powi(-9)
    );

    // Files that are wrong the ways a lightmap goes wrong fail the comparison.
    let srgb = |v: f32| if v <= 0.003_130_8 { 12.92 * v } else { 1.055 * v.powf(1.0 / 2.4) - 0.055 };
    let wrong: [(&str, Vec<[f32; 3]>); 3] = [
        ("rows flipped", flipped(&exr, width)),
        ("times pi", exr.iter().map(|p| p.map(|c| c * std::f32::consts::PI)).collect()),
        ("sRGB-encoded", exr.iter().map(|p| p.map(srgb)).collect()),
    ];
    for (what, values) in wrong {
        let file = bake::export::ktx2::encode(width as u32, height as u32, &values).unwrap();
        let (_, _, _, read) = read_ktx2(&file);
        assert!(compare(&read, &exr).is_err(), "a file with its {what} passes");
    }
}

#[test]
fn each_baked_node_names_its_ktx2_lightmap_for_bevy() {
    let dir = tempfile::tempdir().unwrap();
    // A preview two stops up: Bevy matches it two stops down.
    bake_file(&fixture("everything.glb"), dir.path(), &[&TINY[..], &["--exposure", "2"]].concat());
    let json = SourceAsset::load(&dir.path().join("everything.glb")).unwrap().json;
    let ev100 = -2.0 - 1.2f64.log2();
    let by_name = |name: &str| {
        let nodes = json["nodes"].as_array().unwrap();
        nodes.iter().find(|n| n["name"] == name).unwrap_or_else(|| panic!("no node {name}")).clone()
    };
    // The ground also draws a points primitive (1), which is not baked.
    for name in ["ground", "crate A", "crate B", "flag (static)", "spinner"] {
        let node = by_name(name);
        let bake = &node["extras"]["bake"];
        assert_eq!(bake["lightmap"], "everything.lightmap0.ktx2", "{name}");
        assert_eq!((&bake["texCoord"], &bake["uv_rect"]), (&json!(1), &json!([0.0, 0.0, 1.0, 1.0])), "{name}");
        assert_eq!(bake["primitives"], json!([0]), "{name}");
        assert!((bake["ev100"].as_f64().unwrap() - ev100).abs() < 1e-9, "{name}: {}", bake["ev100"]);
        assert!(bake["content"].as_str().unwrap().contains("L_lm = E/pi"), "{name}");
        let mesh = &json["meshes"][node["mesh"].as_u64().unwrap() as usize];
        assert!(mesh["primitives"][0]["attributes"]["TEXCOORD_1"].is_u64(), "{name}");
    }
    // The ground's own extras stay beside it.
    assert_eq!(by_name("ground")["extras"]["layer"], "static");
    for name in ["flag (skinned)", "flag root joint", "flag tip joint", "camera"] {
        assert!(by_name(name).pointer("/extras/bake").is_none(), "{name} draws nothing baked");
    }
    assert!(dir.path().join("everything.lightmap0.ktx2").is_file());
}
