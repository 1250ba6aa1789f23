//! Occlusion: a sphere above the ground under a uniform sky. The ground
//! point right below a sphere of radius R whose centre is at height d sees a
//! cap of the sky blocked whose cosine-weighted share is (R/d)², so there
//! L_lm = L (1 − (R/d)²); far away the ground sees (almost) the whole sky.
//! The sphere is black so that no light bounces back onto the ground.

use crate::common;

use bake::environment::{EnvironmentMap, Light, LightMode};
use bake::fixtures::{MeshData, Placement, SceneBuilder};
use bake::gpu::Gpu;
use bake::solve::direct::DEFAULT_RAYS;
use bake::texelize::Texel;
use glam::{Quat, Vec3, Vec3Swizzles};

/// Also on a small ray budget (`--direct-rays`), which shares fewer rays
/// out among the same lights: a sixteenth of the rays keeps the shadow's
/// analytic depth.
#[test]
fn sphere_darkens_the_ground_beneath_it_by_the_analytic_amount() {
    let rays = [DEFAULT_RAYS, DEFAULT_RAYS / 16].map(|budget| {
        let baked = sphere_darkens_the_ground(LightMode::Budget { count: 512 }, budget);
        baked.solution.direct.expect("an environment: a direct pass").rays
    });
    eprintln!("rays cast: {} on the default budget, {} on a sixteenth of it", rays[0], rays[1]);
    assert!(rays[1] * 4 < rays[0], "a smaller budget casts fewer rays: {rays:?}");
}

/// With twice as many lights as rays for the sphere, neighbouring small ones share
/// their rays (`solve::light_clusters`, whose unit tests count them): the
/// shadow keeps its analytic depth.
#[test]
fn sphere_darkens_the_ground_by_the_analytic_amount_when_small_lights_share_rays() {
    for mode in [LightMode::Cube { face_size: 32 }, LightMode::Budget { count: 4096 }] {
        let baked = sphere_darkens_the_ground(mode, DEFAULT_RAYS);
        let direct = baked.solution.direct.expect("an environment: a direct pass");
        eprintln!("{mode}: {} lights, {} rays", direct.lights, direct.rays);
    }
}

fn sphere_darkens_the_ground(mode: LightMode, rays: u32) -> bake::Baked {
    let gpu = common::gpu();
    let (radius, height) = (1.0f32, 1.5f32);
    let mut builder = SceneBuilder::new();
    builder.object("ground", &MeshData::plane(12.0, 12.0, 8), [0.5, 0.5, 0.5, 1.0], [0.0; 3], Placement::default());
    builder.object(
        "sphere",
        &MeshData::sphere(radius, 64, 32),
        [0.0, 0.0, 0.0, 1.0],
        [0.0; 3],
        Placement::at(Vec3::new(0.0, height, 0.0)),
    );
    let sky = 1.0;
    let lights = common::lights(&EnvironmentMap::horizon([sky; 3]), mode);
    let mut options = common::options(256);
    options.solve.direct_rays = rays;
    let baked = common::bake(&gpu, &builder, &lights, &options);
    let ground = common::values_of(&baked, 0);

    let below: Vec<f32> = ground.iter().filter(|(t, _)| t.position().xz().length() < 0.1).map(|(_, v)| *v).collect();
    let far: Vec<f32> = ground.iter().filter(|(t, _)| t.position().xz().length() > 5.0).map(|(_, v)| *v).collect();
    assert!(!below.is_empty() && !far.is_empty());
    let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len() as f32;
    let expected = sky * (1.0 - (radius / height).powi(2));
    eprintln!(
        "{mode}, {rays} rays: below the sphere {:.4} (expected {expected:.4}), far away {:.4}",
        mean(&below),
        mean(&far)
    );
    assert!((mean(&below) / expected - 1.0).abs() < 0.03, "below: {} vs {expected}", mean(&below));
    assert!(mean(&far) > 0.97 * sky, "far: {}", mean(&far));
    assert!(mean(&below) < 0.7 * mean(&far));
    baked
}

