//! An independent CPU reference for the lightmap: a Monte Carlo path tracer
//! in f64 that estimates, at given surface points, the value the GPU bake
//! stores, with a standard error. It shares none of the GPU path's
//! approximations: no light extraction from the environment, no depth maps,
//! no patches — exact ray–triangle intersection against every triangle
//! and the environment map at its full resolution. This module is only the
//! estimator: its rays go through the crate's ray-tracing core
//! (`trace::Surfaces`: the BVH, the casts, the alpha cut-outs), which the
//! solve's CPU fix-ups share and which is tested against brute force over
//! every triangle.
//!
//! # What is estimated
//! For a point p with unit normal n (the receiving side) the lightmap value
//! is the incident irradiance over π, in linear RGB radiance units:
//!
//! ```text
//! L_lm(p) = (1/π) ∫_{n·ω > 0} L_in(p, ω) (n·ω) dω
//! ```
//!
//! where L_in is the environment's radiance when the ray escapes, and
//! `Le(q) + ρ(q)·L_lm(q)` when it meets the front of a surface at q
//! (Lambertian surfaces: radiosity in radiance units); the back of a
//! single-sided surface is black. The point's own emission is not part of
//! L_lm. The front side of a triangle is the side of its face normal (from
//! the winding, mirroring applied) flipped to agree with the interpolated
//! shading normal, or the face normal alone where the mesh has no normals or
//! the interpolated normal is zero; double-sided materials have two fronts.
//! Every triangle occludes from both sides. At a surface hit the hemisphere
//! is that of the front-side face normal (shading normals decide the side
//! only, never the cosine), so energy is conserved exactly.
//!
//! Materials are the bake's: ρ(q) is baseColorFactor RGB × the base colour
//! texture's RGB at q, clamped to [0, 1]; Le(q) is the emission × the emissive
//! texture's RGB, clamped to ≥ 0. A cut-out surface (alpha MASK, or BLEND
//! with a base colour texture: `Material::cutoff`) is absent (from both
//! sides, for every ray) where baseColorFactor alpha × the base texture's
//! alpha < the cut-off; a BLEND without a texture is opaque, as the bake
//! treats it. A texture
//! whose image was not decoded is white with alpha 1, and a UV set the mesh
//! lacks reads as (0, 0), as the bake's vertex buffers fill it.
//!
//! # Conventions
//! World space is glTF's: right-handed, +Y up, metres. The environment is an
//! equirectangular map, row 0 at the zenith: direction d of the map's frame
//! falls in column u = 0.5 + atan2(d.z, d.x)/(2π) and row-from-top
//! t = acos(d.y)/π; it is constant over each pixel (nearest look-up), and row
//! r of H has solid angle (2π/W)(cos θ_top − cos θ_bottom) per pixel. A world
//! direction is d_world = R_y(rotation)·d_map (right-handed, degrees), and
//! the map's radiance is multiplied by the intensity. Non-finite or negative
//! texel channels count as 0.
//!
//! # Method
//! Unidirectional path tracing (Kajiya 1986) with next-event estimation to
//! the environment at every vertex, combined with cosine-weighted
//! hemisphere sampling by multiple importance sampling with the balance
//! heuristic (Veach and Guibas, "Optimally Combining Sampling Techniques for
//! Monte Carlo Rendering", SIGGRAPH 1995; Veach, PhD thesis, 1997, ch. 9).
//! The environment is importance-sampled at full resolution by pixel
//! luminance × solid angle from a marginal/conditional 2-D table, uniformly
//! within the pixel in (φ, cos θ) (Pharr, Jakob and Humphreys, *Physically
//! Based Rendering*, 3rd ed., §13.6.7 and §14.2.4), with the map's mean
//! luminance subtracted from the weights and left to cosine sampling (MIS
//! compensation, Karlík et al., SIGGRAPH Asia 2019), so a small, very bright
//! sun is found by nearly every light sample. Russian roulette (with the hit
//! surface's largest albedo channel as survival probability) starts after
//! three surface interactions; `max_bounces` is a hard cap.
//!
//! Textures are sampled at every hit's barycentrics through the triangle's
//! UV sets and KHR_texture_transform, with the sampler's wrap mode per axis
//! and bilinear filtering at the image's full resolution (`trace::texture`): no
//! mip levels, since the Monte Carlo integral itself averages the texture
//! over what the rays reach. Alpha cut-outs are tested inside the BVH
//! traversal, after a triangle is hit and before it shortens the ray, so
//! closest-hit and shadow rays go on through holes without re-tracing; in
//! scenes without MASK materials the traversal runs with no test at all.
//!
//! Punctual lights (`Scene::lights`, KHR_lights_punctual) are sampled at
//! every vertex too, each with one shadow ray to its position (along its
//! direction for a directional light): a delta light no other technique can
//! find, so it takes no MIS weight. It brings (1/π)·E·cos θ, with E what
//! `PunctualLight::towards` gives.
//!
//! Emissive surfaces are sampled at every vertex too (`emitters.rs`): a
//! point drawn on an emissive triangle, chosen by area × emission, with a
//! shadow ray to it, combined with the cosine-sampled rays that hit an
//! emitter by the balance heuristic. Without it a room lit by one small
//! panel needs many times the paths for the same noise.
//!
//! # Robustness and scale
//! Geometry is converted from f32 to f64 once. Möller–Trumbore runs in f64
//! with a barycentric tolerance of 1e-10 (edges overlap a hair, so nothing
//! leaks between adjacent triangles). Secondary rays leave the hit triangle
//! (which they skip) from a point lifted 1e-9 × `scale` along the front
//! normal, and rays from a query point leave from 1e-6 × max(`scale`, |p|∞)
//! along its face normal (its normal when it has none) — about ten f32 ulps,
//! since query points typically come from f32 computations — where `scale`
//! is the largest absolute vertex coordinate. Both are relative, so a scene
//! at 1 mm and at 10 km gives the same answer.
//!
//! # Determinism
//! Each point's samples are split into fixed chunks of 128; chunk c of
//! point i draws from a PCG32 stream keyed by (seed, i, c), and chunks are
//! combined in order. Results depend on the seed and the inputs only, never
//! on the number of threads.

