//! Random scenes baked and checked against the CPU reference, primitive by
//! primitive: a search for scenes where the bake is wrong.
//!
//! ```text
//! cargo run --release --example stress -- 0..40 fixtures/sky_sun.exr 128
//! ```
//!
//! Arguments: a range of seeds, an environment, the atlas size. Prints, per
//! scene, each primitive's bake / reference ratio (sum over up to 48 texels
//! with area) with its standard error, and the worst texel's error over its
//! primitive's mean beyond three standard errors. Texels the path tracer
//! finds buried in another solid are counted, not compared. Knobs, as
//! environment variables: `STRESS_SCALE` (fix the scene's scale),
//! `STRESS_VERBOSE` (print the objects; write /tmp/stressSEED.glb),
//! `STRESS_PRIM=p` (print primitive p's texels), `STRESS_N` (texels per
//! primitive), `STRESS_BORDER` (chart-edge texels instead), `STRESS_ALL`
//! (both), `STRESS_BLACK` (black surfaces: direct light only),
//! `STRESS_NOCONTACT`, `STRESS_TOL`, `STRESS_PATCHES` (solve options).

use std::f32::consts::PI;

use anyhow::Result;
use bake::environment::{EnvLoadOptions, EnvironmentMap, LightMode, LightSet};
use bake::fixtures::{MeshData, Placement, SceneBuilder};
use bake::gpu::Gpu;
use bake::progress::Silent;
use bake::reference::{Reference, ReferenceOptions, ReferencePoint};
use glam::{Quat, Vec3};

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 40) as f32) / (1u64 << 24) as f32
    }
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.next()
    }
    fn pick(&mut self, n: usize) -> usize {
        ((self.next() * n as f32) as usize).min(n - 1)
    }
}