/// Lit share of the texel footprint centred on `centre` with atlas axes
/// `du`, `dv` (world vectors per texel), by a 32 × 32 grid over it.
fn lit_share(centre: Vec3, du: Vec3, dv: Vec3, lit: impl Fn(Vec3) -> bool) -> f32 {
    let n = 32;
    let mut count = 0;
    for j in 0..n {
        for i in 0..n {
            let (a, b) = ((i as f32 + 0.5) / n as f32 - 0.5, (j as f32 + 0.5) / n as f32 - 0.5);
            count += usize::from(lit(centre + du * a + dv * b));
        }
    }
    count as f32 / (n * n) as f32
}

/// A hard shadow edge crosses the ground's texels at an angle: a square
/// slab floats 1 m above the ground under a small sun straight overhead,
/// nothing else lights the scene, and everything is black so nothing
/// bounces. (Overhead, lifting a receiver off its surface against acne
/// does not move the edge.) A texel stands for its footprint, so each
/// texel the edge crosses must hold the lit share of its square, as a box
/// filter gives it, not the 0 or 1 of its centre.
#[test]
fn a_hard_shadow_edge_is_box_filtered_over_each_texels_footprint() {
    hard_shadow_edge_is_box_filtered(1);
}

/// The same edge with the sun's disc split into 512 lights: the texels to
/// supersample are then flagged by a preview under merged lights, and the
/// full set's depth maps gather texels and sub-samples in one pass.
#[test]
fn a_hard_shadow_edge_is_box_filtered_under_a_light_set_too_large_to_render_twice() {
    hard_shadow_edge_is_box_filtered(512);
}

fn hard_shadow_edge_is_box_filtered(sun_parts: usize) {
    let gpu = common::gpu();
    let turn = Quat::from_rotation_y(30f32.to_radians());
    let side = 3.0f32;
    let mut builder = SceneBuilder::new();
    builder.object("ground", &MeshData::plane(6.0, 6.0, 4), [0.0, 0.0, 0.0, 1.0], [0.0; 3], Placement::default());
    builder.object(
        "slab",
        &MeshData::cuboid([side, 0.1, side]),
        [0.0, 0.0, 0.0, 1.0],
        [0.0; 3],
        Placement::at(Vec3::Y).rotated(turn),
    );
    let cos_radius = 0.5f32.to_radians().cos();
    let sun = EnvironmentMap::from_fn(2048, 1024, |d| if d[1] >= cos_radius { [1e3; 3] } else { [0.0; 3] });
    let mut lights = common::lights(&sun, LightMode::Budget { count: 32 });
    assert_eq!(lights.lights.len(), 1, "a uniform disc is one light");
    let whole = lights.lights[0];
    // Equal parts of the disc, placed by a sunflower spiral (one part is the whole light, as extracted).
    if sun_parts > 1 {
        lights.lights = (0..sun_parts)
            .map(|k| {
                let theta = 0.5f32.to_radians() * ((k as f32 + 0.5) / sun_parts as f32).sqrt();
                let phi = k as f32 * 2.399_963;
                Light {
                    direction: [theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin()],
                    solid_angle: whole.solid_angle / sun_parts as f32,
                    ..whole
                }
            })
            .collect();
    }
    let local = |p: Vec3| turn.inverse() * p;
    let lit = |p: Vec3| local(p).xz().abs().max_element() > side / 2.0;

    let mut errors = Vec::new();
    for supersample in [false, true] {
        let mut options = common::options(128);
        options.solve.supersample = supersample;
        let baked = common::bake(&gpu, &builder, &lights, &options);
        let ground = common::values_of(&baked, 0);
        let neighbours = neighbours_of(&ground, baked.texels.width);
        let open =
            ground.iter().filter(|(t, _)| local(t.position()).xz().length() > 2.5).map(|v| v.1).fold(0.0, f32::max);
        let (mut sum, mut count) = (0.0, 0);
        for (t, value) in &ground {
            // Along the slab's edges, away from its corners.
            let q = local(t.position()).xz().abs();
            if q.min_element() > side / 2.0 - 0.3 {
                continue;
            }
            let Some([r, l, u, d]) = neighbours(t) else {
                continue;
            };
            let share = lit_share(t.position(), (r - l) / 2.0, (u - d) / 2.0, lit);
            if share > 0.05 && share < 0.95 {
                sum += (value / open - share).abs();
                count += 1;
            }
        }
        assert!(count >= 40, "only {count} texels on the edge");
        let error = sum / count as f32;
        eprintln!("supersample {supersample}: {count} texels on the edge, mean |value − lit share| {error:.4}");
        errors.push(error);
    }
    assert!(errors[1] < 0.07, "supersampled edge texels are {} from their lit share", errors[1]);
    assert!(errors[1] < 0.5 * errors[0], "supersampling changed the edge error from {} to {}", errors[0], errors[1]);
}

