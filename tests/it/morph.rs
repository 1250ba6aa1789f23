//! Morph targets and animation: a mesh with morph targets is baked in the
//! shape a viewer draws it (base plus each target's displacement times the
//! node's weight, else the mesh's), lit and casting shadows as the same
//! shape drawn plain; an animated node is baked in its rest pose with a
//! notice.

use crate::common;

use bake::environment::{EnvironmentMap, LightMode};
use bake::fixtures::{MeshData, Placement, SceneBuilder};
use glam::Vec3;

/// The box's node sits at `AT`; its target 1 at weight 0.5 stretches it to
/// twice its height (top corners up by `RAISE`) and moves it by `SHIFT`.
const AT: Vec3 = Vec3::new(0.0, 0.3, 0.0);
const RAISE: f32 = 0.6;
const SHIFT: Vec3 = Vec3::new(-0.8, 0.0, 0.4);

/// A grey ground and a grey 0.6 m box whose node draws it with morph weights
/// [0, 0.5]: target 0 (weight 1 in the mesh's default weights, which the
/// node's override) would slide it 2 m aside; target 1, at weight 0.5,
/// displaces it by twice `SHIFT` and raises its top by twice `RAISE`.
fn morphing_box() -> SceneBuilder {
    let mut scene = SceneBuilder::new();
    scene.object("ground", &MeshData::plane(6.0, 6.0, 1), [0.6, 0.6, 0.6, 1.0], [0.0; 3], Placement::default());
    let grey = scene.material("box", [0.7, 0.7, 0.7, 1.0], [0.0; 3]);
    let data = MeshData::cuboid([0.6, 0.6, 0.6]);
    let cube = scene.mesh("box", &data, Some(grey));
    scene.morph_target(cube, "POSITION", &vec![[2.0, 0.0, 0.0]; data.positions.len()]);
    let stretch: Vec<[f32; 3]> = data
        .positions
        .iter()
        .map(|p| (2.0 * (SHIFT + Vec3::Y * if p[1] > 0.0 { RAISE } else { 0.0 })).to_array())
        .collect();
    scene.morph_target(cube, "POSITION", &stretch);
    scene.mesh_weights(cube, &[1.0, 0.0]);
    let node = scene.node("box", cube, Placement::at(AT));
    scene.node_weights(node, &[0.0, 0.5]);
    scene
}

/// The same scene with the box drawn plain in its morphed shape.
fn plain_tall_box() -> SceneBuilder {
    let mut scene = SceneBuilder::new();
    scene.object("ground", &MeshData::plane(6.0, 6.0, 1), [0.6, 0.6, 0.6, 1.0], [0.0; 3], Placement::default());
    let size = [0.6, 0.6 + RAISE, 0.6];
    let centre = AT + SHIFT + Vec3::Y * RAISE * 0.5;
    scene.object("box", &MeshData::cuboid(size), [0.7, 0.7, 0.7, 1.0], [0.0; 3], Placement::at(centre));
    scene
}

/// World bounds (min, max) of primitive `p`.
fn bounds(scene: &bake::scene::Scene, p: usize) -> (Vec3, Vec3) {
    let origin = Vec3::from(scene.origin.map(|c| c as f32));
    let points = scene.primitives[p].positions.iter().map(|&q| Vec3::from(q) + origin);
    points.fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), q| (lo.min(q), hi.max(q)))
}

#[test]
fn a_morphed_box_is_imported_in_the_shape_its_node_weights_give() {
    let scene = common::scene(&morphing_box(), "morph");
    assert_eq!(scene.primitives.len(), 2, "the morphing box is baked: {:?}", scene.notices);
    let (lo, hi) = bounds(&scene, 1);
    let want_lo = AT + SHIFT - Vec3::splat(0.3);
    let want_hi = AT + SHIFT + Vec3::new(0.3, 0.3 + RAISE, 0.3);
    assert!(lo.abs_diff_eq(want_lo, 1e-5) && hi.abs_diff_eq(want_hi, 1e-5), "box spans {lo} to {hi}");
    let notices = &scene.notices;
    assert!(notices.iter().any(|n| n.contains("2 morph targets") && n.contains("[0.0, 0.5]")), "{notices:?}");
}

