//! Progressive-refinement radiosity against known answers: closed rooms
//! (L = Le/(1−ρ)), analytic form factors, colour bleeding, energy bounds,
//! and the independent CPU path tracer.

use crate::common;

use bake::config::BakeOptions;
use bake::environment::{EnvironmentMap, LightMode};
use bake::fixtures::{MeshData, Placement, SceneBuilder, six_wall_room};
use bake::progress::Silent;
use glam::{Quat, Vec3};

/// Bakes a scene lit only by its emitters.
fn bake_emitters(builder: &SceneBuilder, atlas: u32, tweak: impl Fn(&mut BakeOptions)) -> bake::Baked {
    let gpu = common::gpu();
    let mut options = common::options(atlas);
    tweak(&mut options);
    let baked = bake::bake_scene(&gpu, common::scene(builder, "room"), None, &options, &mut Silent).unwrap();
    common::assert_valid(&baked);
    baked
}

/// Area-weighted mean of `value(texel index)` over the texels of `primitives`.
fn area_mean(baked: &bake::Baked, primitives: &[u32], value: impl Fn(usize) -> f32) -> f64 {
    let (mut sum, mut area) = (0.0f64, 0.0f64);
    for (i, t) in baked.texels.texels.iter().enumerate() {
        if primitives.contains(&t.primitive) {
            sum += value(i) as f64 * t.area as f64;
            area += t.area as f64;
        }
    }
    sum / area
}

/// About as many shooter patches as two closed rooms below are cut into:
/// what they check (the mean, the light left unshot) does not depend on how
/// fine the patches are, and a room converges in as many shots per patch
/// either way.
const ROOM_PATCHES: u32 = 256;

#[test]
fn closed_room_with_uniform_emission_reaches_le_over_one_minus_rho() {
    // Bounded runs: the ambient term stands in for the light not yet shot.
    // The default patches: texel by texel, a run stopped short is further
    // off with coarse ones (at ρ = 0.95, 4.5 % after 1,500 shots of 280
    // patches, against 2.3 % after 8,000 of 1,526).
    for (rho, tolerance, shots) in [(0.5f32, 0.02f32, 4_000), (0.95, 0.05, 8_000)] {
        let baked = bake_emitters(&six_wall_room([(rho, 1.0); 6]), 96, |o| o.solve.bounce.max_shots = Some(shots));
        let expected = 1.0 / (1.0 - rho);
        let bounce = baked.solution.bounce.as_ref().expect("the bounce pass ran");
        assert_eq!(bounce.stopped_by, bake::solve::StopReason::MaxShots, "ρ = {rho}: a bounded run");
        let mut worst = 0.0f32;
        for (texel, value) in baked.texels.texels.iter().zip(&baked.solution.lightmap) {
            // Incident light L_lm = (L − Le)/ρ = Le/(1−ρ) as well.
            let error = (value[0] / expected - 1.0).abs();
            worst = worst.max(error);
            assert!(
                error < tolerance,
                "ρ = {rho}: texel at {:?} has {}, expected {expected}",
                texel.position,
                value[0]
            );
        }
        eprintln!(
            "ρ = {rho}: {} shots, stopped by {}, unshot {:.4}, ambient {:.4}, worst error {worst:.4}",
            bounce.shots, bounce.stopped_by, bounce.unshot_fraction, bounce.ambient[0]
        );
        assert!(bounce.shots <= shots + 64);
    }
}

#[test]
fn a_converged_closed_room_counts_the_light_it_had_left_to_shoot() {
    // Converged at the default tolerance, up to 1 % of the light is still
    // unshot; it would have landed where the shots' light did, and must be
    // in the answer: mean L_lm = Le/(1 − ρ) to well within that 1 %.
    let rho = 0.8f32;
    let baked = bake_emitters(&six_wall_room([(rho, 1.0); 6]), 96, |o| o.solve.bounce.patches = ROOM_PATCHES);
    let bounce = baked.solution.bounce.as_ref().expect("the bounce pass ran");
    assert_eq!(bounce.stopped_by, bake::solve::StopReason::Converged);
    let mean = area_mean(&baked, &[0, 1, 2, 3, 4, 5], |i| baked.solution.lightmap[i][0]);
    let expected = 1.0 / (1.0 - rho as f64);
    eprintln!(
        "{} shots, unshot {:.4}, ambient {:.4}: mean {mean:.5}, expected {expected:.5}",
        bounce.shots, bounce.unshot_fraction, bounce.ambient[0]
    );
    assert!(bounce.unshot_fraction > 0.001, "enough light left unshot for the test to mean something");
    assert!((mean / expected - 1.0).abs() < 0.005, "mean {mean} vs {expected}");
}

#[test]
fn the_form_factor_measure_sums_alike_over_any_slots_a_workgroup() {
    // A CPU driver's measure workgroups take all 64 shooter slots of a batch
    // where the texels are many, a GPU's 8: each slot's sums must come out
    // the same bits either way, or a bake would depend on the adapter's kind
    // and the scene's size. A room with walls of different albedos, some
    // glowing, normalizes every patch's form factors at its first shot.
    let room = six_wall_room([(0.7, 0.0), (0.5, 2.0), (0.2, 0.0), (0.8, 1.0), (0.5, 0.0), (0.6, 0.0)]);
    let bake_with = |slots: u32| {
        bake_emitters(&room, 64, |o| {
            o.solve.bounce.measure_slots = Some(slots);
            o.solve.bounce.max_shots = Some(512);
        })
    };
    let narrow = bake_with(8);
    assert!(narrow.solution.bounce.as_ref().is_some_and(|b| b.normalized && b.shots == 512));
    for slots in [64, 32, 5] {
        let other = bake_with(slots);
        let same = narrow
            .solution
            .lightmap
            .iter()
            .zip(&other.solution.lightmap)
            .all(|(a, b)| a.map(f32::to_bits) == b.map(f32::to_bits));
        assert!(same, "{slots} slots a measure workgroup changed the lightmap");
    }
}

#[test]
fn closed_room_with_one_emitting_wall_keeps_the_mean() {
    // Σ A L = Σ A Le + ρ Σ A L in a closed room: mean L = mean Le / (1 − ρ).
    for (rho, tolerance) in [(0.5f32, 0.02f64), (0.95, 0.05)] {
        let mut walls = [(rho, 0.0); 6];
        walls[1].1 = 3.0;
        let baked = bake_emitters(&six_wall_room(walls), 96, |o| {
            o.solve.bounce.max_shots = Some(1_500);
            o.solve.bounce.patches = ROOM_PATCHES;
        });
        let mean = area_mean(&baked, &[0, 1, 2, 3, 4, 5], |i| baked.solution.radiosity(&baked.texels, i)[0]);
        let expected = 3.0 / 6.0 / (1.0 - rho as f64);
        eprintln!("ρ = {rho}: mean radiosity {mean:.4}, expected {expected:.4}");
        assert!((mean / expected - 1.0).abs() < tolerance, "ρ = {rho}: mean {mean} vs {expected}");
        // Farther from the lamp is darker.
        let floor = area_mean(&baked, &[0], |i| baked.solution.lightmap[i][0]);
        let wall = area_mean(&baked, &[2], |i| baked.solution.lightmap[i][0]);
        assert!(floor < wall || rho > 0.9, "the floor (facing the lamp) {floor} vs a wall {wall}");
    }
}

fn mesh_area(mesh: &MeshData) -> f64 {
    let p = |i: u32| Vec3::from(mesh.positions[i as usize]).as_dvec3();
    mesh.indices.chunks(3).map(|t| 0.5 * (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0])).length()).sum()
}

