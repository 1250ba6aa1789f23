//! Solve stage: TexelSet + LightSet in, `Solution` out: the lightmap value
//! L_lm = E/π (incident irradiance over π, linear RGB) of every texel, with
//! radiosity in radiance units L_i = Le_i + ρ_i Σ_j F_ij L_j.
//!
//! Passes, each left out when the scene does not need it:
//! `direct` (environment light through per-light depth maps) and
//! `punctual` (the scene's own lights, along exact shadow rays), then
//! `bounce` (progressive refinement of reflected and emitted light between
//! `patches`).
//!
//! Each GPU pass is a file beside its shader (`solve_<pass>.wgsl`), a struct
//! holding its pipelines and bind groups with a method that records it:
//! `occluders` and `direct`; the bounce pass's `patch_power`, `select`,
//! `hemicube_cull`, `hemicube`, `shooter_cull` and `shoot`, over the buffers
//! they share (`resources`), strung together batch by batch in `bounce`.

pub mod bounce;
mod casters;
mod contact;
pub mod direct;
mod emitted;
mod hemicube;
mod hemicube_cull;
mod light_clusters;
mod occluders;
mod overlaps;
pub mod pass_times;
mod patch_power;
pub mod patches;
pub mod punctual;
mod resources;
mod select;
mod shoot;
mod shooter_cull;
pub mod supersample;
mod surfaces;

use std::cell::LazyCell;
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::Result;
use serde::{Deserialize, Serialize};

use crate::environment::LightSet;
use crate::gpu::Gpu;
use crate::scene::Scene;
use crate::texelize::{Texel, TexelSet};
use crate::trace::Surfaces;
pub use bounce::{BounceOptions, BounceStats, StopReason, TracePoint};
pub use contact::ContactStats;
use overlaps::Overlaps;
use punctual::{Punctual, PunctualStats};

/// Options of the solve, with their defaults.
#[derive(Clone, Debug)]
pub struct SolveOptions {
    /// Lights gathered per GPU batch of the direct pass (at most `direct::MAX_BATCH`).
    pub batch_size: u32,
    /// The direct pass's rays a point (`direct::RayBudget`).
    pub direct_rays: u32,
    /// Gather texels on a sharp change of direct light at sub-samples of
    /// their footprint (`supersample`).
    pub supersample: bool,
    /// Trace the light of texels close to another surface on the CPU
    /// (`contact`).
    pub contact: bool,
    /// Bake the scene's punctual lights (`punctual`); without, they are
    /// left out of the scene before the solve.
    pub punctual: bool,
    pub bounce: BounceOptions,
}

impl Default for SolveOptions {
    fn default() -> Self {
        SolveOptions {
            batch_size: 1024,
            direct_rays: direct::DEFAULT_RAYS,
            supersample: true,
            contact: true,
            punctual: true,
            bounce: BounceOptions::default(),
        }
    }
}

/// Builds the GPU passes' pipelines ahead, in the order a bake needs them,
/// until `stop` is set: each is built once per device (`gpu::built`), so a
/// run can have them built on another thread while its CPU stages go on.
/// The pipelines of rarer cases (cut-outs, clustered lights, probes) are
/// built when first needed.
pub fn warm(gpu: &Gpu, stop: &AtomicBool) {
    let steps: [fn(&Gpu); 6] = [
        direct::warm,
        |gpu| drop(patch_power::pipelines(gpu)),
        |gpu| drop(select::pipeline(gpu)),
        |gpu| drop(hemicube_cull::pipelines(gpu)),
        |gpu| drop(shooter_cull::pipelines(gpu)),
        |gpu| drop(shoot::pipelines(gpu)),
    ];
    for step in steps {
        if stop.load(Ordering::Relaxed) {
            return;
        }
        step(gpu);
    }
}

/// The solved lightmap: one value per covered texel, in `TexelSet` order.
#[derive(Clone, Debug)]
pub struct Solution {
    /// L_lm = E/π per texel, linear RGB.
    pub lightmap: Vec<[f32; 3]>,
    pub direct: Option<direct::DirectStats>,
    /// The punctual lights' pass (`punctual`), when the scene has lights.
    pub punctual: Option<PunctualStats>,
    pub bounce: Option<BounceStats>,
    /// The contact fix-up (`contact`), when it ran.
    pub contact: Option<ContactStats>,
    /// Texels whose direct light is the mean over sub-samples of their
    /// footprint (`supersample`).
    pub supersampled: usize,
    /// Texels another surface lies on or just over (`overlaps`): they bounce
    /// a share of their light, or none (and those hidden under an opaque
    /// surface get none).
    pub overlapped: usize,
    /// Each texel's share of its area that bounces light (`overlaps`), where
    /// any is under 1: the energy sums weigh texels by it, as the bounce does.
    pub shares: Option<Vec<f32>>,
    /// Passes left out and why, for the report.
    pub skipped: Vec<Skipped>,
}

