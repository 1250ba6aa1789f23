//! Renders a baked glTF in Bevy with [`BakePlugin`] and saves a screenshot, then exits:
//!
//! ```sh
//! # in the repository root: bake the fixture (with probes), then, in bevy_bake/, view it
//! cargo run --release -- fixtures/sphere_on_ground.glb --env fixtures/sky_sun.exr --max-atlas-size 512 --probes 0.5 -o baked/
//! cd bevy_bake && xvfb-run -s "-screen 0 1280x720x24" cargo run --example view -- ../baked/sphere_on_ground.glb ../docs/bevy.png
//! ```
//!
//! `--ball X,Y,Z,R` adds a white sphere of radius R at (X, Y, Z) that is not baked: it has no lightmap, so
//! the plugin's irradiance volume (`--probes`) is all that lights it (without the plugin it is black).
//! `--ev100 X` sets the camera's exposure instead (a lightmapped picture darkens by half per step up; bake's
//! unlit preview does not move). `--no-plugin` renders the file as Bevy's glTF loader alone shows it (the default material, bake's unlit
//! preview), with the same camera: the reference the lightmapped picture should match.
//!
//! The picture is lit by the baked light only: no lights, no ambient light, no environment map, no tone
//! mapping, and the camera's exposure is the `ev100` of the file's `extras.bake`, at which Bevy shows
//! albedo · L_lm as the unlit preview does. The camera frames the scene's bounds from azimuth 35°,
//! elevation 25° with a 35° vertical field of view, as the root crate's `examples/render.rs` does.

use std::path::PathBuf;

use bevy::asset::AssetPlugin;
use bevy::camera::Exposure;
use bevy::camera::primitives::Aabb;
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::gltf::{GltfAssetLabel, GltfExtras};
use bevy::pbr::Lightmap;
use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured};
use bevy::window::WindowResolution;
use bevy::winit::{UpdateMode, WinitSettings};
use bevy::world_serialization::{WorldAsset, WorldAssetRoot};
use bevy_bake::{BakePlugin, BakedPrimitive, BakedProbes, NodeBake};

const WIDTH: u32 = 960;
const HEIGHT: u32 = 540;
/// Frames drawn after everything has loaded and before the screenshot.
const SETTLE_FRAMES: u32 = 10;
/// Give up (exit 1) after this many frames.
const MAX_FRAMES: u32 = 2000;

#[derive(Resource)]
struct Run {
    scene: Handle<WorldAsset>,
    out: PathBuf,
    plugin: bool,
    ev100: Option<f32>,
    ball: Option<[f32; 4]>,
    frames: u32,
    phase: Phase,
    /// The last screenshot's pixels: the picture is saved when two in a row are the same and show more than
    /// the clear colour (Bevy compiles pipelines in the background: early frames may miss meshes, or be black).
    last: Option<Vec<u8>>,
}

#[derive(PartialEq)]
enum Phase {
    Loading,
    Settling(u32),
    Capturing,
}

