//! Materials as the bake sees them: base colour and emissive textures through
//! TEXCOORD_0 (sRGB decoded to linear, KHR_texture_transform applied, each
//! lightmap texel averaging its footprint), vertex colours multiplying the
//! base colour, and alpha cut-outs that let light through.

use crate::common;

use bake::environment::{EnvironmentMap, LightMode};
use bake::fixtures::{MeshData, Placement, SceneBuilder};
use glam::{Quat, Vec3};
use image::{Rgba, RgbaImage};
use serde_json::json;

fn solid(color: [u8; 4]) -> RgbaImage {
    RgbaImage::from_pixel(4, 4, Rgba(color))
}

/// A 2×2 m quad facing +Y whose material is built by `dress`.
fn quad(dress: impl Fn(&mut SceneBuilder, usize)) -> SceneBuilder {
    let mut builder = SceneBuilder::new();
    let material = builder.material("quad", [1.0, 1.0, 1.0, 1.0], [0.0; 3]);
    dress(&mut builder, material);
    let mesh = builder.mesh("quad", &MeshData::plane(2.0, 2.0, 2), Some(material));
    builder.node("quad", mesh, Placement::default());
    builder
}

fn albedos(builder: &SceneBuilder) -> Vec<(Vec3, [f32; 3], [f32; 3])> {
    let gpu = common::gpu();
    let lights = common::lights(&EnvironmentMap::constant([1.0; 3]), LightMode::Cube { face_size: 4 });
    let baked = common::bake(&gpu, builder, &lights, &common::options(64));
    baked.texels.texels.iter().filter(|t| t.area > 0.0).map(|t| (t.position(), t.albedo, t.emission)).collect()
}

#[test]
fn base_colour_texture_is_decoded_from_srgb() {
    // 8-bit 128 in sRGB is 0.2158 in linear light; 255 is 1.
    let texels = albedos(&quad(|b, m| {
        let t = b.png_texture(&solid([128, 255, 0, 255]), 10497);
        b.base_color_texture(m, t, None);
    }));
    for (p, albedo, _) in texels {
        assert!((albedo[0] - 0.2158).abs() < 0.003, "at {p}: {albedo:?}");
        assert!((albedo[1] - 1.0).abs() < 0.003 && albedo[2] < 0.001, "at {p}: {albedo:?}");
    }
}

#[test]
fn texture_follows_texcoord_0_and_khr_texture_transform() {
    // The plane's TEXCOORD_0 runs u from 0 at x = −1 to 1 at x = +1.
    let plain = albedos(&quad(|b, m| {
        let t = b.png_texture(&common::halves([0, 0, 0, 255], [255, 255, 255, 255]), 33071);
        b.base_color_texture(m, t, None);
    }));
    for (p, albedo, _) in &plain {
        if p.x < -0.3 {
            assert!(albedo[0] < 0.05, "left half should be black at {p}: {albedo:?}");
        } else if p.x > 0.3 {
            assert!(albedo[0] > 0.95, "right half should be white at {p}: {albedo:?}");
        }
    }
    // uv' = 0.5 + 0.5·uv reads only the white half (texels that are not on
    // the quad's −X edge, whose footprint reaches back across uv' = 0.5).
    let shifted = albedos(&quad(|b, m| {
        let t = b.png_texture(&common::halves([0, 0, 0, 255], [255, 255, 255, 255]), 33071);
        b.base_color_texture(m, t, Some(json!({ "offset": [0.5, 0.0], "scale": [0.5, 1.0] })));
    }));
    for (p, albedo, _) in shifted.iter().filter(|(p, _, _)| p.x > -0.9) {
        assert!(albedo[0] > 0.9, "with the transform everything reads white, at {p}: {albedo:?}");
    }
}