#[test]
fn floor_around_a_ball_resting_on_it_sees_the_sky_the_ball_leaves() {
    // A black ball of radius r resting on a black floor under a constant sky
    // of L = 1 (direct light only). The ball lies wholly above the floor
    // point's horizon, so it hides its view factor (r/D)² cos θ, D the
    // distance to its centre and θ that direction's angle from the normal:
    // L_lm = 1 − r³/D³. Within a few centimetres of the contact the gap under
    // the ball is thinner than a shadow-map texel is wide; the ring from
    // 15 to 40 cm, where the gap is 1.6 to 12 cm, must keep its sky. Further
    // out (45 cm to 1 m) the floor lies in the outer penumbrae of lights
    // near the horizon, which must be neither lit fully nor darkened.
    let gpu = common::gpu();
    let r = 0.7f32;
    let mut builder = SceneBuilder::new();
    builder.object("floor", &MeshData::plane(6.0, 6.0, 6), [0.0, 0.0, 0.0, 1.0], [0.0; 3], Placement::default());
    builder.object("ball", &MeshData::sphere(r, 64, 32), [0.0, 0.0, 0.0, 1.0], [0.0; 3], Placement::at(Vec3::Y * r));
    let lights = common::lights(&EnvironmentMap::constant([1.0; 3]), LightMode::Budget { count: 256 });
    let baked = common::bake(&gpu, &builder, &lights, &common::options(256));
    let expected = |d: f32| 1.0 - (r / (d * d + r * r).sqrt()).powi(3);
    let ring = |from: f32, to: f32| {
        let (mut got, mut want) = (0.0, 0.0);
        for (t, v) in common::values_of(&baked, 0) {
            let d = t.position().xz().length();
            if d >= from && d < to {
                got += v;
                want += expected(d);
            }
        }
        got / want
    };
    let (inner, outer, open) = (ring(0.15, 0.25), ring(0.25, 0.4), ring(1.5, 2.5));
    let beside = ring(0.45, 1.0);
    eprintln!("bake / analytic: 15–25 cm {inner:.3}, 25–40 cm {outer:.3}, 45 cm–1 m {beside:.3}, 1.5–2.5 m {open:.3}");
    assert!((open - 1.0).abs() < 0.02, "the open floor: {open}");
    assert!((beside - 1.0).abs() < 0.01, "45 cm to 1 m from the contact: {beside} of the sky the ball leaves");
    assert!(inner > 0.86, "15–25 cm from the contact: {inner} of the sky the ball leaves");
    assert!(outer > 0.95, "25–40 cm from the contact: {outer} of the sky the ball leaves");
}

/// A wide sun's penumbra has the analytic profile of a disc uncovered by a
/// straight edge. A thin black slab floats above a black ground under a sun
/// of angular radius α = 5° straight overhead (one light, nothing else).
/// From a ground point a distance x outside the slab's edge, the edge (the
/// top one; the bottom one from inside) stands at θ = atan(x / h) from the
/// zenith, so the share of the sun's disc in view is that of a disc cut by
/// a chord at d = θ/α of its radius: 1/2 + (d√(1 − d²) + asin d)/π. At these
/// heights the penumbra is 5 and 10 lightmap texels wide and too wide for
/// the percentage-closer filter: it is marched, ray by ray. The outer
/// penumbra's far part, whose blocker lies beyond the first blocker search
/// (4 shadow-map texels) at 2 m, is held to the profile too.
#[test]
fn a_wide_suns_penumbra_follows_the_share_of_its_disc_in_view() {
    let gpu = common::gpu();
    let slab = MeshData::cuboid([WIDE_SUN_SIDE, 0.02, WIDE_SUN_SIDE]);
    for height in [1.0f32, 2.0] {
        let (all, _) = wide_sun_penumbra_errors(&gpu, &slab, 0.02, Quat::IDENTITY, height);
        assert!(all < 0.035, "the penumbra under a slab at {height} m is {all} from the disc's share in view");
    }
}

