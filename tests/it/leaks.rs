//! Light and shadow must not leak through contacts and walls: floor texels
//! under a box resting on it stay dark, and nothing inside a closed room is
//! lit by the environment outside.

use crate::common;

use bake::environment::{EnvironmentMap, LightMode};
use bake::fixtures::{MeshData, Placement, SceneBuilder};
use glam::{Vec3, Vec3Swizzles};

#[test]
fn floor_under_a_box_resting_on_it_stays_dark() {
    let gpu = common::gpu();
    let mut builder = SceneBuilder::new();
    builder.object("floor", &MeshData::plane(6.0, 6.0, 6), [0.5, 0.5, 0.5, 1.0], [0.0; 3], Placement::default());
    builder.object(
        "box",
        &MeshData::cuboid([1.0, 1.0, 1.0]),
        [0.5, 0.5, 0.5, 1.0],
        [0.0; 3],
        Placement::at(Vec3::new(0.0, 0.5, 0.0)),
    );
    let lights = common::lights(&EnvironmentMap::constant([1.0; 3]), LightMode::Budget { count: 256 });
    let baked = common::bake(&gpu, &builder, &lights, &common::options(128));
    // Texels wholly under the box: their whole square is inside the footprint.
    let texel = 1.0 / baked.atlas.texels_per_unit;
    let (under, open_mean) = under_and_open(&baked, 0, 0.5 - texel, 2.5);
    let worst = under.iter().cloned().fold(0.0, f32::max);
    eprintln!("{} texels under the box: brightest {worst:.4}; open floor {open_mean:.4}", under.len());
    assert!(worst < 0.02 * open_mean, "a texel under the box has {worst}, the open floor {open_mean}");
}

#[test]
fn ground_under_a_floor_a_centimetre_over_it_stays_dark() {
    // A floor of zero thickness a centimetre over the ground (a sixth of a
    // lightmap texel, less than a shadow-map texel): the depth maps take it
    // for the ground's own plane, but no light reaches the ground under it.
    let gpu = common::gpu();
    let mut builder = SceneBuilder::new();
    builder.object("ground", &MeshData::plane(8.0, 8.0, 4), [0.5, 0.5, 0.5, 1.0], [0.0; 3], Placement::default());
    builder.object(
        "floor",
        &MeshData::plane(3.0, 3.0, 3),
        [0.7, 0.7, 0.7, 1.0],
        [0.0; 3],
        Placement::at(Vec3::new(0.0, 0.01, 0.0)),
    );
    let sun_and_sky = EnvironmentMap::sun_and_sky([0.5, 0.6, 0.8], [0.3, 0.8, 0.5], 1e4, 1f32.to_radians());
    let lights = common::lights(&sun_and_sky, LightMode::Budget { count: 256 });
    let baked = common::bake(&gpu, &builder, &lights, &common::options(128));
    let texel = 1.0 / baked.atlas.texels_per_unit;
    assert!(0.01 < 0.25 * texel, "the gap is a small part of a texel ({texel} m)");
    // Ground texels wholly under the floor, a texel in from its edge.
    let (under, open) = under_and_open(&baked, 0, 1.5 - 2.0 * texel, 2.5);
    let worst = under.iter().cloned().fold(0.0, f32::max);
    let (_, floor) = under_and_open(&baked, 1, 0.0, 0.0);
    eprintln!(
        "{} ground texels under the floor: brightest {worst:.4}; open ground {open:.4}; the floor {floor:.4}; \
         {} texels overlapped",
        under.len(),
        baked.solution.overlapped
    );
    assert!(worst < 0.01 * open, "a ground texel under the floor has {worst}, the open ground {open}");
    // The floor itself is lit as open ground is (its light bounces off it, not off the ground under it).
    assert!((floor / open - 1.0).abs() < 0.1, "the floor {floor}, the open ground {open}");
}