#[test]
fn the_inside_of_a_sphere_lit_by_a_glowing_cap_is_evenly_lit() {
    // Inside a sphere every patch's form factor to a point is A/(4πR²)
    // wherever the two are, so a glowing cap lights the whole inside evenly:
    // L_lm = Le · A_cap / A_sphere / (1 − ρ) everywhere. Patches of 64 to
    // the sphere are curved (45° across); one flat parallelogram standing
    // in for one of them in the near field hovered in front of its
    // neighbours and lit them up to 1.47× the mean. And each lights itself:
    // left out, the cap's own patches' glow went to the rest of the sphere
    // and the cap read 8 % low.
    let sphere = MeshData::sphere(1.0, 48, 24);
    let cap = common::inside_of(&sphere, |c| c.y > 0.8);
    let rest = common::inside_of(&sphere, |c| c.y <= 0.8);
    let rho = 0.5;
    let mut builder = SceneBuilder::new();
    builder.object("cap", &cap, [rho, rho, rho, 1.0], [1.0; 3], Placement::default());
    builder.object("rest", &rest, [rho, rho, rho, 1.0], [0.0; 3], Placement::default());
    let baked = bake_emitters(&builder, 128, |o| o.solve.bounce.patches = 64);
    let expected = mesh_area(&cap) / (mesh_area(&cap) + mesh_area(&rest)) / (1.0 - rho as f64);
    let mean = area_mean(&baked, &[0, 1], |i| baked.solution.lightmap[i][0]);
    let values: Vec<f64> = (0..baked.texels.texels.len())
        .filter(|&i| baked.texels.texels[i].area > 0.0)
        .map(|i| baked.solution.lightmap[i][0] as f64 / mean)
        .collect();
    let spread = (values.iter().map(|v| (v - 1.0).powi(2)).sum::<f64>() / values.len() as f64).sqrt();
    let brightest = values.iter().copied().fold(0.0, f64::max);
    let cap_mean = area_mean(&baked, &[0], |i| baked.solution.lightmap[i][0]);
    eprintln!(
        "mean {mean:.4} (expected {expected:.4}), cap {:.4} × the mean, RMS spread {:.2} %, brightest {brightest:.3}",
        cap_mean / mean,
        spread * 100.0
    );
    assert!((mean / expected - 1.0).abs() < 0.02, "mean {mean} vs {expected}");
    assert!((cap_mean / mean - 1.0).abs() < 0.03, "the cap reads {} × the mean", cap_mean / mean);
    assert!(brightest < 1.15, "a texel reads {brightest} × the mean");
    assert!(spread < 0.04, "RMS spread {spread}");
}

#[test]
fn a_floor_laid_twice_or_just_over_itself_glows_and_reflects_once() {
    // A copy of the floor in the floor's plane, or a centimetre over it (a
    // fifth of a texel): the place still emits Le and reflects ρ once, as a
    // path that meets one of the two surfaces there sees, so the closed room
    // still reaches L = Le/(1 − ρ) on every surface. Counting both floors in
    // full left them 10 % dark and the ceiling 5 % bright; the hidden floor,
    // taking light it never gave back, left the room 44 % dark. Texels on an
    // edge between another mesh's triangles, not counted, left both floors
    // 0.6 % dark.
    let rho = 0.8f32;
    let expected = 1.0 / (1.0 - rho as f64);
    // Bounded, the ambient term standing in for the light not yet shot: at
    // 3,000 shots every surface's mean was within 0.8 % of Le/(1 − ρ), at
    // 6,000 within 0.5 % (at convergence, 13,184 shots, within 0.4 %).
    let shots = 3_000;
    for lift in [0.0f32, 0.01] {
        let mut builder = six_wall_room([(rho, 1.0); 6]);
        builder.object(
            "floor over the floor",
            &MeshData::plane(2.0, 2.0, 3),
            [rho, rho, rho, 1.0],
            [1.0; 3],
            Placement::at(Vec3::new(0.0, -1.0 + lift, 0.0)),
        );
        let baked = bake_emitters(&builder, 96, |o| o.solve.bounce.max_shots = Some(shots));
        let texel_size = 1.0 / baked.atlas.texels_per_unit;
        assert!(lift < 0.25 * texel_size, "the lift, {lift} m, is under a texel of {texel_size} m");
        // In the room's floor's plane, both floors are seen; over it, the room's floor is hidden.
        let seen: &[u32] = if lift == 0.0 { &[0, 1, 2, 3, 4, 5, 6] } else { &[1, 2, 3, 4, 5, 6] };
        let bounce = baked.solution.bounce.as_ref().expect("the bounce pass ran");
        let means: Vec<f64> =
            seen.iter().map(|&p| area_mean(&baked, &[p], |i| baked.solution.lightmap[i][0])).collect();
        eprintln!(
            "lift {lift} m: {} texels overlapped, {} shots ({}): mean L_lm by surface {means:.4?}, expected {expected:.4}",
            baked.solution.overlapped, bounce.shots, bounce.stopped_by
        );
        for (&p, mean) in seen.iter().zip(&means) {
            assert!((mean / expected - 1.0).abs() < 0.015, "lift {lift} m: surface {p}'s mean {mean} vs {expected}");
        }
        // Every texel of a floor another lies on or over overlaps, also those
        // on a triangle's edge of either (at first, 1,512 of 1,568 were counted).
        let overlapping: &[u32] = if lift == 0.0 { &[0, 6] } else { &[0] };
        let texels = baked.texels.texels.iter().filter(|t| overlapping.contains(&t.primitive) && t.area > 0.0);
        assert_eq!(baked.solution.overlapped, texels.count(), "lift {lift} m: texels counted as overlapping");
    }
}

#[test]
fn floor_tiles_that_only_meet_along_an_edge_do_not_overlap() {
    // Two tiles of one floor, separate meshes, meeting along an edge: their
    // border texels lie on that edge, and neither tile lies over the other
    // there, so each bounces its own light in full.
    let mut builder = six_wall_room([(0.8, 1.0); 6]);
    for x in [-0.4f32, 0.4] {
        builder.object(
            "tile",
            &MeshData::plane(0.8, 1.6, 2),
            [0.8, 0.8, 0.8, 1.0],
            [0.0; 3],
            Placement::at(Vec3::new(x, -0.5, 0.0)),
        );
    }
    // Overlaps are found before the bounce pass; a few shots suffice.
    let baked = bake_emitters(&builder, 96, |o| o.solve.bounce.max_shots = Some(64));
    assert_eq!(baked.solution.overlapped, 0, "texels counted as overlapping");
}

