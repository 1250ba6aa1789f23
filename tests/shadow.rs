//! Occlusion: a sphere above the ground under a uniform sky. The ground
//! point right below a sphere of radius R whose centre is at height d sees a
//! cap of the sky blocked whose cosine-weighted share is (R/d)², so there
//! L_lm = L (1 − (R/d)²); far away the ground sees (almost) the whole sky.
//! The sphere is black so that no light bounces back onto the ground.

mod common;

use bake::environment::{EnvironmentMap, LightMode};
use bake::fixtures::{MeshData, Placement, SceneBuilder};
use glam::{Vec3, Vec3Swizzles};

#[test]
fn sphere_darkens_the_ground_beneath_it_by_the_analytic_amount() {
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
    let lights = common::lights(&EnvironmentMap::horizon([sky; 3]), LightMode::Budget { count: 512 });
    let baked = common::bake(&gpu, &builder, &lights, &common::options(256));
    let ground = common::values_of(&baked, 0);

    let below: Vec<f32> = ground.iter().filter(|(t, _)| t.position().xz().length() < 0.1).map(|(_, v)| *v).collect();
    let far: Vec<f32> = ground.iter().filter(|(t, _)| t.position().xz().length() > 5.0).map(|(_, v)| *v).collect();
    assert!(!below.is_empty() && !far.is_empty());
    let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len() as f32;
    let expected = sky * (1.0 - (radius / height).powi(2));
    eprintln!("below the sphere {:.4} (expected {expected:.4}), far away {:.4}", mean(&below), mean(&far));
    assert!((mean(&below) / expected - 1.0).abs() < 0.03, "below: {} vs {expected}", mean(&below));
    assert!(mean(&far) > 0.97 * sky, "far: {}", mean(&far));
    assert!(mean(&below) < 0.7 * mean(&far));
}
