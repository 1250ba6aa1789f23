//! Punctual lights (KHR_lights_punctual) baked as direct light: the
//! inverse-square cosine law under a point light, a spot's cone and range as
//! the extension defines them, a directional light's cosine and the hard
//! shadow a box casts in it, light through an alpha cut-out, the power a
//! lamp in a closed room puts in and gets back from its walls, and the same
//! scene against the path tracer. Each light's formula is worked out here
//! from the extension's text, not through `PunctualLight::towards`.

use crate::common;

use std::f64::consts::PI;

use bake::Baked;
use bake::fixtures::{MeshData, Placement, SceneBuilder};
use bake::progress::Silent;
use glam::{DVec3, Quat, Vec3};
use serde_json::json;

/// Bakes `builder` lit by its own lights only (no environment).
fn bake_lit_by_lamps(builder: &SceneBuilder, atlas: u32) -> Baked {
    let gpu = common::gpu();
    let scene = common::scene(builder, "lamps");
    let baked = bake::bake_scene(&gpu, scene, None, &common::options(atlas), &mut Silent).unwrap();
    common::assert_valid(&baked);
    baked
}

/// A black 4 m ground (nothing bounces) with a light over it.
fn ground_under(light: serde_json::Value, placement: Placement) -> SceneBuilder {
    let mut scene = SceneBuilder::new();
    scene.object("ground", &MeshData::plane(4.0, 4.0, 8), [0.0, 0.0, 0.0, 1.0], [0.0; 3], Placement::default());
    scene.light("lamp", light, placement);
    scene
}

/// A node's −Z turned to point straight down.
fn pointing_down() -> Quat {
    Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2)
}

/// L_lm on the ground at distance² `r2` from the foot of a lamp of
/// `intensity` candela `height` over it: E/π = I·h/(h² + r²)^(3/2)/π.
fn under_lamp(intensity: f64, height: f64, r2: f64) -> f64 {
    intensity * height / (height * height + r2).powf(1.5) / PI
}

/// The ground's texels (with an area) and their L_lm, red channel.
fn ground_texels(baked: &Baked) -> Vec<(Vec3, f64)> {
    common::values_of(baked, 0)
        .into_iter()
        .filter(|(t, _)| t.area > 0.0)
        .map(|(t, v)| (t.position(), v as f64))
        .collect()
}

#[test]
fn a_point_light_over_a_plane_gives_the_inverse_square_cosine_law() {
    // I = 10 cd at 1 m over the ground: E = I·h/(h² + r²)^(3/2), L_lm = E/π.
    let (intensity, height) = (10.0, 1.0);
    let light = json!({ "type": "point", "intensity": intensity, "color": [1.0, 0.5, 0.25] });
    let baked = bake_lit_by_lamps(&ground_under(light, Placement::at(Vec3::Y * height as f32)), 64);
    let texels = ground_texels(&baked);
    assert!(texels.len() > 1000);
    let mut worst = 0.0f64;
    for (p, value) in &texels {
        let expected = under_lamp(intensity, height, (p.x * p.x + p.z * p.z) as f64);
        worst = worst.max((value / expected - 1.0).abs());
    }
    eprintln!("{} texels, worst off by {:.3} %", texels.len(), worst * 100.0);
    assert!(worst < 1e-3, "a texel is {:.3} % off the inverse-square cosine law", worst * 100.0);
    // The colour scales each channel.
    let (t, v) = baked.texels.texels.iter().zip(&baked.solution.lightmap).find(|(t, _)| t.area > 0.0).unwrap();
    assert!((v[1] / v[0] - 0.5).abs() < 1e-5 && (v[2] / v[0] - 0.25).abs() < 1e-5, "at {:?}: {v:?}", t.position);
    let stats = baked.solution.punctual.as_ref().expect("the punctual pass ran");
    assert_eq!(stats.lights, 1);
    assert!(baked.solution.bounce.is_none(), "a black ground bounces nothing");
}