#[test]
fn a_room_seen_through_an_opening_in_sunlight_gets_all_its_bounced_light() {
    // A room without its front wall, raised off a sunlit ground, the sun
    // shining in. Most of the light put in leaves the ground for the sky, so
    // 1 % of it unshot is still much of the room's own bounced light: stopped
    // there, the room came out 3 % dark inside and its back wall 6 % (now
    // 1.3 % and 2.9 %). The CPU reference traces the same texels.
    let gpu = common::gpu();
    let mut room = MeshData::room([4.0, 3.0, 4.0]);
    // Faces +X, −X, +Y, −Y, +Z, −Z, six indices each: leave out +Z, the front.
    room.indices.drain(24..30);
    let mut builder = SceneBuilder::new();
    builder.object("room", &room, [0.7, 0.7, 0.7, 1.0], [0.0; 3], Placement::at(Vec3::Y * 2.0));
    builder.object("ground", &MeshData::plane(12.0, 12.0, 4), [0.7, 0.7, 0.7, 1.0], [0.0; 3], Placement::default());
    let sun = Vec3::new(0.3, 0.6, 0.75).normalize();
    let map = EnvironmentMap::from_fn(256, 128, |d| {
        if Vec3::from(d).dot(sun) > 3f32.to_radians().cos() {
            [400.0; 3]
        } else if d[1] > 0.0 {
            [0.3, 0.4, 0.6]
        } else {
            [0.0; 3]
        }
    });
    let lights = common::lights(&map, LightMode::Budget { count: 128 });
    let baked = common::bake(&gpu, &builder, &lights, &common::options(128));
    let bounce = baked.solution.bounce.as_ref().expect("the bounce pass ran");

    let inside: Vec<usize> = (0..baked.texels.texels.len())
        .filter(|&i| baked.texels.texels[i].primitive == 0 && baked.texels.texels[i].area > 0.0)
        .step_by(3)
        .collect();
    let options = bake::reference::ReferenceOptions { samples: 1024, ..Default::default() };
    let reference = bake::reference::Reference::new(&baked.scene, Some(&map), &options);
    let estimates = reference.estimate(&common::reference_points(&baked, &inside));
    // Bake over reference, over all of the inside and over the back wall (−Z).
    let ratio = |keep: &dyn Fn(usize) -> bool| {
        let (mut bake, mut truth) = (0.0f64, 0.0f64);
        for (&i, estimate) in inside.iter().zip(&estimates).filter(|(i, _)| keep(**i)) {
            bake += baked.solution.lightmap[i].iter().map(|&c| c as f64).sum::<f64>();
            truth += estimate.lightmap.iter().sum::<f64>();
        }
        bake / truth
    };
    let all = ratio(&|_| true);
    let back = ratio(&|i| baked.texels.texels[i].normal[2] > 0.9);
    eprintln!(
        "{} shots ({}), unshot {:.4}: inside {all:.3} of the reference over {} texels, back wall {back:.3}",
        bounce.shots,
        bounce.stopped_by,
        bounce.unshot_fraction,
        inside.len()
    );
    assert!((all - 1.0).abs() < 0.022, "the inside is {all} of the reference");
    assert!((back - 1.0).abs() < 0.04, "the back wall is {back} of the reference");
}

/// Mean L_lm over a black receiving unit square facing an emitting unit
/// square of radiance 1 placed by `emitter`: the form factor F(receiver → emitter).
fn form_factor(emitter: Placement) -> f64 {
    let mut builder = SceneBuilder::new();
    builder.object("receiver", &MeshData::plane(1.0, 1.0, 8), [0.0, 0.0, 0.0, 1.0], [0.0; 3], Placement::default());
    builder.object("emitter", &MeshData::plane(1.0, 1.0, 8), [0.0, 0.0, 0.0, 1.0], [1.0; 3], emitter);
    let baked = bake_emitters(&builder, 128, |o| o.solve.bounce.patches = 2048);
    area_mean(&baked, &[0], |i| baked.solution.lightmap[i][0])
}

#[test]
fn parallel_coaxial_squares_match_the_closed_form() {
    // Unit squares one unit apart: F = 0.19982 (Hottel; Howell's catalogue C-11).
    let f = form_factor(Placement::at(Vec3::new(0.0, 1.0, 0.0)).rotated(Quat::from_rotation_x(180f32.to_radians())));
    eprintln!("parallel squares: F = {f:.5} (closed form 0.19982)");
    assert!((f / 0.19982 - 1.0).abs() < 0.03, "F = {f}");
}

#[test]
fn perpendicular_squares_sharing_an_edge_match_the_closed_form() {
    // Unit squares at a right angle along a common edge: F = 0.20004 (Howell C-14).
    let f = form_factor(Placement::at(Vec3::new(0.5, 0.5, 0.0)).rotated(Quat::from_rotation_z(90f32.to_radians())));
    eprintln!("perpendicular squares: F = {f:.5} (closed form 0.20004)");
    assert!((f / 0.20004 - 1.0).abs() < 0.03, "F = {f}");
}

/// Floor texels beside a wall are in contact (`contact`): their light is
/// gathered along 256 cosine rays, which meet a small bright emitter a
/// metre up about once between them. The emitter is sampled where it is
/// too, so each such texel gets the inverse-square law's light: for a
/// square of area A and radiance L at height h, distance d, L_lm = L A h² / (π d⁴).
#[test]
fn floor_beside_a_wall_gets_a_small_emitters_light_without_noise() {
    let (radiance, side) = (100.0f32, 0.1f32);
    let black = [0.0, 0.0, 0.0, 1.0];
    let mut builder = SceneBuilder::new();
    builder.object("floor", &MeshData::plane(2.0, 2.0, 8), black, [0.0; 3], Placement::default());
    let wall = Placement::at(Vec3::new(0.5, 0.25, 0.0));
    builder.object("wall", &MeshData::cuboid([0.05, 0.5, 2.0]), black, [0.0; 3], wall);
    let facing_down = Placement::at(Vec3::new(0.0, 1.0, 0.0)).rotated(Quat::from_rotation_x(180f32.to_radians()));
    builder.object("emitter", &MeshData::plane(side, side, 1), black, [radiance; 3], facing_down);
    // Coarse patches: the contact fix-up then reaches 15 cm out from the wall.
    let baked = bake_emitters(&builder, 128, |o| o.solve.bounce.patches = 64);
    assert!(baked.solution.contact.as_ref().is_some_and(|c| c.gathered > 0), "no texel was in contact");
    let texels = &baked.texels.texels;
    let emitter = texels.iter().filter(|t| t.emission[0] > 0.0).fold(Vec3::ZERO, |sum, t| sum + Vec3::from(t.position));
    let emitter = emitter / texels.iter().filter(|t| t.emission[0] > 0.0).count() as f32;
    let ratios: Vec<f64> = (0..texels.len())
        .filter(|&i| {
            let t = &texels[i];
            let x = t.position[0] - emitter.x;
            t.primitive == 0 && t.area > 0.0 && (0.36..0.46).contains(&x) && (t.position[2] - emitter.z).abs() < 0.8
        })
        .map(|i| {
            let to = emitter - Vec3::from(texels[i].position);
            let expected = radiance * side * side * to.y * to.y / (std::f32::consts::PI * to.length_squared().powi(2));
            (baked.solution.lightmap[i][0] / expected) as f64
        })
        .collect();
    let mean = ratios.iter().sum::<f64>() / ratios.len() as f64;
    let rms = (ratios.iter().map(|r| (r - 1.0).powi(2)).sum::<f64>() / ratios.len() as f64).sqrt();
    eprintln!(
        "{} floor texels beside the wall: bake / inverse-square law {mean:.4} on average, rms {rms:.4}",
        ratios.len()
    );
    assert!(ratios.len() >= 100, "only {} texels beside the wall", ratios.len());
    assert!((mean - 1.0).abs() < 0.03, "bake / inverse-square law {mean} on average");
    assert!(rms < 0.05, "bake / inverse-square law scatters by {rms}");
}

