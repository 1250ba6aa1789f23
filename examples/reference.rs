//! Reference lightmap values at points spread over a scene, by the CPU path
//! tracer in `bake::reference`.
//!
//! ```text
//! cargo run --release --example reference -- SCENE.glb [--env MAP.hdr] \
//!     [--points N] [--samples S] [--out FILE.json]
//! ```
//!
//! Picks N points over the scene's triangles (area-weighted, stratified,
//! deterministic for `--seed`), each on its front side, estimates the
//! lightmap value (E/π, linear RGB) at each with its standard error, prints
//! the time and a summary, and writes the estimates as JSON if asked.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::Parser;
use serde_json::json;

use bake::environment::EnvironmentMap;
use bake::reference::{Reference, ReferenceOptions, ReferencePoint, surface_points};

#[derive(Parser)]
#[command(about = "CPU path-traced reference lightmap values at surface points")]
struct Args {
    /// The glTF scene (.glb or .gltf).
    scene: PathBuf,
    /// Equirectangular HDR environment; without it only emissive materials light the scene.
    #[arg(long)]
    env: Option<PathBuf>,
    /// Environment rotation about +Y, degrees.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    rotation: f32,
    /// Environment intensity factor.
    #[arg(long, default_value_t = 1.0)]
    intensity: f32,
    /// Number of surface points.
    #[arg(long, default_value_t = 64)]
    points: usize,
    /// Paths per point.
    #[arg(long, default_value_t = 1024)]
    samples: u32,
    /// Cap on bounces after the first surface interaction.
    #[arg(long, default_value_t = ReferenceOptions::default().max_bounces)]
    bounces: u32,
    /// Seed for point placement and path sampling.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Where to write the estimates as JSON.
    #[arg(long)]
    out: Option<PathBuf>,
}

fn main() -> Result<()> {
    let args = Args::parse();
    let start = Instant::now();
    let scene = bake::import::load(&args.scene)?;
    let environment = match &args.env {
        Some(path) => Some(
            EnvironmentMap::load(path, &Default::default())
                .with_context(|| format!("environment '{}'", path.display()))?
                .map,
        ),
        None => None,
    };
    if environment.is_none() && !scene.materials.iter().any(|m| m.emission.iter().any(|&e| e > 0.0)) {
        bail!("nothing lights the scene: give --env or use emissive materials");
    }
    let loaded = start.elapsed().as_secs_f64();

    let options = ReferenceOptions {
        samples: args.samples,
        max_bounces: args.bounces,
        seed: args.seed,
        env_rotation_degrees: args.rotation,
        env_intensity: args.intensity,
    };
    let start = Instant::now();
    let reference = Reference::new(&scene, environment.as_ref(), &options);
    let built = start.elapsed().as_secs_f64();

    let picked = surface_points(&scene, args.points, args.seed);
    let points: Vec<ReferencePoint> = picked.iter().map(|p| p.point).collect();
    let start = Instant::now();
    let estimates = reference.estimate(&points);
    let traced = start.elapsed().as_secs_f64();

    let paths = points.len() as f64 * args.samples.max(1) as f64;
    println!(
        "{}: {} triangles, {} points × {} samples; load {loaded:.2} s, build {built:.2} s, trace {traced:.2} s ({:.0} paths/s, {} threads)",
        args.scene.display(),
        reference.triangle_count(),
        points.len(),
        args.samples,
        paths / traced.max(1e-9),
        rayon::current_num_threads(),
    );
    if !estimates.is_empty() {
        let n = estimates.len() as f64;
        let mean: Vec<f64> = (0..3).map(|c| estimates.iter().map(|e| e.lightmap[c]).sum::<f64>() / n).collect();
        let max = (0..3)
            .map(|c| estimates.iter().map(|e| e.lightmap[c]).fold(f64::NEG_INFINITY, f64::max))
            .collect::<Vec<_>>();
        let relative_error = estimates
            .iter()
            .flat_map(|e| (0..3).map(move |c| e.std_error[c] / e.lightmap[c].abs().max(1e-6)))
            .fold(0.0f64, f64::max);
        println!(
            "mean lightmap [{:.4}, {:.4}, {:.4}], max [{:.4}, {:.4}, {:.4}], worst relative standard error {:.2}%",
            mean[0],
            mean[1],
            mean[2],
            max[0],
            max[1],
            max[2],
            100.0 * relative_error
        );
    }

    if let Some(out) = &args.out {
        let rows: Vec<_> = picked
            .iter()
            .zip(&estimates)
            .map(|(p, e)| {
                json!({
                    "primitive": p.primitive,
                    "triangle": p.triangle,
                    "barycentric": p.barycentric,
                    "position": p.point.position,
                    "normal": p.point.normal,
                    "lightmap": e.lightmap,
                    "std_error": e.std_error,
                })
            })
            .collect();
        let document = json!({
            "scene": args.scene,
            "environment": args.env,
            "rotation_degrees": args.rotation,
            "intensity": args.intensity,
            "samples": args.samples,
            "max_bounces": args.bounces,
            "seed": args.seed,
            "seconds": traced,
            "points": rows,
        });
        std::fs::write(out, serde_json::to_vec_pretty(&document)?)
            .with_context(|| format!("writing '{}'", out.display()))?;
        println!("wrote {}", out.display());
    }
    Ok(())
}
