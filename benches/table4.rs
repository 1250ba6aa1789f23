//! The seed paper's Table 4 (Kim & Hong: three bunny statues, 9,225 vertices,
//! radiosity textures of 256²–1024² under 96–6,144 environment lights on a
//! Quadro FX4400), baked again with our times next to the paper's, time and
//! memory per stage, and the error against the CPU reference path tracer;
//! then how the bounce pass scales as texels and triangles double, and the
//! direct light at the meshes' vertices against the texels; and, asked for
//! with `--only ceiling`, the direct pass against bare kernels of its light
//! loop and its rays (`table4/ceiling.rs`). Results go to stdout as
//! markdown; progress to stderr.
//!
//! ```text
//! cargo bench --bench table4                          # everything (see BENCHMARKS.md for how long)
//! cargo bench --bench table4 -- --quick               # a smoke run: two cells at 256², small reference
//! cargo bench --bench table4 -- --only grid --sizes 256,512 --lights 96,384 --modes cube
//! cargo bench --bench table4 -- --only ceiling --sizes 256 --lights 96,1024 --modes budget
//! ```
//!
//! The environment is `--env`, else `$BAKE_BENCH_ENV`, else the captured
//! `/work/shared/env/courtyard.exr` where it exists, else `fixtures/sky_sun.exr`.

#[path = "table4/ceiling.rs"]
mod ceiling;
#[path = "table4/vertex.rs"]
mod vertex;

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Result, bail};
use clap::{Parser, ValueEnum};