/// L_lm at floor point (x, 0, z) under a unit square of radiance 1 at height
/// 2 facing down, whose light a half-plane x > 0 at height 1 blocks: the
/// integral of cos θ cos θ′ / (π r²) over the part of the square it sees
/// (from (x, z), the plane hides the square's points with x′ > −x), summed
/// over a fine grid.
fn under_a_half_shaded_square(x: f64, z: f64) -> f64 {
    let n = 400;
    let cell = 1.0 / n as f64;
    let mut sum = 0.0;
    for i in 0..n {
        let ex = -0.5 + (i as f64 + 0.5) * cell;
        if ex > -x {
            continue;
        }
        for j in 0..n {
            let ez = -0.5 + (j as f64 + 0.5) * cell;
            let r2 = (ex - x).powi(2) + 4.0 + (ez - z).powi(2);
            sum += 4.0 / (r2 * r2) * cell * cell;
        }
    }
    sum / std::f64::consts::PI
}

/// An emitter's penumbra is its own light seen past an edge, not the hard
/// shadows of the points its patches shoot from: a square panel over a
/// black floor, half hidden from it by a black plate half way down (whose
/// edge is under the panel's centre), lights the penumbra on the floor as
/// the integral over the part of the panel each point sees.
#[test]
fn a_panels_penumbra_past_a_plate_is_the_integral_over_what_each_point_sees() {
    let black = [0.0, 0.0, 0.0, 1.0];
    let mut builder = SceneBuilder::new();
    builder.object("floor", &MeshData::plane(4.0, 4.0, 8), black, [0.0; 3], Placement::default());
    let plate = Placement::at(Vec3::new(1.0, 1.0, 0.0));
    builder.object("plate", &MeshData::cuboid([2.0, 0.02, 2.0]), black, [0.0; 3], plate);
    let facing_down = Placement::at(Vec3::new(0.0, 2.0, 0.0)).rotated(Quat::from_rotation_x(180f32.to_radians()));
    builder.object("panel", &MeshData::plane(1.0, 1.0, 4), black, [1.0; 3], facing_down);
    let baked = bake_emitters(&builder, 128, |_| {});
    let unshaded = under_a_half_shaded_square(-1.0, 0.0);
    let errors: Vec<f64> = (baked.texels.texels.iter().enumerate())
        .filter(|(_, t)| t.primitive == 0 && t.area > 0.0 && t.position[0].abs() < 0.4 && t.position[2].abs() < 0.4)
        .map(|(i, t)| {
            let exact = under_a_half_shaded_square(t.position[0] as f64, t.position[2] as f64);
            (baked.solution.lightmap[i][0] as f64 - exact) / unshaded
        })
        .collect();
    let rms = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
    let worst = errors.iter().fold(0.0f64, |m, e| m.max(e.abs()));
    let mean = errors.iter().sum::<f64>() / errors.len() as f64;
    eprintln!(
        "{} penumbra texels: rms error {rms:.4}, mean {mean:.4}, worst {worst:.4} of the unshaded light",
        errors.len()
    );
    assert!(errors.len() >= 100, "only {} texels in the penumbra", errors.len());
    // Split into patches a texel wide, the panel still casts 22 hard shadows
    // a few centimetres apart (rms 0.034); in patches of 3 × 3 texels it was
    // 0.064, with steps of up to 0.12.
    assert!(rms < 0.04, "the penumbra is off by {rms} rms of the unshaded light");
}

/// A black floor and a black sphere, one of them glowing (radiance 1).
fn ball_and_floor(ball_height: f32, radius: f32, glowing_ball: bool) -> SceneBuilder {
    let (ball, floor) = if glowing_ball { ([1.0; 3], [0.0; 3]) } else { ([0.0; 3], [1.0; 3]) };
    let mut builder = SceneBuilder::new();
    let black = [0.0, 0.0, 0.0, 1.0];
    builder.object("floor", &MeshData::plane(6.0, 6.0, 6), black, floor, Placement::default());
    let at = Placement::at(Vec3::new(0.0, ball_height, 0.0));
    builder.object("ball", &MeshData::sphere(radius, 64, 32), black, ball, at);
    builder
}

/// The covered texels of primitive `primitive` lower than `height`.
fn texels_below(baked: &bake::Baked, primitive: u32, height: f32) -> impl Iterator<Item = usize> + '_ {
    (0..baked.texels.texels.len()).filter(move |&i| {
        let t = &baked.texels.texels[i];
        t.primitive == primitive && t.area > 0.0 && t.position[1] < height
    })
}

/// Bake / independent CPU path tracer, summed over texels `lower` of `baked`
/// by height in three bands of `height` above the floor, the contact's first.
fn bands_against_reference(
    baked: &bake::Baked,
    lower: &[usize],
    height: f32,
    environment: Option<&EnvironmentMap>,
) -> [f64; 3] {
    let points = common::reference_points(baked, lower);
    let options = bake::reference::ReferenceOptions { samples: 1024, ..Default::default() };
    let estimates = bake::reference::Reference::new(&baked.scene, environment, &options).estimate(&points);
    let mut bands = [(0.0f64, 0.0f64); 3];
    for (&i, estimate) in lower.iter().zip(&estimates) {
        let band = ((baked.texels.texels[i].position[1] / height * 3.0) as usize).min(2);
        bands[band].0 += baked.solution.lightmap[i][0] as f64;
        bands[band].1 += estimate.lightmap[0];
    }
    bands.map(|(bake, reference)| bake / reference)
}

#[test]
fn glowing_ball_lights_the_floor_as_the_inverse_square_law_says() {
    // A sphere of radius R and radiance 1 entirely above a point of the
    // floor, its centre at height H and distance D, gives it
    // L_lm = E/π = (R/D)² · H/D. Its patches are curved: each must shoot
    // from above its own surface (a hemicube a hair too low saw the sphere
    // from inside), and the floor must take the form factor at its surface
    // (half a texel up, the ball's low patches looked flatter): the floor
    // came out 20 % dark.
    let (radius, height) = (0.5f32, 1.0f32);
    let baked = bake_emitters(&ball_and_floor(height, radius, true), 128, |_| {});
    let rings = [(0.0, 0.6), (0.6, 1.2), (1.2, 2.0), (2.0, 2.9)];
    for (inner, outer) in rings {
        let (mut bake, mut expected) = (0.0f64, 0.0f64);
        for (t, v) in baked.texels.texels.iter().zip(&baked.solution.lightmap) {
            let d = (t.position[0].powi(2) + t.position[2].powi(2)).sqrt();
            if t.primitive == 0 && t.area > 0.0 && d >= inner && d < outer {
                let distance = (d as f64).hypot(height as f64);
                bake += v[0] as f64 * t.area as f64;
                expected += (radius as f64 / distance).powi(2) * height as f64 / distance * t.area as f64;
            }
        }
        let ratio = bake / expected;
        eprintln!("floor {inner}–{outer} m from under the ball: bake / inverse-square law {ratio:.4}");
        assert!((ratio - 1.0).abs() < 0.04, "ring {inner}–{outer} m: {ratio}");
    }
}

#[test]
fn ball_resting_on_a_glowing_floor_sees_it_with_its_underside() {
    // Each texel of the lower half against the independent CPU path tracer
    // at its position. The underside meets the floor at a grazing angle, near
    // the floor's patches: the exact near-field form factor, taken from half
    // a texel off the surface, left the lowest band at 0.77 of the reference.
    let radius = 0.7f32;
    let baked = bake_emitters(&ball_and_floor(radius, radius, false), 128, |_| {});
    let lower: Vec<usize> = texels_below(&baked, 1, radius).step_by(2).collect();
    for (k, ratio) in bands_against_reference(&baked, &lower, radius, None).into_iter().enumerate() {
        eprintln!("underside band {k} (from the contact up): bake / reference {ratio:.4}");
        assert!((ratio - 1.0).abs() < 0.05, "band {k}: {ratio}");
    }
}