#[test]
fn a_texel_averages_the_texture_it_covers() {
    // A one-pixel checker of black and white, 256 × 256 on the quad: every
    // lightmap texel covers many checker squares and must hold their mean (0.5
    // in linear light), not whichever square its centre lands on.
    let checker = RgbaImage::from_fn(256, 256, |x, y| Rgba(if (x + y) % 2 == 0 { [0, 0, 0, 255] } else { [255; 4] }));
    let texels = albedos(&quad(|b, m| {
        let t = b.png_texture(&checker, 10497);
        b.base_color_texture(m, t, None);
    }));
    let values: Vec<f32> = texels.iter().map(|(_, a, _)| a[0]).collect();
    let mean = values.iter().sum::<f32>() / values.len() as f32;
    let worst = values.iter().map(|v| (v - 0.5).abs()).fold(0.0, f32::max);
    eprintln!("checker: mean albedo {mean:.4}, worst texel off by {worst:.4}");
    assert!(worst < 0.05, "a texel is {worst} away from the checker's mean");
}

#[test]
fn a_webp_only_texture_is_decoded_as_its_png_is() {
    // glTF-Transform's `webp` command leaves a texture only an
    // EXT_texture_webp image, and lists the extension as required.
    let image = RgbaImage::from_fn(64, 64, |x, y| Rgba([(x * 4) as u8, (y * 4) as u8, 200, 255]));
    let png = albedos(&quad(|b, m| {
        let t = b.png_texture(&image, 33071);
        b.base_color_texture(m, t, None);
    }));
    let webp = quad(|b, m| {
        let t = b.webp_texture(&image, 33071);
        b.base_color_texture(m, t, None);
    });
    let scene = common::scene(&webp, "webp");
    assert!(scene.notices.iter().all(|n| !n.contains("texture")), "{:?}", scene.notices);
    let webp = albedos(&webp);
    assert_eq!(png.len(), webp.len());
    // Lossless WebP: the same texels, to rounding.
    for ((p, a, _), (_, b, _)) in png.iter().zip(&webp) {
        assert!((0..3).all(|c| (a[c] - b[c]).abs() < 1e-6), "at {p}: {a:?} from the PNG, {b:?} from the WebP");
    }
    let spread =
        png.iter().map(|(_, a, _)| a[0]).fold(0.0, f32::max) - png.iter().map(|(_, a, _)| a[0]).fold(1.0, f32::min);
    assert!(spread > 0.3, "the texture varies across the quad ({spread})");
}

#[test]
fn a_specular_glossiness_material_bakes_its_diffuse_colour() {
    // KHR_materials_pbrSpecularGlossiness: diffuse factor × diffuse texture
    // is the albedo; the white metal-rough fallback beside it is not.
    let texels = albedos(&quad(|b, m| {
        let t = b.png_texture(&common::halves([255, 255, 255, 255], [128, 128, 128, 255]), 33071);
        b.specular_glossiness(m, [0.2, 0.4, 0.6, 1.0], Some(t));
    }));
    for (p, albedo, _) in texels.iter().filter(|(p, _, _)| p.x.abs() > 0.3) {
        let texture = if p.x < 0.0 { 1.0 } else { 0.2158 };
        for (c, diffuse) in [0.2, 0.4, 0.6].into_iter().enumerate() {
            assert!((albedo[c] - diffuse * texture).abs() < 0.003, "at {p}: {albedo:?}");
        }
    }
}

#[test]
fn emissive_texture_scales_emission() {
    let texels = albedos(&quad(|b, m| {
        b.set_emission(m, [4.0, 4.0, 4.0]);
        let t = b.png_texture(&common::halves([0, 0, 0, 255], [255, 255, 255, 255]), 33071);
        b.emissive_texture(m, t);
    }));
    for (p, _, emission) in texels {
        if p.x < -0.3 {
            assert!(emission[0] < 0.05, "at {p}: {emission:?}");
        } else if p.x > 0.3 {
            assert!((emission[0] - 4.0).abs() < 0.05, "at {p}: {emission:?}");
        }
    }
}

