//! The CPU reference against closed-form answers: furnaces, horizons,
//! occluders, closed rooms, form factors, a sun, textures and alpha cut-outs,
//! determinism and scale. Every check prints what it measured.

use std::f64::consts::{FRAC_PI_2, PI, TAU};
use std::path::Path;

use crate::common;

use bake::environment::EnvironmentMap;
use bake::fixtures::{MeshData, Placement, SceneBuilder};
use bake::reference::{Estimate, Reference, ReferenceOptions, ReferencePoint, surface_points};
use bake::scene::Scene;
use glam::{Quat, Vec3};
use image::{Rgba, RgbaImage};
use serde_json::{Value, json};

fn scene(builder: &SceneBuilder) -> Scene {
    let glb = builder.to_glb();
    let source = bake::asset::SourceAsset::from_bytes(Path::new("test.glb"), &glb, None).unwrap();
    bake::import::from_asset(source).unwrap()
}

fn options(samples: u32) -> ReferenceOptions {
    ReferenceOptions { samples, seed: 7, ..Default::default() }
}

fn point(position: [f32; 3], normal: [f32; 3]) -> ReferencePoint {
    ReferencePoint { position, normal, face_normal: None }
}

/// Asserts every channel of `got` is within `sigmas` standard errors and
/// within `relative` of `expected` (both; 1e-12 of slack for rounding).
fn check(name: &str, got: &Estimate, expected: [f64; 3], sigmas: f64, relative: f64) {
    for (c, &e) in expected.iter().enumerate() {
        let (v, s) = (got.lightmap[c], got.std_error[c]);
        let diff = (v - e).abs();
        let slack = 1e-12 * e.abs().max(1e-12);
        eprintln!(
            "{name} [{c}]: got {v:.6} ± {s:.2e}, expected {e:.6}, off by {:.2}σ, {:.3}%",
            if s > 0.0 { diff / s } else { 0.0 },
            if e != 0.0 { 100.0 * diff / e.abs() } else { 0.0 }
        );
        assert!(v.is_finite() && s.is_finite(), "{name}: not finite");
        assert!(diff <= sigmas * s + slack, "{name} [{c}]: {v} vs {e}: {diff} > {sigmas}σ = {}", sigmas * s);
        assert!(diff <= relative * e.abs() + slack, "{name} [{c}]: {v} vs {e}: more than {}%", 100.0 * relative);
    }
}

fn horizon_map(radiance: [f32; 3]) -> EnvironmentMap {
    EnvironmentMap::from_fn(64, 32, |d| if d[1] > 0.0 { radiance } else { [0.0; 3] })
}

#[test]
fn white_furnace_sphere_sees_the_environment() {
    let radiance = [1.0f32, 0.5, 0.25];
    let map = EnvironmentMap::constant(radiance);
    for albedo in [0.0f32, 0.8] {
        let mut builder = SceneBuilder::new();
        builder.object(
            "sphere",
            &MeshData::sphere(1.0, 48, 24),
            [albedo, albedo, albedo, 1.0],
            [0.0; 3],
            Placement::default(),
        );
        let scene = scene(&builder);
        let reference = Reference::new(&scene, Some(&map), &options(1024));
        let points: Vec<ReferencePoint> = surface_points(&scene, 12, 3).iter().map(|p| p.point).collect();
        for (p, e) in points.iter().zip(reference.estimate(&points)) {
            // Normals point outwards.
            assert!(Vec3::from(p.normal).dot(Vec3::from(p.position)) > 0.0);
            check(&format!("furnace albedo {albedo}"), &e, radiance.map(f64::from), 3.0, 0.01);
        }
    }
}

#[test]
fn convex_sphere_under_horizon_sees_the_tilted_sky() {
    // A convex object never sees itself, whatever its albedo: a point with
    // normal n gets the sky fraction L(1 + n_y)/2 of a tilted plane. This
    // exercises light samples and shadow rays against the object itself.
    let radiance = 1.5f32;
    let map = horizon_map([radiance; 3]);
    for albedo in [0.0f32, 0.8] {
        let mut builder = SceneBuilder::new();
        builder.object(
            "sphere",
            &MeshData::sphere(1.0, 48, 24),
            [albedo, albedo, albedo, 1.0],
            [0.0; 3],
            Placement::at(Vec3::new(3.0, 2.0, -1.0)),
        );
        let scene = scene(&builder);
        let reference = Reference::new(&scene, Some(&map), &options(16384));
        let points: Vec<ReferencePoint> = surface_points(&scene, 8, 4).iter().map(|p| p.point).collect();
        for (p, e) in points.iter().zip(reference.estimate(&points)) {
            let expected = radiance as f64 * (1.0 + p.normal[1] as f64) / 2.0;
            let name = format!("sphere under horizon, albedo {albedo}, n_y {:.2}", p.normal[1]);
            // 2 % or 1e-3 of the sky for the points facing almost straight down.
            check(&name, &e, [expected; 3], 4.0, 0.02_f64.max(1.5e-3 / expected));
        }
    }
}

