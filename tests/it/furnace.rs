//! The white furnace: a convex object under a constant environment of
//! radiance L sees the whole sky from every point, so L_lm = E/π = L exactly.

use crate::common;

use bake::environment::{EnvironmentMap, LightMode};
use bake::fixtures::{MeshData, Placement, SceneBuilder};

#[test]
fn sphere_under_constant_sky_is_lit_uniformly_at_l() {
    let gpu = common::gpu();
    let radiance = 1.7;
    let mut builder = SceneBuilder::new();
    builder.object("sphere", &MeshData::sphere(1.0, 48, 24), [0.8, 0.8, 0.8, 1.0], [0.0; 3], Placement::default());
    let lights = common::lights(&EnvironmentMap::constant([radiance; 3]), LightMode::Cube { face_size: 16 });
    let baked = common::bake(&gpu, &builder, &lights, &common::options(128));
    let mut worst: f32 = 0.0;
    for (texel, value) in common::values_of(&baked, 0) {
        let error = (value / radiance - 1.0).abs();
        worst = worst.max(error);
        assert!(error < 0.01, "texel at {:?} has L_lm {value}, expected {radiance} within 1%", texel.position);
    }
    eprintln!("{} texels, worst relative error {worst:.5}", baked.texels.texels.len());
}

#[test]
fn furnace_holds_for_a_box_with_hard_edges() {
    // Flat faces and chart borders on every edge: border texels must get valid
    // positions and normals, or they go dark.
    let gpu = common::gpu();
    let mut builder = SceneBuilder::new();
    builder.object("box", &MeshData::cuboid([1.0, 2.0, 0.5]), [0.5, 0.5, 0.5, 1.0], [0.0; 3], Placement::default());
    let lights = common::lights(&EnvironmentMap::constant([1.0; 3]), LightMode::Cube { face_size: 16 });
    let baked = common::bake(&gpu, &builder, &lights, &common::options(96));
    for (texel, value) in common::values_of(&baked, 0) {
        assert!(
            (value - 1.0).abs() < 0.01,
            "texel at {:?} (normal {:?}) has L_lm {value}",
            texel.position,
            texel.normal
        );
    }
}