/// The same under a sheet of zero thickness (a one-sided plane, an open
/// surface), facing up to the sun or down, away from it. No solid lies
/// between the sheet and the ground: the inner penumbra under it follows
/// the disc's share as the slab's does, and is not black.
#[test]
fn a_wide_suns_penumbra_under_a_sheet_follows_the_share_of_its_disc_in_view() {
    let gpu = common::gpu();
    let sheet = MeshData::plane(WIDE_SUN_SIDE, WIDE_SUN_SIDE, 4);
    for (facing, flip) in [("up", Quat::IDENTITY), ("down", Quat::from_rotation_x(std::f32::consts::PI))] {
        for height in [1.0f32, 2.0] {
            let (all, inner) = wide_sun_penumbra_errors(&gpu, &sheet, 0.0, flip, height);
            assert!(
                all < 0.035 && inner < 0.035,
                "the penumbra under a sheet facing {facing} at {height} m is {all} from the disc's share in view \
                 ({inner} under the sheet)"
            );
        }
    }
}

/// Side of the square blocker in the wide-sun tests.
const WIDE_SUN_SIDE: f32 = 3.0;

/// Bakes `blocker` (turned by `flip`, then 30° about the vertical) at
/// `height` over a black ground under the 5° sun straight overhead, and
/// returns the mean |ground value − share of the disc in view| over its
/// penumbra texels along the edges: all of them, and those under it.
fn wide_sun_penumbra_errors(gpu: &Gpu, blocker: &MeshData, thickness: f32, flip: Quat, height: f32) -> (f32, f32) {
    let cos_alpha = 5f32.to_radians().cos();
    let sun = EnvironmentMap::from_fn(2048, 1024, |d| if d[1] >= cos_alpha { [100.0; 3] } else { [0.0; 3] });
    let mut lights = common::lights(&sun, LightMode::Budget { count: 32 });
    // The disc as the one light it is (extraction may split a wide disc),
    // its energy kept. The map's pixels make its solid angle a few per cent
    // less than the disc's: the light is the cone of the solid angle it has.
    let solid_angle: f32 = lights.lights.iter().map(|l| l.solid_angle).sum();
    let energy: f32 = lights.lights.iter().map(|l| l.radiance[0] * l.solid_angle).sum();
    lights.lights = vec![Light { direction: [0.0, 1.0, 0.0], solid_angle, radiance: [energy / solid_angle; 3] }];
    let alpha = (1.0 - solid_angle / std::f32::consts::TAU).acos();
    assert!((alpha.to_degrees() - 5.0).abs() < 0.1, "the sun's radius is {}°", alpha.to_degrees());

    let turn = Quat::from_rotation_y(30f32.to_radians());
    let local = |p: Vec3| turn.inverse() * p;
    let in_view = |d: f32| {
        let d = d.clamp(-1.0, 1.0);
        0.5 + (d * (1.0 - d * d).sqrt() + d.asin()) / std::f32::consts::PI
    };
    let mut builder = SceneBuilder::new();
    builder.object("ground", &MeshData::plane(6.0, 6.0, 4), [0.0, 0.0, 0.0, 1.0], [0.0; 3], Placement::default());
    builder.object(
        "blocker",
        blocker,
        [0.0, 0.0, 0.0, 1.0],
        [0.0; 3],
        Placement::at(Vec3::Y * height).rotated(turn * flip),
    );
    let baked = common::bake(gpu, &builder, &lights, &common::options(256));
    let ground = common::values_of(&baked, 0);
    let open = ground.iter().filter(|(t, _)| local(t.position()).xz().length() > 2.6).map(|v| v.1).fold(0.0, f32::max);
    // Penumbra texels: all of them, and those under the blocker.
    let (mut all, mut inner) = (Vec::new(), Vec::new());
    for (t, value) in &ground {
        // Along the blocker's edges, away from its corners.
        let q = local(t.position()).xz().abs();
        if q.min_element() > WIDE_SUN_SIDE / 2.0 - 0.5 {
            continue;
        }
        let x = q.max_element() - WIDE_SUN_SIDE / 2.0;
        let edge = height + if x > 0.0 { thickness } else { -thickness } / 2.0;
        let expected = in_view((x / edge).atan() / alpha);
        if expected > 0.02 && expected < 0.98 {
            let error = (value / open - expected).abs();
            all.push(error);
            if x < 0.0 {
                inner.push(error);
            }
        }
    }
    let mean = |e: &[f32]| e.iter().sum::<f32>() / e.len().max(1) as f32;
    let (mean_all, mean_inner) = (mean(&all), mean(&inner));
    eprintln!(
        "blocker at {height} m: {} penumbra texels, mean |value − share in view| {mean_all:.4} ({mean_inner:.4} under \
         it)",
        all.len()
    );
    assert!(all.len() >= 100, "only {} texels in the penumbra", all.len());
    (mean_all, mean_inner)
}