impl Solution {
    /// Outgoing radiance of texel `i`: albedo·L_lm + emission.
    pub fn radiosity(&self, texels: &TexelSet, i: usize) -> [f32; 3] {
        let t = &texels.texels[i];
        [0, 1, 2].map(|c| t.albedo[c] * self.lightmap[i][c] + t.emission[c])
    }
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Skipped {
    pub pass: String,
    pub reason: String,
}

fn skip(skipped: &mut Vec<Skipped>, pass: &str, reason: &str) {
    skipped.push(Skipped { pass: pass.into(), reason: reason.into() });
}

/// Runs every pass the scene needs. `progress(done, total)` reports the
/// current pass.
pub fn run(
    gpu: &Gpu,
    scene: &Scene,
    texels: &TexelSet,
    lights: Option<&LightSet>,
    texels_per_unit: f32,
    options: &SolveOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Solution> {
    let inputs = Inputs { gpu, scene, texels, texels_per_unit, options };
    let mut skipped = Vec::new();
    // The scene's triangles on the CPU, built when a pass first asks (the
    // supersample fix-up, the shooter patches, the contact fix-up).
    let occluders = LazyCell::new(|| Surfaces::new(scene));
    let environment = lights.filter(|l| !l.lights.is_empty());
    match lights {
        Some(lights) if lights.lights.is_empty() => skip(&mut skipped, "direct", "the environment has no energy"),
        None => skip(&mut skipped, "direct", "no environment was given"),
        Some(_) => {}
    }
    let punctual = (!scene.lights.is_empty()).then(|| Punctual::new(scene, &occluders));
    // Surfaces on or just over one another (`overlaps`).
    let texel_size = 1.0 / texels_per_unit.max(1e-30);
    let overlaps = overlaps::find(scene, texels, texel_size);
    let shares = overlaps.as_ref().map(|o| o.shares.as_slice());
    let mut lit = light_directly(&inputs, &occluders, environment, punctual.as_ref(), shares, progress)?;

    // The direct light alone, for the contact fix-up.
    let direct_only = options.contact.then(|| lit.lightmap.clone());
    let mut bounce_stats = bounce(&inputs, &occluders, overlaps.as_ref(), &mut lit, &mut skipped, progress)?;
    // What lies hidden under an opaque surface gets no light, whatever the
    // depth maps made of the surface over it (first, so the contact fix-up
    // gathers none of their light).
    if let Some(overlaps) = &overlaps {
        for (value, &hidden) in lit.lightmap.iter_mut().zip(&overlaps.hidden) {
            if hidden {
                *value = [0.0; 3];
            }
        }
    }
    let mut contact_stats = None;
    let hidden = overlaps.as_ref().map(|o| o.hidden.as_slice());
    if let Some(direct) = &direct_only {
        // The reach is in shooter patches' cells (`patches::build`'s), with
        // or without a bounce pass.
        let cell = patches::cell_size(texels, options.bounce.patches) as f64 * texel_size as f64;
        let direct = contact::Direct {
            environment: environment.map(|l| l.lights.as_slice()),
            punctual: lit.punctual_light.as_deref(),
            total: direct,
        };
        let lightmap = &mut lit.lightmap;
        let geometry =
            contact::Geometry { scene, surfaces: &occluders, texels, hidden, shares, texel_size: texel_size as f64 };
        let stats = contact::fix(&geometry, &direct, lightmap, cell);
        if stats.gathered > 0
            && let Some(bounce) = bounce_stats.as_mut()
        {
            trace_after_contact(bounce, &stats, lightmap, options);
        }
        contact_stats = Some(stats);
    }
    let overlapped = overlaps.as_ref().map_or(0, Overlaps::count);
    Ok(Solution {
        lightmap: lit.lightmap,
        direct: lit.direct,
        punctual: lit.punctual,
        bounce: bounce_stats,
        contact: contact_stats,
        supersampled: lit.supersampled,
        overlapped,
        shares: overlaps.map(|o| o.shares),
        skipped,
    })
}

/// What every pass of the solve reads.
struct Inputs<'a> {
    gpu: &'a Gpu,
    scene: &'a Scene,
    texels: &'a TexelSet,
    texels_per_unit: f32,
    options: &'a SolveOptions,
}

/// The lightmap after the direct passes, and what the later passes need of them.
struct Lit {
    /// L_lm per texel: the environment's and the punctual lights' light.
    lightmap: Vec<[f32; 3]>,
    direct: Option<direct::DirectStats>,
    punctual: Option<PunctualStats>,
    /// The punctual lights' L_lm, for the contact fix-up.
    punctual_light: Option<Vec<[f32; 3]>>,
    /// The environment pass's covered share of each texel's hemisphere.
    coverage: Option<Vec<f32>>,
    /// Whether light may bounce: false where every texel sees open sky in
    /// every direction.
    sees_itself: bool,
    supersampled: usize,
}

/// The direct passes (environment and punctual lights), when the scene has
/// either: their light as L_lm per texel (0 without them).
fn light_directly(
    inputs: &Inputs,
    occluders: &LazyCell<Surfaces, impl FnOnce() -> Surfaces>,
    environment: Option<&LightSet>,
    punctual: Option<&Punctual>,
    shares: Option<&[f32]>,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Lit> {
    let texels = inputs.texels;
    // Where surfaces overlap, the power each pass delivered is summed over
    // the texels as the bounce counts them.
    let counted = shares.map(|shares| overlaps::counted(texels, shares));
    let mut lit = Lit {
        lightmap: vec![[0.0f32; 3]; texels.texels.len()],
        direct: None,
        punctual: None,
        punctual_light: None,
        coverage: None,
        sees_itself: true,
        supersampled: 0,
    };
    if environment.is_none() && punctual.is_none() {
        return Ok(lit);
    }
    let light = direct_light_with(inputs, occluders, environment, punctual, progress)?;
    lit.supersampled = light.supersampled;
    if let Some(mut direct) = light.environment {
        if let Some(counted) = &counted {
            direct.stats.power_received = direct::power_received(counted, &direct.irradiance);
        }
        for (value, e) in lit.lightmap.iter_mut().zip(&direct.irradiance) {
            *value = e.map(|c| c / std::f32::consts::PI);
        }
        lit.sees_itself = direct.stats.shadowed_texels > 0;
        lit.direct = Some(direct.stats);
        lit.coverage = Some(direct.coverage);
    }
    if let (Some(irradiance), Some(punctual)) = (light.punctual, punctual) {
        lit.punctual = Some(punctual.stats(&counted.as_ref().unwrap_or(texels).texels, &irradiance));
        let own: Vec<[f32; 3]> = irradiance.iter().map(|e| e.map(|c| c / std::f32::consts::PI)).collect();
        for (value, l) in lit.lightmap.iter_mut().zip(&own) {
            (0..3).for_each(|c| value[c] += l[c]);
        }
        // A point light's light may bounce anywhere.
        lit.sees_itself = true;
        lit.punctual_light = Some(own);
    }
    Ok(lit)
}

/// The bounce pass over `lit.lightmap`, or the reason it is left out in
/// `skipped` (as is emission's, where no surface is emissive).
fn bounce(
    inputs: &Inputs,
    occluders: &LazyCell<Surfaces, impl FnOnce() -> Surfaces>,
    overlaps: Option<&Overlaps>,
    lit: &mut Lit,
    skipped: &mut Vec<Skipped>,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Option<BounceStats>> {
    let Inputs { gpu, scene, texels, texels_per_unit, options } = *inputs;
    let emitters = texels.texels.iter().any(Texel::emits);
    let reflects =
        texels.texels.iter().zip(&lit.lightmap).any(|(t, l)| t.area > 0.0 && (0..3).any(|c| t.albedo[c] * l[c] > 0.0));
    if !emitters {
        skip(skipped, "emission", "no surface is emissive");
    }
    if !emitters && !reflects {
        skip(skipped, "bounce", "no light to bounce: the surfaces are black or unlit");
        return Ok(None);
    }
    if !lit.sees_itself {
        skip(skipped, "bounce", "no surface sees another (every texel sees open sky in every direction)");
        return Ok(None);
    }
    let texel_size = 1.0 / texels_per_unit.max(1e-30);
    let patches = patches::build(
        texels,
        options.bounce.patches,
        texel_size,
        Some(patches::Sight { occluders, hidden: overlaps.map(|o| o.hidden.as_slice()) }),
    );
    // Overlapping surfaces bounce the light of their place once between
    // them: the bounce pass weighs each texel by its share of the area.
    let surfaces = bounce::Surfaces {
        scene,
        texels,
        shares: overlaps.map(|o| o.shares.as_slice()),
        patches: &patches,
        coverage: lit.coverage.as_deref(),
        texels_per_unit,
    };
    Ok(Some(bounce::run(gpu, &surfaces, &mut lit.lightmap, &options.bounce, progress)?))
}

/// Ends the bounce pass's convergence trace with a point after the contact
/// fix-up, which changes the light the pass left near contacts: `--plot`
/// then ends at the error the report gives (corner under courtyard: the
/// trace ended at 2.9 %, the report said 1.6 %).
fn trace_after_contact(
    bounce: &mut BounceStats,
    contact: &ContactStats,
    lightmap: &[[f32; 3]],
    options: &SolveOptions,
) {
    let Some(last) = bounce.trace.last().cloned() else {
        return;
    };
    let probes = options.bounce.probes.as_deref().filter(|p| !p.texels.is_empty());
    let reference_error = probes.map(|p| p.lightmap_error(lightmap));
    bounce.trace.push(TracePoint { seconds: last.seconds + contact.seconds, reference_error, ..last });
}

/// The direct pass with the supersample fix-up when it is asked for, and how
/// many texels it supersampled.
#[cfg(feature = "internals")]
pub fn direct_light(
    gpu: &Gpu,
    scene: &Scene,
    texels: &TexelSet,
    lights: &LightSet,
    texels_per_unit: f32,
    options: &SolveOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<(direct::Direct, usize)> {
    let occluders = LazyCell::new(|| Surfaces::new(scene));
    let inputs = Inputs { gpu, scene, texels, texels_per_unit, options };
    let light = direct_light_with(&inputs, &occluders, Some(lights), None, progress)?;
    Ok((light.environment.expect("the environment's light was gathered"), light.supersampled))
}

/// Direct light from the environment and from punctual lights, with the
/// supersample fix-up where it is asked for.
struct DirectLight {
    /// The environment's, when there is one.
    environment: Option<direct::Direct>,
    /// The punctual lights' irradiance E per texel, when the scene has any.
    punctual: Option<Vec<[f32; 3]>>,
    /// Texels gathered at sub-samples of their footprint.
    supersampled: usize,
}

/// Gathers the environment's light (`environment`, on the GPU) and the
/// punctual lights' (`punctual`, on the CPU) at every texel. Texels where
/// the two together change sharply are gathered again at sub-samples of
/// their footprint (`supersample`), both kinds of light alike. The scene's
/// triangles on the CPU are built once for the whole solve (here, when the
/// supersample fix-up plans its sub-samples).
fn direct_light_with(
    inputs: &Inputs,
    occluders: &LazyCell<Surfaces, impl FnOnce() -> Surfaces>,
    environment: Option<&LightSet>,
    punctual: Option<&Punctual>,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<DirectLight> {
    let Inputs { gpu, scene, texels, texels_per_unit, options } = *inputs;
    let start = std::time::Instant::now();
    let pass = environment.map(|_| direct::DirectPass::new(gpu, scene)).transpose()?;
    let gather = |points: &[Texel], lights: &LightSet, progress: &mut dyn FnMut(u64, u64)| {
        let pass = pass.as_ref().expect("a pass where there are lights");
        pass.gather(points, lights, options, progress)
    };
    let mut direct = environment
        .map(|lights| Ok::<_, anyhow::Error>(gather(&texels.texels, lights, progress)?.into_direct(texels, lights)))
        .transpose()?;
    let punctual_at_texels = punctual.map(|p| p.irradiance(&texels.texels));
    let plan = if options.supersample {
        let environment = direct.as_ref().map(|d| (&d.irradiance[..], &d.shadowed[..]));
        let edges = supersample::Edges::new(texels.texels.len(), environment, punctual_at_texels.as_deref());
        supersample::plan(occluders, texels, &edges)
    } else {
        None
    };
    let Some(plan) = plan else {
        if let Some(direct) = &mut direct {
            direct.stats.seconds = start.elapsed().as_secs_f64();
        }
        return Ok(DirectLight { environment: direct, punctual: punctual_at_texels, supersampled: 0 });
    };
    if let (Some(direct), Some(lights)) = (&mut direct, environment) {
        let at_samples = gather(&plan.samples.texels, lights, &mut |_, _| {})?;
        direct.stats.evaluations += lights.lights.len() as u64 * plan.samples.texels.len() as u64;
        direct.stats.rays += at_samples.rays;
        direct.stats.batches += at_samples.batches;
        supersample::fold(&plan, &at_samples.irradiance, &mut direct.irradiance);
        direct.stats.power_received = direct::power_received(texels, &direct.irradiance);
        direct.stats.seconds = start.elapsed().as_secs_f64();
    }
    let punctual = punctual.zip(punctual_at_texels).map(|(punctual, mut irradiance)| {
        let texel_size = 1.0 / texels_per_unit.max(1e-30) as f64;
        let at_samples = punctual.irradiance_at_sub_samples(&plan.samples.texels, texel_size);
        supersample::fold(&plan, &at_samples, &mut irradiance);
        irradiance
    });
    Ok(DirectLight { environment: direct, punctual, supersampled: plan.texels })
}