#[test]
fn horizon_map_lights_by_orientation() {
    let radiance = 2.0f32;
    let map = horizon_map([radiance; 3]);
    let cases = [
        ("up", Quat::IDENTITY, [0.0, 1.0, 0.0], 1.0),
        ("vertical", Quat::from_rotation_x(FRAC_PI_2 as f32), [0.0, 0.0, 1.0], 0.5),
        ("down", Quat::from_rotation_x(PI as f32), [0.0, -1.0, 0.0], 0.0),
    ];
    for (name, rotation, normal, fraction) in cases {
        for with_normals in [true, false] {
            let mut mesh = MeshData::plane(1.0, 1.0, 2);
            if !with_normals {
                // Front side from the winding alone.
                mesh.normals.clear();
            }
            let mut builder = SceneBuilder::new();
            builder.object("plane", &mesh, [0.5, 0.5, 0.5, 1.0], [0.0; 3], Placement::default().rotated(rotation));
            let scene = scene(&builder);
            let reference = Reference::new(&scene, Some(&map), &options(65536));
            let points: Vec<ReferencePoint> = surface_points(&scene, 2, 1).iter().map(|p| p.point).collect();
            for p in &points {
                assert!((Vec3::from(p.normal) - Vec3::from(normal)).length() < 1e-5, "{name}: normal {:?}", p.normal);
            }
            for e in reference.estimate(&points) {
                let expected = (radiance * fraction) as f64;
                // A step in the integrand: about 2.4 % standard error per √1024 samples.
                check(&format!("horizon {name}, normals {with_normals}"), &e, [expected; 3], 4.0, 0.015);
            }
        }
    }
}

#[test]
fn black_sphere_above_hides_its_solid_angle() {
    let (r, d, sky) = (1.0f64, 2.0f64, 1.5f32);
    let (segments, rings) = (128, 64);
    let mut builder = SceneBuilder::new();
    builder.object(
        "sphere",
        &MeshData::sphere(r as f32, segments, rings),
        [0.0, 0.0, 0.0, 1.0],
        [0.0; 3],
        Placement::at(Vec3::new(0.0, d as f32, 0.0)),
    );
    let scene = scene(&builder);
    let map = EnvironmentMap::constant([sky; 3]);
    let reference = Reference::new(&scene, Some(&map), &options(16384));
    let e = reference.estimate(&[point([0.0; 3], [0.0, 1.0, 0.0])])[0];
    let expected = sky as f64 * (1.0 - (r / d).powi(2));
    // The mesh is inscribed: its silhouette is smaller than the sphere's by
    // at most the gap between the sphere and the nearest face planes.
    let inner = r * (PI / segments as f64).cos() * (PI / (2 * rings) as f64).cos();
    let facets = sky as f64 * (r * r - inner * inner) / (d * d);
    eprintln!("sphere: faceting allows {facets:.2e}; {} triangles", reference.triangle_count());
    check("sphere above", &e, [expected; 3], 4.0 + facets / e.std_error[0], 0.01);
}