mod emitters;
mod probes;
mod sampling;
mod trace;

use glam::DVec3;
use rayon::prelude::*;

use crate::environment::EnvironmentMap;
use crate::scene::{PunctualLight, Scene};
use crate::trace::random::Rng;
use crate::trace::rays::Triangle;
use crate::trace::surfaces::{Surfaces, Textures, texture};
use crate::trace::texture::Texture;
use emitters::Emitters;
#[cfg(feature = "internals")]
pub use probes::reference_probes_within;
pub use probes::{Probes, ReferenceCheck, reference_probes};
use sampling::EnvSampler;

/// Samples per independent random stream (see the module's "Determinism").
const CHUNK: u32 = 128;

/// How to estimate.
#[derive(Clone, Debug, PartialEq)]
pub struct ReferenceOptions {
    /// Paths per point (each path carries a light sample at every vertex).
    /// The standard error falls as 1/√samples. 0 is treated as 1.
    pub samples: u32,
    /// Cap on surface interactions after the first: light that reached the
    /// point by more than this many diffuse reflections is dropped (a bias of
    /// about ρ^(max_bounces+1) of the multiply reflected light in a closed
    /// room of albedo ρ). Russian roulette ends most paths long before.
    pub max_bounces: u32,
    /// Seed of every random stream: equal seeds and inputs give bit-identical
    /// results on any number of threads.
    pub seed: u64,
    /// Rotation of the environment about +Y in degrees (d_world = R_y·d_map,
    /// right-handed).
    pub env_rotation_degrees: f32,
    /// Factor on the environment's radiance.
    pub env_intensity: f32,
}

impl Default for ReferenceOptions {
    /// 1024 samples, at most 64 bounces, seed 0, no rotation, intensity 1.
    fn default() -> Self {
        ReferenceOptions { samples: 1024, max_bounces: 64, seed: 0, env_rotation_degrees: 0.0, env_intensity: 1.0 }
    }
}

/// A point at which to estimate the lightmap value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReferencePoint {
    /// Position in the scene's coordinates (world − `Scene::origin`), metres,
    /// on a surface or anywhere in space.
    pub position: [f32; 3],
    /// Unit world normal of the receiving side: light arriving from the
    /// hemisphere it points into is gathered. Need not be exactly unit (it is
    /// normalised); a zero or non-finite normal gives a NaN estimate.
    pub normal: [f32; 3],
    /// Geometric normal of the surface the point lies on, on `normal`'s side
    /// (a lightmap texel's triangle); `None` for a point in space. Light from
    /// behind that plane is inside the surface and never reaches the point,
    /// also where a smooth shading `normal` leans past it: a ray sent there
    /// would hit the point's own triangle from the front and count it as a
    /// lit surface (on a lumpy mesh such self-hits can be most of its
    /// interreflected light).
    pub face_normal: Option<[f32; 3]>,
}