#[test]
fn red_textured_floor_bounces_red_light_onto_a_white_wall() {
    let gpu = common::gpu();
    let mut builder = SceneBuilder::new();
    let red = builder.material("floor", [1.0, 1.0, 1.0, 1.0], [0.0; 3]);
    let t = builder.png_texture(&solid([230, 20, 20, 255]), 10497);
    builder.base_color_texture(red, t, None);
    let floor = builder.mesh("floor", &MeshData::plane(4.0, 4.0, 4), Some(red));
    builder.node("floor", floor, Placement::default());
    builder.object(
        "wall",
        &MeshData::plane(2.0, 4.0, 4),
        [0.8, 0.8, 0.8, 1.0],
        [0.0; 3],
        Placement::at(Vec3::new(-2.0, 1.0, 0.0)).rotated(Quat::from_rotation_z(-90f32.to_radians())),
    );
    let lights = common::lights(&EnvironmentMap::constant([1.0; 3]), LightMode::Cube { face_size: 8 });
    let baked = common::bake(&gpu, &builder, &lights, &common::options(96));
    let (mut low, mut high) = ([0.0f32; 3], [0.0f32; 3]);
    for (t, v) in baked.texels.texels.iter().zip(&baked.solution.lightmap) {
        if t.primitive == 1 {
            let target = if t.position[1] < 0.5 { &mut low } else { &mut high };
            for c in 0..3 {
                target[c] += v[c];
            }
        }
    }
    let (near, far) = (low[0] / low[1], high[0] / high[1]);
    eprintln!("wall light red/green: {near:.3} next to the floor, {far:.3} higher up");
    assert!(near > 1.1 && near > far, "near {near}, far {far}");
}

#[test]
fn alpha_cut_out_lets_sunlight_through_the_holes() {
    // A canopy 1 m above the ground, opaque on its −X half and cut out
    // (alpha 0) on its +X half, under a sun overhead: the ground is lit
    // under the holes and shadowed under the solid half. A blend whose
    // texture holds the alpha is cut the same way (at alpha 0.5): foliage
    // and fences are often exported blended.
    for mode in ["MASK", "BLEND"] {
        let (under_solid, under_holes, open) = ground_under_a_canopy(&|b, canopy| match mode {
            "MASK" => b.alpha_mask(canopy, 0.5),
            _ => b.alpha_blend(canopy),
        });
        eprintln!(
            "{mode}: ground under the solid half {under_solid:.3}, under the holes {under_holes:.3}, open {open:.3}"
        );
        assert!(under_solid < 0.1 * open, "{mode}: the solid half casts a shadow");
        assert!(under_holes > 0.9 * open, "{mode}: the cut-out half lets the sun through");
    }
    // A blend without a texture has no holes: at a constant alpha of 0.6
    // it is baked as opaque (the texels under both halves are in shadow).
    let (under_solid, under_holes, open) = ground_under_a_canopy(&|b, canopy| {
        b.alpha_blend(canopy);
        b.set_base_color_alpha(canopy, 0.6);
        b.clear_base_color_texture(canopy);
    });
    eprintln!("constant blend: under one half {under_solid:.3}, the other {under_holes:.3}, open {open:.3}");
    assert!(under_solid < 0.1 * open && under_holes < 0.1 * open, "the constant blend shades the ground");
}

/// Mean L_lm on the ground under a canopy whose texture is opaque on its
/// −X half and clear on its +X half; `alpha` sets its alpha mode.
fn ground_under_a_canopy(alpha: Dress) -> (f32, f32, f32) {
    let texture =
        |b: &mut SceneBuilder| b.png_texture(&common::halves([128, 128, 128, 255], [128, 128, 128, 0]), 33071);
    common::ground_under_a_canopy(&texture, alpha)
}