/// Lights whose cone reaches above a tilted ground by no more than a
/// rounding error, beside a blocker: none of a light's rays leaves the
/// face, and often neither does the last one, aimed just over the horizon
/// (its rounding differs from the test that let the light in). The pass must
/// still end, though a GPU has no loop limit to stop it, and the ground gets
/// the nothing such a light gives it.
#[test]
fn lights_grazing_the_horizon_by_a_rounding_error_end_their_rays() {
    let gpu = common::gpu();
    // Tilted, so that the face normal is not an axis and roundings vary.
    let turn = Quat::from_euler(glam::EulerRot::XYZ, 0.3, 0.7, 0.2);
    let mut builder = SceneBuilder::new();
    builder.object(
        "ground",
        &MeshData::plane(6.0, 6.0, 4),
        [0.5, 0.5, 0.5, 1.0],
        [0.0; 3],
        Placement::default().rotated(turn),
    );
    // Black, so that the light it catches bounces nowhere.
    builder.object(
        "blocker",
        &MeshData::cuboid([1.0, 1.0, 4.0]),
        [0.0, 0.0, 0.0, 1.0],
        [0.0; 3],
        Placement::at(turn * Vec3::new(1.5, 0.5, 0.0)).rotated(turn),
    );
    // A cube-map texel's cone (6,144 lights), tipped so that its top edge
    // stands a few ulps of sin α over the ground's horizon (or just under
    // it), towards the blocker.
    let solid_angle = 4.0 * std::f32::consts::PI / 6144.0;
    let versine = solid_angle as f64 / std::f64::consts::TAU;
    let sin_alpha = (versine * (2.0 - versine)).sqrt() as f32;
    let ulp = f32::from_bits(sin_alpha.to_bits() + 1) - sin_alpha;
    let count = 256;
    // Each light alone would light a face square to it to E = 1.
    let radiance = [1.0 / solid_angle; 3];
    let mut lights = common::lights(&EnvironmentMap::horizon([1.0; 3]), LightMode::Budget { count: 1 });
    lights.lights = (0..count)
        .map(|k| {
            let cos_f = -sin_alpha + (k % 7) as f32 * ulp;
            let across = (k as f32 / count as f32 - 0.5) * 0.6;
            let level = (1.0 - (cos_f as f64).powi(2)).sqrt() as f32;
            let d = turn * Vec3::new(level * across.cos(), cos_f, level * across.sin());
            Light { direction: d.normalize().to_array(), solid_angle, radiance }
        })
        .collect();
    let baked = common::bake(&gpu, &builder, &lights, &common::options(128));
    let brightest = common::values_of(&baked, 0).iter().map(|v| v.1).fold(0.0, f32::max);
    eprintln!("{count} grazing lights: brightest ground texel {brightest:e}");
    assert!(brightest < 1e-4, "the ground took {brightest} from lights below its horizon");
}

/// A black bowl: the lower half of a unit sphere's inside.
fn black_bowl() -> SceneBuilder {
    let bowl = common::inside_of(&MeshData::sphere(1.0, 48, 24), |c| c.y < 0.0);
    let mut builder = SceneBuilder::new();
    builder.object("bowl", &bowl, [0.0, 0.0, 0.0, 1.0], [0.0; 3], Placement::default());
    builder
}

