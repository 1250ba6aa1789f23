//! GPU instances (EXT_mesh_gpu_instancing): a node that draws its mesh at
//! several placements bakes exactly as the same objects drawn by plain
//! nodes: every instance lit, shadowing the ground and the other instances,
//! each with its own lightmap region.

use crate::common;

use bake::environment::{EnvironmentMap, LightMode};
use bake::fixtures::{MeshData, Placement, SceneBuilder};
use glam::{Quat, Vec3};

/// Where the node sits, and its three instances relative to it: one plain,
/// one turned, one scaled (so every part of the transform matters).
fn placements() -> (Placement, Vec<Placement>) {
    let node = Placement::at(Vec3::new(0.3, 0.0, -0.4)).rotated(Quat::from_rotation_y(0.5));
    let instances = vec![
        Placement::at(Vec3::new(-1.4, 0.3, 0.0)),
        Placement::at(Vec3::new(0.0, 0.3, 0.6)).rotated(Quat::from_rotation_y(0.8)),
        Placement::at(Vec3::new(1.5, 0.45, -0.2)).scaled(Vec3::splat(1.5)),
    ];
    (node, instances)
}

/// A grey ground and three grey boxes, drawn as instances of one node or,
/// with `instanced` false, by three plain nodes at the composed placements.
fn boxes_on_ground(instanced: bool) -> SceneBuilder {
    let mut scene = SceneBuilder::new();
    scene.object("ground", &MeshData::plane(6.0, 6.0, 1), [0.6, 0.6, 0.6, 1.0], [0.0; 3], Placement::default());
    let grey = scene.material("box", [0.7, 0.7, 0.7, 1.0], [0.0; 3]);
    let cube = scene.mesh("box", &MeshData::cuboid([0.6, 0.6, 0.6]), Some(grey));
    let (node, instances) = placements();
    if instanced {
        scene.instanced_node("boxes", cube, node, &instances);
    } else {
        for (k, instance) in instances.iter().enumerate() {
            // The node's scale is 1, so node · instance is again translation, rotation, scale.
            let composed = Placement::at(node.translation + node.rotation * instance.translation)
                .rotated(node.rotation * instance.rotation)
                .scaled(instance.scale);
            scene.node(&format!("box {k}"), cube, composed);
        }
    }
    scene
}

#[test]
fn gpu_instances_bake_like_the_same_boxes_drawn_by_plain_nodes() {
    let gpu = common::gpu();
    let sky = EnvironmentMap::sun_and_sky([0.4, 0.5, 0.7], [0.3, 0.8, 0.5], 1e3, 1f32.to_radians());
    let lights = common::lights(&sky, LightMode::Budget { count: 128 });
    let options = common::options(128);
    let instanced = common::bake(&gpu, &boxes_on_ground(true), &lights, &options);
    let plain = common::bake(&gpu, &boxes_on_ground(false), &lights, &options);

    let keys: Vec<_> = instanced.scene.primitives.iter().map(|p| (p.node, p.instance)).collect();
    assert_eq!(keys, [(0, None), (1, Some(0)), (1, Some(1)), (1, Some(2))], "one primitive per instance");
    let notices = &instanced.scene.notices;
    assert!(notices.iter().any(|n| n.contains("3 GPU instances") && n.contains("'boxes'")), "{notices:?}");
    let (a, b) = (common::primitive_means(&instanced), common::primitive_means(&plain));
    eprintln!("instanced {a:.4?}\nplain     {b:.4?}");
    for (k, (a, b)) in a.iter().zip(&b).enumerate() {
        assert!((a / b - 1.0).abs() < 0.02, "primitive {k}: {a:.4} as instances, {b:.4} as plain nodes");
    }
    // The instances are not one box lit three times: the scaled one stands
    // higher in the sun and its faces are bigger, the turned one shades
    // differently; their means differ as the plain nodes' do.
    assert!((a[3] / a[1] - b[3] / b[1]).abs() < 0.02);
}
