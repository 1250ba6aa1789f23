//! `bake`: a lightmap baker for glTF scenes under captured HDR environments.
//!
//! ```text
//! import ─► unwrap ─► texelize ─► environment ─► solve ─► export ─► report
//! ```
//! Each stage is a module with one job and plain data between stages
//! (`Scene`, `Atlas`, `TexelSet`, `LightSet`, `Solution`). `run` strings
//! them together for the CLI; `bake_scene` does the in-memory part for tests
//! and library users:
//!
//! ```no_run
//! # fn main() -> anyhow::Result<()> {
//! use std::path::Path;
//! use bake::config::{BakeOptions, EnvironmentOptions};
//!
//! let gpu = bake::Gpu::new(None)?;
//! let scene = bake::load_scene(Path::new("assets/room.glb"))?;
//! let (lights, _) = bake::load_environment(Path::new("studio.exr"), &EnvironmentOptions::default())?;
//! let baked = bake::bake_scene(&gpu, scene, Some(&lights), &BakeOptions::default(), &mut bake::progress::Silent)?;
//! // Texel i of the atlas is baked.texels.texels[i]; its light (L_lm, linear RGB) is baked.solution.lightmap[i].
//! let _ = (&baked.texels.texels[0], baked.solution.lightmap[0]);
//! # Ok(())
//! # }
//! ```

#![warn(clippy::too_many_lines)]

// The front door: what a program embedding bake uses. `run` bakes what a
// `Config` names into files (the CLI's whole job); `bake_scene` bakes a
// loaded `Scene` in memory; `check` reads and checks a report.
pub mod check;
pub mod cli;
pub mod config;
pub mod progress;
pub mod report;

pub use environment::LightSet;
pub use gpu::Gpu;
pub use import::load as load_scene;
pub use output::remove_staging_on_signals;
pub use probes::Probes;
pub use scene::Scene;
pub use solve::{Solution, StopReason};
pub use texelize::{Texel, TexelSet};
pub use unwrap::Atlas;

/// Modules public only with the `internals` feature (the crate's own tests,
/// benches and examples), crate-private otherwise.
macro_rules! internal_modules {
    ($($name:ident),* $(,)?) => {$(
        #[cfg(feature = "internals")]
        pub mod $name;
        #[cfg(not(feature = "internals"))]
        mod $name;
    )*};
}

/// Procedural test scenes, for the crate's own tests, benches and examples.
#[cfg(feature = "internals")]
pub mod fixtures;

internal_modules!(
    asset,
    colour,
    environment,
    export,
    files,
    gpu,
    import,
    limits,
    memory,
    output,
    plot,
    probes,
    reference,
    repeats,
    scene,
    solve,
    texelize,
    trace,
    unwrap,
);

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use anyhow::{Context, Result, bail};

use config::{BakeOptions, Config, EnvironmentOptions};
use environment::EnvironmentMap;
use memory::MemoryProbe;
use progress::Progress;
use report::{AtlasReport, EnvironmentReport, InputFile, OptionsReport, Report, SceneReport, StageTime, TexelReport};

/// A scene baked in memory.
pub struct Baked {
    pub scene: Scene,
    pub atlas: Atlas,
    pub texels: TexelSet,
    pub solution: Solution,
    pub stages: Vec<StageTime>,
    pub notices: Vec<String>,
    /// `--reference`: the bake's error against the CPU reference.
    pub reference: Option<report::ReferenceReport>,
    /// The atlas is the input's own TEXCOORD_1 (`--keep-uv1`), not a new unwrap.
    pub uv1_reused: bool,
    /// `--probes`: the irradiance volume.
    pub probes: Option<probes::Probes>,
}

/// Times `f` as stage `name` of `scene` and measures its memory, reporting to `progress`.
fn stage<T>(
    gpu: &Gpu,
    progress: &mut dyn Progress,
    stages: &mut Vec<StageTime>,
    scene: &str,
    name: &str,
    f: impl FnOnce(&mut dyn Progress) -> Result<(T, String)>,
) -> Result<T> {
    let start = Instant::now();
    let probe = MemoryProbe::start(Some(gpu));
    progress.stage(scene, name);
    gpu.enter_stage(name);
    // On a lost device every GPU call fails in its own words: say what happened instead.
    let (value, summary) = f(progress).map_err(|e| gpu.lost_error(name).unwrap_or(e))?;
    progress.finish(&summary);
    let memory = probe.and_then(|p| p.finish(Some(gpu)));
    stages.push(StageTime { stage: name.to_string(), seconds: start.elapsed().as_secs_f64(), memory });
    Ok(value)
}

