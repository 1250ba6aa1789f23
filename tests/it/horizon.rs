//! Under an environment that is L above the horizon and 0 below, with
//! nothing else in the scene: an upward plane gets L_lm = L, a vertical one
//! L/2, a downward one 0 (design notes, "References a test can trust").

use crate::common;

use bake::environment::{EnvironmentMap, LightMode};
use bake::fixtures::{MeshData, Placement, SceneBuilder};
use glam::Quat;

fn plane_value(rotation: Quat) -> (f32, f32) {
    let gpu = common::gpu();
    let mut builder = SceneBuilder::new();
    builder.object(
        "plane",
        &MeshData::plane(2.0, 2.0, 2),
        [0.5, 0.5, 0.5, 1.0],
        [0.0; 3],
        Placement::default().rotated(rotation),
    );
    let lights = common::lights(&EnvironmentMap::horizon([2.0; 3]), LightMode::Cube { face_size: 16 });
    let baked = common::bake(&gpu, &builder, &lights, &common::options(64));
    let values: Vec<f32> = common::values_of(&baked, 0).into_iter().map(|(_, v)| v).collect();
    let min = values.iter().cloned().fold(f32::INFINITY, f32::min);
    let max = values.iter().cloned().fold(f32::NEG_INFINITY, f32::max);
    (min, max)
}

#[test]
fn upward_plane_sees_the_whole_sky() {
    let (min, max) = plane_value(Quat::IDENTITY);
    assert!((min / 2.0 - 1.0).abs() < 0.02 && (max / 2.0 - 1.0).abs() < 0.02, "L_lm in [{min}, {max}], expected 2");
}

#[test]
fn vertical_plane_sees_half_the_sky() {
    for rotation in [Quat::from_rotation_x(90f32.to_radians()), Quat::from_rotation_z(90f32.to_radians())] {
        let (min, max) = plane_value(rotation);
        assert!((min - 1.0).abs() < 0.02 && (max - 1.0).abs() < 0.02, "L_lm in [{min}, {max}], expected 1");
    }
}

#[test]
fn downward_plane_sees_no_sky() {
    let (min, max) = plane_value(Quat::from_rotation_x(180f32.to_radians()));
    assert!(min >= 0.0 && max < 0.02 * 2.0, "L_lm in [{min}, {max}], expected 0");
}