/// A ring (major and minor radius, `segments` around) of `colour` lying on
/// a white floor `floor` metres square.
fn ring_on_floor(floor: f32, major: f32, minor: f32, segments: u32, colour: [f32; 4]) -> SceneBuilder {
    let mut builder = SceneBuilder::new();
    builder.object("floor", &MeshData::plane(floor, floor, 4), [0.8, 0.8, 0.8, 1.0], [0.0; 3], Placement::default());
    let ring = MeshData::torus(major, minor, segments, 24);
    builder.object("ring", &ring, colour, [0.0; 3], Placement::at(Vec3::new(0.0, minor, 0.0)));
    builder
}

#[test]
fn torus_resting_on_a_sunlit_floor_sees_the_shadow_beneath_it_with_its_underside() {
    // A black ring lying on a white floor, the sun overhead: the floor under
    // the tube is in its shadow, a strip narrower than a shooter patch, and
    // the floor beside it is lit. The tube's underside sees mostly the
    // shadow. Lit by the floor patches' mean unshot light, the lowest band
    // came out at twice the CPU path tracer's value (1.99), the bands above
    // at 0.88 and 0.90.
    let gpu = common::gpu();
    let (major, minor) = (0.4f32, 0.05f32);
    let builder = ring_on_floor(2.0, major, minor, 64, [0.0, 0.0, 0.0, 1.0]);
    let sun = EnvironmentMap::from_fn(512, 256, |d| if d[1] > 0.995 { [1000.0; 3] } else { [0.0; 3] });
    let lights = common::lights(&sun, LightMode::Budget { count: 64 });
    let baked = common::bake(&gpu, &builder, &lights, &common::options(128));
    let lower: Vec<usize> = texels_below(&baked, 1, minor).collect();
    let ratios = bands_against_reference(&baked, &lower, minor, Some(&sun));
    eprintln!("ring underside, bake / reference by band from the contact up: {ratios:.3?}");
    // From the bounce pass alone the contact's band kept an excess (1.36):
    // the floor's own shadow there is a few texels wide. Gathered along rays
    // from the texels they meet (the contact fix-up), it is 1.03.
    for (k, ratio) in ratios.iter().enumerate() {
        assert!((ratio - 1.0).abs() < 0.1, "band {k}: {ratio}");
    }
}

#[test]
fn the_floor_under_a_ring_and_the_ring_over_it_get_the_light_that_slips_between_them() {
    // A light ring lying on a white floor under a low sun and a sky: the
    // sun shines in under the tube's outer side, and light bounces back and
    // forth in the wedge between tube and floor, a gap narrower than a
    // shooter patch or a depth-map texel. The floor under the tube and the
    // tube's lowest part, against the CPU path tracer. From the GPU passes
    // alone they got 0.84 and 0.89 of its light, with an RMSE of 23 and 16 %
    // of their mean; traced along rays (the contact fix-up), 0.981 and 0.978
    // with 6 % (the path tracer's own noise is about 3 % per texel at 1,024
    // samples; the test takes 512, about 4 %).
    let gpu = common::gpu();
    let (major, minor) = (0.6f32, 0.2f32);
    let builder = ring_on_floor(4.0, major, minor, 48, [0.8, 0.7, 0.4, 1.0]);
    let sun = [0.9f32, 0.35, 0.25];
    let sun_and_sky = EnvironmentMap::sun_and_sky([0.4, 0.5, 0.7], sun, 2e3, 1f32.to_radians());
    let lights = common::lights(&sun_and_sky, LightMode::Budget { count: 256 });
    let baked = common::bake(&gpu, &builder, &lights, &common::options(256));
    let under_tube = |t: &bake::texelize::Texel| {
        let r = t.position[0].hypot(t.position[2]);
        (r - major).abs() < 0.75 * minor
    };
    // Every other texel: about a thousand each, so the path tracer's noise
    // over the sum stays near 0.15 %.
    let floor: Vec<usize> =
        texels_below(&baked, 0, 1.0).filter(|&i| under_tube(&baked.texels.texels[i])).step_by(2).collect();
    let ring: Vec<usize> = texels_below(&baked, 1, 0.3 * minor).step_by(2).collect();
    let options = bake::reference::ReferenceOptions { samples: 512, ..Default::default() };
    let reference = bake::reference::Reference::new(&baked.scene, Some(&sun_and_sky), &options);
    for (what, texels) in [("floor under the tube", &floor), ("tube's lowest part", &ring)] {
        let estimates = reference.estimate(&common::reference_points(&baked, texels));
        let (ratio, rmse) = common::ratio_and_rmse(&common::against_reference(&baked, texels, &estimates));
        eprintln!(
            "{what}: {} texels, bake / reference {ratio:.3}, RMSE {:.1} % of the mean",
            texels.len(),
            rmse * 100.0
        );
        assert!((ratio - 1.0).abs() < 0.05, "{what}: bake / reference {ratio}");
        assert!(rmse < 0.1, "{what}: RMSE {rmse}");
    }
}

#[test]
fn a_small_ball_on_a_large_ground_gets_the_light_the_ground_bounces_under_it() {
    // A ball of 0.25 m on a 40 m ground, under a sun and a sky: the ball's
    // lower half is lit mostly by the ground around it. The ground's shooter
    // patches are 1.25 m (the atlas's cells are one size for the scene), and
    // a hemicube sees from one point of a patch: shot from cells five times
    // the ball's width, the lower half's bands got 0.80, 0.72 and 0.82 of the
    // path tracer's light. Split where a smaller object stands over them,
    // the cells gave 0.88, 0.93 and 0.95 (the contact band kept the dark
    // contact found under balls before); the contact fix-up, which traces
    // the light of the texels near the ground along rays, gives 1.03, 0.97
    // and 0.96.
    let gpu = common::gpu();
    let radius = 0.25f32;
    let mut builder = SceneBuilder::new();
    let grey = [0.5, 0.5, 0.5, 1.0];
    builder.object("ground", &MeshData::plane(40.0, 40.0, 4), grey, [0.0; 3], Placement::default());
    let ball = MeshData::sphere(radius, 32, 16);
    builder.object("ball", &ball, [0.8, 0.8, 0.8, 1.0], [0.0; 3], Placement::at(Vec3::Y * radius));
    let sun_and_sky = EnvironmentMap::sun_and_sky([0.5, 0.6, 0.8], [0.3, 0.8, 0.5], 1e3, 1f32.to_radians());
    let lights = common::lights(&sun_and_sky, LightMode::Budget { count: 256 });
    let baked = common::bake(&gpu, &builder, &lights, &common::options(512));
    let lower: Vec<usize> = texels_below(&baked, 1, radius).collect();
    let ratios = bands_against_reference(&baked, &lower, radius, Some(&sun_and_sky));
    eprintln!(
        "{} texels on the ball's lower half, bake / reference by band from the contact up: {ratios:.3?}",
        lower.len()
    );
    for (k, ratio) in ratios.iter().enumerate() {
        assert!((0.93..1.07).contains(ratio), "band {k}: {ratio}");
    }
}