#[test]
fn vertex_colours_multiply_the_base_colour_where_each_texel_lies() {
    // The quad runs x from −1 to 1; COLOR_0 ramps linearly from 0.2 to 1
    // (red), stays 0.5 (green) and is 1 (blue) at every vertex.
    let plane = MeshData::plane(2.0, 2.0, 2);
    let colors: Vec<[f32; 3]> = plane.positions.iter().map(|p| [0.6 + 0.4 * p[0], 0.5, 1.0]).collect();
    let mut builder = SceneBuilder::new();
    let material = builder.material("quad", [0.8, 0.8, 0.8, 1.0], [0.0; 3]);
    let mesh = builder.mesh("quad", &plane, Some(material));
    builder.vertex_colors(mesh, &colors);
    builder.node("quad", mesh, Placement::default());
    let texels = albedos(&builder);
    assert!(texels.len() > 100);
    for (p, albedo, _) in texels {
        let expected = [0.8 * (0.6 + 0.4 * p.x), 0.4, 0.8];
        for c in 0..3 {
            assert!(
                (albedo[c] - expected[c]).abs() < 2e-3,
                "at x = {:.3}: albedo {albedo:?}, expected {expected:?}",
                p.x
            );
        }
    }
}

#[test]
fn vertex_coloured_closed_room_reaches_le_over_one_minus_rho_and_bakes_its_texture_without_them() {
    // Every wall emits Le and reflects ρ = base colour 0.8 × COLOR_0
    // (0.625, 0.3125, 0.9375) = (0.5, 0.25, 0.75): L_lm = Le/(1 − ρ) per
    // channel, (2, 1.333, 4) × Le. The baked texture is multiplied by
    // COLOR_0 again in a viewer, so it holds 0.8 · L_lm + Le / COLOR_0.
    let gpu = common::gpu();
    let le = 0.25f32;
    let tint = [0.625f32, 0.3125, 0.9375];
    let builder = bake::fixtures::vertex_coloured_room([2.0, 2.0, 2.0], 0.8, le, tint);
    let scene = common::scene(&builder, "room");
    let baked = bake::bake_scene(&gpu, scene, None, &common::options(64), &mut bake::progress::Silent).unwrap();
    common::assert_valid(&baked);
    let (mut sum, mut area) = ([0.0f64; 3], 0.0f64);
    for (t, v) in baked.texels.texels.iter().zip(&baked.solution.lightmap) {
        for c in 0..3 {
            sum[c] += v[c] as f64 * t.area as f64;
        }
        area += t.area as f64;
    }
    let expected = tint.map(|t| le as f64 / (1.0 - 0.8 * t as f64));
    for c in 0..3 {
        let mean = sum[c] / area;
        eprintln!("channel {c}: mean L_lm {mean:.4}, expected {:.4}", expected[c]);
        assert!((mean / expected[c] - 1.0).abs() < 0.03, "channel {c}: {mean:.4} against {:.4}", expected[c]);
    }
    let (_, beauty, _) = bake::export::lightmap::images(&baked.texels, &baked.solution.lightmap, &[], 0, &[]);
    let (t, l) = baked.texels.texels.iter().zip(&baked.solution.lightmap).find(|(t, _)| t.area > 0.0).unwrap();
    let stored = beauty.pixels[t.index as usize];
    for c in 0..3 {
        let expected = 0.8 * l[c] + le / tint[c];
        assert!((stored[c] / expected - 1.0).abs() < 1e-4, "channel {c}: texture {} against {expected}", stored[c]);
    }
    // Shown as emission (a cut-out's baked form), which viewers do not
    // multiply by COLOR_0, the texture holds the whole value.
    let (_, emission, _) = bake::export::lightmap::images(&baked.texels, &baked.solution.lightmap, &[true], 0, &[]);
    let stored = emission.pixels[t.index as usize];
    for c in 0..3 {
        let expected = 0.8 * tint[c] * l[c] + le;
        assert!((stored[c] / expected - 1.0).abs() < 1e-4, "channel {c}: emission {} against {expected}", stored[c]);
    }
}