use bake::config::BakeOptions;
use bake::environment::{EnvironmentMap, LightMode, LightSet};
use bake::fixtures::{TABLE4_STATUE_FREQUENCY, three_statues};
use bake::gpu::Gpu;
use bake::progress::Silent;
use bake::reference::{ReferenceCheck, reference_probes};
use bake::scene::Scene;
use bake::solve::TracePoint;
use bake::solve::patches::Sight;
use bake::texelize::TexelSet;

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum Mode {
    /// The paper's lights: every texel of an N×N-per-face cube map (6·N² lights).
    Cube,
    /// Our default: a budget of K lights placed by energy (median cut).
    Budget,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum Section {
    Grid,
    /// The bounce pass as texels and triangles double.
    Bounce,
    /// The direct light at the vertices (the paper's per-vertex comparison) against the texels.
    Vertex,
    /// The direct pass against bare kernels of its light loop and its rays.
    Ceiling,
}

#[derive(Parser)]
#[command(about = "Table 4 of the seed paper, with errors, bounce scaling and a per-vertex baseline")]
struct Args {
    /// Smoke run: 96 lights at 256² in both modes, a small reference.
    #[arg(long)]
    quick: bool,
    /// Atlas sizes (the paper's radiosity texture sizes).
    #[arg(long, value_delimiter = ',', default_values_t = [256, 512, 1024])]
    sizes: Vec<u32>,
    /// Light counts (cube mode needs 6·N²: 96, 384, 1536, 6144).
    #[arg(long, value_delimiter = ',', default_values_t = [6144, 1536, 384, 96])]
    lights: Vec<u32>,
    #[arg(long, value_delimiter = ',', default_values = ["cube", "budget"])]
    modes: Vec<Mode>,
    /// Which parts to run.
    #[arg(long, value_delimiter = ',', default_values = ["grid", "bounce", "vertex"])]
    only: Vec<Section>,
    /// Equirectangular environment map.
    #[arg(long)]
    env: Option<PathBuf>,
    /// Texels the CPU reference estimates per atlas size (0: no error column).
    #[arg(long, default_value_t = 256)]
    reference_texels: usize,
    /// Paths per reference texel.
    #[arg(long, default_value_t = 16384)]
    reference_samples: u32,
    /// Statue frequency (10·f² + 2 vertices per statue).
    #[arg(long, default_value_t = TABLE4_STATUE_FREQUENCY)]
    frequency: u32,
    /// Grid bakes without the supersample fix-up (its cost is the difference).
    #[arg(long)]
    no_supersample: bool,
    /// Grid bakes without the contact fix-up (its cost is the difference).
    #[arg(long)]
    no_contact_trace: bool,
    /// Budget lights of the per-vertex comparison (at each of `--sizes`).
    #[arg(long, default_value_t = 384)]
    vertex_lights: u32,
    /// Shooter patches of the grid bakes' bounce pass (`bake --patches`).
    #[arg(long, default_value_t = bake::solve::BounceOptions::default().patches)]
    patches: u32,
    /// Shooters per GPU batch of the grid bakes' bounce pass (at most 64).
    #[arg(long, default_value_t = bake::solve::BounceOptions::default().shooters_per_batch)]
    shooters_per_batch: u32,
    /// Passed by `cargo bench`; ignored.
    #[arg(long, hide = true)]
    bench: bool,
}

/// The paper's Table 4 (rows (a)–(d): three statues), seconds.
fn paper_seconds(lights: u32, size: u32) -> Option<f64> {
    let row = match lights {
        6144 => [28.504, 19.904, 16.208],
        1536 => [10.396, 5.344, 4.520],
        384 => [3.152, 1.924, 1.754],
        96 => [1.105, 1.066, 0.705],
        _ => return None,
    };
    match size {
        1024 => Some(row[0]),
        512 => Some(row[1]),
        256 => Some(row[2]),
        _ => None,
    }
}

fn light_mode(mode: Mode, count: u32) -> Result<LightMode> {
    Ok(match mode {
        Mode::Cube => {
            let face = ((count / 6) as f64).sqrt().round() as u32;
            if 6 * face * face != count {
                bail!("cube mode needs 6·N² lights, not {count}");
            }
            LightMode::Cube { face_size: face }
        }
        Mode::Budget => LightMode::Budget { count },
    })
}

/// One baked cell of the grid.
struct Cell {
    mode: Mode,
    requested: u32,
    size: u32,
    lights: usize,
    atlas: (u32, u32),
    texels: usize,
    /// Seconds: light extraction, unwrap, texelize, solve (direct, bounce and the rest).
    light_seconds: f64,
    unwrap: f64,
    texelize: f64,
    solve: f64,
    direct: f64,
    bounce: f64,
    /// The contact fix-up, after the bounce pass.
    contact: f64,
    peak_rss: Option<u64>,
    gpu_peak: Option<u64>,
    evaluations: u64,
    rays: u64,
    batches: usize,
    patches: usize,
    shots: u64,
    stopped_by: String,
    unshot: f64,
    error: Option<f64>,
    trace: Vec<TracePoint>,
    /// CPU seconds over wall seconds of the bake: cores the run had (2 at most here).
    cores: f64,
}

impl Cell {
    fn total(&self) -> f64 {
        self.light_seconds + self.unwrap + self.texelize + self.solve
    }
}

/// The bench scene, imported fresh for each bake (a bake consumes its scene).
struct Statues {
    glb: Vec<u8>,
}

impl Statues {
    fn new(frequency: u32) -> Statues {
        Statues { glb: three_statues(frequency).to_glb() }
    }
    fn scene(&self) -> Result<Scene> {
        let source = bake::asset::SourceAsset::from_bytes(Path::new("three_statues.glb"), &self.glb, None)?;
        bake::import::from_asset(source)
    }
}

/// Unwrap as `bake_scene` does (deterministic).
fn unwrap(scene: &Scene, options: &BakeOptions) -> Result<bake::unwrap::Atlas> {
    let meshes: Vec<bake::unwrap::MeshInput> = scene
        .primitives
        .iter()
        .map(|p| bake::unwrap::MeshInput { positions: &p.positions, indices: &p.indices })
        .collect();
    bake::unwrap::run(&meshes, &options.unwrap)
}

/// Unwrap and texelize as `bake_scene` does (both are deterministic), for the
/// reference and for timing the direct pass alone.
fn texelize(gpu: &Gpu, scene: &Scene, options: &BakeOptions) -> Result<TexelSet> {
    bake::texelize::run(gpu, scene, &unwrap(scene, options)?)
}

/// CPU seconds (user + system) this process has used, all threads (lavapipe's workers included), from
/// `/proc/self/stat`; 0 where it cannot be read. CPU over wall time says how many cores a run had: the
/// machine is shared, so a run that got fewer than its 2 cores ran slower than the adapter can.
fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else { return 0.0 };
    // Fields after the command name (which is in parentheses and may hold spaces): state is field 3,
    // utime and stime are fields 14 and 15, in clock ticks (USER_HZ, 100 on Linux).
    let rest = stat.rsplit_once(')').map_or("", |(_, r)| r);
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let tick = |i: usize| fields.get(i).and_then(|f| f.parse::<f64>().ok()).unwrap_or(0.0);
    (tick(11) + tick(12)) / 100.0
}