/// Lightmap values (red) of primitive `p`'s texels within `inside` of the
/// vertical axis in x and z (none left out), and their mean beyond `outside`.
fn under_and_open(baked: &bake::Baked, p: u32, inside: f32, outside: f32) -> (Vec<f32>, f32) {
    let values = common::values_of(baked, p);
    let reach = |t: &bake::texelize::Texel| t.position().xz().abs().max_element();
    let under: Vec<f32> = values.iter().filter(|(t, _)| reach(t) < inside).map(|(_, v)| *v).collect();
    let open: Vec<f32> = values.iter().filter(|(t, _)| reach(t) >= outside).map(|(_, v)| *v).collect();
    assert!(!under.is_empty() || inside <= 0.0, "no texel within {inside} of the axis");
    (under, open.iter().sum::<f32>() / open.len() as f32)
}

#[test]
fn nothing_inside_a_closed_room_is_lit_from_outside() {
    let gpu = common::gpu();
    let builder = room_on_ground([0.7, 0.7, 0.7, 1.0], [0.5, 0.5, 0.5, 1.0]);
    let sun_and_sky = EnvironmentMap::sun_and_sky([0.5, 0.6, 0.8], [0.3, 0.8, 0.5], 1e4, 1f32.to_radians());
    let lights = common::lights(&sun_and_sky, LightMode::Budget { count: 256 });
    let baked = common::bake(&gpu, &builder, &lights, &common::options(128));
    let inside = common::values_of(&baked, 0);
    let worst = inside.iter().map(|(_, v)| *v).fold(0.0, f32::max);
    let outside = common::values_of(&baked, 1);
    let ground = outside.iter().map(|(_, v)| *v).fold(0.0, f32::max);
    eprintln!("brightest texel inside the room {worst:.2e}; brightest ground texel {ground:.3}");
    // The direct pass lets nothing in. What remains comes from the hemicube's
    // resolution: receivers within half a texel of a corner, just behind a
    // wall seen obliquely by a ground patch, measured 1.4e-4 of the ground;
    // a real leak through a wall or a contact is of the order of 1e-2 and up.
    assert!(worst <= 1e-3 * ground, "light leaked into the room: {worst} against the ground's {ground}");
}

/// The same closed room on a ground plane of zero thickness, under light
/// from below the horizon only. The light sees the ground's underside
/// first, and the room's floor lies in the ground's plane: the room is in
/// the depth maps only as what lies behind a sheet, and a shadow ray from
/// its walls must be caught where it crosses the ground. Unobstructed, a
/// wall facing sideways would get E/π = L/2 here; one of the 16 shadow rays
/// of one of the 256 lights (ω ≈ 2π/128) at 60° from the wall's normal
/// carries L·ω·cos θ/(16π) ≈ 5·10⁻⁴ L, three times the limit.
#[test]
fn nothing_inside_a_closed_room_is_lit_from_below_the_ground() {
    let gpu = common::gpu();
    let builder = room_on_ground([0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, 1.0]);
    let below = EnvironmentMap::from_fn(512, 256, |d| if d[1] < 0.0 { [1.0; 3] } else { [0.0; 3] });
    let lights = common::lights(&below, LightMode::Budget { count: 256 });
    let baked = common::bake(&gpu, &builder, &lights, &common::options(128));
    let inside = common::values_of(&baked, 0);
    let (worst, at) =
        inside.iter().fold((0.0f32, Vec3::ZERO), |a, (t, v)| if *v > a.0 { (*v, t.position()) } else { a });
    eprintln!("brightest texel inside the room {worst:.2e} at {at}");
    assert!(worst <= 1.5e-4, "light from below leaked into the room: {worst} at {at}, of a radiance of 1");
}