/// A CPU driver ends a shader's loops after 65,535 turns in all: the direct
/// pass must see where that cut a point short and gather it again, or the
/// point keeps a walk's or a light's share unfinished. Inside a black bowl
/// under a uniform sky every light may be blocked and each ray walks the
/// bowl's triangles, so one batch of 1,024 lights runs past that limit at
/// lavapipe's points, and 32 lights a batch stay well within it: the two
/// must cast the same rays and agree but for the order of the sums.
#[test]
fn points_a_loop_limit_cuts_short_get_all_their_light() {
    let gpu = common::gpu();
    let builder = black_bowl();
    let lights = common::lights(&EnvironmentMap::from_fn(64, 32, |_| [1.0; 3]), LightMode::Budget { count: 1024 });
    let bake_in_batches = |batch_size| {
        let mut options = common::options(24);
        options.solve.batch_size = batch_size;
        options.solve.supersample = false;
        options.solve.contact = false;
        common::bake(&gpu, &builder, &lights, &options)
    };
    let (whole, parts) = (bake_in_batches(1024), bake_in_batches(32));
    let stats = |baked: &bake::Baked| baked.solution.direct.clone().expect("a direct pass");
    let (whole_stats, parts_stats) = (stats(&whole), stats(&parts));
    eprintln!(
        "{} lights: {} passes in one batch, {} in batches of 32; rays {} and {}",
        lights.lights.len(),
        whole_stats.batches,
        parts_stats.batches,
        whole_stats.rays,
        parts_stats.rays
    );
    assert_eq!(whole_stats.rays, parts_stats.rays, "the two cast different rays");
    let worst = whole
        .solution
        .lightmap
        .iter()
        .zip(&parts.solution.lightmap)
        .fold(0.0f32, |worst, (a, b)| worst.max((a[1] - b[1]).abs() / b[1].max(1e-6)));
    assert!(worst < 1e-4, "a texel differs by {worst} between one batch and batches of 32");
}

/// A texel on a concave surface beside a shadow edge is supersampled: its
/// sub-samples lie on the plane of its facet, and past a crease that plane
/// runs behind the next facet, where a sub-sample's rays start inside the
/// surface and find it blocked (a statue's texel read 0.66 of its light).
/// A black bowl (the lower half of a sphere's inside) under a sun 40° up:
/// the rim shadows part of it, and every texel whose whole footprint the
/// sun lights holds the light of its centre, E ∝ n·s, supersampled or not.
#[test]
fn texels_of_a_concave_surface_beside_a_shadow_edge_keep_their_light() {
    let gpu = common::gpu();
    let builder = black_bowl();
    let sun_direction = Vec3::new(40f32.to_radians().cos(), 40f32.to_radians().sin(), 0.0);
    let cos_radius = 0.5f32.to_radians().cos();
    let sun = EnvironmentMap::from_fn(2048, 1024, |d| {
        if Vec3::from(d).dot(sun_direction) >= cos_radius { [1e3; 3] } else { [0.0; 3] }
    });
    let lights = common::lights(&sun, LightMode::Budget { count: 32 });
    assert_eq!(lights.lights.len(), 1, "a uniform disc is one light");
    let baked = common::bake(&gpu, &builder, &lights, &common::options(128));
    assert!(baked.solution.supersampled > 50, "{} texels supersampled", baked.solution.supersampled);
    // On the unit sphere a ray from q towards the sun meets it again at
    // t = −2 q·s; the point is lit where that is above the rim (y = 0).
    let lit = |q: Vec3| {
        let q = q.normalize();
        q.dot(sun_direction) < -0.05 && (q - 2.0 * q.dot(sun_direction) * sun_direction).y > 0.02
    };
    let texels = common::values_of(&baked, 0);
    let neighbours = neighbours_of(&texels, baked.texels.width);
    let (mut ratios, mut edge_texels) = (Vec::new(), 0);
    for (t, value) in &texels {
        let Some([r, l, u, d]) = neighbours(t) else {
            continue;
        };
        let (du, dv) = ((r - l) / 4.0, (u - d) / 4.0);
        let corners = [du + dv, du - dv, -du + dv, -du - dv].map(|c| t.position() + c);
        if !corners.iter().all(|&c| lit(c)) || !lit(t.position()) {
            continue;
        }
        // Texels whose neighbours straddle the edge are the ones supersampled.
        edge_texels += usize::from(![r, l, u, d].iter().all(|&n| lit(n)));
        ratios.push(value / t.normal().dot(sun_direction).max(1e-6));
    }
    let mut sorted = ratios.clone();
    sorted.sort_by(f32::total_cmp);
    let typical = sorted[sorted.len() / 2];
    let worst = ratios.iter().map(|r| (r / typical - 1.0).abs()).fold(0.0f32, f32::max);
    eprintln!(
        "{} lit texels ({edge_texels} beside the edge), {} supersampled in all; worst {worst:.4} off E ∝ n·s",
        ratios.len(),
        baked.solution.supersampled
    );
    assert!(edge_texels >= 20, "only {edge_texels} wholly lit texels beside the edge");
    assert!(worst < 0.05, "a wholly lit texel is {worst:.3} off the light at its centre");
}