#[test]
fn a_shading_normal_leaning_past_its_plane_gathers_nothing_from_behind_it() {
    // A wide white floor whose smooth normals lean 30° off its plane, under a
    // uniform sky: the point on it sees the sky over the part of its
    // cosine lobe above the floor, (1 + cos 30°)/2 of it, and nothing from
    // below, where the floor itself is. A ray sent there must not meet the
    // floor's own front and count it as a lit surface (that gave 0.99).
    let tilt = 30f32.to_radians();
    let lean = [0.0, tilt.cos(), tilt.sin()];
    let mut floor = MeshData::plane(40.0, 40.0, 1);
    floor.normals = vec![lean; floor.positions.len()];
    let mut builder = SceneBuilder::new();
    builder.object("floor", &floor, [0.8, 0.8, 0.8, 1.0], [0.0; 3], Placement::default());
    let scene = scene(&builder);
    let map = EnvironmentMap::constant([1.0; 3]);
    let reference = Reference::new(&scene, Some(&map), &options(65536));
    let on_floor = ReferencePoint { position: [0.3, 0.0, -0.2], normal: lean, face_normal: Some([0.0, 1.0, 0.0]) };
    let e = reference.estimate(&[on_floor])[0];
    let expected = (1.0 + (tilt as f64).cos()) / 2.0;
    check("leaning normal on a floor", &e, [expected; 3], 4.0, 0.01);
}

fn closed_room(albedo: f32, emission: f32) -> Scene {
    let mut builder = SceneBuilder::new();
    builder.object(
        "room",
        &MeshData::room([2.0, 3.0, 4.0]),
        [albedo, albedo, albedo, 1.0],
        [emission; 3],
        Placement::default(),
    );
    scene(&builder)
}

#[test]
fn closed_room_converges_to_the_geometric_series() {
    let le = 0.6f32;
    for (albedo, samples, relative) in [(0.5f32, 4096, 0.02), (0.9, 16384, 0.05)] {
        let scene = closed_room(albedo, le);
        let reference = Reference::new(&scene, None, &options(samples));
        let mut points: Vec<ReferencePoint> = surface_points(&scene, 3, 2).iter().map(|p| p.point).collect();
        // And the centre of the room, looking sideways.
        points.push(point([0.0; 3], [1.0, 0.0, 0.0]));
        let expected = le as f64 / (1.0 - albedo as f64);
        for e in reference.estimate(&points) {
            check(&format!("room albedo {albedo}"), &e, [expected; 3], 4.0, relative);
        }
    }
}

#[test]
fn vertex_colours_multiply_the_rooms_albedo() {
    // Base colour 0.8 × COLOR_0 (0.625, 0.3125, 0.9375): ρ = (0.5, 0.25, 0.75).
    let (le, tint) = (0.6f32, [0.625f32, 0.3125, 0.9375]);
    let scene = scene(&bake::fixtures::vertex_coloured_room([2.0, 3.0, 4.0], 0.8, le, tint));
    let reference = Reference::new(&scene, None, &options(8192));
    let points: Vec<ReferencePoint> = surface_points(&scene, 3, 2).iter().map(|p| p.point).collect();
    let expected = tint.map(|t| le as f64 / (1.0 - 0.8 * t as f64));
    for e in reference.estimate(&points) {
        check("vertex-coloured room", &e, expected, 4.0, 0.03);
    }
}

#[test]
fn a_bounce_cap_cuts_the_closed_rooms_series_after_as_many_reflections() {
    // Every path from a wall of a closed emitting room meets a wall at once:
    // with light that took more than k reflections dropped, L = Le·Σ_{i≤k} ρ^i.
    // With k = 0 (the direct light alone, as the per-vertex bench compares)
    // and 1 no path is ended at random.
    let (albedo, le) = (0.5f64, 0.6f32);
    let scene = closed_room(albedo as f32, le);
    let mut points: Vec<ReferencePoint> = surface_points(&scene, 3, 5).iter().map(|p| p.point).collect();
    points.push(point([0.0; 3], [0.0, 1.0, 0.0]));
    for max_bounces in [0u32, 1, 3] {
        let reference = Reference::new(&scene, None, &ReferenceOptions { max_bounces, ..options(4096) });
        let expected = le as f64 * (0..=max_bounces).map(|i| albedo.powi(i as i32)).sum::<f64>();
        for e in reference.estimate(&points) {
            check(&format!("room, {max_bounces} bounces"), &e, [expected; 3], 4.0, 0.02);
        }
    }
}

/// View factor from a point on the axis of an a×b rectangle (half-sides
/// `a`, `b`) at distance `c`, facing it.
fn view_factor(a: f64, b: f64, c: f64) -> f64 {
    let (ra, rb) = ((a * a + c * c).sqrt(), (b * b + c * c).sqrt());
    2.0 / PI * (a / ra * (b / ra).atan() + b / rb * (a / rb).atan())
}

