//! KTX2 textures (KHR_texture_basisu), as web pipelines leave them: bake
//! decodes ETC1S and UASTC to the pixels Binomial's own transcoder gives,
//! bakes a KTX2-only texture as it bakes a PNG of those pixels (albedo and
//! cut-outs alike), and refuses a broken file with a notice, never a crash.
//! The files are written by Binomial's encoder and the reference decoding
//! made by Binomial's transcoder, both from `pipeline/ktx2.mjs` (the npm
//! package ktx2-encoder, pinned in pipeline/package-lock.json and installed
//! by pipeline/setup.sh); without them these tests fail, they never skip.

use crate::common;

use std::path::Path;

use bake::asset::ktx2;
use bake::environment::{EnvironmentMap, LightMode};
use bake::fixtures::{MeshData, Placement, SceneBuilder};
use glam::Vec3;
use image::{Rgba, RgbaImage};

/// A texture with detail in every channel: ramps in red and green, a
/// checker in blue and, in alpha, a left half opaque and a right half clear.
fn pattern(width: u32, height: u32) -> RgbaImage {
    RgbaImage::from_fn(width, height, |x, y| {
        let checker = if (x / 8 + y / 8) % 2 == 0 { 40 } else { 210 };
        let alpha = if x < width / 2 { 255 } else { 0 };
        Rgba([(x * 255 / (width - 1)) as u8, (y * 255 / (height - 1)) as u8, checker, alpha])
    })
}

/// `image` encoded by Binomial's encoder with `codec` (etc1s or uastc):
/// the KTX2 file and Binomial's decoding of the same blocks.
fn encode(image: &RgbaImage, codec: &str, dir: &Path) -> (Vec<u8>, RgbaImage) {
    let raw = dir.join(format!("{codec}.rgba"));
    std::fs::write(&raw, image.as_raw()).unwrap();
    let (ktx2, basis, decoded) =
        (dir.join(format!("{codec}.ktx2")), dir.join(format!("{codec}.basis")), dir.join(format!("{codec}.out")));
    let (width, height) = (image.width().to_string(), image.height().to_string());
    for (output, container) in [(&ktx2, "ktx2"), (&basis, "basis")] {
        let args = [raw.as_os_str(), width.as_ref(), height.as_ref(), output.as_os_str(), codec.as_ref()];
        let mut args = [&["encode".as_ref()][..], &args].concat();
        if container == "basis" {
            args.push("basis".as_ref());
        }
        common::node("pipeline/ktx2.mjs", &args);
    }
    common::node("pipeline/ktx2.mjs", &["transcode".as_ref(), basis.as_os_str(), decoded.as_os_str()]);
    let theirs = RgbaImage::from_raw(image.width(), image.height(), std::fs::read(decoded).unwrap()).unwrap();
    (std::fs::read(ktx2).unwrap(), theirs)
}

#[test]
fn etc1s_and_uastc_decode_to_the_pixels_binomials_transcoder_gives() {
    let dir = tempfile::tempdir().unwrap();
    let image = pattern(64, 48);
    for (codec, worst_allowed) in [("etc1s", 80), ("uastc", 8)] {
        let (file, theirs) = encode(&image, codec, dir.path());
        let ours = ktx2::decode(&file).unwrap_or_else(|e| panic!("{codec}: {e:#}"));
        assert_eq!(ours.dimensions(), (64, 48), "{codec}");
        let differing = ours.as_raw().iter().zip(theirs.as_raw()).filter(|(a, b)| a != b).count();
        assert_eq!(differing, 0, "{codec}: {differing} bytes differ from Binomial's decoding");
        // And the codec kept the picture (a blank or shifted decoding of both
        // would agree with itself).
        let errors: Vec<i32> =
            ours.as_raw().iter().zip(image.as_raw()).map(|(a, b)| (*a as i32 - *b as i32).abs()).collect();
        let worst = *errors.iter().max().unwrap();
        let mean = errors.iter().sum::<i32>() as f64 / errors.len() as f64;
        eprintln!("{codec}: {} bytes, against the source mean error {mean:.2}, worst {worst}", file.len());
        assert!(worst <= worst_allowed && mean < 6.0, "{codec}: mean error {mean}, worst {worst}");
    }
}