fn main() -> AppExit {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = || {
        eprintln!("usage: view BAKED.glb|BAKED.gltf OUT.png [--no-plugin] [--ev100 X] [--ball X,Y,Z,R]");
        AppExit::error()
    };
    let (mut plugin, mut ev100, mut ball, mut paths) = (true, None, None, Vec::new());
    let mut args = args.iter();
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--no-plugin" => plugin = false,
            "--ev100" => match args.next().and_then(|x| x.parse::<f32>().ok()) {
                Some(x) => ev100 = Some(x),
                None => return usage(),
            },
            "--ball" => {
                let numbers: Option<Vec<f32>> =
                    args.next().and_then(|x| x.split(',').map(|n| n.parse::<f32>().ok()).collect());
                match numbers.as_deref() {
                    Some(&[x, y, z, r]) if r > 0.0 => ball = Some([x, y, z, r]),
                    _ => return usage(),
                }
            }
            _ if arg.starts_with("--") => return usage(),
            _ => paths.push(arg),
        }
    }
    let [gltf, out] = paths[..] else { return usage() };
    let gltf = std::path::absolute(gltf).expect("current directory");
    let folder = gltf.parent().expect("a file's folder").to_string_lossy().into_owned();
    let name = gltf.file_name().expect("a file name").to_string_lossy().into_owned();

    let mut app = App::new();
    app.add_plugins(DefaultPlugins.set(AssetPlugin { file_path: folder, ..default() }).set(WindowPlugin {
        primary_window: Some(Window {
            title: "bevy_bake".into(),
            resolution: WindowResolution::new(WIDTH, HEIGHT).with_scale_factor_override(1.0),
            resizable: false,
            ..default()
        }),
        ..default()
    }));
    if plugin {
        app.add_plugins(BakePlugin);
    }
    let scene = app.world().resource::<AssetServer>().load(GltfAssetLabel::Scene(0).from_asset(name));
    app.insert_resource(WinitSettings { focused_mode: UpdateMode::Continuous, unfocused_mode: UpdateMode::Continuous })
        .insert_resource(ClearColor(Color::linear_rgb(0.18, 0.18, 0.18)))
        .insert_resource(GlobalAmbientLight::NONE)
        .insert_resource(Run {
            scene,
            out: PathBuf::from(out),
            plugin,
            ev100,
            ball,
            frames: 0,
            phase: Phase::Loading,
            last: None,
        })
        .add_systems(Startup, setup)
        .add_systems(Update, drive)
        .run()
}