fn mib(bytes: Option<u64>) -> String {
    bytes.map_or("–".into(), |b| format!("{:.0}", b as f64 / (1 << 20) as f64))
}

fn percent(x: Option<f64>) -> String {
    x.map_or("–".into(), |e| format!("{:.2} %", e * 100.0))
}

fn mode_name(mode: Mode) -> &'static str {
    match mode {
        Mode::Cube => "cube",
        Mode::Budget => "budget",
    }
}

fn environment_path(args: &Args) -> PathBuf {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    if let Some(path) = &args.env {
        return path.clone();
    }
    if let Some(path) = std::env::var_os("BAKE_BENCH_ENV") {
        return PathBuf::from(path);
    }
    let captured = Path::new("/work/shared/env/courtyard.exr");
    if captured.exists() { captured.to_path_buf() } else { root.join("fixtures/sky_sun.exr") }
}

fn commit() -> String {
    std::process::Command::new("git")
        .args(["rev-parse", "--short", "HEAD"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map_or("unknown".into(), |o| String::from_utf8_lossy(&o.stdout).trim().to_string())
}

fn main() -> Result<()> {
    let mut args = Args::parse();
    if args.quick {
        args.sizes = vec![256];
        args.lights = vec![96];
        args.reference_texels = args.reference_texels.min(64);
        args.reference_samples = args.reference_samples.min(1024);
        args.only.retain(|s| !matches!(s, Section::Bounce));
    }
    let started = Instant::now();
    let gpu = Gpu::new(None)?;
    let env_path = environment_path(&args);
    let map = Arc::new(EnvironmentMap::load(&env_path, &Default::default())?.map);
    let statues = Statues::new(args.frequency);
    let scene = statues.scene()?;
    let vertices: usize = scene.primitives.iter().map(|p| p.positions.len()).sum();
    println!("# Table 4 benchmark\n");
    println!(
        "adapter: {} ({}, {}, {}); commit {}; scene: three statues (frequency {}) on a ground, {} vertices, {} \
         triangles; environment: {} ({}×{})\n",
        gpu.adapter.name,
        gpu.adapter.backend,
        gpu.adapter.device_type,
        gpu.adapter.driver,
        commit(),
        args.frequency,
        vertices,
        scene.triangle_count(),
        env_path.display(),
        map.width,
        map.height
    );
    if args.only.contains(&Section::Grid) {
        grid(&gpu, &args, &statues, &map)?;
    }
    if args.only.contains(&Section::Bounce) {
        bounce_scaling(&gpu)?;
    }
    if args.only.contains(&Section::Vertex) {
        vertex_table(&gpu, &args, &statues, &map)?;
    }
    if args.only.contains(&Section::Ceiling) {
        ceiling_table(&gpu, &args, &statues, &map)?;
    }
    println!("\nbenchmark wall time: {:.0} s", started.elapsed().as_secs_f64());
    Ok(())
}

/// The direct pass against its bare-kernel ceiling (`ceiling.rs`) in every
/// cell of the grid's sizes, modes and light counts.
fn ceiling_table(gpu: &Gpu, args: &Args, statues: &Statues, map: &Arc<EnvironmentMap>) -> Result<()> {
    println!("\n## Direct pass against its bare-kernel ceiling\n");
    println!(
        "The same points and lights through bare kernels (benches/table4/ceiling.rs): the light loop (each pair's \
         cosine and power) and shadow rays (trace.wgsl's walk, one ray per lane and turn, every lane walking). \
         Ceiling = the light loop + the pass's walks (nodes and triangles visited) at the bare rays' rate per \
         visit.\n"
    );
    println!(
        "| lights | mode | atlas | texels | pairs (M) | rays (M) | visits per ray | direct (s) | M pairs/s | \
         bare light loop (s) | bare visits per ray | bare M visits/s | ceiling (s) | ceiling M pairs/s | \
         direct / ceiling |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for &size in &args.sizes {
        let mut options = BakeOptions::default();
        options.unwrap.max_atlas_size = size;
        let scene = statues.scene()?;
        let texels = texelize(gpu, &scene, &options)?;
        for &mode in &args.modes {
            for &count in &args.lights {
                let lights = LightSet::extract(map, light_mode(mode, count)?, 0.0, 1.0);
                let c = ceiling::measure(gpu, &scene, &texels.texels, &lights)?;
                eprintln!(
                    "ceiling {size}² {} {count}: direct {:.2} s, ceiling {:.2} s",
                    mode_name(mode),
                    c.direct,
                    c.seconds()
                );
                let per_ray = |visits: u64, rays: u64| visits as f64 / rays.max(1) as f64;
                println!(
                    "| {} | {} | {size}² | {} | {:.0} | {:.1} | {:.1} | {:.2} | {:.1} | {:.2} | {:.1} | {:.0} | {:.2} | \
                     {:.1} | {:.1} |",
                    c.lights,
                    mode_name(mode),
                    c.points,
                    c.pairs() / 1e6,
                    c.rays as f64 / 1e6,
                    per_ray(c.visits, c.rays),
                    c.direct,
                    c.pairs() / c.direct / 1e6,
                    c.light_loop,
                    per_ray(c.bare_visits, c.bare_rays),
                    c.visit_rate() / 1e6,
                    c.seconds(),
                    c.pairs() / c.seconds() / 1e6,
                    c.direct / c.seconds()
                );
            }
        }
    }
    Ok(())
}

/// The mode and light count of the cell whose error-against-time curve is
/// printed, at the largest atlas: the most lights, in the paper's mode when
/// the grid has it.
fn curve_cell(args: &Args) -> (Mode, u32) {
    let mode = if args.modes.contains(&Mode::Cube) { Mode::Cube } else { args.modes[0] };
    (mode, args.lights.iter().copied().max().unwrap_or(0))
}

fn grid(gpu: &Gpu, args: &Args, statues: &Statues, map: &Arc<EnvironmentMap>) -> Result<()> {
    let started = Instant::now();
    let mut cells = Vec::new();
    let mut references = Vec::new();
    let mut sizes = args.sizes.clone();
    sizes.sort_unstable();
    for &size in &sizes {
        let mut options = BakeOptions::default();
        options.unwrap.max_atlas_size = size;
        options.solve.supersample = !args.no_supersample;
        options.solve.contact = !args.no_contact_trace;
        options.solve.bounce.patches = args.patches;
        options.solve.bounce.shooters_per_batch = args.shooters_per_batch;
        // The reference at texels of this atlas size (every cell of the size bakes the same texels).
        let probes = if args.reference_texels > 0 {
            let scene = statues.scene()?;
            let texels = texelize(gpu, &scene, &options)?;
            let check = ReferenceCheck {
                texels: args.reference_texels,
                samples: args.reference_samples,
                environment: Some(map.clone()),
                env_rotation_degrees: 0.0,
                env_intensity: 1.0,
            };
            let start = Instant::now();
            let (probes, noise) = reference_probes(&scene, &texels, &check);
            let seconds = start.elapsed().as_secs_f64();
            eprintln!("{size}²: reference at {} texels × {} paths: {seconds:.1} s", probes.texels.len(), check.samples);
            references.push((size, probes.texels.len(), check.samples, noise, seconds));
            Some((Arc::new(probes), texels))
        } else {
            None
        };
        for &mode in &args.modes {
            for &count in &args.lights {
                let start = Instant::now();
                let lights = LightSet::extract(map, light_mode(mode, count)?, 0.0, 1.0);
                let light_seconds = start.elapsed().as_secs_f64();
                // Only the curve's cell reads its probes back at every batch
                // (the others' error is taken from the final lightmap): the
                // read-backs are a measurement, and would add to the time.
                let curve = size == *sizes.last().unwrap() && (mode, count) == curve_cell(args);
                options.solve.bounce.probes = probes.as_ref().filter(|_| curve).map(|p| p.0.clone());
                let (wall, cpu) = (Instant::now(), cpu_seconds());
                let baked = bake::bake_scene(gpu, statues.scene()?, Some(&lights), &options, &mut Silent)?;
                let cores = (cpu_seconds() - cpu) / wall.elapsed().as_secs_f64();
                let error = match &probes {
                    Some((probes, texels)) => {
                        for &i in &probes.texels {
                            if baked.texels.texels.get(i as usize) != texels.texels.get(i as usize) {
                                bail!("the bake's texels differ from the reference's at {size}²");
                            }
                        }
                        let values = probes.texels.iter().map(|&i| baked.solution.lightmap[i as usize].map(f64::from));
                        Some(probes.relative_rmse(values))
                    }
                    None => None,
                };
                let stage = |name: &str| baked.stages.iter().find(|s| s.stage == name);
                let seconds = |name: &str| stage(name).map_or(0.0, |s| s.seconds);
                let memories = baked.stages.iter().filter_map(|s| s.memory.as_ref());
                let peak_rss = memories.clone().map(|m| m.peak_rss_bytes).max();
                let gpu_peak = memories.filter_map(|m| m.gpu_peak_bytes).max();
                let direct = baked.solution.direct.as_ref();
                let bounce = baked.solution.bounce.as_ref();
                let cell = Cell {
                    mode,
                    requested: count,
                    size,
                    lights: lights.lights.len(),
                    atlas: (baked.atlas.width, baked.atlas.height),
                    texels: baked.texels.texels.len(),
                    light_seconds,
                    unwrap: seconds("unwrap"),
                    texelize: seconds("texelize"),
                    solve: seconds("solve"),
                    direct: direct.map_or(0.0, |d| d.seconds),
                    bounce: bounce.map_or(0.0, |b| b.seconds),
                    contact: baked.solution.contact.as_ref().map_or(0.0, |c| c.seconds),
                    peak_rss,
                    gpu_peak,
                    evaluations: direct.map_or(0, |d| d.evaluations),
                    rays: direct.map_or(0, |d| d.rays),
                    batches: direct.map_or(0, |d| d.batches),
                    patches: bounce.map_or(0, |b| b.patches),
                    shots: bounce.map_or(0, |b| b.shots),
                    stopped_by: bounce.map_or("skipped".into(), |b| b.stopped_by.to_string()),
                    unshot: bounce.map_or(0.0, |b| b.unshot_fraction),
                    error,
                    trace: bounce.map_or(Vec::new(), |b| b.trace.clone()),
                    cores,
                };
                eprintln!(
                    "{size}² {} {count}: {} texels, {:.1} s (unwrap {:.2} s, texelize {:.2} s, direct {:.1} s, \
                     bounce {:.1} s, {} shots), error {}, {:.2} cores, {:.0} s since the grid started",
                    mode_name(mode),
                    cell.texels,
                    cell.total(),
                    cell.unwrap,
                    cell.texelize,
                    cell.direct,
                    cell.bounce,
                    cell.shots,
                    percent(cell.error),
                    cell.cores,
                    started.elapsed().as_secs_f64()
                );
                cells.push(cell);
            }
        }
    }
    let grid_seconds = started.elapsed().as_secs_f64();

    println!("## Table 4\n");
    println!(
        "Times in seconds. \"ours\" = light extraction + unwrap + texelize + solve (direct + bounce + patch set-up); \
         the paper's time covers its radiosity solve (its parametrization was made beforehand in 3ds Max). \
         Error: relative RMSE of L_lm against the CPU reference path tracer at the texels below (reference noise \
         included). Peak RSS: the process's resident-set high-water mark over the bake's stages (on lavapipe it \
         includes the \"GPU\" memory); GPU: wgpu's allocator at the stages' waits.\n"
    );
    println!(
        "| lights | mode | atlas | texels | paper | ours | ours/paper | lights | unwrap | texelize | direct | bounce \
         | shots | stopped | peak RSS (MiB) | GPU (MiB) | error | cores |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for c in &cells {
        let paper = paper_seconds(c.requested, c.size);
        println!(
            "| {} | {} | {}² ({}×{}) | {} | {} | {:.2} | {} | {:.3} | {:.2} | {:.2} | {:.2} | {:.2} | {} | {} | {} | {} \
             | {} | {:.2} |",
            c.lights,
            mode_name(c.mode),
            c.size,
            c.atlas.0,
            c.atlas.1,
            c.texels,
            paper.map_or("–".into(), |p| format!("{p:.3}")),
            c.total(),
            paper.map_or("–".into(), |p| format!("{:.2}", c.total() / p)),
            c.light_seconds,
            c.unwrap,
            c.texelize,
            c.direct,
            c.bounce,
            c.shots,
            c.stopped_by,
            mib(c.peak_rss),
            mib(c.gpu_peak),
            percent(c.error),
            c.cores
        );
    }
    println!();
    for (size, texels, samples, noise, seconds) in &references {
        println!(
            "Reference at {size}²: {texels} texels × {samples} paths, noise {:.2} %, {seconds:.1} s on the CPU \
             (not in the times above).",
            noise * 100.0
        );
    }
    println!("\nGrid wall time (references included): {grid_seconds:.0} s\n");

    println!("## Throughput\n");
    println!(
        "Direct: texel·light pairs evaluated over the direct pass's time. Bounce: shots (a shooter patch's hemicube \
         and every texel's gather from it) per second, and texel·shooter pairs per second.\n"
    );
    println!(
        "| lights | mode | atlas | texels | rays (M) | batches | pairs (M) | direct (s) | M pairs/s | patches | shots \
         | bounce (s) | shots/s | M texel·shooters/s |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for c in &cells {
        println!(
            "| {} | {} | {}² | {} | {:.1} | {} | {:.0} | {:.2} | {:.1} | {} | {} | {:.2} | {:.1} | {:.1} |",
            c.lights,
            mode_name(c.mode),
            c.size,
            c.texels,
            c.rays as f64 / 1e6,
            c.batches,
            c.evaluations as f64 / 1e6,
            c.direct,
            c.evaluations as f64 / c.direct.max(1e-9) / 1e6,
            c.patches,
            c.shots,
            c.bounce,
            c.shots as f64 / c.bounce.max(1e-9),
            c.shots as f64 * c.texels as f64 / c.bounce.max(1e-9) / 1e6
        );
    }

    // The error-against-time curve of the heaviest cell.
    let (curve_mode, curve_count) = curve_cell(args);
    let heaviest = cells.iter().rev().find(|c| c.mode == curve_mode && c.requested == curve_count);
    if let Some(c) = heaviest {
        let offset = c.total() - c.bounce - c.contact;
        println!(
            "\n## Error against time: {} {} lights at {}²\n\nThe bounce pass's trace: one point per batch of shots \
             (every point up to 16, then every k-th), and one after the contact fix-up ({:.1} s) where it took \
             texels. \"time\" counts from the bake's start (the bounce pass starts at {offset:.1} s, after light \
             extraction, unwrap, texelize and the direct pass); the estimate is the solver's own (the ambient term \
             for the unshot light over the mean); the error is the relative RMSE against the reference of the \
             lightmap as it would be if the pass stopped there.\n",
            mode_name(c.mode),
            c.lights,
            c.size,
            c.contact
        );
        println!("| time (s) | bounce (s) | shots | unshot | estimate | error |");
        println!("|---|---|---|---|---|---|");
        let step = c.trace.len().div_ceil(16).max(1);
        for (i, t) in c.trace.iter().enumerate() {
            if i % step == 0 || i + 1 == c.trace.len() {
                println!(
                    "| {:.1} | {:.1} | {} | {:.2} % | {:.2} % | {} |",
                    offset + t.seconds,
                    t.seconds,
                    t.shots,
                    t.unshot_fraction * 100.0,
                    t.error_estimate * 100.0,
                    percent(t.reference_error)
                );
            }
        }
        println!(
            "| {:.1} | {:.1} | {} | {:.2} % | (final) | {} |",
            c.total(),
            c.bounce,
            c.shots,
            c.unshot * 100.0,
            percent(c.error)
        );
    }
    Ok(())
}

fn vertex_table(gpu: &Gpu, args: &Args, statues: &Statues, map: &Arc<EnvironmentMap>) -> Result<()> {
    println!("\n## Per-vertex baseline: the direct light at the vertices\n");
    println!(
        "The paper's Fig. 14 compares its texels with incremental radiosity at the vertices. Here the same direct \
         pass and shadow rays run at the {} lights' texels (with the supersample fix-up, as a bake) and at the \
         meshes' vertices, interpolated across each triangle (benches/table4/vertex.rs). Errors: relative RMSE \
         against the CPU reference of the direct light alone (no reflections) at {} texel centres × {} paths. \
         The bounce pass has no per-vertex form (it shoots between atlas patches and texels), so this compares \
         the direct light only.\n",
        args.vertex_lights, args.reference_texels, args.reference_samples
    );
    println!("| atlas | texels | per texel (s) | error | vertices | per vertex (s) | error | reference noise |");
    println!("|---|---|---|---|---|---|---|---|");
    let lights = LightSet::extract(map, LightMode::Budget { count: args.vertex_lights }, 0.0, 1.0);
    let scene = statues.scene()?;
    let setup = vertex::Setup {
        gpu,
        environment: map,
        lights: &lights,
        probes: args.reference_texels.max(1),
        samples: args.reference_samples,
    };
    for &size in &args.sizes {
        let mut options = BakeOptions::default();
        options.unwrap.max_atlas_size = size;
        let c = vertex::compare(&setup, &scene, &options)?;
        eprintln!(
            "vertex {size}²: texels {:.2} s {:.2} %, vertices {:.2} s {:.2} %",
            c.texel_seconds,
            100.0 * c.texel_error,
            c.vertex_seconds,
            100.0 * c.vertex_error
        );
        println!(
            "| {size}² | {} | {:.2} | {:.2} % | {} | {:.2} | {:.2} % | {:.2} % |",
            c.texels,
            c.texel_seconds,
            100.0 * c.texel_error,
            c.vertices,
            c.vertex_seconds,
            100.0 * c.vertex_error,
            100.0 * c.noise
        );
    }
    Ok(())
}

/// The bounce pass alone for a fixed number of shots from a uniform start (every texel's L_lm = 1),
/// as texels and triangles double: what one shot costs (its hemicube sees every triangle, its
/// gather every texel).
fn bounce_scaling(gpu: &Gpu) -> Result<()> {
    const SHOTS: u64 = 256;
    println!("\n## Scaling of the bounce pass: {SHOTS} shots\n");
    println!(
        "`solve::bounce::run` alone, {SHOTS} shots in batches of 32 from a lightmap of 1 everywhere (timing only), \
         default patches and hemicube size (128²). Pairs: texels × shots.\n"
    );
    println!("| run | texels | triangles | patches | bounce (s) | shots/s | M texel·shots/s | cores |");
    println!("|---|---|---|---|---|---|---|---|");
    let runs = [(17, 181), (17, 256), (17, 362), (17, 512), (12, 256), (24, 256), (34, 256)];
    for (frequency, size) in runs {
        let statues = Statues::new(frequency);
        let scene = statues.scene()?;
        let mut options = BakeOptions::default();
        options.unwrap.max_atlas_size = size;
        let atlas = unwrap(&scene, &options)?;
        let texels = bake::texelize::run(gpu, &scene, &atlas)?;
        let tpu = atlas.texels_per_unit;
        let patches = bake::solve::patches::build(
            &texels,
            options.solve.bounce.patches,
            1.0 / tpu,
            Some(Sight { occluders: &bake::trace::Surfaces::new(&scene), hidden: None }),
        );
        let mut bounce = options.solve.bounce.clone();
        bounce.max_shots = Some(SHOTS);
        bounce.tolerance = 0.0;
        let mut lightmap = vec![[1.0f32; 3]; texels.texels.len()];
        let (wall, cpu) = (Instant::now(), cpu_seconds());
        let surfaces = bake::solve::bounce::Surfaces {
            scene: &scene,
            texels: &texels,
            shares: None,
            patches: &patches,
            coverage: None,
            texels_per_unit: tpu,
        };
        let stats = bake::solve::bounce::run(gpu, &surfaces, &mut lightmap, &bounce, &mut |_, _| {})?;
        let cores = (cpu_seconds() - cpu) / wall.elapsed().as_secs_f64();
        println!(
            "| atlas {size}², statue frequency {frequency} | {} | {} | {} | {:.2} | {:.1} | {:.1} | {cores:.2} |",
            texels.texels.len(),
            scene.triangle_count(),
            stats.patches,
            stats.seconds,
            stats.shots as f64 / stats.seconds,
            stats.shots as f64 * texels.texels.len() as f64 / stats.seconds / 1e6
        );
        eprintln!("bounce scaling {size}² f{frequency}: {:.2} s", stats.seconds);
    }
    println!();
    Ok(())
}