/// Refuses options the adapter cannot honour, naming its limit: an atlas
/// page wider than its largest 2D texture.
pub fn check_adapter_limits(gpu: &Gpu, options: &BakeOptions) -> Result<()> {
    let max = gpu.limits.max_texture_dimension_2d;
    let wanted = options.unwrap.max_atlas_size;
    if wanted > max {
        bail!(
            "--max-atlas-size {wanted} is larger than adapter '{}' allows: its largest texture is {max}×{max} \
             texels (max_texture_dimension_2d); use --max-atlas-size {max} or less",
            gpu.adapter.name
        );
    }
    Ok(())
}

/// Unwraps, texelizes and solves `scene` under `lights` (if any).
pub fn bake_scene(
    gpu: &Gpu,
    mut scene: Scene,
    lights: Option<&LightSet>,
    options: &BakeOptions,
    progress: &mut dyn Progress,
) -> Result<Baked> {
    check_adapter_limits(gpu, options)?;
    let name = scene.name.clone();
    let mut stages = Vec::new();
    let mut notices = scene.notices.clone();
    if let Some(notice) = punctual_notice(&mut scene, options.solve.punctual) {
        progress.notice(&notice);
        notices.push(notice);
    }
    // The probe grid, known before the solve so a bad spacing fails at once.
    let probe_plan = match &options.probes {
        Some(p) => Some((p, probes::grid_for(&scene, p).context("--probes")?)),
        None => None,
    };
    let (atlas, uv1_reused) = stage(gpu, progress, &mut stages, &name, "unwrap", |_| unwrap_scene(&scene, options))?;
    for notice in &atlas.notices {
        progress.notice(notice);
    }
    notices.extend(atlas.notices.iter().cloned());
    let texels = stage(gpu, progress, &mut stages, &name, "texelize", |_| texelize_atlas(gpu, &scene, &atlas))?;
    let mut solve_options = options.solve.clone();
    let mut reference = None;
    if let Some(check) = &options.reference {
        let start = Instant::now();
        let (probes, noise) = stage(gpu, progress, &mut stages, &name, "reference", |_| {
            let (probes, noise) = reference::reference_probes(&scene, &texels, check);
            let summary = format!(
                "{} texels × {} paths on the CPU, noise {:.2}%",
                probes.texels.len(),
                check.samples,
                noise * 100.0
            );
            Ok(((probes, noise), summary))
        })?;
        reference = Some((std::sync::Arc::new(probes), noise, start.elapsed().as_secs_f64()));
        solve_options.bounce.probes = reference.as_ref().map(|r| r.0.clone());
    }
    let solution = stage(gpu, progress, &mut stages, &name, "solve", |progress| {
        let solution = solve::run(gpu, &scene, &texels, lights, atlas.texels_per_unit, &solve_options, &mut |d, t| {
            progress.update(d, t)
        })?;
        let summary = solve_summary(&solution, &texels);
        Ok((solution, summary))
    })?;
    if let Some(punctual) = &solution.punctual {
        for notice in solve::punctual::dark_light_notices(&scene.lights, &punctual.dark, &texels.texels) {
            progress.notice(&notice);
            notices.push(notice);
        }
    }
    let probes = match probe_plan {
        Some((probe_options, grid)) => Some(stage(gpu, progress, &mut stages, &name, "probes", |progress| {
            let solved = probes::Solved { scene: &scene, atlas: &atlas, texels: &texels, solution: &solution };
            let probes = probes::run(gpu, &solved, lights, grid, probe_options, &mut |d, t| progress.update(d, t))?;
            let s = &probes.stats;
            let [nx, ny, nz] = s.grid.counts;
            let summary = format!("{nx}×{ny}×{nz} probes, {} buried, {} rays each", s.buried, s.rays + s.lights as u32);
            Ok((probes, summary))
        })?),
        None => None,
    };
    let reference = reference.map(|(probes, noise, seconds)| report::ReferenceReport {
        texels: probes.texels.len(),
        samples: options.reference.as_ref().map_or(0, |r| r.samples),
        seconds,
        noise,
        error: probes.lightmap_error(&solution.lightmap),
    });
    Ok(Baked { scene, atlas, texels, solution, stages, notices, reference, uv1_reused, probes })
}