#[test]
fn morph_targets_displace_normals_texture_coordinates_and_colours() {
    // One quad facing +Y; target 0 tips its normals toward +X, target 1
    // shifts TEXCOORD_0, target 2 darkens COLOR_0; the mesh's weights apply.
    let mut scene = SceneBuilder::new();
    let quad = MeshData::plane(1.0, 1.0, 1);
    let mesh = scene.mesh("quad", &quad, None);
    scene.vertex_colors(mesh, &[[1.0, 1.0, 1.0]; 4]);
    scene.morph_target(mesh, "NORMAL", &[[1.0, -1.0, 0.0]; 4]);
    scene.morph_target(mesh, "TEXCOORD_0", &[[0.5, 0.25]; 4]);
    scene.morph_target(mesh, "COLOR_0", &[[-1.0, -0.5, 0.0]; 4]);
    scene.mesh_weights(mesh, &[1.0, 2.0, 0.5]);
    scene.node("quad", mesh, Placement::default());
    let imported = common::scene(&scene, "quad");
    let p = &imported.primitives[0];
    let normals = p.normals.as_ref().expect("normals");
    // (0, 1, 0) + 1·(1, -1, 0) = (1, 0, 0).
    assert!(normals.iter().all(|n| Vec3::from(*n).abs_diff_eq(Vec3::X, 1e-6)), "{normals:?}");
    let uv0 = p.uv0.as_ref().expect("uv0");
    for (uv, base) in uv0.iter().zip(&quad.uv0) {
        assert!((uv[0] - base[0] - 1.0).abs() < 1e-6 && (uv[1] - base[1] - 0.5).abs() < 1e-6, "{uv:?}");
    }
    assert!(p.colors.as_ref().expect("colours").iter().all(|c| *c == [0.5, 0.75, 1.0]), "{:?}", p.colors);
}

#[test]
fn an_animated_node_is_baked_in_its_rest_pose_with_a_notice() {
    // Weights animated from [0, 0] to [0, 1]: the node's own [0, 0.5] is its rest pose.
    let mut builder = morphing_box();
    builder.animate_weights(1, &[(0.0, vec![0.0, 0.0]), (1.0, vec![0.0, 1.0])]);
    let scene = common::scene(&builder, "morph");
    let (lo, hi) = bounds(&scene, 1);
    assert!(hi.y - lo.y > 0.6 + RAISE - 1e-5, "baked at the node's weights, not a key's: {lo} to {hi}");
    let notices = &scene.notices;
    assert!(notices.iter().any(|n| n.contains("node 1 'box' is animated (weights)")), "{notices:?}");

    // The everything fixture's orb spins; the flag's bending joint draws nothing baked.
    let source = bake::asset::SourceAsset::from_bytes(
        std::path::Path::new("everything.glb"),
        &bake::fixtures::everything(),
        None,
    )
    .unwrap();
    let scene = bake::import::from_asset(source).unwrap();
    let animated: Vec<&String> = scene.notices.iter().filter(|n| n.contains("is animated")).collect();
    assert_eq!(animated.len(), 1, "{animated:?}");
    assert!(animated[0].starts_with("node 7 'spinner' is animated (rotation)"), "{animated:?}");
}

#[test]
fn a_morphed_box_bakes_like_the_same_box_drawn_plain() {
    let gpu = common::gpu();
    let sky = EnvironmentMap::sun_and_sky([0.4, 0.5, 0.7], [0.3, 0.8, 0.5], 1e3, 1f32.to_radians());
    let lights = common::lights(&sky, LightMode::Budget { count: 128 });
    let options = common::options(128);
    let morphed = common::bake(&gpu, &morphing_box(), &lights, &options);
    let plain = common::bake(&gpu, &plain_tall_box(), &lights, &options);
    let (a, b) = (common::primitive_means(&morphed), common::primitive_means(&plain));
    eprintln!("morphed {a:.4?}\nplain   {b:.4?}");
    assert_eq!(a.len(), 2, "the morphing box is baked");
    for (k, (a, b)) in a.iter().zip(&b).enumerate() {
        assert!((a / b - 1.0).abs() < 0.02, "primitive {k}: {a:.4} morphed, {b:.4} plain");
    }
}