#[test]
fn transmissive_and_blended_materials_that_pass_little_light_are_named_in_a_notice_as_baked_opaque() {
    let mut builder = SceneBuilder::new();
    builder.object("glass", &MeshData::plane(1.0, 1.0, 1), [0.9, 0.9, 0.9, 1.0], [0.0; 3], Placement::default());
    builder.object("leaf", &MeshData::plane(1.0, 1.0, 1), [0.2, 0.6, 0.2, 0.5], [0.0; 3], Placement::default());
    builder.object("tinted", &MeshData::plane(1.0, 1.0, 1), [0.5, 0.5, 0.5, 0.5], [0.0; 3], Placement::default());
    let glb = builder.to_glb();
    let parsed = gltf::binary::Glb::from_slice(&glb).unwrap();
    let mut document: serde_json::Value = serde_json::from_slice(&parsed.json).unwrap();
    document["materials"][0]["extensions"] = json!({ "KHR_materials_transmission": { "transmissionFactor": 0.3 } });
    document["materials"][1]["extensions"] =
        json!({ "KHR_materials_diffuse_transmission": { "diffuseTransmissionFactor": 0.4 } });
    document["materials"][2]["alphaMode"] = json!("BLEND");
    let json = serde_json::to_vec(&document).unwrap();
    let bytes = bake::export::glb::encode(&json, &parsed.bin.unwrap());
    let source = bake::asset::SourceAsset::from_bytes(std::path::Path::new("glass.glb"), &bytes, None).unwrap();
    let notices = bake::import::from_asset(source).unwrap().notices;
    eprintln!("{notices:#?}");
    for expected in [
        "material 0 'glass' transmits light (KHR_materials_transmission): baked as opaque",
        "material 1 'leaf' transmits light (KHR_materials_diffuse_transmission): baked as opaque",
        "material 2 'tinted' is alpha-blended at a constant alpha: baked as opaque",
    ] {
        assert!(notices.iter().any(|n| n.contains(expected)), "no notice says '{expected}'");
    }
}

/// What makes a material what a test wants.
type Dress<'a> = &'a dyn Fn(&mut SceneBuilder, usize);

/// L_lm on a grey 4 m ground under the horizon sky (L = 2 above, 0 below)
/// with a 1 m pane 0.3 m over its middle, the pane's material set by
/// `dress`: the texels under the pane (within 0.3 m of its axis) and the
/// number of primitives baked.
fn ground_under_a_pane(dress: impl Fn(&mut SceneBuilder, usize)) -> (Vec<f32>, usize) {
    let gpu = common::gpu();
    let mut builder = SceneBuilder::new();
    builder.object("ground", &MeshData::plane(4.0, 4.0, 8), [0.5, 0.5, 0.5, 1.0], [0.0; 3], Placement::default());
    let pane = builder.material("pane", [0.9, 0.9, 0.9, 1.0], [0.0; 3]);
    dress(&mut builder, pane);
    let mesh = builder.mesh("pane", &MeshData::cuboid([1.0, 0.02, 1.0]), Some(pane));
    builder.node("pane", mesh, Placement::at(Vec3::Y * 0.3));
    let baked_primitives = common::scene(&builder, "pane").primitives.len();
    let lights = common::lights(&EnvironmentMap::horizon([2.0; 3]), LightMode::Cube { face_size: 16 });
    let baked = common::bake(&gpu, &builder, &lights, &common::options(64));
    let under = common::values_of(&baked, 0)
        .into_iter()
        .filter(|(t, _)| t.area > 0.0 && t.position().x.abs() < 0.3 && t.position().z.abs() < 0.3)
        .map(|(_, v)| v)
        .collect();
    (under, baked_primitives)
}