/// The unwrap stage: the scene's own TEXCOORD_1 (`--keep-uv1`) or a new
/// unwrap, whether it was the former, and the stage's summary.
fn unwrap_scene(scene: &Scene, options: &BakeOptions) -> Result<((Atlas, bool), String)> {
    // Repeated triangles share their first copy's UVs: unwrap without them, then put them back.
    let unique: Vec<Vec<u32>> = scene.primitives.iter().map(|p| repeats::without(&p.indices, &p.repeats)).collect();
    let meshes: Vec<unwrap::MeshInput> = scene
        .primitives
        .iter()
        .zip(&unique)
        .map(|(p, indices)| unwrap::MeshInput { positions: &p.positions, indices })
        .collect();
    let kept = options.keep_uv1.then(|| existing_uv1(scene, &meshes, &options.unwrap));
    let (mut atlas, reused) = match kept {
        Some(Ok(atlas)) => (atlas, true),
        Some(Err(why)) => {
            let mut atlas = unwrap::run(&meshes, &options.unwrap).context("unwrap")?;
            atlas.notices.insert(0, format!("--keep-uv1: TEXCOORD_1 not reused: {why}; unwrapped instead"));
            (atlas, false)
        }
        None => (unwrap::run(&meshes, &options.unwrap).context("unwrap")?, false),
    };
    let unwrapped = std::mem::take(&mut atlas.meshes);
    atlas.meshes = (scene.primitives.iter().zip(unwrapped))
        .map(|(p, mesh)| repeats::restore(&p.indices, &p.repeats, mesh))
        .collect();
    let summary = format!(
        "{}×{} atlas, {} charts, {:.0}% used, {:.3} texels/m",
        atlas.width,
        atlas.height,
        atlas.chart_count,
        atlas.utilization * 100.0,
        atlas.texels_per_unit
    );
    Ok(((atlas, reused), summary))
}

/// The texelize stage: the atlas's covered texels, and the stage's summary.
fn texelize_atlas(gpu: &Gpu, scene: &Scene, atlas: &Atlas) -> Result<(TexelSet, String)> {
    let texels = match atlas.width * atlas.height {
        0 => None,
        _ => Some(texelize::run(gpu, scene, atlas)?).filter(|t| !t.texels.is_empty()),
    };
    // Nothing to bake: the input's geometry or the user's density, not a GPU failure.
    let Some(texels) = texels else {
        if atlas.chart_count == 0 {
            bail!(
                "the unwrap laid out none of the scene's triangles (each is degenerate at its size: a sliver \
                 or a speck): nothing to lightmap"
            );
        }
        bail!(
            "at {} texels per metre the scene covers no lightmap texel: raise --texels-per-unit",
            limits::figure(f64::from(atlas.texels_per_unit))
        );
    };
    let summary = format!("{} texels covering {:.4} m²", texels.texels.len(), texels.total_area());
    Ok((texels, summary))
}

/// The solve stage's summary: what each pass that ran did.
fn solve_summary(solution: &Solution, texels: &TexelSet) -> String {
    let mut parts = Vec::new();
    if let Some(d) = &solution.direct {
        parts.push(format!("{} lights × {} texels, {} rays", d.lights, texels.texels.len(), d.rays));
    }
    if let Some(p) = &solution.punctual {
        parts.push(format!("{} punctual lights along {} shadow rays in {:.1} s", p.lights, p.rays, p.seconds));
    }
    if let Some(b) = &solution.bounce {
        parts.push(format!(
            "{} shots from {} patches ({}), {:.2}% unshot",
            b.shots,
            b.patches,
            b.stopped_by,
            b.unshot_fraction * 100.0
        ));
    }
    if let Some(c) = solution.contact.as_ref().filter(|c| c.gathered > 0) {
        parts.push(format!(
            "{} texels in contact gathered along rays ({} with traced direct light) in {:.1} s",
            c.gathered, c.traced, c.seconds
        ));
    }
    if parts.is_empty() { "nothing to solve".to_string() } else { parts.join("; ") }
}

