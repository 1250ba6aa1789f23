//! Unwrap stage: world-space triangle meshes in, lightmap UVs (glTF `TEXCOORD_1`) out.
//!
//! All meshes of a scene share **one** lightmap page of at most
//! [`UnwrapOptions::max_atlas_size`]² texels. Two interchangeable backends produce it:
//! [`Backend::Xatlas`] (the 2019 C++ xatlas compiled by the `xatlas-rs` crate, driven through
//! [`xatlas_ffi`]) and [`Backend::Uvunwrap`] (the pure-Rust `uvunwrap` crate).
//!
//! Conventions shared by every item of this module:
//! - positions are world space, in metres; a density is in texels per metre (texels/m);
//! - UVs are normalized page coordinates in `[0, 1]`, `(0, 0)` being the corner of texel row 0,
//!   column 0 (the top-left of the image, glTF's convention): texel `(x, y)` of a `W × H` page
//!   covers `uv ∈ [x/W, (x+1)/W] × [y/H, (y+1)/H]`;
//! - with padding `p`, texels touched by different charts are at least `2p` empty texels apart
//!   (Chebyshev distance, so diagonal neighbours count) and texels touched by any chart are at
//!   least `p` texels from the page border;
//! - the output is deterministic: the same input and options give bit-identical output.
//!
//! Every result is verified before it is returned ([`inspect`]: no texel shared by two charts,
//! no chart folding over itself, no mirrored triangle, real padding; about 30 ms for 20k
//! triangles on a 1024² page). Should a backend break these promises on some input, [`run`]
//! falls back to the other backend and says so in [`Atlas::notices`].
//!
//! [`from_existing`] makes the same [`Atlas`] from UVs the input already has (`--keep-uv1`),
//! when they are inside the page and do not overlap.

mod check;
mod existing;
mod uvunwrap;
mod xatlas;
pub mod xatlas_ffi;

pub use check::inspect;
pub use existing::from_existing;

use std::fmt;
use std::str::FromStr;

/// One triangle mesh to unwrap.
#[derive(Clone, Copy, Debug)]
pub struct MeshInput<'a> {
    /// World-space vertex positions, in metres. Must be finite.
    pub positions: &'a [[f32; 3]],
    /// Triangle list: three indices into `positions` per triangle. Its length must be a multiple
    /// of 3. Degenerate, duplicate and needle triangles are allowed.
    pub indices: &'a [u32],
}

impl<'a> MeshInput<'a> {
    /// A mesh from world-space positions (metres) and a triangle list.
    #[cfg(feature = "internals")]
    pub fn new(positions: &'a [[f32; 3]], indices: &'a [u32]) -> Self {
        MeshInput { positions, indices }
    }
}

/// The unwrapper behind [`run`].
///
/// The default is [`Backend::Uvunwrap`], chosen on the measurements of
/// `cargo run --release --example unwrap_compare` (sphere, cube, torus, 10 m ground quad, sphere
/// on ground, and a 10k-vertex / 20k-triangle statue-like mesh; automatic density on a 1024²
/// page, padding 2):
/// - both are overlap-free and correctly padded on every scene (xatlas once this module
///   corrects its one-sided padding), so validity doesn't decide;
/// - texel density: uvunwrap gives every chart exactly the requested density (per-chart area
///   error 1.000, area-weighted mean triangle distortion 1.00–1.08), while the 2019 xatlas gives
///   curved charts 1.3–1.6× (statue: 2.1×) the texel area they should get (it scales charts by
///   surface/parametric area instead of its square root), mean triangle distortion up to 1.57;
/// - the same page holds a higher density with uvunwrap (sphere 231 vs 182 texels/m, torus 205
///   vs 182, statue 484 vs 352; xatlas' figures are nominal, its curved charts being inflated);
/// - uvunwrap is 10–60× faster (statue: 0.26 s vs 14.6 s, where xatlas' chart growing alone
///   takes ~10 s), pure Rust, deterministic by design, and re-solves invalid charts itself.
///
/// xatlas makes fewer, larger charts on organic meshes (statue: 8 vs 19), hence fewer seams;
/// it remains available for comparison.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Backend {
    /// xatlas (2019, C++ via `xatlas-rs`'s static library): charts, LSCM, random bitmap packing.
    Xatlas,
    /// uvunwrap (pure Rust): charts, LSCM + ARAP, shape packing.
    #[default]
    Uvunwrap,
}