#[test]
fn a_spot_lights_its_cone_and_range_as_the_extension_defines_them() {
    // Pointing down from 2 m: full within 0.2 rad of its axis, falling as
    // ((cos θ − cos 0.5)/(cos 0.2 − cos 0.5))² to 0 at 0.5 rad, and its
    // range window max(min(1 − (d/3)⁴, 1), 0) on top of the inverse square.
    let (intensity, height, range, inner, outer) = (40.0, 2.0, 3.0f64, 0.2f64, 0.5f64);
    let light = json!({
        "type": "spot", "intensity": intensity, "range": range,
        "spot": { "innerConeAngle": inner, "outerConeAngle": outer },
    });
    let placement = Placement::at(Vec3::Y * height as f32).rotated(pointing_down());
    let baked = bake_lit_by_lamps(&ground_under(light, placement), 64);
    let texel = 4.0 / baked.atlas.texels_per_unit as f64;
    let (mut inside, mut outside, mut worst) = (0, 0, 0.0f64);
    for (p, value) in ground_texels(&baked) {
        let r = ((p.x * p.x + p.z * p.z) as f64).sqrt();
        // Where the cone's falloff starts and ends it bends: a texel there
        // is the mean over its footprint (supersampled), not its centre's.
        if [inner, outer].iter().any(|a| (r - height * a.tan()).abs() < texel) {
            continue;
        }
        let d = r.hypot(height);
        let cos = height / d;
        let cone = ((cos - outer.cos()) / (inner.cos() - outer.cos())).clamp(0.0, 1.0).powi(2);
        let window = (1.0 - (d / range).powi(4)).clamp(0.0, 1.0);
        let expected = intensity * cos / (d * d) * cone * window / PI;
        if expected == 0.0 {
            assert_eq!(value, 0.0, "at r = {r:.3}: {value} outside the cone");
            outside += 1;
            continue;
        }
        inside += 1;
        worst = worst.max((value / expected - 1.0).abs());
    }
    eprintln!("{inside} texels in the cone, {outside} outside; worst off by {:.3} %", worst * 100.0);
    assert!(inside > 100 && outside > 100);
    assert!(worst < 1e-3, "a texel is {:.3} % off the cone's falloff and range window", worst * 100.0);
}

#[test]
fn a_spot_whose_outer_cone_is_the_specs_bound_of_half_pi_lights_by_cos_squared() {
    // JSON's π/2 read as an f32 is a little over the f64 π/2: the spec's bound
    // itself, not past it. With inner 0 the cone's falloff is (cos θ)².
    let intensity = 40.0;
    let light = json!({
        "type": "spot", "intensity": intensity,
        "spot": { "innerConeAngle": 0.0, "outerConeAngle": std::f64::consts::FRAC_PI_2 },
    });
    let placement = Placement::at(Vec3::Y * 2.0).rotated(pointing_down());
    let baked = bake_lit_by_lamps(&ground_under(light, placement), 64);
    let mut worst = 0.0f64;
    for (p, value) in ground_texels(&baked) {
        let d = ((p.x * p.x + p.z * p.z) as f64).sqrt().hypot(2.0);
        let cos = 2.0 / d;
        let expected = intensity * cos.powi(3) / (d * d) / PI;
        worst = worst.max((value / expected - 1.0).abs());
    }
    assert!(worst < 1e-3, "a texel is {:.3} % off I cos³θ / (π d²)", worst * 100.0);
}

/// Whether the segment from `p` along `d` meets the axis-aligned box `lo`..`hi`.
fn ray_meets_box(p: DVec3, d: DVec3, lo: DVec3, hi: DVec3) -> bool {
    let (mut near, mut far) = (0.0f64, f64::INFINITY);
    for a in 0..3 {
        let (t1, t2) = ((lo[a] - p[a]) / d[a], (hi[a] - p[a]) / d[a]);
        near = near.max(t1.min(t2));
        far = far.min(t1.max(t2));
    }
    near <= far
}