/// A lightmap value with its uncertainty.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    /// L_lm = E/π, linear RGB in the scene's radiance units (those of the
    /// environment map × intensity and of the materials' emission).
    pub lightmap: [f64; 3],
    /// Monte Carlo standard error of `lightmap` per channel: the sample
    /// standard deviation over √samples (infinite with a single sample).
    pub std_error: [f64; 3],
}

/// A point on a scene's surface chosen by [`surface_points`].
#[cfg(feature = "internals")]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePoint {
    /// Index into `Scene::primitives`.
    pub primitive: usize,
    /// Triangle index within the primitive.
    pub triangle: usize,
    /// Barycentric coordinates of the point (weights of the triangle's
    /// second and third vertices).
    pub barycentric: [f32; 2],
    /// The point and its front-side normal (the side the lightmap receives on).
    pub point: ReferencePoint,
}

/// What a surface does with light, in f64. The factors are glTF's, with
/// non-finite channels read as 0; the textures multiply them and the
/// products are clamped as the bake's texelize pass does (albedo to [0, 1],
/// emission to ≥ 0). Whether the surface is there at all (alpha cut-outs)
/// is `trace::Surfaces`' business.
#[derive(Clone, Debug)]
struct SurfaceMaterial {
    /// baseColorFactor RGB.
    base_color: DVec3,
    emission: DVec3,
    /// Only textures whose image was decoded: a missing one is white, as in
    /// the bake (`texture_ref` in gpu::materials).
    base_texture: Option<Texture>,
    emissive_texture: Option<Texture>,
    double_sided: bool,
}

impl SurfaceMaterial {
    /// `m` with its textures' images looked up in `image_slots` (scene image
    /// index → index into the surfaces' images, `None` if not decoded).
    fn new(m: &crate::scene::Material, image_slots: &[Option<usize>]) -> SurfaceMaterial {
        let finite = |v: f32| if v.is_finite() { v as f64 } else { 0.0 };
        SurfaceMaterial {
            base_color: DVec3::new(finite(m.base_color[0]), finite(m.base_color[1]), finite(m.base_color[2])),
            emission: DVec3::from(m.emission.map(finite)),
            base_texture: texture(&m.base_color_texture, image_slots),
            emissive_texture: texture(&m.emissive_texture, image_slots),
            double_sided: m.double_sided,
        }
    }
}

/// Albedo from a base colour factor × texture: non-finite channels 0, clamped to [0, 1].
fn clamp_albedo(c: DVec3) -> DVec3 {
    DVec3::select(c.is_finite_mask(), c, DVec3::ZERO).clamp(DVec3::ZERO, DVec3::ONE)
}

/// Emission from a factor × texture: non-finite channels 0, negative ones 0.
fn clamp_emission(c: DVec3) -> DVec3 {
    DVec3::select(c.is_finite_mask(), c, DVec3::ZERO).max(DVec3::ZERO)
}

/// What a surface does at one point: its albedo and emitted radiance.
#[derive(Clone, Copy, Debug)]
struct SurfaceSample {
    albedo: DVec3,
    emission: DVec3,
}

/// A scene prepared for reference estimates: its surfaces as rays meet them
/// (`trace::Surfaces`, with every texture and vertex colour kept), what its
/// materials do with light, and the environment's sampling tables. Build
/// once, then call [`Reference::estimate`] as often as needed.
pub struct Reference {
    surfaces: Surfaces,
    /// Per material of the surfaces' table.
    materials: Vec<SurfaceMaterial>,
    env: Option<EnvSampler>,
    /// The emissive triangles, sampled at every vertex.
    emitters: Emitters,
    /// The scene's punctual lights, sampled at every vertex.
    lights: Vec<PunctualLight>,
    /// Lift of secondary ray origins along the front normal, metres.
    surface_offset: f64,
    samples: u32,
    max_bounces: u32,
    seed: u64,
}