/// The same by the midpoint rule: ∫ cos θ cos θ' / (π r²) dA = ∫ c² / (π r⁴) dA.
fn view_factor_numeric(a: f64, b: f64, c: f64, n: usize) -> f64 {
    let (dx, dy) = (2.0 * a / n as f64, 2.0 * b / n as f64);
    let mut sum = 0.0;
    for i in 0..n {
        for j in 0..n {
            let (x, y) = (-a + (i as f64 + 0.5) * dx, -b + (j as f64 + 0.5) * dy);
            let r2 = x * x + y * y + c * c;
            sum += c * c / (PI * r2 * r2);
        }
    }
    sum * dx * dy
}

fn facing_squares(emitter_rotation: Quat, emission: f32) -> Scene {
    let mut builder = SceneBuilder::new();
    builder.object("receiver", &MeshData::plane(1.0, 1.0, 1), [0.0, 0.0, 0.0, 1.0], [0.0; 3], Placement::default());
    builder.object(
        "emitter",
        &MeshData::plane(1.0, 1.0, 1),
        [0.0, 0.0, 0.0, 1.0],
        [emission; 3],
        Placement::at(Vec3::new(0.0, 1.0, 0.0)).rotated(emitter_rotation),
    );
    scene(&builder)
}

#[test]
fn form_factor_of_facing_squares() {
    let closed = view_factor(0.5, 0.5, 1.0);
    let numeric = view_factor_numeric(0.5, 0.5, 1.0, 1000);
    eprintln!("view factor: closed form {closed:.8}, numeric {numeric:.8}");
    assert!((closed - numeric).abs() < 1e-6);
    // An asymmetric rectangle checks the formula's a/b pairing too.
    let (closed2, numeric2) = (view_factor(0.3, 1.1, 0.7), view_factor_numeric(0.3, 1.1, 0.7, 1000));
    eprintln!("view factor 0.6×2.2 at 0.7: closed form {closed2:.8}, numeric {numeric2:.8}");
    assert!((closed2 - numeric2).abs() < 1e-6);

    // Emitters are sampled at every vertex: 4,096 paths land within 1 %
    // (found only by cosine rays, their standard error was about 3 %).
    let le = 5.0f32;
    let scene = facing_squares(Quat::from_rotation_x(PI as f32), le);
    let reference = Reference::new(&scene, None, &options(4096));
    let e = reference.estimate(&[point([0.0; 3], [0.0, 1.0, 0.0])])[0];
    check("form factor", &e, [le as f64 * closed; 3], 4.0, 0.01);
}

#[test]
fn back_of_single_sided_emitter_is_black() {
    // The emitter faces away from the receiver: black unless double-sided.
    let le = 5.0f32;
    let mut scene = facing_squares(Quat::IDENTITY, le);
    let p = [point([0.0; 3], [0.0, 1.0, 0.0])];
    let e = Reference::new(&scene, None, &options(4096)).estimate(&p)[0];
    eprintln!("single-sided emitter seen from behind: {:?}", e.lightmap);
    assert_eq!(e.lightmap, [0.0; 3]);
    for m in &mut scene.materials {
        m.double_sided = true;
    }
    let e = Reference::new(&scene, None, &options(4096)).estimate(&p)[0];
    check("double-sided emitter from behind", &e, [le as f64 * view_factor(0.5, 0.5, 1.0); 3], 4.0, 0.01);
}

/// Direction of the centre of pixel (row, col) of a W×H map.
fn pixel_direction(row: usize, col: usize, w: usize, h: usize) -> Vec3 {
    let theta = (row as f64 + 0.5) / h as f64 * PI;
    let phi = ((col as f64 + 0.5) / w as f64 - 0.5) * TAU;
    Vec3::new((theta.sin() * phi.cos()) as f32, theta.cos() as f32, (theta.sin() * phi.sin()) as f32)
}

/// ∫ over pixel (row, col) of max(n·ω, 0) dω, by a fine grid in (φ, cos θ).
fn pixel_cosine_integral(row: usize, col: usize, w: usize, h: usize, n: Vec3) -> f64 {
    let k = 64;
    let (c0, c1) = ((row as f64 * PI / h as f64).cos(), ((row + 1) as f64 * PI / h as f64).cos());
    let (p0, p1) = ((col as f64 / w as f64 - 0.5) * TAU, ((col + 1) as f64 / w as f64 - 0.5) * TAU);
    let mut sum = 0.0;
    for i in 0..k {
        for j in 0..k {
            let ct = c0 + (c1 - c0) * (i as f64 + 0.5) / k as f64;
            let st = (1.0 - ct * ct).sqrt();
            let phi = p0 + (p1 - p0) * (j as f64 + 0.5) / k as f64;
            let d = [st * phi.cos(), ct, st * phi.sin()];
            sum += (n.x as f64 * d[0] + n.y as f64 * d[1] + n.z as f64 * d[2]).max(0.0);
        }
    }
    sum * (c0 - c1) * (p1 - p0) / (k * k) as f64
}

