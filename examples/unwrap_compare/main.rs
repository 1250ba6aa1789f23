//! Compares the unwrap backends on procedural scenes and prints one markdown table per backend.
//!
//! `cargo run --release --example unwrap_compare [-- RUNS [PAGE [PADDING]]]`
//! (defaults: 5 timed runs, automatic density on a 1024² page, padding 2).
//!
//! Columns: charts; utilization (chart UV area over page area); overlap-free (no texel touched
//! by two charts, no flipped triangle, gaps ≥ 2·padding and ≥ padding to the border, checked by
//! conservative rasterization at page resolution); max area distortion per chart and mean per
//! triangle (`max(r, 1/r)`, r = UV texel area / world area · density²; 1 = exact); density and
//! page; median wall time over the runs (charting, parameterization, density search and output).

mod meshes;

use std::time::Instant;

use bake::unwrap::{Backend, UnwrapOptions, inspect, run};

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let runs: usize = args.first().map_or(Ok(5), |s| s.parse())?;
    let page: u32 = args.get(1).map_or(Ok(1024), |s| s.parse())?;
    let padding: u32 = args.get(2).map_or(Ok(2), |s| s.parse())?;
    let scenes = meshes::scenes();
    println!(
        "Automatic density, {page}² page, padding {padding}, median of {runs} runs, {} threads available.\n",
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    for backend in Backend::ALL {
        println!("### {backend}\n");
        println!(
            "| scene | triangles | charts | utilization | overlap-free | max chart distortion | mean triangle distortion | texels/m | page | time (ms) |"
        );
        println!("|---|---|---|---|---|---|---|---|---|---|");
        for (name, scene) in &scenes {
            let inputs: Vec<_> = scene.iter().map(|m| m.input()).collect();
            let options = UnwrapOptions { backend, texels_per_unit: None, max_atlas_size: page, padding };
            let mut times = Vec::new();
            let mut atlas = None;
            for _ in 0..runs.max(1) {
                let start = Instant::now();
                let a = run(&inputs, &options)?;
                times.push(start.elapsed().as_secs_f64() * 1e3);
                if let Some(prev) = &atlas {
                    assert_eq!(prev, &a, "{backend} is not deterministic on {name}");
                }
                atlas = Some(a);
            }
            times.sort_by(f64::total_cmp);
            let atlas = atlas.expect("at least one run");
            let q = inspect(&inputs, &atlas, 2 * padding + 1);
            let triangles: usize = scene.iter().map(|m| m.triangle_count()).sum();
            let valid = if q.is_valid(padding) {
                "yes".to_string()
            } else {
                format!(
                    "**no** ({} texels shared by charts, {} within a chart, {} flipped, gap {:?}, border {:?})",
                    q.overlap_texels, q.self_overlap_texels, q.flipped_triangles, q.min_chart_gap, q.min_border_gap
                )
            };
            println!(
                "| {name} | {triangles} | {} | {:.1}% | {valid} | {:.3} | {:.3} | {:.1} | {}×{} | {:.1} |",
                atlas.chart_count,
                100.0 * atlas.utilization,
                q.max_chart_distortion,
                q.mean_triangle_distortion,
                atlas.texels_per_unit,
                atlas.width,
                atlas.height,
                times[times.len() / 2],
            );
            for n in &atlas.notices {
                eprintln!("  {backend} / {name}: {n}");
            }
        }
        println!();
    }
    Ok(())
}