impl Reference {
    /// Prepares `scene` (every triangle of every primitive, its material, its
    /// normals, the textures its material samples and their UV sets) and, if
    /// given, `environment` under the options' rotation and intensity.
    /// Without an environment escaping rays see black.
    ///
    /// # Panics
    /// If the environment's texel count is not width × height.
    pub fn new(scene: &Scene, environment: Option<&EnvironmentMap>, options: &ReferenceOptions) -> Reference {
        let surfaces = Surfaces::build(scene, Textures::All);
        let default_material = crate::scene::Material::default();
        let materials: Vec<SurfaceMaterial> = scene
            .materials
            .iter()
            .chain(std::iter::once(&default_material))
            .map(|m| SurfaceMaterial::new(m, &surfaces.image_slots))
            .collect();
        let env = environment
            .filter(|m| m.width > 0 && m.height > 0)
            .map(|m| EnvSampler::new(m, options.env_rotation_degrees as f64, options.env_intensity as f64));
        let emitters = Emitters::new(surfaces.triangles(), |t| clamp_emission(materials[t.material as usize].emission));
        Reference {
            emitters,
            materials,
            env,
            lights: scene.lights.clone(),
            surface_offset: 1e-9 * surfaces.scale,
            surfaces,
            samples: options.samples.max(1),
            max_bounces: options.max_bounces,
            seed: options.seed,
        }
    }

    /// Number of triangles traced against (degenerate ones are left out).
    #[cfg(feature = "internals")]
    pub fn triangle_count(&self) -> usize {
        self.surfaces.triangles().len()
    }

    /// The largest absolute vertex coordinate (metres) that ray offsets are
    /// relative to.
    #[cfg(feature = "internals")]
    pub fn scale(&self) -> f64 {
        self.surfaces.scale
    }

    /// The albedo and emission of `tri` at barycentrics (u, v).
    fn surface_at(&self, tri: &Triangle, u: f64, v: f64) -> SurfaceSample {
        let m = &self.materials[tri.material as usize];
        let Some(&[ca, cb, cc]) = self.surfaces.corner_colors(tri) else {
            return SurfaceSample { albedo: clamp_albedo(m.base_color), emission: clamp_emission(m.emission) };
        };
        let uv = self.surfaces.texcoords_at(tri, u, v);
        let images = &self.surfaces.images;
        let rgb = |t: &Option<Texture>| t.as_ref().map_or(DVec3::ONE, |t| t.sample(images, uv).truncate());
        // glTF: base colour = factor · texture · COLOR_0.
        let tint = ca * (1.0 - u - v) + cb * u + cc * v;
        SurfaceSample {
            albedo: clamp_albedo(m.base_color * rgb(&m.base_texture) * tint),
            emission: clamp_emission(m.emission * rgb(&m.emissive_texture)),
        }
    }

    /// Estimates L_lm at every point (same order), in parallel over points
    /// and chunks of samples on rayon's current pool. A point with a
    /// non-finite position or a zero or non-finite normal gets NaN values.
    pub fn estimate(&self, points: &[ReferencePoint]) -> Vec<Estimate> {
        let chunks = self.samples.div_ceil(CHUNK) as usize;
        let stats: Vec<Stats> = (0..points.len() * chunks)
            .into_par_iter()
            .map(|task| {
                let (i, c) = (task / chunks, task % chunks);
                let first = c as u32 * CHUNK;
                let count = CHUNK.min(self.samples - first);
                self.chunk(&points[i], i as u64, c as u64, count)
            })
            .collect();
        stats
            .chunks(chunks)
            .map(|per_point| {
                let total = per_point.iter().fold(Stats::default(), |acc, s| acc.merge(s));
                total.estimate()
            })
            .collect()
    }

    /// `count` paths of stream (point, chunk); marked invalid for a bad point.
    fn chunk(&self, point: &ReferencePoint, index: u64, chunk: u64, count: u32) -> Stats {
        let p = DVec3::from(point.position.map(|v| v as f64));
        let n = DVec3::from(point.normal.map(|v| v as f64));
        let n = n.normalize_or_zero();
        if !p.is_finite() || n == DVec3::ZERO || !n.is_finite() {
            return Stats::invalid();
        }
        // A usable face normal on the receiving side, else none.
        let face = point
            .face_normal
            .map(|f| DVec3::from(f.map(|v| v as f64)).normalize_or_zero())
            .filter(|f| f.is_finite() && f.dot(n) > 0.0);
        let offset = 1e-6 * self.surfaces.scale.max(p.abs().max_element());
        // Lifted off its own plane, so that no ray above it meets it.
        let origin = p + face.unwrap_or(n) * offset;
        let mut rng = Rng::new(&[self.seed, index, chunk]);
        let mut stats = Stats::default();
        for _ in 0..count {
            stats.push(self.sample_path(origin, n, face, &mut rng));
        }
        stats
    }
}