#[test]
fn sun_is_importance_sampled() {
    let (w, h) = (512usize, 256usize);
    let (sky, sun) = (1.0f32, 1.0e5f32);
    let mut map = EnvironmentMap::from_fn(w as u32, h as u32, |d| if d[1] > 0.0 { [sky; 3] } else { [0.0; 3] });
    let sun_pixels = [(80, 100), (80, 101), (81, 100), (81, 101)];
    for &(r, c) in &sun_pixels {
        map.texels[r * w + c] = [sun; 3];
    }
    let sun_dir = (pixel_direction(80, 100, w, h) + pixel_direction(81, 101, w, h)).normalize();
    eprintln!("sun direction {sun_dir:?}, {:.1}° above the horizon", sun_dir.y.asin().to_degrees());

    // (rotation, intensity): the map turned about +Y, so the sun moves with it.
    for (rotation, intensity) in [(0.0f32, 1.0f32), (90.0, 2.0), (-33.0, 0.5)] {
        let turn = Quat::from_rotation_y(rotation.to_radians());
        let normal = turn * sun_dir;
        let sun_integral: f64 = sun_pixels.iter().map(|&(r, c)| pixel_cosine_integral(r, c, w, h, sun_dir)).sum();
        let expected = intensity as f64
            * (sky as f64 * ((1.0 + sun_dir.y as f64) / 2.0 - sun_integral / PI) + sun as f64 * sun_integral / PI);
        let mut builder = SceneBuilder::new();
        builder.object(
            "panel",
            &MeshData::plane(1.0, 1.0, 1),
            [0.5, 0.5, 0.5, 1.0],
            [0.0; 3],
            Placement::default().rotated(Quat::from_rotation_arc(Vec3::Y, normal)),
        );
        let scene = scene(&builder);
        let reference = Reference::new(
            &scene,
            Some(&map),
            &ReferenceOptions { env_rotation_degrees: rotation, env_intensity: intensity, ..options(1024) },
        );
        let e = reference.estimate(&[point([0.0; 3], normal.to_array())])[0];
        eprintln!(
            "sun rotation {rotation}°, intensity {intensity}: sun {:.3}, sky {:.3}",
            intensity as f64 * sun as f64 * sun_integral / PI,
            expected - intensity as f64 * sun as f64 * sun_integral / PI
        );
        check(&format!("sun at {rotation}°"), &e, [expected; 3], 4.0, 0.01);
    }
}

/// Linear value of an 8-bit sRGB code: PNG colour textures are sRGB, and
/// the importer decodes them with this transfer function.
fn srgb_to_linear(code: u8) -> f64 {
    let c = code as f64 / 255.0;
    if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
}

fn solid(rgba: [u8; 4]) -> RgbaImage {
    RgbaImage::from_pixel(4, 4, Rgba(rgba))
}

/// The sRGB codes of a constant texture colour and their linear values.
const CODES: [u8; 3] = [188, 128, 64];

fn linear_codes() -> [f64; 3] {
    CODES.map(srgb_to_linear)
}