/// What happens to the scene's punctual lights, for the user: baked, or
/// (`bake` false) kept in the output only, in which case they leave the
/// scene the solve sees.
fn punctual_notice(scene: &mut Scene, bake: bool) -> Option<String> {
    let count = scene.lights.len();
    if count == 0 {
        return None;
    }
    if !bake {
        scene.lights.clear();
        return Some(format!(
            "{count} punctual light(s) (KHR_lights_punctual) are kept in the output but not baked \
             (--no-punctual-lights)"
        ));
    }
    Some(format!(
        "{count} punctual light(s) (KHR_lights_punctual) are baked as direct light; they stay in the output, so an \
         engine that also lights the baked surfaces with them counts their light twice"
    ))
}

/// The scene's own TEXCOORD_1 as the atlas (`--keep-uv1`), or why not, naming
/// the primitive and the check it failed.
fn existing_uv1(scene: &Scene, meshes: &[unwrap::MeshInput], options: &unwrap::UnwrapOptions) -> Result<Atlas, String> {
    let name = |i: usize| {
        let p = &scene.primitives[i];
        let instance = p.instance.map(|k| format!(", instance {k}")).unwrap_or_default();
        format!("mesh {} primitive {} on node {}{instance}", p.mesh, p.primitive, p.node)
    };
    let mut uvs = Vec::new();
    for (i, p) in scene.primitives.iter().enumerate() {
        let primitive = scene.source.document.meshes().nth(p.mesh).and_then(|m| m.primitives().nth(p.primitive));
        let Some(accessor) = primitive.and_then(|q| q.get(&gltf::Semantic::TexCoords(1))) else {
            return Err(format!("{} has no TEXCOORD_1", name(i)));
        };
        let uv = asset::accessor::read_vectors::<2>(&scene.source, &accessor);
        uvs.push(uv.map_err(|e| format!("{}: TEXCOORD_1: {e}", name(i)))?);
    }
    let uvs: Vec<&[[f32; 2]]> = uvs.iter().map(Vec::as_slice).collect();
    unwrap::from_existing(meshes, &uvs, options).map_err(|e| e.describe(name))
}

/// Loads the environment and extracts its lights.
pub fn load_environment(path: &Path, options: &EnvironmentOptions) -> Result<(LightSet, EnvironmentReport)> {
    let start = Instant::now();
    let loaded = EnvironmentMap::load(path, &environment::EnvLoadOptions { clamp_nonfinite: options.clamp_nonfinite })?;
    check_radiance(path, &loaded.map, options.intensity)?;
    let lights = LightSet::extract(&loaded.map, options.lights, options.rotation_degrees, options.intensity);
    let mut notices = loaded.notices;
    if lights.lights.is_empty() {
        // An error only for a scene with no emitters of its own (see `run`).
        notices
            .push("the environment has no energy (every texel is black): only emissive surfaces light the bake".into());
    }
    let report = EnvironmentReport {
        path: path.to_path_buf(),
        width: loaded.map.width,
        height: loaded.map.height,
        mode: options.lights.to_string(),
        lights: lights.lights.len(),
        dropped: lights.dropped,
        map_integral: lights.map_integral,
        captured: lights.captured,
        rotation_degrees: options.rotation_degrees,
        intensity: options.intensity,
        seconds: start.elapsed().as_secs_f64(),
        memory: None,
        notices,
    };
    Ok((lights, report))
}

/// Refuses an environment whose brightest texel, scaled by
/// `--env-intensity`, is more radiance than [`limits::MAX_LIGHT`], naming
/// the texel: the light set and the solve would overflow f32.
fn check_radiance(path: &Path, map: &EnvironmentMap, intensity: f32) -> Result<()> {
    let Some((index, value)) = map.brightest() else { return Ok(()) };
    let radiance = f64::from(value) * f64::from(intensity);
    if radiance <= limits::MAX_LIGHT {
        return Ok(());
    }
    let (col, row) = (index % map.width as usize, index / map.width as usize);
    let scaled = match intensity {
        1.0 => String::new(),
        _ => format!(" × --env-intensity {} = {}", limits::figure(intensity.into()), limits::figure(radiance)),
    };
    let message = format!(
        "texel (col,row) ({col},{row}) is {}{scaled}, more radiance than the {:.0e} bake accepts (f32 \
         headroom, README 'Bad input')",
        limits::figure(value.into()),
        limits::MAX_LIGHT
    );
    Err(environment::EnvLoadError { path: path.to_path_buf(), message }.into())
}

