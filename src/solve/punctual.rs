//! Punctual lights (KHR_lights_punctual): the directional, point and spot
//! lights the scene's nodes place (`Scene::lights`), baked as direct light.
//! Each texel takes E = Σ E_k cos θ_k V_k, E_k as the extension defines it
//! (`PunctualLight::towards`: inverse square, range window, spot cone),
//! with V_k from one exact shadow ray on the CPU that passes alpha cut-outs
//! as the bake's depth maps do. A delta light casts a hard shadow: the
//! supersample fix-up anti-aliases its edge as it does the environment's
//! (`solve::direct_light_with` gathers both together). A light that lit no
//! point is named in a notice (`dark_light_notices`).
//!
//! A shading normal leaning past its triangle's plane weighs the light by
//! its own cosine, and a ray below the plane is turned to skim it, as the
//! direct pass and the contact fix-up do: light the normal faces is not
//! blocked by the texel's own facet.

use std::sync::atomic::{AtomicBool, Ordering};

use glam::{DVec3, Vec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::contact::skim_above;
use crate::limits::{figure, figure_f32};
use crate::scene::{LightKind, PunctualLight, Scene};
use crate::texelize::Texel;
use crate::trace::Surfaces;

/// Ray origins leave a point this far along its face normal, relative to
/// the scene's size or the point's distance from the origin, whichever is
/// larger: about ten f32 ulps of a texel's position (as the reference's).
const LIFT: f64 = 1e-6;
/// A sub-sample of a texel's footprint lies on its texel's plane, which a
/// curved surface may rise above: its rays leave this many texels off it.
/// The direct pass lifts its receivers as far. A surface facing the same
/// way within that height is its own surface, bent over the plane: the rays
/// leave as far above that. One facing back is another surface (a floor
/// under a ring): they leave half way to it. (From the plane itself, a
/// torus's sub-samples shadowed themselves under their neighbouring facets:
/// dark dots along the terminator of a lamp over it.)
const SUB_SAMPLE_LIFT_TEXELS: f64 = 0.25;
/// Surfaces whose front normals agree this well (cosine) face the same way.
const SAME_WAY_COS: f64 = 0.5;
/// Dark lights named one by one (`dark_light_notices`); a file of thousands
/// gets one notice for the rest, and the bake no search for their reasons.
const MAX_DARK_NOTICES: usize = 8;

/// What the punctual pass did, for the report.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct PunctualStats {
    /// Lights baked (those that give light).
    pub lights: usize,
    /// Shadow rays traced, sub-samples of the supersample fix-up included.
    pub rays: u64,
    pub seconds: f64,
    /// Power the lights delivered to the texels, Σ E·A, RGB (irradiance ×
    /// m²; lm when the lights are in candela and lux). The report's energy
    /// balance counts it as direct light.
    pub power_received: [f64; 3],
    /// The lights (indices into `Scene::lights`) that lit no point: each
    /// gets a notice (`dark_light_notices`), which the report carries.
    #[serde(skip)]
    pub dark: Vec<usize>,
}

/// The scene's punctual lights and its surfaces for their shadow rays.
pub struct Punctual<'a> {
    lights: &'a [PunctualLight],
    /// Only its shadow rays are used: exact, through cut-outs.
    surfaces: &'a Surfaces,
    stats: std::sync::Mutex<PunctualStats>,
    /// Per light: whether it has lit any point yet.
    reached: Vec<AtomicBool>,
}