#[test]
fn a_directional_light_lights_by_its_cosine_and_a_box_casts_a_hard_shadow() {
    // 3 lux from 60° above the horizon, towards −X: E = 3·sin 60° on the
    // ground, 0 in the box's shadow (found here by ray against box).
    let elevation = 60f64.to_radians();
    let mut scene = SceneBuilder::new();
    scene.object("ground", &MeshData::plane(4.0, 4.0, 8), [0.0, 0.0, 0.0, 1.0], [0.0; 3], Placement::default());
    scene.object("box", &MeshData::cuboid([0.5; 3]), [0.0, 0.0, 0.0, 1.0], [0.0; 3], Placement::at(Vec3::Y * 0.25));
    // −Z turned to point down at 60° below the horizon, towards −X.
    let turn = Quat::from_rotation_y(std::f32::consts::FRAC_PI_2) * Quat::from_rotation_x(-elevation as f32);
    scene.light("sun", json!({ "type": "directional", "intensity": 3.0 }), Placement::default().rotated(turn));
    let baked = bake_lit_by_lamps(&scene, 128);
    let towards_sun = DVec3::new(elevation.cos(), elevation.sin(), 0.0);
    let (lo, hi) = (DVec3::new(-0.25, 0.0, -0.25), DVec3::new(0.25, 0.5, 0.25));
    let texel = 4.0 / baked.atlas.texels_per_unit as f64;
    let (mut lit, mut shadowed) = (0, 0);
    for (p, value) in ground_texels(&baked) {
        let p = p.as_dvec3();
        let blocked = |q: DVec3| ray_meets_box(q, towards_sun, lo, hi);
        // Texels a footprint's width from the shadow's edge only.
        let around = [-1.0, 1.0].map(|s| [DVec3::X, DVec3::Z].map(|a| blocked(p + a * s * texel)));
        let all = around.iter().flatten().all(|&b| b) && blocked(p);
        let none = !around.iter().flatten().any(|&b| b) && !blocked(p);
        if all {
            assert!(value < 1e-6, "at {p}: {value} in the box's shadow");
            shadowed += 1;
        } else if none {
            let expected = 3.0 * elevation.sin() / PI;
            assert!((value / expected - 1.0).abs() < 1e-4, "at {p}: {value} in the open, {expected} expected");
            lit += 1;
        }
    }
    eprintln!("{lit} lit texels, {shadowed} in the shadow");
    assert!(lit > 1000 && shadowed > 20);
}

#[test]
fn light_passes_an_alpha_cut_out_where_its_texture_is_clear() {
    // A lamp straight over a masked panel of vertical stripes (clear where
    // u·8 is odd, in 8 stripes across its 2 m): under the clear stripes the
    // ground gets the unblocked inverse-square light, under the solid ones
    // none.
    let (intensity, lamp, panel) = (10.0, 2.0f32, 1.0f32);
    let mut scene = ground_under(json!({ "type": "point", "intensity": intensity }), Placement::at(Vec3::Y * lamp));
    let material = scene.material("stripes", [1.0, 1.0, 1.0, 1.0], [0.0; 3]);
    let stripes =
        image::RgbaImage::from_fn(64, 8, |x, _| image::Rgba([0, 0, 0, if (x / 8) % 2 == 0 { 255 } else { 0 }]));
    let texture = scene.png_texture(&stripes, 33071);
    scene.base_color_texture(material, texture, None);
    scene.alpha_mask(material, 0.5);
    let mesh = scene.mesh("panel", &MeshData::plane(2.0, 2.0, 1), Some(material));
    scene.node("panel", mesh, Placement::at(Vec3::Y * panel));
    let baked = bake_lit_by_lamps(&scene, 128);
    // The ground point whose ray to the lamp crosses the panel at x: the
    // panel's TEXCOORD_0 runs u from 0 at x = −1 to 1 at x = +1.
    let (mut open, mut blocked) = (0, 0);
    for (p, value) in ground_texels(&baked) {
        let at_panel = p.x * (lamp - panel) / lamp;
        let stripe = (at_panel + 1.0) * 4.0;
        let inside = p.z.abs() * (lamp - panel) / lamp < 0.95 && at_panel.abs() < 0.95;
        // Texels whose footprint reaches a stripe's edge are left out.
        let edge = (stripe - stripe.round()).abs() < 0.15;
        if !inside || edge {
            continue;
        }
        let unblocked = under_lamp(intensity, lamp as f64, (p.x * p.x + p.z * p.z) as f64);
        if (stripe as i32) % 2 == 0 {
            assert!(value < 1e-6, "at {p}: {value} under a solid stripe");
            blocked += 1;
        } else {
            assert!((value / unblocked - 1.0).abs() < 1e-3, "at {p}: {value} under a clear stripe, {unblocked}");
            open += 1;
        }
    }
    eprintln!("{open} texels under clear stripes, {blocked} under solid ones");
    assert!(open > 50 && blocked > 50);
}