impl Backend {
    /// Both backends, in a fixed order.
    pub const ALL: [Backend; 2] = [Backend::Xatlas, Backend::Uvunwrap];

    /// The lowercase name accepted by [`FromStr`] and printed by [`Display`](fmt::Display).
    pub fn name(self) -> &'static str {
        match self {
            Backend::Xatlas => "xatlas",
            Backend::Uvunwrap => "uvunwrap",
        }
    }
}

impl fmt::Display for Backend {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A backend name that is neither `xatlas` nor `uvunwrap`.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown unwrap backend {0:?} (expected \"xatlas\" or \"uvunwrap\")")]
pub struct ParseBackendError(pub String);

impl FromStr for Backend {
    type Err = ParseBackendError;

    /// `"xatlas"` or `"uvunwrap"`, case-insensitive, surrounding whitespace ignored.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let t = s.trim();
        Backend::ALL
            .into_iter()
            .find(|b| b.name().eq_ignore_ascii_case(t))
            .ok_or_else(|| ParseBackendError(s.to_string()))
    }
}

/// How to unwrap.
#[derive(Clone, Debug, PartialEq)]
pub struct UnwrapOptions {
    /// Which unwrapper to use.
    pub backend: Backend,
    /// Texel density in texels per metre. `None`: automatic, the highest density at which
    /// everything fits one `max_atlas_size²` page. A fixed density that would not fit is lowered
    /// until it does, with a notice in [`Atlas::notices`]. Must be finite and `> 0`.
    pub texels_per_unit: Option<f32>,
    /// Cap on the page width and height, in texels (default 1024). Must exceed `2 · padding`.
    pub max_atlas_size: u32,
    /// Empty texels between charts and around the page edge, in texels (default 2): texels of
    /// different charts are at least `2 · padding` apart, and at least `padding` from the border.
    pub padding: u32,
}

impl Default for UnwrapOptions {
    fn default() -> Self {
        UnwrapOptions { backend: Backend::default(), texels_per_unit: None, max_atlas_size: 1024, padding: 2 }
    }
}

/// The unwrapped scene: one lightmap page and the meshes' new vertices.
#[derive(Clone, Debug, PartialEq)]
pub struct Atlas {
    /// Page width in texels, `<= max_atlas_size`. 0 only for an empty atlas (nothing with
    /// surface area to unwrap).
    pub width: u32,
    /// Page height in texels, `<= max_atlas_size`. 0 only for an empty atlas.
    pub height: u32,
    /// The texel density actually used, in texels per metre (0 for an empty atlas). With
    /// [`Backend::Xatlas`] it is nominal: xatlas gives curved charts more texel area than this
    /// (by their surface / parametric area ratio, typically 1.1–1.6×).
    pub texels_per_unit: f32,
    /// Number of charts over all meshes; chart ids are `0..chart_count`.
    pub chart_count: u32,
    /// Fraction of the page covered by charts: total UV area of all charted triangles over the
    /// page area, in `[0, 1]`.
    pub utilization: f32,
    /// One per input mesh, in input order.
    pub meshes: Vec<UnwrappedMesh>,
    /// Human-readable remarks, e.g. a lowered density or a backend quirk worked around.
    pub notices: Vec<String>,
}

impl Atlas {
    /// True if no chart was produced (no input triangle has surface area).
    pub fn is_empty(&self) -> bool {
        self.chart_count == 0
    }
}

/// One mesh with lightmap UVs.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct UnwrappedMesh {
    /// New vertices; vertices on chart seams are duplicated. Input vertices used by no triangle
    /// are dropped.
    pub vertices: Vec<AtlasVertex>,
    /// The input's triangles, in the same order, indexing `vertices`.
    pub indices: Vec<u32>,
}

/// One output vertex.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AtlasVertex {
    /// Index of the input vertex (in [`MeshInput::positions`]) this vertex was made from: copy
    /// its other attributes from there.
    pub xref: u32,
    /// Normalized page coordinates in `[0, 1]` (see the module conventions).
    pub uv: [f32; 2],
    /// Global chart id across all meshes (`< chart_count`), or `u32::MAX` for a vertex that
    /// belongs to no chart: one used only by ignored (zero-area) triangles, whose corners all
    /// collapse onto one UV so that they cover no texel.
    pub chart: u32,
}