fn random_scene(seed: u64) -> (SceneBuilder, String) {
    let mut rng = Rng(seed.wrapping_mul(0x9E3779B97F4A7C15) ^ 0x1234);
    rng.next();
    let scale = [0.01f32, 0.1, 1.0, 10.0, 100.0][rng.pick(5)];
    let scale = std::env::var("STRESS_SCALE").map_or(scale, |s| s.parse().unwrap());
    let mut scene = SceneBuilder::new();
    let mut what = format!("scale {scale}:");
    let ground = rng.range(0.2, 0.9);
    let ground = if std::env::var("STRESS_BLACK").is_ok() { 0.0 } else { ground };
    let size = rng.range(6.0, 20.0);
    scene.object(
        "ground",
        &MeshData::plane(size * scale, size * scale, 4),
        [ground, ground, ground, 1.0],
        [0.0; 3],
        Placement::default(),
    );
    let count = 2 + rng.pick(6);
    for i in 0..count {
        let kind = rng.pick(6);
        let albedo = [rng.range(0.1, 0.95), rng.range(0.1, 0.95), rng.range(0.1, 0.95), 1.0];
        let albedo = if std::env::var("STRESS_BLACK").is_ok() { [0.0, 0.0, 0.0, 1.0] } else { albedo };
        let s = rng.range(0.3, 2.0);
        let x = rng.range(-size / 3.0, size / 3.0);
        let z = rng.range(-size / 3.0, size / 3.0);
        let turn = Quat::from_rotation_y(rng.range(0.0, 2.0 * PI));
        let float = if rng.next() < 0.3 { rng.range(0.05, 1.0) } else { 0.0 };
        let (mesh, y, name) = match kind {
            0 => {
                let h = rng.range(0.2, 3.0);
                (MeshData::cuboid([s, h, s * rng.range(0.3, 1.5)]), h / 2.0, "box")
            }
            1 => (MeshData::sphere(s / 2.0, 32, 16), s / 2.0, "sphere"),
            2 => (MeshData::torus(s / 2.0, s / 6.0, 32, 16), s / 6.0, "torus"),
            3 => (MeshData::statue(8, rng.pick(3) as u32), 0.0, "statue"),
            4 => {
                // a thin wall
                let h = rng.range(1.0, 3.0);
                (MeshData::cuboid([s * 2.0, h, 0.05]), h / 2.0, "wall")
            }
            _ => {
                // a table-like slab up in the air
                let h = rng.range(0.5, 1.5);
                (MeshData::cuboid([s, 0.08, s]), h, "slab")
            }
        };
        let placement = Placement::at(Vec3::new(x, y + float, z) * scale)
            .rotated(turn)
            .scaled(Vec3::splat(scale * if kind == 3 { s } else { 1.0 }));
        if std::env::var("STRESS_VERBOSE").is_ok() {
            println!(
                "  {name}{i}: albedo {albedo:?} at {:?} turn {:?} scale {:?} size {s} float {float}",
                placement.translation, placement.rotation, placement.scale
            );
        }
        scene.object(&format!("{name}{i}"), &mesh, albedo, [0.0; 3], placement);
        what += &format!(" {name}{i}");
    }
    (scene, what)
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let seeds = args.get(1).map(|s| s.as_str()).unwrap_or("0..10");
    let (a, b) = seeds.split_once("..").unwrap();
    let env = args.get(2).cloned().unwrap_or("fixtures/sky_sun.exr".into());
    let atlas: u32 = args.get(3).map(|s| s.parse().unwrap()).unwrap_or(256);
    let map = EnvironmentMap::load(&env, &EnvLoadOptions::default())?.map;
    let lights = LightSet::extract(&map, LightMode::Budget { count: 256 }, 0.0, 1.0);
    let gpu = Gpu::new(None)?;
    for seed in a.parse::<u64>()?..b.parse::<u64>()? {
        let (builder, what) = random_scene(seed);
        let glb = builder.to_glb();
        if std::env::var("STRESS_VERBOSE").is_ok() {
            std::fs::write(format!("/tmp/stress{seed}.glb"), &glb)?;
        }
        let source =
            bake::asset::SourceAsset::from_bytes(std::path::Path::new(&format!("stress{seed}.glb")), &glb, None)?;
        let scene = bake::import::from_asset(source)?;
        let mut options = bake::config::BakeOptions::default();
        options.unwrap.max_atlas_size = atlas;
        if std::env::var("STRESS_NOCONTACT").is_ok() {
            options.solve.contact = false;
        }
        if let Ok(t) = std::env::var("STRESS_TOL") {
            options.solve.bounce.tolerance = t.parse()?;
        }
        if let Ok(t) = std::env::var("STRESS_PATCHES") {
            options.solve.bounce.patches = t.parse()?;
        }
        let start = std::time::Instant::now();
        let baked = match bake::bake_scene(&gpu, scene, Some(&lights), &options, &mut Silent) {
            Ok(b) => b,
            Err(e) => {
                println!("seed {seed}: FAILED {e:#} ({what})");
                continue;
            }
        };
        let secs = start.elapsed().as_secs_f64();
        // up to 48 texels per primitive, spread evenly
        let mut per: Vec<Vec<usize>> = vec![Vec::new(); baked.scene.primitives.len()];
        let border = std::env::var("STRESS_BORDER").is_ok();
        for (i, t) in baked.texels.texels.iter().enumerate() {
            if (t.area > 0.0) == border && std::env::var("STRESS_ALL").is_err() {
                continue;
            }
            per[t.primitive as usize].push(i);
        }
        let reference =
            Reference::new(&baked.scene, Some(&map), &ReferenceOptions { samples: 1024, ..Default::default() });
        let mut line = format!("seed {seed} ({secs:.0} s, {} texels):", baked.texels.texels.len());
        let mut worst = 0.0f64;
        let mut worst_texel = 0.0f64;
        for (p, texels) in per.iter().enumerate() {
            if texels.is_empty() {
                continue;
            }
            let step = (texels.len() / std::env::var("STRESS_N").map_or(48, |v| v.parse().unwrap())).max(1);
            let chosen: Vec<usize> = texels.iter().step_by(step).copied().collect();
            let points: Vec<ReferencePoint> = chosen
                .iter()
                .map(|&i| {
                    let t = &baked.texels.texels[i];
                    ReferencePoint { position: t.position, normal: t.normal, face_normal: Some(t.face_normal) }
                })
                .collect();
            let estimates = reference.estimate(&points);
            let (mut sb, mut sr, mut var) = (0.0, 0.0, 0.0);
            let mut texel_errors = Vec::new();
            let mut buried = 0;
            for (&i, e) in chosen.iter().zip(&estimates) {
                let b: f64 = baked.solution.lightmap[i].iter().map(|&c| c as f64).sum::<f64>() / 3.0;
                let r = e.lightmap.iter().sum::<f64>() / 3.0;
                // Every path blocked without light: a texel buried in another solid, which no viewer sees.
                if r == 0.0 {
                    buried += 1;
                    continue;
                }
                if std::env::var("STRESS_PRIM").is_ok_and(|v| v == p.to_string()) {
                    let t = &baked.texels.texels[i];
                    println!(
                        "    texel {i} area {:.3} at {:?} n {:?}: bake {b:.4} ref {r:.4}",
                        t.area, t.position, t.normal
                    );
                }
                sb += b;
                sr += r;
                var += e.std_error.iter().map(|s| s * s).sum::<f64>() / 9.0;
                texel_errors.push((b - r).abs() - 3.0 * (e.std_error.iter().sum::<f64>() / 3.0));
            }
            let mean_ref = sr / (chosen.len() - buried).max(1) as f64;
            for d in texel_errors.drain(..) {
                worst_texel = worst_texel.max(d / mean_ref.max(1e-12));
            }
            let ratio = sb / sr.max(1e-12);
            let noise = var.sqrt() / sr.max(1e-12);
            worst = worst.max(((ratio - 1.0).abs() - 2.0 * noise).max(0.0));
            line += &format!(" p{p} {ratio:.3}±{noise:.3}");
            if buried > 0 {
                line += &format!("({buried} buried)");
            }
        }
        println!("{line}  WORST {:.1}% texel {:.2} [{what}]", worst * 100.0, worst_texel);
    }
    Ok(())
}