/// A lamp (an emissive sheet facing down) sealed inside a box whose faces
/// point outwards, held up over a ground plane. From inside, the lamp sees
/// only the box's backs; the bounce pass leaves out the far side of a solid
/// from a shooter outside it, and must not take the lamp for one: the
/// ground stays dark. Without the box, the same lamp lights it.
#[test]
fn a_lamp_sealed_in_a_box_of_outward_faces_lights_nothing_outside() {
    let gpu = common::gpu();
    let lamp_over_ground = |boxed: bool| {
        let mut builder = SceneBuilder::new();
        let ground = [0.5, 0.5, 0.5, 1.0];
        builder.object("ground", &MeshData::plane(8.0, 8.0, 4), ground, [0.0; 3], Placement::default());
        let lamp = Placement::at(Vec3::Y * 2.0).rotated(glam::Quat::from_rotation_x(std::f32::consts::PI));
        builder.object("lamp", &MeshData::plane(0.8, 0.8, 1), [0.0, 0.0, 0.0, 1.0], [5.0; 3], lamp);
        if boxed {
            let shell = [0.5, 0.5, 0.5, 1.0];
            let at = Placement::at(Vec3::Y * 2.0);
            builder.object("box", &MeshData::cuboid([1.0, 1.0, 1.0]), shell, [0.0; 3], at);
        }
        let dark = common::lights(&EnvironmentMap::constant([0.0; 3]), LightMode::Budget { count: 16 });
        let baked = common::bake(&gpu, &builder, &dark, &common::options(128));
        common::values_of(&baked, 0).iter().map(|(_, v)| *v).fold(0.0, f32::max)
    };
    let (open, sealed) = (lamp_over_ground(false), lamp_over_ground(true));
    eprintln!("brightest ground texel: lamp in the open {open:.3}, sealed in the box {sealed:.2e}");
    assert!(open > 0.1, "the lamp in the open should light the ground: {open}");
    assert!(sealed <= 1e-3 * open, "light left the sealed box: {sealed} against {open} in the open");
}

/// A closed 4 × 3 × 4 m room of inward-facing walls (object 0) standing on
/// a 12 m ground plane (object 1), its floor in the ground's plane.
fn room_on_ground(room: [f32; 4], ground: [f32; 4]) -> SceneBuilder {
    let mut builder = SceneBuilder::new();
    builder.object("room", &MeshData::room([4.0, 3.0, 4.0]), room, [0.0; 3], Placement::at(Vec3::Y * 1.5));
    builder.object("ground", &MeshData::plane(12.0, 12.0, 4), ground, [0.0; 3], Placement::default());
    builder
}

/// A wall thinner than a texel stands on a continuous floor under a low
/// sun: the floor behind it is in its shadow right up to its foot. A texel
/// there whose square reaches under the wall to the lit side must not
/// average in that light (its supersamples stop at the wall).
#[test]
fn supersampling_does_not_reach_through_a_thin_wall() {
    let gpu = common::gpu();
    let mut builder = SceneBuilder::new();
    builder.object("floor", &MeshData::plane(6.0, 6.0, 6), [0.0, 0.0, 0.0, 1.0], [0.0; 3], Placement::default());
    // Off the texel grid's lines, so that texel centres lie behind it, not in it.
    let (thickness, wall_z) = (0.01, 0.04);
    builder.object(
        "wall",
        &MeshData::cuboid([4.0, 1.0, thickness]),
        [0.0, 0.0, 0.0, 1.0],
        [0.0; 3],
        Placement::at(Vec3::new(0.0, 0.5, wall_z)),
    );
    // 30° above the horizon on the wall's +z side: its shadow reaches 1.7 m.
    let sun = Vec3::new(0.0, 0.5, 0.75f32.sqrt());
    let cos_radius = 0.5f32.to_radians().cos();
    let sky =
        EnvironmentMap::from_fn(2048, 1024, |d| if Vec3::from(d).dot(sun) >= cos_radius { [1e3; 3] } else { [0.0; 3] });
    let lights = common::lights(&sky, LightMode::Budget { count: 32 });
    let baked = common::bake(&gpu, &builder, &lights, &common::options(64));
    let texel = 1.0 / baked.atlas.texels_per_unit;
    assert!(texel > 4.0 * thickness, "the wall must be thinner than a texel ({texel} m)");
    let floor = common::values_of(&baked, 0);
    let open = floor.iter().filter(|(t, _)| t.position().z > wall_z + 0.5).map(|v| v.1).fold(0.0, f32::max);
    let behind: Vec<f32> = floor
        .iter()
        .filter(|(t, _)| {
            t.position().x.abs() < 1.5 && (wall_z - 1.0..wall_z - thickness / 2.0).contains(&t.position().z)
        })
        .map(|v| v.1)
        .collect();
    let worst = behind.iter().cloned().fold(0.0, f32::max);
    eprintln!(
        "{} texels behind the wall: brightest {worst:.4} of the open floor's {open:.3}; supersampled {}",
        behind.len(),
        baked.solution.supersampled
    );
    assert!(baked.solution.supersampled > 0);
    assert!(worst < 0.02 * open, "a texel behind the wall has {worst}, the open floor {open}");
}