/// Errors from [`run`] for invalid input.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum UnwrapError {
    /// A mesh's index count is not a multiple of 3.
    #[error("mesh {mesh}: index count {count} is not a multiple of 3")]
    InvalidIndexCount { mesh: usize, count: usize },
    /// An index refers to a vertex that doesn't exist.
    #[error("mesh {mesh}: index {index} out of range ({vertex_count} vertices)")]
    IndexOutOfRange { mesh: usize, index: u32, vertex_count: usize },
    /// A position is NaN or infinite.
    #[error("mesh {mesh}: vertex {vertex} has a non-finite position")]
    NonFinitePosition { mesh: usize, vertex: usize },
    /// A mesh has more vertices or indices than the backends can address with `u32`.
    #[error("mesh {mesh} is too large ({count} indices or vertices)")]
    TooLarge { mesh: usize, count: usize },
    /// An option is out of range.
    #[error("invalid unwrap option {option}: {requirement}")]
    InvalidOption { option: &'static str, requirement: String },
    /// The charts cannot share one page at any density: too many charts for the padding.
    #[error(
        "{charts} charts do not fit one {size}x{size} page with padding {padding} at any density; \
         raise max_atlas_size or lower padding"
    )]
    DoesNotFit { charts: u32, size: u32, padding: u32 },
}

/// Unwraps `meshes` onto one lightmap page (see the module documentation for conventions).
///
/// Input meshes are world space (metres); output UVs are normalized page coordinates. Meshes
/// without triangles give empty [`UnwrappedMesh`]es; if nothing has surface area the atlas is
/// empty (`width == height == 0`, `chart_count == 0`, every vertex at uv `(0, 0)` with chart
/// `u32::MAX`) and a notice says so.
///
/// The result is verified (see the module documentation); if the chosen backend's atlas breaks
/// the promises, the other backend's is returned instead, with a notice.
///
/// Errors: invalid input ([`UnwrapError`]), or charts that cannot fit one page.
pub fn run(meshes: &[MeshInput], options: &UnwrapOptions) -> anyhow::Result<Atlas> {
    validate(meshes, options)?;
    let unwrap = |backend| -> anyhow::Result<Atlas> {
        let mut atlas = match backend {
            Backend::Xatlas => xatlas::unwrap(meshes, options)?,
            Backend::Uvunwrap => uvunwrap::unwrap(meshes, options)?,
        };
        finish(meshes, &mut atlas);
        Ok(atlas)
    };
    let mut atlas = unwrap(options.backend)?;
    // Verify the promises (no overlap, no flip, real padding) on every result: a backend that
    // breaks them on some input falls back to the other one, with a notice.
    if let Some(problem) = problems(meshes, &atlas, options.padding) {
        let other = match options.backend {
            Backend::Xatlas => Backend::Uvunwrap,
            Backend::Uvunwrap => Backend::Xatlas,
        };
        let note = format!("{} produced an invalid atlas ({problem})", options.backend);
        match unwrap(other) {
            Ok(mut alt) if problems(meshes, &alt, options.padding).is_none() => {
                alt.notices.insert(0, format!("{note}; used {other} instead"));
                atlas = alt;
            }
            // The other backend does no better: keep the first result, flagged.
            _ => atlas.notices.push(note),
        }
    }
    Ok(atlas)
}

/// What is wrong with `atlas`, if anything (see [`Quality::is_valid`]).
fn problems(meshes: &[MeshInput], atlas: &Atlas, padding: u32) -> Option<String> {
    if atlas.is_empty() {
        return None;
    }
    let q = inspect(meshes, atlas, 2 * padding + 1);
    if q.is_valid(padding) {
        return None;
    }
    Some(format!(
        "{} texels shared by two charts, {} texel centres covered twice within a chart, \
         {} mirrored triangles, {} malformed triangles, closest charts {:?} texels apart, \
         {:?} texels from the border",
        q.overlap_texels,
        q.self_overlap_texels,
        q.flipped_triangles,
        q.malformed_triangles,
        q.min_chart_gap,
        q.min_border_gap
    ))
}