#[test]
fn a_lamp_in_a_closed_room_puts_in_its_power_and_the_walls_return_the_geometric_series() {
    // A point light of I candela in a closed room sends Φ = 4πI onto its
    // walls; walls of albedo ρ then hold Σ E·A = Φ/(1 − ρ) in all.
    let (intensity, rho) = (5.0, 0.5);
    let mut scene = SceneBuilder::new();
    let size = [4.0, 3.0, 4.0];
    scene.object(
        "room",
        &MeshData::room(size),
        [rho as f32, rho as f32, rho as f32, 1.0],
        [0.0; 3],
        Placement::default(),
    );
    scene.light("lamp", json!({ "type": "point", "intensity": intensity }), Placement::at(Vec3::new(0.3, 1.2, -0.4)));
    let baked = bake_lit_by_lamps(&scene, 128);
    let flux = 4.0 * PI * intensity;
    let direct = baked.solution.punctual.as_ref().unwrap().power_received[0];
    let total: f64 =
        baked.texels.texels.iter().zip(&baked.solution.lightmap).map(|(t, v)| PI * v[0] as f64 * t.area as f64).sum();
    eprintln!("direct {direct:.4} of Φ = {flux:.4}; in all {total:.4}, Φ/(1 − ρ) = {:.4}", flux / (1.0 - rho));
    assert!((direct / flux - 1.0).abs() < 0.01, "the walls received {direct:.4} of the lamp's {flux:.4}");
    assert!((total / (flux / (1.0 - rho)) - 1.0).abs() < 0.02, "the walls hold {total:.4} in all");
}

#[test]
fn spot_and_point_lights_bake_as_the_path_tracer_sees_them() {
    // A grey ground, a box and a ball under a spot and a coloured point
    // light: the bake's direct and bounced light against the CPU reference,
    // away from shadow edges (a texel there holds the mean over its
    // footprint, not the light at its centre; sampled by index stride, which
    // texel lands on an edge changed with the adapter's rasterization).
    let mut scene = SceneBuilder::new();
    scene.object("ground", &MeshData::plane(6.0, 6.0, 4), [0.7, 0.7, 0.7, 1.0], [0.0; 3], Placement::default());
    scene.object(
        "box",
        &MeshData::cuboid([0.8, 1.0, 0.8]),
        [0.8, 0.6, 0.4, 1.0],
        [0.0; 3],
        Placement::at(Vec3::new(-0.8, 0.5, 0.0)),
    );
    scene.object(
        "ball",
        &MeshData::sphere(0.5, 32, 16),
        [0.5, 0.7, 0.9, 1.0],
        [0.0; 3],
        Placement::at(Vec3::new(0.9, 0.5, 0.3)),
    );
    let spot = json!({ "type": "spot", "intensity": 30.0, "spot": { "innerConeAngle": 0.3, "outerConeAngle": 0.7 } });
    let aim = Quat::from_rotation_y(0.4) * Quat::from_rotation_x(-1.1);
    scene.light("spot", spot, Placement::at(Vec3::new(0.5, 3.0, 2.0)).rotated(aim));
    scene.light(
        "bulb",
        json!({ "type": "point", "intensity": 4.0, "color": [1.0, 0.8, 0.6] }),
        Placement::at(Vec3::new(-1.5, 1.6, -1.2)),
    );
    let baked = bake_lit_by_lamps(&scene, 128);
    let edges = across_an_edge(&baked);
    let texels: Vec<usize> = (0..baked.texels.texels.len())
        .filter(|&i| baked.texels.texels[i].area > 0.0 && !edges[i])
        .step_by(41)
        .collect();
    let options = bake::reference::ReferenceOptions { samples: 2048, ..Default::default() };
    let estimates = bake::reference::Reference::new(&baked.scene, None, &options)
        .estimate(&common::reference_points(&baked, &texels));
    let (mut sum_bake, mut sum_reference, mut squared) = (0.0f64, 0.0f64, 0.0f64);
    let mean_reference = estimates.iter().map(|e| e.lightmap[0]).sum::<f64>() / estimates.len() as f64;
    for (&i, e) in texels.iter().zip(&estimates) {
        let value = baked.solution.lightmap[i][0] as f64;
        sum_bake += value;
        sum_reference += e.lightmap[0];
        squared += (value - e.lightmap[0]).powi(2);
    }
    let rmse = (squared / texels.len() as f64).sqrt() / mean_reference;
    let bias = sum_bake / sum_reference - 1.0;
    eprintln!("{} texels: bias {:+.2} %, RMSE {:.2} % of the mean", texels.len(), bias * 100.0, rmse * 100.0);
    assert!(texels.len() > 200);
    assert!(bias.abs() < 0.02, "the bake's mean is {:+.2} % off the path tracer's", bias * 100.0);
    assert!(rmse < 0.03, "RMSE {:.2} % of the mean", rmse * 100.0);
}