impl<'a> Punctual<'a> {
    /// The pass for `scene`'s lights, its shadow rays through `occluders`.
    pub fn new(scene: &'a Scene, occluders: &'a Surfaces) -> Punctual<'a> {
        let stats = PunctualStats { lights: scene.lights.len(), ..Default::default() };
        let reached = scene.lights.iter().map(|_| AtomicBool::new(false)).collect();
        Punctual { lights: &scene.lights, surfaces: occluders, stats: std::sync::Mutex::new(stats), reached }
    }

    /// Irradiance E (RGB) at each texel, in order: points on the surface.
    pub fn irradiance(&self, texels: &[Texel]) -> Vec<[f32; 3]> {
        self.gather(texels, 0.0)
    }

    /// Irradiance E at sub-samples of texels' footprints (`supersample`),
    /// texels `texel_size` wide.
    pub fn irradiance_at_sub_samples(&self, samples: &[Texel], texel_size: f64) -> Vec<[f32; 3]> {
        self.gather(samples, SUB_SAMPLE_LIFT_TEXELS * texel_size)
    }

    /// E at each point, its rays leaving `lift` off it (or half way to a
    /// surface nearer in front), and at least `LIFT` relative.
    fn gather(&self, points: &[Texel], lift: f64) -> Vec<[f32; 3]> {
        let start = std::time::Instant::now();
        let irradiance: Vec<[f32; 3]> = points.par_iter().map(|t| self.at(t, lift).as_vec3().to_array()).collect();
        let mut stats = self.stats.lock().unwrap_or_else(|e| e.into_inner());
        stats.rays += (points.len() * self.lights.len()) as u64;
        stats.seconds += start.elapsed().as_secs_f64();
        irradiance
    }

    /// What the pass did, with the power it delivered: Σ E·A over `texels`
    /// of their final punctual irradiance `irradiance`.
    pub fn stats(&self, texels: &[Texel], irradiance: &[[f32; 3]]) -> PunctualStats {
        let mut stats = self.stats.lock().unwrap_or_else(|e| e.into_inner()).clone();
        stats.power_received = texels.iter().zip(irradiance).fold([0.0; 3], |mut sum, (t, e)| {
            for c in 0..3 {
                sum[c] += e[c] as f64 * t.area as f64;
            }
            sum
        });
        stats.dark = (0..self.lights.len()).filter(|&k| !self.reached[k].load(Ordering::Relaxed)).collect();
        stats
    }

    /// E at one texel: each light's irradiance times the cosine of its
    /// shading normal, where one shadow ray reaches the light.
    fn at(&self, t: &Texel, lift: f64) -> DVec3 {
        let n = t.normal().as_dvec3();
        let face = Vec3::from(t.face_normal).as_dvec3().try_normalize().unwrap_or(n);
        let p = t.position().as_dvec3();
        let start = p + face * (LIFT * self.surfaces.scale.max(p.abs().max_element()));
        let room = match (lift > 0.0).then(|| self.surfaces.first_surface(start, face, lift)) {
            None => 0.0,
            Some(None) => lift,
            Some(Some((d, other))) if other.dot(face) > SAME_WAY_COS => d + lift,
            Some(Some((d, _))) => 0.5 * d,
        };
        let origin = start + face * room;
        let mut sum = DVec3::ZERO;
        for (light, reached) in self.lights.iter().zip(&self.reached) {
            let Some(incident) = light.towards(origin) else { continue };
            let cos = n.dot(incident.direction);
            if cos > 0.0 && !self.surfaces.blocked(origin, skim_above(incident.direction, face), incident.distance) {
                sum += incident.irradiance * cos;
                // Loaded first: a store on every lit point would make the
                // threads fight over the flag's cache line.
                if !reached.load(Ordering::Relaxed) {
                    reached.store(true, Ordering::Relaxed);
                }
            }
        }
        sum
    }
}

/// One notice for each light in `dark` (indices into `lights`) that lit
/// none of the points `texels`, the first `MAX_DARK_NOTICES` of them, then
/// one for the rest: a user whose lamp vanished from the bake is told which
/// and, where it is its range, why.
pub fn dark_light_notices(lights: &[PunctualLight], dark: &[usize], texels: &[Texel]) -> Vec<String> {
    let nearest = |p: DVec3| texels.iter().map(|t| t.position().as_dvec3().distance(p)).fold(f64::INFINITY, f64::min);
    let mut notices: Vec<String> = dark
        .iter()
        .take(MAX_DARK_NOTICES)
        .map(|&k| {
            let light = &lights[k];
            let what = format!("{} lights no texel", light.label);
            let reach = light.range.filter(|_| light.kind != LightKind::Directional);
            match reach.map(|range| (range, nearest(light.position))) {
                Some((range, distance)) if range <= distance => format!(
                    "{what}: its range ({} m) ends before the nearest surface, {} m away",
                    figure_f32(range as f32),
                    if distance >= 1e-3 { format!("{distance:.3}") } else { figure(distance) }
                ),
                _ => format!(
                    "{what}: every surface in its reach faces away from it, lies outside its cone or is shadowed"
                ),
            }
        })
        .collect();
    if dark.len() > MAX_DARK_NOTICES {
        notices.push(format!("{} more punctual lights light no texel", dark.len() - MAX_DARK_NOTICES));
    }
    notices
}