/// Checks the input against the documented requirements.
fn validate(meshes: &[MeshInput], options: &UnwrapOptions) -> Result<(), UnwrapError> {
    if let Some(t) = options.texels_per_unit
        && !(t.is_finite() && t > 0.0)
    {
        return Err(UnwrapError::InvalidOption {
            option: "texels_per_unit",
            requirement: format!("must be finite and > 0, got {t}"),
        });
    }
    if options.max_atlas_size <= options.padding.saturating_mul(2) {
        return Err(UnwrapError::InvalidOption {
            option: "max_atlas_size",
            requirement: format!(
                "must exceed 2 x padding ({}), got {}",
                2 * u64::from(options.padding),
                options.max_atlas_size
            ),
        });
    }
    // Pages beyond 32K² texels are unreasonable for a lightmap and risk overflow in the backends.
    const MAX_SIZE: u32 = 1 << 15;
    if options.max_atlas_size > MAX_SIZE {
        return Err(UnwrapError::InvalidOption {
            option: "max_atlas_size",
            requirement: format!("must be at most {MAX_SIZE}, got {}", options.max_atlas_size),
        });
    }
    for (mi, m) in meshes.iter().enumerate() {
        let count = m.indices.len().max(m.positions.len());
        if count >= u32::MAX as usize / 2 {
            return Err(UnwrapError::TooLarge { mesh: mi, count });
        }
        if !m.indices.len().is_multiple_of(3) {
            return Err(UnwrapError::InvalidIndexCount { mesh: mi, count: m.indices.len() });
        }
        if let Some(&index) = m.indices.iter().find(|&&i| i as usize >= m.positions.len()) {
            return Err(UnwrapError::IndexOutOfRange { mesh: mi, index, vertex_count: m.positions.len() });
        }
        if let Some(vertex) = m.positions.iter().position(|p| p.iter().any(|c| !c.is_finite())) {
            return Err(UnwrapError::NonFinitePosition { mesh: mi, vertex });
        }
    }
    Ok(())
}

/// Common post-processing: utilization recomputed the same way for both backends, UVs clamped
/// to `[0, 1]`, and a notice for an empty atlas.
fn finish(meshes: &[MeshInput], atlas: &mut Atlas) {
    let mut area = 0.0f64;
    for out in &mut atlas.meshes {
        for v in &mut out.vertices {
            v.uv = v.uv.map(|c| if c.is_finite() { c.clamp(0.0, 1.0) } else { 0.0 });
        }
        for t in out.indices.chunks_exact(3) {
            let [a, b, c] = [0, 1, 2].map(|k| out.vertices[t[k] as usize]);
            if a.chart == u32::MAX || a.chart != b.chart || a.chart != c.chart {
                continue;
            }
            area += check::uv_area(a.uv, b.uv, c.uv).abs();
        }
    }
    atlas.utilization = if atlas.width > 0 && atlas.height > 0 { area.min(1.0) as f32 } else { 0.0 };
    if atlas.chart_count == 0 {
        let triangles: usize = meshes.iter().map(|m| m.indices.len() / 3).sum();
        atlas.notices.push(format!("empty atlas: none of the {triangles} input triangles has surface area"));
    }
}

/// The atlas for input without surface area: no page, no chart, every triangle's corners on
/// uv `(0, 0)` (one output vertex per distinct input vertex, in first-use order).
pub(crate) fn empty_atlas(meshes: &[MeshInput]) -> Atlas {
    let meshes = meshes
        .iter()
        .map(|m| {
            let mut map = std::collections::HashMap::new();
            let mut vertices = Vec::new();
            let indices = m
                .indices
                .iter()
                .map(|&i| {
                    *map.entry(i).or_insert_with(|| {
                        vertices.push(AtlasVertex { xref: i, uv: [0.0, 0.0], chart: u32::MAX });
                        (vertices.len() - 1) as u32
                    })
                })
                .collect();
            UnwrappedMesh { vertices, indices }
        })
        .collect();
    Atlas { width: 0, height: 0, texels_per_unit: 0.0, chart_count: 0, utilization: 0.0, meshes, notices: Vec::new() }
}