/// Per texel, whether its light bends sharply across it (a shadow edge):
/// its value is then the mean over its footprint, which a path traced from
/// its centre does not estimate. Along an atlas row or column, its
/// neighbours differ, or bend about it, by over a fifth of the largest of
/// the three.
fn across_an_edge(baked: &Baked) -> Vec<bool> {
    let texels = &baked.texels;
    let at: std::collections::HashMap<u32, usize> =
        texels.texels.iter().enumerate().map(|(k, t)| (t.index, k)).collect();
    let value = |index: u32| at.get(&index).map(|&k| baked.solution.lightmap[k][0]);
    let edge = |(t, centre): (&bake::texelize::Texel, &[f32; 3])| {
        [1, texels.width].iter().any(|&step| match (value(t.index.wrapping_sub(step)), value(t.index + step)) {
            (Some(a), Some(b)) => (a - b).abs().max((a + b - 2.0 * centre[0]).abs()) > 0.2 * a.max(b).max(centre[0]),
            _ => false,
        })
    };
    texels.texels.iter().zip(&baked.solution.lightmap).map(edge).collect()
}

#[test]
fn a_curved_surface_s_sub_samples_do_not_shadow_themselves() {
    // A faceted torus under a lamp: where the lamp's light bends across a
    // texel (its terminator), the texel is the mean of sub-samples on its
    // plane, which the neighbouring facets rise above. Their light must be
    // about the centre's, not blocked by those facets (their mean fell to
    // 0.45 of it: dark dots along the terminator).
    let mut scene = SceneBuilder::new();
    let torus = MeshData::torus(0.6, 0.22, 48, 24);
    scene.object("torus", &torus, [0.0, 0.0, 0.0, 1.0], [0.0; 3], Placement::at(Vec3::Y * 0.22));
    let lamp = Placement::at(Vec3::new(0.3, 2.0, 0.8));
    scene.light("lamp", json!({ "type": "point", "intensity": 10.0 }), lamp);
    let gpu = common::gpu();
    let mut options = common::options(256);
    let mut bake = |supersample: bool| {
        options.solve.supersample = supersample;
        bake::bake_scene(&gpu, common::scene(&scene, "torus"), None, &options, &mut Silent).unwrap()
    };
    let (sampled, centred) = (bake(true), bake(false));
    assert!(sampled.solution.supersampled > 100, "{} texels supersampled", sampled.solution.supersampled);
    let peak = centred.solution.lightmap.iter().map(|v| v[0]).fold(0.0f32, f32::max);
    let worst = (sampled.solution.lightmap.iter().zip(&centred.solution.lightmap))
        .filter(|(_, c)| c[0] > 0.05 * peak)
        .map(|(s, c)| s[0] / c[0])
        .fold(f32::INFINITY, f32::min);
    eprintln!(
        "{} texels supersampled; the lowest mean of sub-samples is {worst:.3} of its centre",
        sampled.solution.supersampled
    );
    assert!(worst > 0.8, "a texel's sub-samples gave {worst:.3} of its centre's light");
}