/// Running mean and sum of squared deviations (Welford; merged with Chan et
/// al.'s pairwise formula), per channel.
#[derive(Clone, Copy, Debug, Default)]
struct Stats {
    n: f64,
    mean: DVec3,
    m2: DVec3,
    invalid: bool,
}

impl Stats {
    fn invalid() -> Stats {
        Stats { invalid: true, ..Default::default() }
    }

    fn push(&mut self, x: DVec3) {
        self.n += 1.0;
        let delta = x - self.mean;
        self.mean += delta / self.n;
        self.m2 += delta * (x - self.mean);
    }

    fn merge(self, other: &Stats) -> Stats {
        if self.n == 0.0 {
            return Stats { invalid: self.invalid || other.invalid, ..*other };
        }
        let n = self.n + other.n;
        let delta = other.mean - self.mean;
        Stats {
            n,
            mean: self.mean + delta * (other.n / n),
            m2: self.m2 + other.m2 + delta * delta * (self.n * other.n / n),
            invalid: self.invalid || other.invalid,
        }
    }

    fn estimate(&self) -> Estimate {
        if self.invalid || self.n == 0.0 {
            return Estimate { lightmap: [f64::NAN; 3], std_error: [f64::NAN; 3] };
        }
        let std_error = if self.n > 1.0 {
            (self.m2.max(DVec3::ZERO) / ((self.n - 1.0) * self.n)).to_array().map(f64::sqrt)
        } else {
            [f64::INFINITY; 3]
        };
        Estimate { lightmap: self.mean.to_array(), std_error }
    }
}

/// `count` points spread over the surface of `scene`, area-weighted and
/// stratified (point k falls in the k-th of `count` equal slices of the total
/// area, in primitive and triangle order), uniformly within its triangle,
/// each with its front-side normal per the module's convention.
/// Deterministic for a `seed`. Degenerate triangles get no points; a scene
/// without area gives none.
#[cfg(feature = "internals")]
pub fn surface_points(scene: &Scene, count: usize, seed: u64) -> Vec<SurfacePoint> {
    let triangles = crate::trace::surfaces::scene_triangles(scene);
    let mut cumulative = Vec::with_capacity(triangles.len() + 1);
    let mut total = 0.0f64;
    cumulative.push(0.0);
    for (_, _, t) in &triangles {
        total += 0.5 * t.e1.cross(t.e2).length();
        cumulative.push(total);
    }
    if count == 0 || !total.is_finite() || total <= 0.0 {
        return Vec::new();
    }
    let mut rng = Rng::new(&[seed, u64::MAX]);
    (0..count)
        .map(|k| {
            let x = (k as f64 + rng.next_f64()) / count as f64 * total;
            let i = (cumulative.partition_point(|&c| c <= x).max(1) - 1).min(triangles.len() - 1);
            let (primitive, triangle, tri) = &triangles[i];
            let su = rng.next_f64().sqrt();
            let r2 = rng.next_f64();
            let (u, v) = (su * (1.0 - r2), su * r2);
            let position = tri.point(u, v);
            let normal = tri.front_normal(u, v);
            SurfacePoint {
                primitive: *primitive,
                triangle: *triangle,
                barycentric: [u as f32, v as f32],
                point: ReferencePoint {
                    position: position.to_array().map(|c| c as f32),
                    normal: normal.to_array().map(|c| c as f32),
                    face_normal: Some(normal.to_array().map(|c| c as f32)),
                },
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn albedo_and_emission_are_clamped_after_the_texture_multiplies() {
        // A factor above 1 times a dark texel is not clipped to the texel.
        let albedo = clamp_albedo(DVec3::new(2.0, 1.5, 0.5) * DVec3::new(0.25, 1.0, 1.0));
        assert_eq!(albedo, DVec3::new(0.5, 1.0, 0.5));
        assert_eq!(clamp_albedo(DVec3::new(f64::NAN, -1.0, f64::INFINITY)), DVec3::ZERO);
        assert_eq!(clamp_emission(DVec3::new(f64::NAN, -1.0, 7.0)), DVec3::new(0.0, 0.0, 7.0));
    }
}