#[test]
fn clear_glass_and_a_faint_blend_let_the_sky_through_while_frosted_glass_shades() {
    // Left out of the bake, a see-through pane lets the ground see the whole
    // sky: L_lm = L = 2, as with nothing over it (tests/it/horizon.rs).
    // A texture can only lower a blend's alpha, so a textured blend at a
    // factor under 0.5 is as see-through; a specular-glossiness blend's
    // alpha is its diffuse factor's.
    let clear: [(&str, Dress); 4] = [
        ("clear glass", &|b, m| b.transmission(m, 1.0)),
        ("a blend at alpha 0.2", &|b, m| {
            b.alpha_blend(m);
            b.set_base_color_alpha(m, 0.2);
        }),
        ("a textured blend at alpha 0.3", &|b, m| {
            let t = b.png_texture(&solid([255, 255, 255, 255]), 10497);
            b.base_color_texture(m, t, None);
            b.alpha_blend(m);
            b.set_base_color_alpha(m, 0.3);
        }),
        ("a specular-glossiness blend at diffuse alpha 0.2", &|b, m| {
            b.specular_glossiness(m, [0.9, 0.9, 0.9, 0.2], None);
            b.alpha_blend(m);
        }),
    ];
    for (what, dress) in clear {
        let (under, primitives) = ground_under_a_pane(dress);
        assert_eq!(primitives, 1, "{what}: the pane is left out");
        assert!(under.len() > 20);
        let worst = under.iter().map(|v| (v / 2.0 - 1.0).abs()).fold(0.0, f32::max);
        eprintln!("{what}: {} texels under the pane, worst {:.3} % off L_lm = 2", under.len(), worst * 100.0);
        for v in &under {
            assert!((v / 2.0 - 1.0).abs() < 0.02, "{what}: a texel under the pane has L_lm {v}, expected 2");
        }
    }
    // A glowing pane (a lamp's cover modelled as glass) stays: its light counts.
    let mut lamp = SceneBuilder::new();
    let cover = lamp.material("lamp cover", [1.0; 4], [1.0, 0.9, 0.7]);
    lamp.transmission(cover, 1.0);
    let mesh = lamp.mesh("cover", &MeshData::cuboid([0.2, 0.2, 0.2]), Some(cover));
    lamp.node("cover", mesh, Placement::default());
    let glowing = common::scene(&lamp, "lamp");
    assert_eq!(glowing.primitives.len(), 1, "{:?}", glowing.notices);
    // Passing less than half the light, a pane is baked as opaque and shades
    // the ground under it: the control that the test can fail.
    let (under, primitives) = ground_under_a_pane(|b, m| b.transmission(m, 0.3));
    assert_eq!(primitives, 2);
    let mean = under.iter().sum::<f32>() / under.len() as f32;
    eprintln!("under a pane baked as opaque: mean L_lm {mean} of 2");
    assert!(mean < 1.2, "under a pane baked as opaque the ground should be in shade: mean L_lm {mean}");
}

#[test]
fn a_texture_on_a_set_bake_does_not_read_is_baked_as_absent_with_a_notice() {
    // A black texture over a white factor: through TEXCOORD_0 the quad is
    // black; through TEXCOORD_2 (KHR_texture_transform's override), which
    // the scene does not keep, it takes the factor alone, not whatever
    // another set's coordinates would read.
    let on_set = |set: u32| {
        quad(move |b, m| {
            let t = b.png_texture(&solid([0, 0, 0, 255]), 10497);
            b.base_color_texture(m, t, Some(json!({ "texCoord": set })));
        })
    };
    for (set, expected) in [(0, 0.0), (2, 1.0)] {
        let texels = albedos(&on_set(set));
        assert!(!texels.is_empty());
        for (p, albedo, _) in texels {
            assert!((albedo[0] - expected).abs() < 0.003, "TEXCOORD_{set}: albedo {albedo:?} at {p}");
        }
    }
    let notices = common::scene(&on_set(2), "set2").notices;
    let expected = "material 0 'quad': its base colour texture 0 samples TEXCOORD_2, which bake does not read";
    assert!(notices.iter().any(|n| n.starts_with(expected)), "{notices:#?}");
    assert!(common::scene(&on_set(0), "set0").notices.iter().all(|n| !n.contains("TEXCOORD")));
}