#[test]
fn lights_are_placed_by_their_nodes_and_one_scaled_to_nothing_is_left_out() {
    let mut scene = SceneBuilder::new();
    scene.object("ground", &MeshData::plane(2.0, 2.0, 1), [0.5, 0.5, 0.5, 1.0], [0.0; 3], Placement::default());
    let spot = json!({ "type": "spot", "intensity": 2.0, "color": [1.0, 0.5, 0.0], "range": 9.0, "spot": {} });
    let aim = Quat::from_rotation_x(-0.5);
    scene.light("spot", spot, Placement::at(Vec3::new(1.0, 2.0, 3.0)).rotated(aim));
    let hidden = Placement::at(Vec3::Y).scaled(Vec3::ZERO);
    scene.light("hidden", json!({ "type": "point", "name": "bulb" }), hidden);
    scene.light("dark", json!({ "type": "point", "intensity": 0.0 }), Placement::at(Vec3::Y));
    let imported = common::scene(&scene, "lights");
    assert_eq!(imported.lights.len(), 1, "{:?}", imported.lights);
    let light = &imported.lights[0];
    assert_eq!(light.node, 1);
    assert!(light.position.abs_diff_eq(DVec3::new(1.0, 2.0, 3.0), 1e-6), "{}", light.position);
    // Its node's −Z, turned 0.5 rad down about +X.
    let expected = DVec3::new(0.0, -(0.5f64).sin(), -(0.5f64).cos());
    assert!(light.direction.abs_diff_eq(expected, 1e-6), "{}", light.direction);
    assert_eq!(light.intensity, DVec3::new(2.0, 1.0, 0.0));
    assert_eq!(light.range, Some(9.0));
    assert!(matches!(light.kind, bake::scene::LightKind::Spot { inner_cone, outer_cone }
        if inner_cone == 0.0 && (outer_cone - std::f64::consts::FRAC_PI_4).abs() < 1e-6));
    let notices = &imported.notices;
    assert!(
        notices.iter().any(|n| n.starts_with("light 1 'bulb' on node 2 'hidden'") && n.contains("left out")),
        "{notices:?}"
    );
}

#[test]
fn a_light_that_lights_no_texel_is_named_with_the_reason() {
    // Over the ground, 2 m up: a lamp whose range ends half a metre out, a
    // spot turned to the sky, and a lamp that lights the ground.
    let short = json!({ "type": "point", "intensity": 10.0, "range": 0.5, "name": "short" });
    let mut scene = ground_under(short, Placement::at(Vec3::Y * 2.0));
    let upward = json!({ "type": "spot", "intensity": 10.0, "name": "upward", "spot": { "outerConeAngle": 0.5 } });
    scene.light("sky", upward, Placement::at(Vec3::Y * 2.0).rotated(pointing_down().inverse()));
    scene.light("bulb", json!({ "type": "point", "intensity": 10.0 }), Placement::at(Vec3::Y * 2.0));
    let baked = bake_lit_by_lamps(&scene, 32);
    let dark: Vec<&String> = baked.notices.iter().filter(|n| n.contains("lights no texel")).collect();
    eprintln!("{dark:#?}");
    assert_eq!(dark.len(), 2, "only the two dark lights are named: {:?}", baked.notices);
    assert!(dark[0].starts_with("light 0 'short' on node 1 'lamp' lights no texel: its range (0.5 m) ends before"));
    assert!(dark[0].contains("nearest surface, 2.0"), "the ground is 2 m below it");
    assert!(dark[1].starts_with("light 1 'upward' on node 2 'sky' lights no texel: every surface"));
    assert!(ground_texels(&baked).iter().any(|&(_, v)| v > 0.0), "the third lamp lights the ground");
}

#[test]
fn many_dark_lights_are_named_up_to_eight_and_counted_beyond() {
    let short = |k: usize| json!({ "type": "point", "intensity": 1.0, "range": 0.1, "name": format!("spark {k}") });
    let mut scene = ground_under(short(0), Placement::at(Vec3::Y));
    for k in 1..11 {
        scene.light("spark", short(k), Placement::at(Vec3::new(k as f32 * 0.1, 1.0, 0.0)));
    }
    let baked = bake_lit_by_lamps(&scene, 16);
    let dark: Vec<&String> = baked.notices.iter().filter(|n| n.contains("no texel")).collect();
    assert_eq!(dark.len(), 9, "{dark:#?}");
    assert!(dark[7].starts_with("light 7 'spark 7' on node 8 'spark' lights no texel: its range (0.1 m)"));
    assert_eq!(dark[8], "3 more punctual lights light no texel");
}