/// A ball rests on a black floor under light from below the horizon only.
/// The floor covers the ball's underside from it: a texel there facing
/// within 18° of straight down can see, past the ball itself, at most
/// (1 − cos 18°)/2 = 2.4 % of its cosine-weighted hemisphere above the
/// horizon (which is dark) and a band under the horizon beyond the floor's
/// edge of well under 0.1 %. Lifting the receiver off its surface to test
/// the shadow maps must not lift it through the floor it nearly touches.
/// The ball's equator, 0.5 m up, sees that band 18° deep: about a fifth of
/// its hemisphere's weight.
#[test]
fn underside_of_a_ball_resting_on_the_floor_sees_no_light_from_below() {
    underside_resting_on_the_floor_sees_no_light_from_below(&MeshData::sphere(0.5, 48, 24), 0.5);
}

/// The same with a ring lying on the floor: it touches the floor along a
/// circle of vertices, so texels on that circle lie on the floor itself
/// (not millimetres above it, as the ball's nearest ones do), and a texel's
/// flat footprint, extended across the circle, dips below the floor.
#[test]
fn underside_of_a_ring_lying_on_the_floor_sees_no_light_from_below() {
    underside_resting_on_the_floor_sees_no_light_from_below(&MeshData::torus(0.6, 0.22, 48, 24), 0.22);
}

/// `mesh` stands on a black floor with its lowest point at `height` below
/// its origin, under light from below the horizon only.
fn underside_resting_on_the_floor_sees_no_light_from_below(mesh: &MeshData, height: f32) {
    let gpu = common::gpu();
    let mut builder = SceneBuilder::new();
    builder.object("floor", &MeshData::plane(3.0, 3.0, 6), [0.0, 0.0, 0.0, 1.0], [0.0; 3], Placement::default());
    builder.object("object", mesh, [0.5, 0.5, 0.5, 1.0], [0.0; 3], Placement::at(Vec3::new(0.0, height, 0.0)));
    let below = EnvironmentMap::from_fn(512, 256, |d| if d[1] < 0.0 { [1.0; 3] } else { [0.0; 3] });
    let lights = common::lights(&below, LightMode::Budget { count: 256 });
    let baked = common::bake(&gpu, &builder, &lights, &common::options(128));
    let object = common::values_of(&baked, 1);
    let underside: Vec<(Vec3, f32)> =
        object.iter().filter(|(t, _)| t.normal().y < -0.95).map(|(t, v)| (t.position(), *v)).collect();
    let (at, worst) = underside.iter().cloned().fold((Vec3::ZERO, 0.0), |a, b| if b.1 > a.1 { b } else { a });
    let side = object.iter().filter(|(t, _)| t.normal().y.abs() < 0.1).map(|v| v.1).fold(0.0, f32::max);
    eprintln!("{} underside texels: brightest {worst:.4} at {at}; brightest at the equator {side:.3}", underside.len());
    assert!(!underside.is_empty());
    assert!(side > 0.1, "the light from below must reach the equator ({side})");
    assert!(worst < 0.03, "an underside texel at {at} has {worst}");
}