#[test]
fn a_wall_standing_across_the_ground_gets_the_ground_light_down_to_its_foot() {
    // A wall standing on a ground, across the ground's shooter patches,
    // under a sun in front of it. A patch whose hemicube stood behind the
    // wall shot its sunlit half's light from there, and the wall's front
    // never saw it: the 10 cm bands of the wall's foot came out 0.79, 0.89
    // and 0.93 of the path tracer's light at 256² (of the bounced light in
    // its lowest 3 cm, 0.26). Cut where their hemicube's origin cannot see
    // all of them, the patches give 0.96, 0.95 and 0.95.
    let mut builder = SceneBuilder::new();
    let grey = [0.5, 0.5, 0.5, 1.0];
    builder.object("ground", &MeshData::plane(8.0, 8.0, 4), grey, [0.0; 3], Placement::default());
    builder.object("wall", &MeshData::plane(3.0, 2.0, 4), [0.8, 0.8, 0.8, 1.0], [0.0; 3], wall_on_the_ground());
    for (k, ratio) in wall_foot_bands(&builder, |t| t.primitive == 1).iter().enumerate() {
        assert!((0.9..1.1).contains(ratio), "band {k}: {ratio}");
    }
}

#[test]
fn a_wall_merged_into_the_grounds_mesh_gets_the_ground_light_down_to_its_foot() {
    // The wall above, in the ground's mesh (as exporters often merge what
    // shares a material): only other primitives cut a shooter patch where
    // it stood across one, and the wall's foot got 0.97, 0.90 and 0.93 of
    // the path tracer's light, against 0.98, 0.95 and 0.95 as two meshes.
    let mut both = MeshData::plane(8.0, 8.0, 4);
    both.append(&MeshData::plane(3.0, 2.0, 4), wall_on_the_ground());
    let mut builder = SceneBuilder::new();
    builder.object("ground and wall", &both, [0.5, 0.5, 0.5, 1.0], [0.0; 3], Placement::default());
    for (k, ratio) in wall_foot_bands(&builder, |t| t.normal[1].abs() < 0.5).iter().enumerate() {
        assert!((0.93..1.07).contains(ratio), "band {k}: {ratio}");
    }
}

#[test]
fn a_rooms_walls_get_the_floors_light_down_to_their_foot_where_patches_are_three_texels_wide() {
    // A white room with two boxes, lit by a panel under its ceiling, at an
    // atlas where a shooter patch is three texels wide: the rows of the
    // walls' foot within a floor patch are lit by it from too few points.
    // With the contact fix-up reaching only half a patch (1.5 texels), the
    // walls' second and third rows were 1.1 % and 0.6 % dark against the
    // path tracer; reaching at least three texels (contact.rs), they are
    // within 0.4 %.
    let height = 3.0f32;
    let mut builder = SceneBuilder::new();
    let white = [0.8, 0.8, 0.8, 1.0];
    let room = MeshData::room([5.0, height, 4.0]);
    builder.object("room", &room, white, [0.0; 3], Placement::at(Vec3::Y * (0.5 * height)));
    let facing_down = Placement::at(Vec3::Y * (height - 0.01)).rotated(Quat::from_rotation_x(180f32.to_radians()));
    builder.object("panel", &MeshData::plane(1.2, 1.2, 2), white, [10.0; 3], facing_down);
    builder.object("box", &MeshData::cuboid([0.8; 3]), white, [0.0; 3], Placement::at(Vec3::new(1.2, 0.4, 0.5)));
    let tall = MeshData::cuboid([0.6, 1.8, 0.6]);
    builder.object("tall box", &tall, [0.8, 0.7, 0.2, 1.0], [0.0; 3], Placement::at(Vec3::new(-1.3, 0.9, -0.8)));
    let baked = bake_emitters(&builder, 128, |_| {});
    let side = 1.0 / baked.atlas.texels_per_unit;
    let rows = 3.0 * side;
    let on_a_wall = |&i: &usize| baked.texels.texels[i].face_normal[1].abs() < 0.5;
    let foot: Vec<usize> = texels_below(&baked, 0, rows).filter(on_a_wall).collect();
    let ratios = bands_against_reference(&baked, &foot, rows, None);
    eprintln!(
        "{} texels of the walls' three lowest rows ({side:.3} m), bake / reference by row: {ratios:.4?}",
        foot.len()
    );
    for (k, ratio) in ratios.iter().enumerate() {
        assert!((ratio - 1.0).abs() < 0.008, "row {k}: {ratio}");
    }
}

/// A 3 × 2 m wall standing across the middle of an 8 m ground, facing +Z.
fn wall_on_the_ground() -> Placement {
    Placement::at(Vec3::new(0.0, 1.0, 0.0)).rotated(Quat::from_rotation_x(90f32.to_radians()))
}

/// Bake / path tracer over the wall's texels (`wall`) in its lowest 30 cm,
/// by 10 cm band from the ground up, under a sun in front of it.
fn wall_foot_bands(builder: &SceneBuilder, wall: impl Fn(&bake::texelize::Texel) -> bool) -> [f64; 3] {
    let gpu = common::gpu();
    let sun_and_sky = EnvironmentMap::sun_and_sky([0.5, 0.6, 0.8], [0.3, 0.8, 0.5], 1e3, 1f32.to_radians());
    let lights = common::lights(&sun_and_sky, LightMode::Budget { count: 256 });
    let baked = common::bake(&gpu, builder, &lights, &common::options(256));
    let height = 0.3;
    let lower: Vec<usize> = (0..baked.texels.texels.len())
        .filter(|&i| {
            let t = &baked.texels.texels[i];
            wall(t) && t.area > 0.0 && t.position[1] < height
        })
        .collect();
    let ratios = bands_against_reference(&baked, &lower, height, Some(&sun_and_sky));
    eprintln!(
        "{} texels on the wall's foot, bake / reference by 10 cm band from the ground up: {ratios:.3?}",
        lower.len()
    );
    ratios
}

/// A white floor with a red wall standing on one edge, under a uniform sky.
fn floor_and_red_wall(floor_albedo: f32) -> SceneBuilder {
    let mut builder = SceneBuilder::new();
    builder.object(
        "floor",
        &MeshData::plane(4.0, 4.0, 8),
        [floor_albedo, floor_albedo, floor_albedo, 1.0],
        [0.0; 3],
        Placement::default(),
    );
    builder.object(
        "red wall",
        &MeshData::plane(2.0, 4.0, 8),
        [0.9, 0.1, 0.1, 1.0],
        [0.0; 3],
        Placement::at(Vec3::new(-2.0, 1.0, 0.0)).rotated(Quat::from_rotation_z(-90f32.to_radians())),
    );
    builder
}

#[test]
fn white_floor_is_redder_next_to_a_red_wall() {
    let gpu = common::gpu();
    let lights = common::lights(&EnvironmentMap::constant([1.0; 3]), LightMode::Cube { face_size: 8 });
    let baked = common::bake(&gpu, &floor_and_red_wall(0.8), &lights, &common::options(128));
    let redness = |near: bool| {
        let (mut r, mut g) = (0.0, 0.0);
        for (t, v) in baked.texels.texels.iter().zip(&baked.solution.lightmap) {
            let x = t.position[0];
            if t.primitive == 0 && ((near && x < -1.6) || (!near && x > 1.6)) {
                r += v[0];
                g += v[1];
            }
        }
        r / g
    };
    let (near, far) = (redness(true), redness(false));
    eprintln!("red/green of the floor's light: {near:.4} next to the wall, {far:.4} far from it");
    assert!(near > far * 1.05, "near {near} far {far}");
}