/// A 2×2 m quad facing +Y, its base colour from texture `make`.
fn quad(make: impl Fn(&mut SceneBuilder) -> usize) -> SceneBuilder {
    let mut builder = SceneBuilder::new();
    let material = builder.material("quad", [1.0, 1.0, 1.0, 1.0], [0.0; 3]);
    let texture = make(&mut builder);
    builder.base_color_texture(material, texture, None);
    let mesh = builder.mesh("quad", &MeshData::plane(2.0, 2.0, 2), Some(material));
    builder.node("quad", mesh, Placement::default());
    builder
}

fn albedos(builder: &SceneBuilder) -> Vec<(Vec3, [f32; 3])> {
    let gpu = common::gpu();
    let lights = common::lights(&EnvironmentMap::constant([1.0; 3]), LightMode::Cube { face_size: 4 });
    let baked = common::bake(&gpu, builder, &lights, &common::options(64));
    baked.texels.texels.iter().filter(|t| t.area > 0.0).map(|t| (t.position(), t.albedo)).collect()
}

#[test]
fn a_ktx2_only_texture_bakes_its_albedo_as_a_png_of_its_pixels_does() {
    let dir = tempfile::tempdir().unwrap();
    let opaque = RgbaImage::from_fn(64, 64, |x, y| {
        let p = pattern(64, 64).get_pixel(x, y).0;
        Rgba([p[0], p[1], p[2], 255])
    });
    let (file, pixels) = encode(&opaque, "uastc", dir.path());
    let builder = quad(|b| b.ktx2_texture(&file, 33071));
    let scene = common::scene(&builder, "ktx2");
    assert!(scene.notices.iter().all(|n| !n.contains("texture") && !n.contains("image")), "{:?}", scene.notices);
    let from_ktx2 = albedos(&builder);
    let from_png = albedos(&quad(|b| b.png_texture(&pixels, 33071)));
    let factors_only = albedos(&quad(|b| b.png_texture(&RgbaImage::from_pixel(4, 4, Rgba([255; 4])), 33071)));
    assert_eq!(from_ktx2.len(), from_png.len());
    for ((p, a), (_, b)) in from_ktx2.iter().zip(&from_png) {
        assert!((0..3).all(|c| (a[c] - b[c]).abs() < 1e-6), "at {p}: {a:?} from the KTX2, {b:?} from the PNG");
    }
    // What the bake saw before it decoded KTX2: the white factor alone.
    let mean = |texels: &[(Vec3, [f32; 3])]| {
        texels.iter().map(|(_, a)| (a[0] + a[1] + a[2]) / 3.0).sum::<f32>() / texels.len() as f32
    };
    let (ktx2_mean, white_mean) = (mean(&from_ktx2), mean(&factors_only));
    eprintln!("mean albedo: {ktx2_mean:.3} from the KTX2 texture, {white_mean:.3} from the factor alone");
    assert!(ktx2_mean < 0.5 * white_mean, "the texture darkens the quad ({ktx2_mean} against {white_mean})");
}

#[test]
fn a_ktx2_cut_out_lets_sunlight_through_its_clear_half() {
    // An ETC1S canopy over the ground, alpha MASK: its left half opaque, its
    // right half clear, under a sun overhead.
    let dir = tempfile::tempdir().unwrap();
    let (file, _) = encode(&pattern(64, 64), "etc1s", dir.path());
    let (under_opaque, under_clear, open) =
        common::ground_under_a_canopy(&|b| b.ktx2_texture(&file, 33071), &|b, canopy| b.alpha_mask(canopy, 0.5));
    eprintln!("ground under the opaque half {under_opaque:.3}, under the clear half {under_clear:.3}, open {open:.3}");
    assert!(under_opaque < 0.1 * open, "the opaque half casts a shadow");
    assert!(under_clear > 0.9 * open, "the clear half lets the sun through");
}