#[test]
fn textured_closed_room_converges_to_the_geometric_series() {
    // A closed room of uniform albedo ρ and emission Le has L_lm = Le/(1 − ρ)
    // everywhere. Here ρ = baseColorFactor × a constant texture, per channel.
    let (le, factor) = (0.6f32, [0.9f32, 1.0, 1.0, 1.0]);
    let [r, g, b] = CODES;
    let colour = solid([r, g, b, 255]);
    // The second case reads TEXCOORD_1, which the room lacks: like the bake,
    // the reference reads it as (0, 0), here moved by the offset into the
    // texture's coloured right half (its white left half would make ρ_g = 1).
    let two_tone = common::halves([255; 4], [r, g, b, 255]);
    let missing_set = json!({ "texCoord": 1, "offset": [0.75, 0.5] });
    for (name, image, transform) in
        [("TEXCOORD_0", &colour, None), ("missing TEXCOORD_1", &two_tone, Some(missing_set))]
    {
        let mut builder = SceneBuilder::new();
        let material = builder.material("room", factor, [le; 3]);
        let texture = builder.png_texture(image, 10497);
        builder.base_color_texture(material, texture, transform);
        let mesh = builder.mesh("room", &MeshData::room([2.0, 3.0, 4.0]), Some(material));
        builder.node("room", mesh, Placement::default());
        let scene = scene(&builder);
        let reference = Reference::new(&scene, None, &options(4096));
        let mut points: Vec<ReferencePoint> = surface_points(&scene, 3, 2).iter().map(|p| p.point).collect();
        points.push(point([0.0; 3], [1.0, 0.0, 0.0]));
        let albedo: Vec<f64> = linear_codes().iter().zip(factor).map(|(t, f)| t * f as f64).collect();
        let expected = [0, 1, 2].map(|c| le as f64 / (1.0 - albedo[c]));
        for e in reference.estimate(&points) {
            check(&format!("textured room, {name}, albedo {albedo:.4?}"), &e, expected, 4.0, 0.02);
        }
    }
}

/// A black receiver square at y = 0 facing up under a 1 m emitter square at
/// y = 1 facing down, emitting `le` × `texture` (through TEXCOORD_0, which
/// runs u from 0 at x = −½ to 1 at x = +½).
fn textured_emitter(le: f32, texture: &RgbaImage) -> Scene {
    let mut builder = SceneBuilder::new();
    builder.object("receiver", &MeshData::plane(1.0, 1.0, 1), [0.0, 0.0, 0.0, 1.0], [0.0; 3], Placement::default());
    let material = builder.material("emitter", [0.0, 0.0, 0.0, 1.0], [le; 3]);
    let t = builder.png_texture(texture, 33071);
    builder.emissive_texture(material, t);
    let mesh = builder.mesh("emitter", &MeshData::plane(1.0, 1.0, 1), Some(material));
    builder.node("emitter", mesh, Placement::at(Vec3::new(0.0, 1.0, 0.0)).rotated(Quat::from_rotation_x(PI as f32)));
    scene(&builder)
}

#[test]
fn emissive_texture_scales_the_form_factor() {
    let le = 5.0f32;
    let f = view_factor(0.5, 0.5, 1.0);
    let [r, g, b] = CODES;
    let linear = linear_codes();
    // A constant colour scales the emission per channel. Half black, half
    // white: the point on the axis sees each half with half the view factor,
    // by symmetry (bilinear filtering blends the seam antisymmetrically).
    let cases = [
        ("constant colour", solid([r, g, b, 255]), linear.map(|l| le as f64 * f * l)),
        ("half black, half white", common::halves([0, 0, 0, 255], [255; 4]), [le as f64 * f / 2.0; 3]),
    ];
    for (name, texture, expected) in cases {
        let scene = textured_emitter(le, &texture);
        let e = Reference::new(&scene, None, &options(16384)).estimate(&[point([0.0; 3], [0.0, 1.0, 0.0])])[0];
        check(&format!("emissive texture, {name}"), &e, expected, 4.0, 0.02);
    }
}

#[test]
fn a_cut_out_emitter_glows_only_where_it_is_solid() {
    // A glowing 2×2 m canopy, MASKed by a texture solid where u < 0.5, over a
    // point on its axis, no environment: L = Le·F/2 by symmetry. The light
    // samples drawn on the emitter must drop the points that fall in its
    // holes, as the cosine rays pass through them (counted, the point read
    // 59 % too bright).
    let le = 3.0f32;
    let mut builder = SceneBuilder::new();
    let material = builder.material("canopy", [0.0, 0.0, 0.0, 1.0], [le; 3]);
    let t = builder.png_texture(&common::halves([0, 0, 0, 255], [0, 0, 0, 0]), 33071);
    builder.base_color_texture(material, t, None);
    builder.alpha_mask(material, 0.5);
    let mesh = builder.mesh("canopy", &MeshData::plane(2.0, 2.0, 2), Some(material));
    builder.node("canopy", mesh, Placement::at(Vec3::new(0.0, 1.0, 0.0)).rotated(Quat::from_rotation_x(PI as f32)));
    let scene = scene(&builder);
    let e = Reference::new(&scene, None, &options(4096)).estimate(&[point([0.0; 3], [0.0, 1.0, 0.0])])[0];
    check("half cut-out emitter", &e, [le as f64 * view_factor(1.0, 1.0, 1.0) / 2.0; 3], 4.0, 0.02);
}