/// Cheap checks before any GPU work: every input and the environment are
/// readable files. Errors name the file.
pub fn preflight(config: &Config) -> Result<()> {
    let readable = |path: &Path, what: &str| -> Result<()> {
        let opened = files::open(path).map(|_| ());
        opened.map_err(|e| anyhow::anyhow!("{what} '{}': cannot read: {e}", path.display()))
    };
    for input in &config.inputs {
        readable(input, "input")?;
    }
    if let Some(env) = &config.environment {
        readable(env, "environment")?;
    }
    Ok(())
}

/// The whole run: every input baked into a staging folder, then moved into
/// `config.output` together with `report.json` only if everything succeeded.
pub fn run(config: &Config, gpu: &Gpu, progress: &mut dyn Progress) -> Result<Report> {
    let stop = AtomicBool::new(false);
    std::thread::scope(|scope| {
        let warm = || drop(scope.spawn(|| solve::warm(gpu, &stop)));
        let report = run_inputs(config, gpu, progress, warm);
        stop.store(true, Ordering::Relaxed);
        report
    })
}

/// `run`'s work. Once the environment has loaded, `warm` starts building
/// the solve's pipelines on another thread while the first scene is
/// imported, unwrapped and texelized (not during the load, which that
/// slows by more than it saves on a 2-core machine); a run that fails stops
/// it after the pipeline under way.
fn run_inputs(config: &Config, gpu: &Gpu, progress: &mut dyn Progress, warm: impl FnOnce()) -> Result<Report> {
    let start = Instant::now();
    check_adapter_limits(gpu, &config.bake)?;
    let mut staging = output::Staging::new(&config.output, &config.inputs)?;
    // An environment map lying in the output folder under an output's name is an input too.
    staging.protect(config.environment.iter().cloned());
    let mut inputs = Vec::new();
    for input in &config.inputs {
        inputs.push(InputFile::hash("scene", input)?);
    }
    if let Some(env) = &config.environment {
        inputs.push(InputFile::hash("environment", env)?);
    }
    let environment = config.environment.as_ref().map(|path| environment_stage(path, config, progress)).transpose()?;
    warm();

    // `--reference` traces against the full-resolution map, not the light set.
    let mut bake_options = config.bake.clone();
    if let (Some(check), Some(path)) = (&mut bake_options.reference, &config.environment) {
        let load = environment::EnvLoadOptions { clamp_nonfinite: config.environment_options.clamp_nonfinite };
        check.environment = Some(std::sync::Arc::new(EnvironmentMap::load(path, &load)?.map));
    }

    let mut scenes = Vec::new();
    for input in &config.inputs {
        let lights = environment.as_ref().map(|(lights, _)| lights);
        scenes.push(bake_input(gpu, config, input, lights, &bake_options, &mut staging, progress)?);
    }

    let report = Report {
        schema_version: report::SCHEMA_VERSION,
        bake_version: env!("CARGO_PKG_VERSION").to_string(),
        inputs,
        options: OptionsReport::from(config),
        adapter: gpu.adapter.clone(),
        environment: environment.map(|(_, report)| report),
        scenes,
        total_seconds: start.elapsed().as_secs_f64(),
    };
    let json = serde_json::to_vec_pretty(&report).context("serializing the report")?;
    std::fs::write(staging.dir().join("report.json"), json).context("writing report.json")?;
    staging.commit()?;
    Ok(report)
}

/// The environment stage of `run`: the map at `path` loaded and its lights
/// extracted, once for every input.
fn environment_stage(
    path: &Path,
    config: &Config,
    progress: &mut dyn Progress,
) -> Result<(LightSet, EnvironmentReport)> {
    progress.stage("", "environment");
    let probe = MemoryProbe::start(None);
    let (lights, mut report) = load_environment(path, &config.environment_options)?;
    report.memory = probe.and_then(|p| p.finish(None));
    for notice in &report.notices {
        progress.notice(notice);
    }
    progress.finish(&format!("{} lights from {}×{} map", report.lights, report.width, report.height));
    Ok((lights, report))
}