#[test]
fn black_surfaces_bounce_nothing_and_reflection_never_exceeds_albedo() {
    let gpu = common::gpu();
    let lights = common::lights(&EnvironmentMap::constant([1.0; 3]), LightMode::Cube { face_size: 8 });
    // All black: bouncing would add light from nowhere.
    let mut black = SceneBuilder::new();
    black.object("floor", &MeshData::plane(4.0, 4.0, 4), [0.0, 0.0, 0.0, 1.0], [0.0; 3], Placement::default());
    black.object(
        "wall",
        &MeshData::plane(2.0, 4.0, 4),
        [0.0, 0.0, 0.0, 1.0],
        [0.0; 3],
        Placement::at(Vec3::new(-2.0, 1.0, 0.0)).rotated(Quat::from_rotation_z(-90f32.to_radians())),
    );
    let baked = common::bake(&gpu, &black, &lights, &common::options(96));
    assert!(baked.solution.bounce.is_none(), "a black scene has nothing to bounce");
    assert!(baked.solution.skipped.iter().any(|s| s.pass == "bounce"));

    // With albedo, the light every surface receives by bouncing is at most ρ times what was received.
    let baked = common::bake(&gpu, &floor_and_red_wall(0.8), &lights, &common::options(96));
    let bounce = baked.solution.bounce.as_ref().unwrap();
    assert!(bounce.closure <= 1.0);
    let received: f64 =
        baked.texels.texels.iter().zip(&baked.solution.lightmap).map(|(t, v)| v[1] as f64 * t.area as f64).sum();
    let reflected: f64 = baked
        .texels
        .texels
        .iter()
        .zip(&baked.solution.lightmap)
        .map(|(t, v)| (t.albedo[1] * v[1]) as f64 * t.area as f64)
        .sum();
    assert!(reflected <= 0.9 * received + 1e-9, "reflected {reflected} vs received {received}");
}

#[test]
fn gpu_bake_matches_the_cpu_reference_with_interreflection() {
    // An open box (floor and three walls) under a sky: light bounces between
    // the walls. The reference traces exact rays in f64 at the texels' own
    // positions, with nothing shared with the GPU path.
    let gpu = common::gpu();
    let mut builder = SceneBuilder::new();
    let walls = [
        ("floor", Quat::IDENTITY, Vec3::ZERO, [0.7, 0.7, 0.7]),
        ("back", Quat::from_rotation_x(90f32.to_radians()), Vec3::new(0.0, 1.0, -1.0), [0.7, 0.7, 0.7]),
        ("left", Quat::from_rotation_z(-90f32.to_radians()), Vec3::new(-1.0, 1.0, 0.0), [0.8, 0.2, 0.2]),
        ("right", Quat::from_rotation_z(90f32.to_radians()), Vec3::new(1.0, 1.0, 0.0), [0.2, 0.8, 0.2]),
    ];
    for (name, rotation, at, albedo) in walls {
        let [r, g, b] = albedo;
        builder.object(
            name,
            &MeshData::plane(2.0, 2.0, 4),
            [r, g, b, 1.0],
            [0.0; 3],
            Placement::at(at).rotated(rotation),
        );
    }
    let map = EnvironmentMap::from_fn(128, 64, |d| if d[1] > 0.0 { [1.0, 1.0, 1.0] } else { [0.2, 0.2, 0.2] });
    let lights = common::lights(&map, LightMode::Cube { face_size: 16 });
    let baked = common::bake(&gpu, &builder, &lights, &common::options(96));
    assert!(baked.solution.bounce.is_some());

    let sample: Vec<usize> =
        (0..baked.texels.texels.len()).step_by(7).filter(|&i| baked.texels.texels[i].area > 0.0).collect();
    let points = common::reference_points(&baked, &sample);
    let options = bake::reference::ReferenceOptions { samples: 512, ..Default::default() };
    let reference = bake::reference::Reference::new(&baked.scene, Some(&map), &options);
    let estimates = reference.estimate(&points);
    let (mut squared, mut mean) = (0.0f64, 0.0f64);
    for (&i, estimate) in sample.iter().zip(&estimates) {
        for c in 0..3 {
            let d = baked.solution.lightmap[i][c] as f64 - estimate.lightmap[c];
            squared += d * d;
            mean += estimate.lightmap[c];
        }
    }
    let n = (sample.len() * 3) as f64;
    let relative_rmse = (squared / n).sqrt() / (mean / n);
    eprintln!("GPU vs CPU reference over {} texels: relative RMSE {relative_rmse:.4}", sample.len());
    assert!(relative_rmse < 0.05, "relative RMSE {relative_rmse}");
}

#[test]
fn hemicube_faces_drawing_only_the_casters_they_see_give_the_same_bake() {
    // Each hemicube face draws the casters a compute pass lists for it, and
    // a face whose list would overflow draws them all. With no room for
    // lists every face draws every caster; with little, most faces' lists
    // overflow. corner normalizes its form factors, so the hemicubes'
    // depths and their front-facing marks both count.
    //
    // The lists leave out a solid's far side (the sphere, box and torus), which no ray from
    // outside meets first. Drawn, it ties with the near side along the box's
    // outline, where the two meet at the same depth and the marks in the
    // depth's low bits pick the winner: a few hemicube pixels, measured at
    // 5.3e-4 of the mean texel at most. A triangle wrongly left out is a
    // hole in a wall or in the box, of the order of the whole light.
    let gpu = common::gpu();
    let map = EnvironmentMap::from_fn(128, 64, |d| if d[1] > 0.0 { [1.0, 0.9, 0.8] } else { [0.1; 3] });
    let lights = common::lights(&map, LightMode::Budget { count: 32 });
    let with_lists = |bytes: u64| {
        let mut options = common::options(64);
        options.solve.bounce.face_list_bytes = bytes;
        // The lists are compared at equal shots, not at convergence.
        options.solve.bounce.max_shots = Some(512);
        common::bake(&gpu, &bake::fixtures::corner(), &lights, &options)
    };
    let culled = with_lists(bake::solve::BounceOptions::default().face_list_bytes);
    let bounce = culled.solution.bounce.as_ref().unwrap();
    assert!(bounce.shots > 0 && bounce.normalized, "{bounce:?}");
    let lightmap = &culled.solution.lightmap;
    let mean = lightmap.iter().flatten().sum::<f32>() / (3 * lightmap.len()) as f32;
    for bytes in [0, 256 << 10] {
        let other = with_lists(bytes);
        let differences =
            lightmap.iter().zip(&other.solution.lightmap).flat_map(|(a, b)| (0..3).map(|c| (a[c] - b[c]).abs()));
        let worst = differences.fold(0.0f32, f32::max);
        eprintln!("lists of at most {bytes} bytes: largest difference {:.2e} of the mean texel", worst / mean);
        assert!(worst <= 2e-3 * mean, "lists of at most {bytes} bytes change the bake by {worst} (mean {mean})");
    }
}

#[test]
fn a_ring_on_a_coarse_sunlit_ground_lights_its_chart_edges_as_their_neighbours() {
    // A ring 5 m across lying on a 60 m ground under the sun-and-sky
    // fixture: the tube's lower part sees the sunlit ground beside the
    // contact. Its chart-edge texels (no area, but a viewer's bilinear
    // filter reads them at the chart's edge) were left out of the contact
    // fix-up and kept the GPU passes' light: 0.644, 0.917 and 0.944 of the
    // path tracer's by band from the contact up (now 1.026, 0.994, 0.961),
    // while the texels inside the charts, fixed up, got 1.047, 0.983 and
    // 0.965.
    let gpu = common::gpu();
    let map = EnvironmentMap::load(common::repo("fixtures/sky_sun.exr"), &Default::default()).unwrap().map;
    let lights = common::lights(&map, LightMode::Budget { count: 256 });
    let (major, minor) = (2.4f32, 0.8f32);
    let builder = ring_on_floor(60.0, major, minor, 32, [0.6, 0.6, 0.6, 1.0]);
    let baked = common::bake(&gpu, &builder, &lights, &common::options(128));
    let lower = |with_area: bool| -> Vec<usize> {
        (0..baked.texels.texels.len())
            .filter(|&i| {
                let t = &baked.texels.texels[i];
                t.primitive == 1 && (t.area > 0.0) == with_area && t.position[1] < 1.3 * minor
            })
            .collect()
    };
    for (what, texels) in [("texels", lower(true)), ("chart-edge texels", lower(false))] {
        let ratios = bands_against_reference(&baked, &texels, minor, Some(&map));
        eprintln!("{} lower {what}, bake / reference by band from the contact up: {ratios:.3?}", texels.len());
        for (k, ratio) in ratios.iter().enumerate() {
            assert!((0.93..1.07).contains(ratio), "{what}, band {k}: {ratio}");
        }
    }
}

