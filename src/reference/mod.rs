//! An independent CPU reference for the lightmap: a Monte Carlo path tracer
//! in f64 that estimates, at given surface points, the value the GPU bake
//! stores, with a standard error. It shares none of the GPU path's
//! approximations: no light extraction from the environment, no depth maps,
//! no patches — exact ray–triangle intersection against every triangle
//! (through a BVH) and the environment map at its full resolution.
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
//! Emissive surfaces are only found when a cosine-sampled ray happens to hit
//! them (there is no list of emissive triangles to sample). This is unbiased
//! but the variance grows as emitters get smaller and brighter: an emitter of
//! solid angle Ω seen with radiance Le adds a per-sample variance of about
//! Le²·(Ω/π)(1 − Ω/π). For the large emitters lightmapped scenes use this is
//! fine; for tiny bright ones raise `samples` and watch `std_error`.
//!
//! # Robustness and scale
//! Geometry is converted from f32 to f64 once. Möller–Trumbore runs in f64
//! with a barycentric tolerance of 1e-10 (edges overlap a hair, so nothing
//! leaks between adjacent triangles). Secondary rays leave the hit triangle
//! (which they skip) from a point lifted 1e-9 × `scale` along the front
//! normal, and rays from a query point leave from 1e-6 × max(`scale`, |p|∞)
//! along its normal — about ten f32 ulps, since query points typically come
//! from f32 computations — where `scale` is the largest absolute vertex
//! coordinate. Both are relative, so a scene at 1 mm and at 10 km gives the
//! same answer.
//!
//! # Determinism
//! Each point's samples are split into fixed chunks of 128; chunk c of
//! point i draws from a PCG32 stream keyed by (seed, i, c), and chunks are
//! combined in order. Results depend on the seed and the inputs only, never
//! on the number of threads.

mod bvh;
mod sampling;
mod trace;

use glam::DVec3;
use rayon::prelude::*;

use crate::environment::EnvironmentMap;
use crate::scene::Scene;
use bvh::{Bvh, Triangle};
use sampling::{EnvSampler, Rng};

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

/// What a surface does with light, in f64 (albedo clamped to [0, 1],
/// emission to non-negative finite values).
#[derive(Clone, Debug)]
struct SurfaceMaterial {
    albedo: DVec3,
    emission: DVec3,
    double_sided: bool,
}

impl SurfaceMaterial {
    fn new(m: &crate::scene::Material) -> SurfaceMaterial {
        let clean = |v: f32, hi: f64| {
            if v.is_finite() { (v as f64).clamp(0.0, hi) } else { 0.0 }
        };
        SurfaceMaterial {
            albedo: DVec3::new(clean(m.base_color[0], 1.0), clean(m.base_color[1], 1.0), clean(m.base_color[2], 1.0)),
            emission: DVec3::new(
                clean(m.emission[0], f64::MAX),
                clean(m.emission[1], f64::MAX),
                clean(m.emission[2], f64::MAX),
            ),
            double_sided: m.double_sided,
        }
    }
}

/// A scene prepared for reference estimates: a BVH over all its triangles
/// (f64, per-triangle material and normals) and the environment's sampling
/// tables. Build once, then call [`Reference::estimate`] as often as needed.
pub struct Reference {
    bvh: Bvh,
    materials: Vec<SurfaceMaterial>,
    env: Option<EnvSampler>,
    /// Largest absolute vertex coordinate, metres (1 for an empty scene).
    scale: f64,
    /// Lift of secondary ray origins along the front normal, metres.
    surface_offset: f64,
    samples: u32,
    max_bounces: u32,
    seed: u64,
}