/// One input of `run`: imported, baked under the environment's `lights`
/// and exported into the staging folder (with its plot, `--plot`).
fn bake_input(
    gpu: &Gpu,
    config: &Config,
    input: &Path,
    lights: Option<&LightSet>,
    bake_options: &BakeOptions,
    staging: &mut output::Staging,
    progress: &mut dyn Progress,
) -> Result<SceneReport> {
    let mut stages = Vec::new();
    let scene = stage(gpu, progress, &mut stages, &input_stem(input), "import", |_| {
        let scene = import::load_with(input, &config.import)?;
        let summary = format!("{} primitives, {} triangles", scene.primitives.len(), scene.triangle_count());
        Ok((scene, summary))
    })?;
    for notice in &scene.notices {
        progress.notice(notice);
    }
    staging.protect(export::source_files(&scene.source));
    check_lit(config, input, &scene, lights)?;
    let baked = bake_scene(gpu, scene, lights, bake_options, progress)
        .with_context(|| format!("input '{}'", input.display()))?;
    stages.extend(baked.stages.iter().cloned());
    let exported = stage(gpu, progress, &mut stages, &baked.scene.name, "export", |_| {
        let results = export::Input {
            scene: &baked.scene,
            atlas: &baked.atlas,
            texels: &baked.texels,
            lightmap: &baked.solution.lightmap,
            uv1_reused: baked.uv1_reused,
            probes: baked.probes.as_ref().map(|p| probes::write::gltf_record(&baked.scene.name, p)),
        };
        let mut stats = export::run(&results, &config.bake.export, staging.dir())
            .with_context(|| format!("input '{}': export", input.display()))?;
        if let Some(probes) = &baked.probes {
            stats.files.extend(write_probes(&baked.scene.name, probes, staging.dir())?);
        }
        let summary = format!("{} files", stats.files.len());
        Ok((stats, summary))
    })?;
    let mut scene = scene_report(input, &baked, stages, exported, &config.bake, staging);
    if config.report.plot {
        let path = staging.dir().join(format!("{}.convergence.svg", scene.name));
        let svg = plot::convergence_svg(&scene).with_context(|| format!("input '{}': plot", input.display()))?;
        std::fs::write(&path, svg).with_context(|| format!("writing {}", path.display()))?;
        scene.outputs.push(staging.final_path(&path));
    }
    Ok(scene)
}

/// Writes the probe volume's files (`probes::write`) into `dir`.
fn write_probes(name: &str, probes: &probes::Probes, dir: &Path) -> Result<Vec<std::path::PathBuf>> {
    let names = probes::write::file_names(name);
    let contents = [
        probes::write::encode_ktx2(probes)?,
        probes::write::encode_json(name, probes)?,
        probes::write::encode_bin(probes),
    ];
    let mut files = Vec::new();
    for (name, bytes) in names.iter().zip(contents) {
        let path = dir.join(name);
        export::write_new(&path, &bytes)?;
        files.push(path);
    }
    Ok(files)
}

/// Refuses an input nothing lights: no environment `lights` (or a black
/// map) and no light sources of its own.
fn check_lit(config: &Config, input: &Path, scene: &Scene, lights: Option<&LightSet>) -> Result<()> {
    // Light sources of the scene's own: emissive materials, punctual lights it bakes.
    let own_light = scene.materials.iter().any(|m| m.emission.iter().any(|&e| e > 0.0))
        || config.bake.solve.punctual && !scene.lights.is_empty();
    match (lights, &config.environment) {
        (None, _) if !own_light => {
            bail!(
                "input '{}': nothing lights the scene: give --env, or use emissive materials or punctual lights",
                input.display()
            )
        }
        (Some(lights), Some(env)) if lights.lights.is_empty() && !own_light => bail!(
            "environment '{}': the map has no energy (every texel is black) and input '{}' has no emissive \
             materials or punctual lights: nothing lights the scene",
            env.display(),
            input.display()
        ),
        _ => Ok(()),
    }
}

fn input_stem(input: &Path) -> String {
    input.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default()
}