fn setup(mut commands: Commands, run: Res<Run>) {
    commands.spawn(WorldAssetRoot(run.scene.clone()));
    commands.spawn((
        Camera3d::default(),
        Projection::Perspective(PerspectiveProjection { fov: 35f32.to_radians(), ..default() }),
        Tonemapping::None,
        Transform::from_xyz(0.0, 2.0, 10.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
}

#[allow(clippy::too_many_arguments)]
fn drive(
    mut commands: Commands,
    mut run: ResMut<Run>,
    assets: Res<AssetServer>,
    meshes: Query<(&Aabb, &GlobalTransform), With<Mesh3d>>,
    nodes: Query<&GltfExtras>,
    lightmapped: Query<(), With<Lightmap>>,
    baked: Query<(&BakedPrimitive, &MeshMaterial3d<StandardMaterial>)>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    mut mesh_assets: ResMut<Assets<Mesh>>,
    probes: Query<(&BakedProbes, &GlobalTransform)>,
    mut camera: Query<(&mut Transform, &mut Projection, Entity), With<Camera3d>>,
    mut exit: MessageWriter<AppExit>,
) {
    run.frames += 1;
    if run.frames > MAX_FRAMES {
        error!("no screenshot after {MAX_FRAMES} frames");
        exit.write(AppExit::error());
        return;
    }
    match run.phase {
        Phase::Loading => {
            if !assets.is_loaded_with_dependencies(&run.scene) || meshes.is_empty() {
                return;
            }
            let (mut transform, mut projection, camera) = camera.single_mut().expect("one camera");
            let (centre, radius) = bounds(&meshes);
            let (azimuth, elevation) = (35f32.to_radians(), 25f32.to_radians());
            let direction =
                Vec3::new(elevation.cos() * azimuth.sin(), elevation.sin(), elevation.cos() * azimuth.cos());
            let fov = 35f32.to_radians();
            let distance = radius / (fov * 0.5).sin() * 0.85;
            *transform = Transform::from_translation(centre + direction * distance).looking_at(centre, Vec3::Y);
            if let Projection::Perspective(p) = projection.as_mut() {
                p.near = distance * 0.01;
                p.far = distance + radius * 2.0;
            }
            // The same exposure with and without the plugin, from the file's own record.
            let file_ev100 = nodes.iter().find_map(|e| NodeBake::from_extras(&e.value).ok().flatten()).map(|b| b.ev100);
            let Some(file_ev100) = file_ev100 else {
                error!("no node with extras.bake: not a baked file");
                exit.write(AppExit::error());
                return;
            };
            let ev100 = run.ev100.unwrap_or(file_ev100);
            commands.entity(camera).insert(Exposure { ev100 });
            let unlit = baked.iter().filter(|(_, m)| materials.get(&m.0).is_none_or(|m| m.unlit)).count();
            info!(
                "scene loaded after {} frames: {} meshes, {} lightmapped ({unlit} of them unlit), {} probe volumes {:?}; \
                 camera EV100 {ev100:.3} (the file's {file_ev100:.3})",
                run.frames,
                meshes.iter().count(),
                lightmapped.iter().count(),
                probes.iter().count(),
                probes.iter().map(|(p, t)| (p.counts, t.translation(), t.scale())).collect::<Vec<_>>(),
            );
            if run.plugin && (lightmapped.is_empty() || unlit > 0 || baked.iter().any(|(b, _)| b.ev100 != file_ev100)) {
                error!(
                    "the plugin attached no lightmap, left an unlit material, or lightmaps with different exposures"
                );
                exit.write(AppExit::error());
                return;
            }
            if let Some([x, y, z, r]) = run.ball {
                commands.spawn((
                    Mesh3d(mesh_assets.add(Sphere::new(r).mesh().uv(48, 24))),
                    MeshMaterial3d(materials.add(StandardMaterial { perceptual_roughness: 1.0, ..default() })),
                    Transform::from_xyz(x, y, z),
                ));
            }
            run.phase = Phase::Settling(SETTLE_FRAMES);
        }
        Phase::Settling(0) => {
            commands.spawn(Screenshot::primary_window()).observe(captured);
            run.phase = Phase::Capturing;
        }
        Phase::Settling(n) => run.phase = Phase::Settling(n - 1),
        Phase::Capturing => {}
    }
}

fn captured(screenshot: On<ScreenshotCaptured>, mut run: ResMut<Run>, mut exit: MessageWriter<AppExit>) {
    let Some(pixels) = screenshot.image.data.clone() else { return };
    let first = pixels.get(..4).unwrap_or_default();
    let uniform = pixels.chunks_exact(4).all(|p| p == first);
    if uniform || run.last.as_ref() != Some(&pixels) {
        info!("frame {}: {}, taking another", run.frames, if uniform { "nothing drawn yet" } else { "not settled" });
        run.last = Some(pixels);
        run.phase = Phase::Settling(SETTLE_FRAMES);
        return;
    }
    match screenshot.image.clone().try_into_dynamic() {
        Ok(picture) => match picture.to_rgb8().save(&run.out) {
            Ok(()) => {
                info!("frame {}: saved {}", run.frames, run.out.display());
                exit.write(AppExit::Success);
            }
            Err(e) => {
                error!("writing {}: {e}", run.out.display());
                exit.write(AppExit::error());
            }
        },
        Err(e) => {
            error!("screenshot: {e}");
            exit.write(AppExit::error());
        }
    }
}

/// The centre and radius of the world-space bounds of every mesh's bounding box.
fn bounds(meshes: &Query<(&Aabb, &GlobalTransform), With<Mesh3d>>) -> (Vec3, f32) {
    let (mut lo, mut hi) = (Vec3::MAX, Vec3::MIN);
    for (aabb, transform) in meshes {
        let (c, h) = (Vec3::from(aabb.center), Vec3::from(aabb.half_extents));
        for corner in 0..8 {
            let sign = Vec3::new(
                if corner & 1 == 0 { -1.0 } else { 1.0 },
                if corner & 2 == 0 { -1.0 } else { 1.0 },
                if corner & 4 == 0 { -1.0 } else { 1.0 },
            );
            let p = transform.transform_point(c + h * sign);
            lo = lo.min(p);
            hi = hi.max(p);
        }
    }
    ((lo + hi) * 0.5, ((hi - lo).length() * 0.5).max(1e-6))
}
