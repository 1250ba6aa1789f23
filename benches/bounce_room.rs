//! The bounce pass on its own: a closed 2 m room of six inward-facing walls,
//! each glowing with Le = 1 and of albedo ρ, baked to convergence (mean L_lm
//! = Le/(1 − ρ)). No environment and no direct pass, so the time is the
//! bounce's batches: shooter selection, hemicubes, the gather. Results go to
//! stdout as markdown.
//!
//! ```text
//! cargo bench --bench bounce_room                     # ρ 0.8 at 256 and 1,024 patches, 96² atlas
//! cargo bench --bench bounce_room -- 0.5 0.8 0.95     # other albedos
//! ```

use std::time::Instant;

use anyhow::Result;
use bake::asset::SourceAsset;
use bake::config::BakeOptions;
use bake::fixtures::six_wall_room;
use bake::gpu::Gpu;
use bake::progress::Silent;

fn main() -> Result<()> {
    let albedos: Vec<f32> =
        std::env::args().skip(1).filter(|a| a != "--bench").map(|a| a.parse()).collect::<Result<_, _>>()?;
    let albedos = if albedos.is_empty() { vec![0.8] } else { albedos };
    let gpu = Gpu::new(None)?;
    println!("adapter: {}\n", gpu.adapter);
    println!("| ρ | patches | shots | batches | bounce (s) | ms per batch | mean L_lm | expected |");
    println!("|---|---|---|---|---|---|---|---|");
    for &albedo in &albedos {
        for patches in [256, 1024] {
            let glb = six_wall_room([(albedo, 1.0); 6]).to_glb();
            let scene = bake::import::from_asset(SourceAsset::from_bytes("room.glb".as_ref(), &glb, None)?)?;
            let mut options = BakeOptions::default();
            options.unwrap.max_atlas_size = 96;
            options.solve.bounce.patches = patches;
            let start = Instant::now();
            let baked = bake::bake_scene(&gpu, scene, None, &options, &mut Silent)?;
            let wall = start.elapsed().as_secs_f64();
            let bounce = baked.solution.bounce.as_ref().expect("a closed room bounces");
            let lightmap = &baked.solution.lightmap;
            let mean = lightmap.iter().map(|v| v[0] as f64).sum::<f64>() / lightmap.len() as f64;
            println!(
                "| {albedo} | {} | {} | {} | {:.2} | {:.1} | {mean:.4} | {:.4} |",
                bounce.patches,
                bounce.shots,
                bounce.batches,
                bounce.seconds,
                1e3 * bounce.seconds / bounce.batches.max(1) as f64,
                1.0 / (1.0 - albedo as f64)
            );
            eprintln!("ρ {albedo}, {patches} patches: {wall:.2} s wall");
        }
    }
    Ok(())
}