/// The triangles of `scene` in f64 with their front-side data, skipping
/// degenerate or non-finite ones; material indices refer to `scene.materials`
/// with `scene.materials.len()` for glTF's default material.
fn scene_triangles(scene: &Scene) -> Vec<(usize, usize, Triangle)> {
    let default_material = scene.materials.len() as u32;
    let mut out = Vec::with_capacity(scene.triangle_count());
    for (pi, p) in scene.primitives.iter().enumerate() {
        let material = p.material.filter(|&m| m < scene.materials.len()).map_or(default_material, |m| m as u32);
        let normals = p.normals.as_ref().filter(|n| n.len() == p.positions.len());
        let vec = |v: [f32; 3]| DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64);
        for t in 0..p.triangle_count() {
            let idx = [0, 1, 2].map(|k| p.indices[3 * t + k] as usize);
            if idx.iter().any(|&i| i >= p.positions.len()) {
                continue;
            }
            let [a, b, c] = idx.map(|i| vec(p.positions[i]));
            let (e1, e2) = (b - a, c - a);
            let cross = e1.cross(e2);
            let len = cross.length();
            if !(len > 0.0 && len.is_finite() && a.is_finite()) {
                continue;
            }
            let face = if p.mirrored { -cross / len } else { cross / len };
            let normals = normals.map(|n| {
                idx.map(|i| {
                    let v = vec(n[i]);
                    if v.is_finite() { v } else { DVec3::ZERO }
                })
            });
            out.push((pi, t, Triangle { v0: a, e1, e2, face, normals, material }));
        }
    }
    out
}

impl Reference {
    /// Prepares `scene` (every triangle of every primitive, its material, its
    /// normals) and, if given, `environment` under the options' rotation and
    /// intensity. Without an environment escaping rays see black.
    ///
    /// # Panics
    /// If the environment's texel count is not width × height.
    pub fn new(scene: &Scene, environment: Option<&EnvironmentMap>, options: &ReferenceOptions) -> Reference {
        let mut materials: Vec<SurfaceMaterial> = scene.materials.iter().map(SurfaceMaterial::new).collect();
        materials.push(SurfaceMaterial::new(&crate::scene::Material::default()));
        let triangles: Vec<Triangle> = scene_triangles(scene).into_iter().map(|(_, _, t)| t).collect();
        let scale = triangles
            .iter()
            .flat_map(|t| [t.v0, t.v0 + t.e1, t.v0 + t.e2])
            .map(|v| v.abs().max_element())
            .fold(0.0f64, f64::max);
        let scale = if scale > 0.0 && scale.is_finite() { scale } else { 1.0 };
        let env = environment
            .filter(|m| m.width > 0 && m.height > 0)
            .map(|m| EnvSampler::new(m, options.env_rotation_degrees as f64, options.env_intensity as f64));
        Reference {
            bvh: Bvh::new(triangles),
            materials,
            env,
            scale,
            surface_offset: 1e-9 * scale,
            samples: options.samples.max(1),
            max_bounces: options.max_bounces,
            seed: options.seed,
        }
    }

    /// Number of triangles traced against (degenerate ones are left out).
    pub fn triangle_count(&self) -> usize {
        self.bvh.triangles.len()
    }

    /// The largest absolute vertex coordinate (metres) that ray offsets are
    /// relative to.
    pub fn scale(&self) -> f64 {
        self.scale
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
        let offset = 1e-6 * self.scale.max(p.abs().max_element());
        let origin = p + n * offset;
        let mut rng = Rng::new(&[self.seed, index, chunk]);
        let mut stats = Stats::default();
        for _ in 0..count {
            stats.push(self.sample_path(origin, n, &mut rng));
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

/// The scene's triangles for visibility tests outside the reference: the
/// solve's supersample fix-up asks whether a segment along a surface
/// crosses other geometry.
pub(crate) struct Occluders(Bvh);

impl Occluders {
    pub(crate) fn new(scene: &Scene) -> Occluders {
        Occluders(Bvh::new(scene_triangles(scene).into_iter().map(|(_, _, t)| t).collect()))
    }

    /// Whether any triangle crosses the segment from `a` to `b` (ends excluded).
    pub(crate) fn blocks(&self, a: DVec3, b: DVec3) -> bool {
        self.0.occluded(a, b - a, 1.0, None)
    }
}

/// `count` points spread over the surface of `scene`, area-weighted and
/// stratified (point k falls in the k-th of `count` equal slices of the total
/// area, in primitive and triangle order), uniformly within its triangle,
/// each with its front-side normal per the module's convention.
/// Deterministic for a `seed`. Degenerate triangles get no points; a scene
/// without area gives none.
pub fn surface_points(scene: &Scene, count: usize, seed: u64) -> Vec<SurfacePoint> {
    let triangles = scene_triangles(scene);
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
                },
            }
        })
        .collect()
}