#[test]
fn a_file_with_ktx2_textures_bakes_into_a_valid_file_that_keeps_them() {
    // A textured ground and box, as gltfpack `-tc` leaves them: KTX2 images
    // only, the extension required. Through the CLI as a build step runs it.
    let dir = tempfile::tempdir().unwrap();
    let (file, pixels) = encode(&pattern(64, 64), "uastc", dir.path());
    let scene = |texture: &dyn Fn(&mut SceneBuilder) -> usize| {
        let mut builder = SceneBuilder::new();
        let material = builder.material("textured", [1.0, 1.0, 1.0, 1.0], [0.0; 3]);
        let t = texture(&mut builder);
        builder.base_color_texture(material, t, None);
        let ground = builder.mesh("ground", &MeshData::plane(4.0, 4.0, 2), Some(material));
        builder.node("ground", ground, Placement::default());
        let cube = builder.mesh("box", &MeshData::cuboid([0.5; 3]), Some(material));
        builder.node("box", cube, Placement::at(Vec3::new(0.0, 0.25, 0.0)));
        builder.to_glb()
    };
    let (ktx2_input, png_input) = (dir.path().join("ktx2.glb"), dir.path().join("png.glb"));
    std::fs::write(&ktx2_input, scene(&|b| b.ktx2_texture(&file, 10497))).unwrap();
    // The same pixels as a PNG: what the KTX2 texture must bake as.
    std::fs::write(&png_input, scene(&|b| b.png_texture(&pixels, 10497))).unwrap();
    let args = ["--max-atlas-size", "64", "--lights", "64", "--max-shots", "128", "-q"];
    let ours = common::bake_file(&ktx2_input, &dir.path().join("out-ktx2"), &args);
    let theirs = common::bake_file(&png_input, &dir.path().join("out-png"), &args);
    let notices = &ours.scenes[0].notices;
    assert!(notices.iter().all(|n| !n.contains("texture") && !n.contains("image")), "{notices:?}");
    let means = |report: &bake::report::Report| -> Vec<[f64; 3]> {
        report.scenes[0].energy.iter().map(|e| e.stats.mean_lightmap).collect()
    };
    assert_eq!(means(&ours), means(&theirs), "each primitive's mean lightmap value");

    let baked = dir.path().join("out-ktx2/ktx2.glb");
    common::node("pipeline/validate.mjs", &[baked.as_os_str()]);
    let output = bake::asset::SourceAsset::load(&baked).unwrap();
    assert!(output.json["extensionsRequired"].to_string().contains("KHR_texture_basisu"));
    let kept = output.document.images().filter(|i| output.image_bytes(i.index()).unwrap().0 == file).count();
    assert_eq!(kept, 1, "the KTX2 image is carried through as it was");
}

#[test]
fn broken_ktx2_files_are_errors_not_crashes() {
    const ATTEMPTS: usize = 20_000;
    let dir = tempfile::tempdir().unwrap();
    let mut decoded = 0;
    for codec in ["etc1s", "uastc"] {
        let (file, _) = encode(&pattern(32, 32), codec, dir.path());
        // Cut short at every length, then bytes overwritten by a fixed
        // sequence (an LCG), half of them in the first 256 bytes, where the
        // header, level index and codebooks lie: each must decode or give
        // an error.
        for length in 0..file.len() {
            assert!(ktx2::decode(&file[..length]).is_err(), "{codec} cut to {length} bytes decodes");
        }
        let mut state: u64 = 0x2545_f491_4f6c_dd1d;
        let mut next = || {
            state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            (state >> 33) as usize
        };
        for _ in 0..ATTEMPTS {
            let mut broken = file.clone();
            for _ in 0..1 + next() % 4 {
                let span = if next() % 2 == 0 { broken.len().min(256) } else { broken.len() };
                let at = next() % span;
                broken[at] = next() as u8;
            }
            match ktx2::decode(&broken) {
                Ok(_) => decoded += 1,
                // decode's last resort, a panic in the transcoder caught:
                // its checks of the header should have refused the file.
                Err(e) => assert!(!format!("{e}").contains("transcoder failed"), "{codec}: {e}"),
            }
        }
    }
    eprintln!("{decoded} of {} damaged files still decoded (damage in pixel data decodes)", 2 * ATTEMPTS);
}