/// For a texel of `texels`, the positions of its atlas neighbours: right,
/// left, in the next row and in the row before (`width` texels a row),
/// where all four are among `texels`.
fn neighbours_of(texels: &[(Texel, f32)], width: u32) -> impl Fn(&Texel) -> Option<[Vec3; 4]> {
    let at: std::collections::HashMap<u32, Vec3> = texels.iter().map(|(t, _)| (t.index, t.position())).collect();
    let width = width as i64;
    move |t| {
        let near = |d: i64| at.get(&((t.index as i64 + d) as u32)).copied();
        Some([near(1)?, near(-1)?, near(width)?, near(-width)?])
    }
}

#[test]
fn a_rolling_terrain_whose_occluder_walks_give_up_gets_its_direct_light() {
    // A black heightfield of 120 × 120 cells rolling ±0.5 m, under a low sun
    // and a sky: the plane of almost every texel cuts the terrain again and
    // again, so the occluder pass stops walking at its limit for many of
    // them and leaves every direction to the rays (under sky_sun's 64
    // lights, a limit of 4,096 nodes instead of 512 spared 7 % of the
    // rays). The hills' shadows and the sky between them, against the CPU
    // path tracer (black: direct light only). Bake gave 0.998 of its light
    // with an RMSE of 0.6 %, and 0.999 with 1.4 % in the shadows; walks cut
    // short that kept only the cones they had found gave 5.9 % there.
    let gpu = common::gpu();
    let mut terrain = MeshData::plane(20.0, 20.0, 120);
    for p in &mut terrain.positions {
        p[1] = 0.5 * (0.7 * p[0]).sin() * (0.6 * p[2]).cos();
    }
    terrain.normals = bake::fixtures::vertex_normals(&terrain.positions, &terrain.indices);
    let mut builder = SceneBuilder::new();
    builder.object("terrain", &terrain, [0.0, 0.0, 0.0, 1.0], [0.0; 3], Placement::default());
    let sun_and_sky = EnvironmentMap::sun_and_sky([0.4, 0.5, 0.7], [0.9, 0.25, 0.35], 2e4, 1f32.to_radians());
    let lights = common::lights(&sun_and_sky, LightMode::Budget { count: 64 });
    let baked = common::bake(&gpu, &builder, &lights, &common::options(64));
    let texels: Vec<usize> =
        (0..baked.texels.texels.len()).filter(|&i| baked.texels.texels[i].area > 0.0).step_by(3).collect();
    let options = bake::reference::ReferenceOptions { samples: 256, ..Default::default() };
    let reference = bake::reference::Reference::new(&baked.scene, Some(&sun_and_sky), &options);
    let estimates = reference.estimate(&common::reference_points(&baked, &texels));
    let pairs = common::against_reference(&baked, &texels, &estimates);
    let mean = pairs.iter().map(|p| p.1).sum::<f64>() / pairs.len() as f64;
    // The hills' shadows (and the faces turned from the sun): under half
    // the mean.
    let shadowed: Vec<(f64, f64)> = pairs.iter().copied().filter(|p| p.1 < 0.5 * mean).collect();
    for (what, set) in [("every third texel", &pairs), ("those in shadow", &shadowed)] {
        let (ratio, rmse) = common::ratio_and_rmse(set);
        eprintln!(
            "{what}: {} texels, bake / reference {ratio:.4}, RMSE {:.1} % of their mean",
            set.len(),
            rmse * 100.0
        );
        assert!((ratio - 1.0).abs() < 0.02, "{what}: bake / reference {ratio}");
        assert!(rmse < 0.03, "{what}: RMSE {rmse}");
    }
    assert!(shadowed.len() * 10 > pairs.len(), "{} of {} texels in shadow", shadowed.len(), pairs.len());
}