#[test]
fn a_slab_just_over_a_sunlit_ground_keeps_its_underside_dark() {
    // A 2 m slab 10 cm thick, 5 mm and 5 cm over a 20 m ground (texels of
    // 16 cm), the sun overhead. The ground under it lies within a texel of
    // the slab's top, facing the same way: hidden (`overlaps`), it gets no
    // light. Gather rays from the underside that met it took the light of
    // the surface over it, the slab's sunlit top: at 5 mm the underside
    // came out 431 times the path tracer's light (2.6 to 96 times by band
    // at 5 cm). Now they meet the dark gap (the underside: 0.10 and 0.26 of
    // the path tracer's light, which finds a little light slipping in under
    // the edges).
    let gpu = common::gpu();
    let map = EnvironmentMap::sun_and_sky([0.4, 0.5, 0.7], [0.0, 1.0, 0.0], 2e3, 1f32.to_radians());
    let lights = common::lights(&map, LightMode::Budget { count: 256 });
    let (size, centre) = (2.0f32, Vec3::new(0.13, 0.0, 0.07));
    for gap in [0.005f32, 0.05] {
        let mut builder = SceneBuilder::new();
        let ground = MeshData::plane(20.0, 20.0, 4);
        builder.object("ground", &ground, [0.8, 0.8, 0.8, 1.0], [0.0; 3], Placement::default());
        let slab = MeshData::cuboid([size, 0.1, size]);
        let placement = Placement::at(centre + Vec3::Y * (gap + 0.05));
        builder.object("slab", &slab, [0.6, 0.6, 0.6, 1.0], [0.0; 3], placement);
        let baked = common::bake(&gpu, &builder, &lights, &common::options(128));
        let texels = &baked.texels.texels;
        let reference = bake::reference::Reference::new(&baked.scene, Some(&map), &Default::default());
        let ratio = |face: &dyn Fn([f32; 3]) -> bool| {
            let set: Vec<usize> =
                (0..texels.len()).filter(|&i| texels[i].primitive == 1 && face(texels[i].normal)).collect();
            let estimates = reference.estimate(&common::reference_points(&baked, &set));
            let bake: f64 = set.iter().map(|&i| baked.solution.lightmap[i][0] as f64).sum();
            bake / estimates.iter().map(|e| e.lightmap[0]).sum::<f64>()
        };
        let (underside, sides) = (ratio(&|n| n[1] < -0.9), ratio(&|n| n[1].abs() < 0.1));
        eprintln!("gap {gap} m: bake / reference underside {underside:.3}, sides {sides:.3}");
        assert!(underside < 1.1, "gap {gap} m: the underside got {underside} of the path tracer's light");
        // Rays from the sides meeting the ground just outside the slab,
        // where its texel is hidden, take the ground's next texel out (the
        // sides: 0.987 and 0.959 of the path tracer's light; 0.940 and 0.939
        // where only another primitive's texel stood in, the slab's darker
        // ones).
        assert!((sides - 1.0).abs() < 0.05, "gap {gap} m: the sides got {sides} of the path tracer's light");
        // The ground under it stays dark.
        let under = |t: &bake::texelize::Texel| (Vec3::from(t.position) - centre).abs().max_element() < 0.4 * size;
        for (t, light) in texels.iter().zip(&baked.solution.lightmap) {
            if t.primitive == 0 && t.area > 0.0 && under(t) {
                assert_eq!(*light, [0.0; 3], "gap {gap} m: ground under the slab at {:?}", t.position);
            }
        }
    }
}

#[test]
fn a_ball_resting_on_the_floor_and_the_floor_under_it_return_no_more_light_than_they_get() {
    // The corner fixture (a ball resting on the floor among other things)
    // under a sky L and a low sun (8° up, in under the ball) of solid angle
    // Ω at L_sun: no texel takes in more than (L + L_sun·Ω/π)/(1 − ρ_max)
    // (directly at most L + L_sun·Ω/π, and each bounce returns at most
    // ρ_max of the most any texel takes). The ball's lowest patch and the
    // floor under it lie millimetres apart; seen from just under it, the
    // patch's sub-cell squares overlap, and with their form factors summed
    // past 1 the two passed light back and forth with a gain over 1 until
    // the bake was infinite (1e36, then NaN, after 4,000 shots).
    let gpu = common::gpu();
    let builder = bake::fixtures::corner();
    let sun = Vec3::new(0.804, 0.137, 0.578).normalize();
    let (sun_cos, l_sun, l_sky) = (0.99995f32, 20000.0f32, 1.0f32);
    let sky =
        EnvironmentMap::from_fn(1024, 512, |d| if Vec3::from(d).dot(sun) > sun_cos { [l_sun; 3] } else { [l_sky; 3] });
    let lights = common::lights(&sky, LightMode::Budget { count: 64 });
    let mut options = common::options(128);
    options.solve.contact = false;
    let baked = common::bake(&gpu, &builder, &lights, &options);
    let rho = baked.texels.texels.iter().flat_map(|t| t.albedo).fold(0.0f32, f32::max);
    let omega = std::f32::consts::TAU * (1.0 - sun_cos);
    // The map's pixels at the sun's edge: a few percent of slack.
    let bound = 1.05 * (l_sky + l_sun * omega / std::f32::consts::PI) / (1.0 - rho);
    let most = baked.solution.lightmap.iter().flatten().fold(0.0f32, |a, &b| a.max(b));
    eprintln!("brightest texel {most} (bound {bound}, ρ_max {rho})");
    assert!(most <= bound, "a texel takes in {most}, more than {bound}");
}

#[test]
fn a_closed_room_settles_in_a_few_shots_a_patch_by_shooting_ahead() {
    // Each shooter also shoots the light it will still receive by the
    // ambient term's estimate: a white-ish closed room, which took ~37 shots
    // a patch at ρ = 0.95 without it, settles in a few, as accurately.
    let rho = 0.95f32;
    let baked = bake_emitters(&six_wall_room([(rho, 1.0); 6]), 64, |_| {});
    let bounce = baked.solution.bounce.as_ref().expect("the bounce pass ran");
    assert_eq!(bounce.stopped_by, bake::solve::StopReason::Converged);
    let per_patch = bounce.shots as f64 / bounce.patches as f64;
    let expected = 1.0 / (1.0 - rho);
    let worst = baked.solution.lightmap.iter().map(|v| (v[0] / expected - 1.0).abs()).fold(0.0f32, f32::max);
    eprintln!("{} shots of {} patches ({per_patch:.1} a patch), worst texel {worst:.4}", bounce.shots, bounce.patches);
    assert!(per_patch < 4.0, "{per_patch:.1} shots a patch");
    assert!(worst < 0.03, "a texel is {worst:.4} off Le/(1 − ρ)");
}