/// A base colour texture: image, glTF wrap code for both axes, KHR_texture_transform.
type TextureSetup<'a> = (&'a RgbaImage, u32, Option<Value>);

/// A black 2×2 m canopy 1 m above the origin, facing down, alpha-MASKed at
/// 0.5 (BLEND with `blend`) with base colour alpha `alpha` × `texture`
/// (TEXCOORD_0's u runs from 0 at x = −1 to 1 at x = +1), under a sky of
/// radiance 1 above the horizon.
fn canopy_estimate(alpha: f32, texture: Option<TextureSetup>, blend: bool) -> Estimate {
    let mut builder = SceneBuilder::new();
    let material = builder.material("canopy", [0.0, 0.0, 0.0, alpha], [0.0; 3]);
    if let Some((image, wrap, transform)) = texture {
        let t = builder.png_texture(image, wrap);
        builder.base_color_texture(material, t, transform);
    }
    match blend {
        true => builder.alpha_blend(material),
        false => builder.alpha_mask(material, 0.5),
    }
    let mesh = builder.mesh("canopy", &MeshData::plane(2.0, 2.0, 2), Some(material));
    builder.node("canopy", mesh, Placement::at(Vec3::new(0.0, 1.0, 0.0)).rotated(Quat::from_rotation_x(PI as f32)));
    let scene = scene(&builder);
    let reference = Reference::new(&scene, Some(&horizon_map([1.0; 3])), &options(16384));
    reference.estimate(&[point([0.0; 3], [0.0, 1.0, 0.0])])[0]
}

#[test]
fn alpha_cut_outs_let_the_sky_through() {
    // The point sees the sky (radiance 1) except where the canopy is solid:
    // L = 1 − F_solid. Light samples (shadow rays) and cosine rays must both
    // pass the holes.
    let full = view_factor(1.0, 1.0, 1.0);
    let (clamp, repeat, mirror) = (33071, 10497, 33648);
    let opaque = solid([0, 0, 0, 255]);
    let clear = solid([0, 0, 0, 0]);
    // Solid where u < 0.5, cut out where u ≥ 0.5. A point on the axis sees
    // the solid half with half the view factor, by symmetry.
    let half = common::halves([0, 0, 0, 255], [0, 0, 0, 0]);
    let cases: [(&str, f32, Option<TextureSetup>, f64); 7] = [
        ("texture alpha 1", 1.0, Some((&opaque, clamp, None)), full),
        ("texture alpha 0", 1.0, Some((&clear, clamp, None)), 0.0),
        ("no texture, factor alpha 0.25", 0.25, None, 0.0),
        ("left half solid", 1.0, Some((&half, clamp, None)), full / 2.0),
        // u' = 0.5 + u/2 reads only the cut-out half.
        (
            "transform to the holes",
            1.0,
            Some((&half, clamp, Some(json!({ "offset": [0.5, 0.0], "scale": [0.5, 1.0] })))),
            0.0,
        ),
        // u' = 2u: solid on x ∈ [−1, −½) and [0, ½), the mirror image of the holes.
        ("repeated twice", 1.0, Some((&half, repeat, Some(json!({ "scale": [2.0, 1.0] })))), full / 2.0),
        // u' = 2u mirrored at u' = 1: solid on the outer strips |x| > ½.
        (
            "mirrored twice",
            1.0,
            Some((&half, mirror, Some(json!({ "scale": [2.0, 1.0] })))),
            full - view_factor(0.5, 1.0, 1.0),
        ),
    ];
    for (name, alpha, texture, solid_factor) in cases {
        let e = canopy_estimate(alpha, texture, false);
        check(&format!("canopy, {name}"), &e, [1.0 - solid_factor; 3], 4.0, 0.02);
    }
    // A blend is cut where its texture's alpha is under 0.5, as the bake
    // cuts it; without a texture, at a constant alpha of 0.6, it is solid.
    let e = canopy_estimate(1.0, Some((&half, clamp, None)), true);
    check("blended canopy, left half solid", &e, [1.0 - full / 2.0; 3], 4.0, 0.02);
    let e = canopy_estimate(0.6, None, true);
    check("blended canopy, constant alpha 0.6", &e, [1.0 - full; 3], 4.0, 0.02);
}