/// World-space area of a triangle, in m².
pub(crate) fn triangle_area(p: [[f32; 3]; 3]) -> f64 {
    let [a, b, c] = p.map(|v| v.map(f64::from));
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let w = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    let n = [u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]];
    0.5 * (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt()
}

/// Total world-space surface area of all meshes, in m².
pub(crate) fn total_area(meshes: &[MeshInput]) -> f64 {
    meshes
        .iter()
        .flat_map(|m| m.indices.chunks_exact(3).map(|t| triangle_area([0, 1, 2].map(|k| m.positions[t[k] as usize]))))
        .sum()
}

/// Formats a density for notices: 3 significant digits.
pub(crate) fn fmt_density(t: f64) -> String {
    if t >= 100.0 {
        format!("{t:.0}")
    } else if t >= 10.0 {
        format!("{t:.1}")
    } else {
        format!("{t:.3}")
    }
}

/// The outcome of one packing trial at a given density.
pub(crate) struct Trial<T> {
    /// Page width and height the packing needs, in texels (padding included).
    pub width: u32,
    pub height: u32,
    /// Backend-specific packing result.
    pub result: T,
}

/// The densest packing found that fits one `max_size²` page, with its density.
pub(crate) struct Fitted<T> {
    pub density: f64,
    pub trial: Trial<T>,
    /// How many packings were tried.
    pub trials: u32,
}

/// Finds the highest density (texels per unit of the backend's space) whose packing fits one
/// `max_size × max_size` page, re-packing only.
///
/// `pack(density)` packs at `density` (one growing page). With `requested`, the density never
/// exceeds it and it is returned as is if it fits; otherwise the search starts at `estimate`.
/// Page sides scale about linearly with the density, which the search exploits (secant steps
/// towards the page edge), bisecting geometrically where packing is not monotone. It stops when
/// the bracket is within 1% or after a bounded number of trials, and returns the best fit seen.
pub(crate) fn fit_density<T>(
    mut pack: impl FnMut(f64) -> anyhow::Result<Trial<T>>,
    requested: Option<f64>,
    estimate: f64,
    max_size: u32,
) -> anyhow::Result<Option<Fitted<T>>> {
    const MAX_TRIALS: u32 = 14;
    const TOLERANCE: f64 = 1.01;
    let side = |t: &Trial<T>| t.width.max(t.height).max(1) as f64;
    let fits = |t: &Trial<T>| t.width <= max_size && t.height <= max_size;
    let target = max_size as f64;

    let mut trials = 0;
    let mut best: Option<Fitted<T>> = None;
    let mut lo = 0.0f64; // highest density known to fit
    let mut hi = f64::INFINITY; // lowest density known not to fit
    let mut next = match requested {
        Some(r) => r,
        None => estimate,
    };
    if let Some(r) = requested {
        hi = r * (1.0 + 1e-6);
    }
    // Densities below this are pointless: every chart is down to its padding.
    let floor = next * 1e-6;
    while trials < MAX_TRIALS {
        if !(next.is_finite() && next > floor) {
            break;
        }
        let s = next;
        let t = pack(s)?;
        trials += 1;
        let predicted = s * target / side(&t);
        if fits(&t) {
            lo = s;
            let done = requested.is_some_and(|r| s >= r);
            best = Some(Fitted { density: s, trial: t, trials });
            if done {
                break;
            }
        } else {
            hi = hi.min(s);
        }
        if hi.is_finite() && lo > 0.0 && hi <= lo * TOLERANCE {
            break;
        }
        // Next density: the secant prediction (slightly conservative) when it falls strictly
        // inside the bracket, otherwise the geometric midpoint, or a step down/up when the
        // bracket is still open.
        let guess = predicted * 0.995;
        next = if lo > 0.0 && hi.is_finite() {
            if guess > lo * 1.002 && guess < hi / 1.002 { guess } else { (lo * hi).sqrt() }
        } else if lo > 0.0 {
            // Fits, no upper bound yet: grow towards the page edge, at least a little.
            guess.max(lo * 1.02)
        } else {
            // Doesn't fit yet: shrink, at least a little, more if packing overhead dominates.
            guess.min(s * 0.9)
        };
    }
    if let Some(b) = &mut best {
        b.trials = trials;
    }
    Ok(best)
}