fn scene_report(
    input: &Path,
    baked: &Baked,
    stages: Vec<StageTime>,
    exported: export::ExportStats,
    options: &BakeOptions,
    staging: &output::Staging,
) -> SceneReport {
    let scene = &baked.scene;
    let keys: Vec<_> = scene.primitives.iter().map(scene::ScenePrimitive::key).collect();
    let names = primitive_names(scene);
    let mut notices = baked.notices.clone();
    notices.extend(exported.notices.iter().cloned());
    SceneReport {
        name: scene.name.clone(),
        input: input.to_path_buf(),
        outputs: exported.files.iter().map(|f| staging.final_path(f)).collect(),
        stages,
        skipped: baked.solution.skipped.clone(),
        notices,
        primitives: scene.primitives.len(),
        triangles: scene.triangle_count(),
        atlas: AtlasReport {
            index: 0,
            width: baked.atlas.width,
            height: baked.atlas.height,
            texels_per_unit: baked.atlas.texels_per_unit,
            charts: baked.atlas.chart_count,
            utilization: baked.atlas.utilization,
            unwrapper: if baked.uv1_reused { "input TEXCOORD_1".into() } else { options.unwrap.backend.to_string() },
            energy: report::atlas_energy(&baked.texels, &baked.solution),
        },
        texels: TexelReport {
            covered: baked.texels.texels.len(),
            area: baked.texels.total_area(),
            dilated: exported.dilated_texels,
            fixups: fixups(baked, &exported),
            seams: exported.stitch.clone(),
        },
        direct: baked.solution.direct.clone(),
        punctual: baked.solution.punctual.clone(),
        bounce: baked.solution.bounce.clone(),
        contact: baked.solution.contact.clone(),
        energy: report::primitive_energy(&baked.texels, &baked.solution, &keys, &names),
        reference: baked.reference.clone(),
        probes: baked.probes.as_ref().map(|p| p.stats.clone()),
    }
}

/// Each primitive's name in the report: its node's name (else its mesh's,
/// else `nodeN`), the instance in brackets, then `#` and its index.
fn primitive_names(scene: &Scene) -> Vec<String> {
    scene
        .primitives
        .iter()
        .map(|p| {
            let mesh = scene.source.document.meshes().nth(p.mesh);
            let node = scene.source.document.nodes().nth(p.node);
            let label = node
                .and_then(|n| n.name().map(str::to_string))
                .or_else(|| mesh.and_then(|m| m.name().map(str::to_string)));
            let instance = p.instance.map(|k| format!("[{k}]")).unwrap_or_default();
            format!("{}{instance}#{}", label.unwrap_or_else(|| format!("node{}", p.node)), p.primitive)
        })
        .collect()
}

/// What each fix-up stage did to the texels, for the report.
fn fixups(baked: &Baked, exported: &export::ExportStats) -> Vec<report::Fixup> {
    vec![
        report::Fixup {
            stage: "border".into(),
            texels: baked.texels.texels.iter().filter(|t| t.area == 0.0).count(),
            what: "texels a chart only borders: placed on the nearest point inside their triangle, \
                   off the chart's edge, so they see neither through nor under what meets it"
                .into(),
        },
        report::Fixup {
            stage: "supersample".into(),
            texels: baked.solution.supersampled,
            what: "texels a sharp edge of direct light crosses: the mean of sub-samples over the part of \
                   their footprint the centre reaches along the surface"
                .into(),
        },
        report::Fixup {
            stage: "contact".into(),
            texels: baked.solution.contact.as_ref().map_or(0, |c| c.gathered),
            what: "texels another surface comes close to (a ball's underside over the floor, the floor under \
                   a ring): their bounced light gathered along 256 rays from the texels the rays meet, and \
                   their direct light traced too where the surface is within two texels"
                .into(),
        },
        report::Fixup {
            stage: "overlap".into(),
            texels: baked.solution.overlapped,
            what: "texels another surface lies on (facing the same way) or just over: they bounce their \
                   place's light once between them, not once each; those hidden within a texel under an \
                   opaque one get no light"
                .into(),
        },
        report::Fixup {
            stage: "dilation".into(),
            texels: exported.dilated_texels,
            what: "padding texels filled from their own chart, so bilinear filtering reads no black".into(),
        },
        report::Fixup {
            stage: "stitch".into(),
            texels: exported.stitch.texels,
            what: "texels moved by least squares so the two sides of every UV seam agree".into(),
        },
    ]
}