fn sphere_on_ground(scale: f32) -> SceneBuilder {
    let mut builder = SceneBuilder::new();
    let s = Vec3::splat(scale);
    builder.object(
        "ground",
        &MeshData::plane(8.0, 8.0, 4),
        [0.8, 0.7, 0.6, 1.0],
        [0.0; 3],
        Placement::default().scaled(s),
    );
    builder.object(
        "sphere",
        &MeshData::sphere(1.0, 32, 16),
        [0.9, 0.9, 0.9, 1.0],
        [0.0; 3],
        Placement::at(Vec3::new(0.0, 1.0, 0.0) * scale).scaled(s),
    );
    builder.object(
        "block",
        &MeshData::cuboid([1.0, 2.0, 1.0]),
        [0.3, 0.6, 0.9, 1.0],
        [0.0; 3],
        Placement::at(Vec3::new(2.0, 1.0, 0.5) * scale).scaled(s),
    );
    builder
}

#[test]
fn deterministic_for_any_thread_count() {
    let scene = scene(&sphere_on_ground(1.0));
    let map = horizon_map([1.0, 0.9, 0.8]);
    let points: Vec<ReferencePoint> = surface_points(&scene, 16, 5).iter().map(|p| p.point).collect();
    let run = |threads: usize, seed: u64| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let reference = Reference::new(&scene, Some(&map), &ReferenceOptions { seed, ..options(300) });
        pool.install(|| reference.estimate(&points))
    };
    let one = run(1, 11);
    let two = run(2, 11);
    eprintln!("first point: {:?} (1 thread) {:?} (2 threads)", one[0].lightmap, two[0].lightmap);
    assert_eq!(one, two);
    let other = run(2, 12);
    assert_ne!(one, other, "a different seed should give different noise");
}

#[test]
fn same_answer_at_any_scale() {
    let map = horizon_map([1.0, 0.9, 0.8]);
    let sample = |scale: f32| {
        let scene = scene(&sphere_on_ground(scale));
        let mut points: Vec<ReferencePoint> = surface_points(&scene, 10, 9).iter().map(|p| p.point).collect();
        // On the ground right beside the sphere's contact point, and on the
        // block's side just above the ground: contact shadows and corners.
        points.push(point([0.02 * scale, 0.0, 0.0], [0.0, 1.0, 0.0]));
        points.push(point([1.5 * scale, 0.01 * scale, 0.5 * scale], [-1.0, 0.0, 0.0]));
        let reference = Reference::new(&scene, Some(&map), &options(512));
        let estimates = reference.estimate(&points);
        (points, estimates)
    };
    let (base_points, base) = sample(1.0);
    let mut largest = 0.0f64;
    for scale in [1e-3f32, 1e4] {
        let (points, scaled) = sample(scale);
        for (i, (a, b)) in base.iter().zip(&scaled).enumerate() {
            let p = Vec3::from(points[i].position) / scale;
            assert!((p - Vec3::from(base_points[i].position)).length() < 1e-4, "point {i} moved");
            for c in 0..3 {
                let sigma = (a.std_error[c].powi(2) + b.std_error[c].powi(2)).sqrt();
                let diff = (a.lightmap[c] - b.lightmap[c]).abs();
                largest = largest.max(diff / a.lightmap[c].abs().max(1e-3));
                if c == 0 {
                    eprintln!(
                        "scale {scale:e}, point {i}: {:.5} vs {:.5} (±{sigma:.1e})",
                        a.lightmap[c], b.lightmap[c]
                    );
                }
                assert!(
                    diff <= 4.0 * sigma + 1e-9,
                    "scale {scale}: point {i} [{c}]: {} vs {}",
                    a.lightmap[c],
                    b.lightmap[c]
                );
            }
        }
    }
    eprintln!("largest relative difference from scale 1: {largest:.2e}");
}

#[test]
fn invalid_points_give_nan() {
    let scene = closed_room(0.5, 1.0);
    let reference = Reference::new(&scene, None, &options(16));
    let e = reference.estimate(&[point([0.0; 3], [0.0; 3]), point([f32::NAN, 0.0, 0.0], [0.0, 1.0, 0.0])]);
    assert!(e.iter().all(|e| e.lightmap.iter().all(|v| v.is_nan())));
}
