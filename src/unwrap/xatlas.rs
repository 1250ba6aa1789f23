//! The xatlas backend: a safe wrapper over the 2019 xatlas that `xatlas-rs` 0.1.3 compiles
//! (<https://github.com/jpcy/xatlas>, MIT, Jonathan Young; declarations in
//! [`super::xatlas_ffi`]), and the unwrap built on it.
//!
//! Charts are computed and parameterized once; packing is repeated at different densities
//! ([`super::fit_density`]) on one growing page (`PackOptions::resolution = 0`, so xatlas never
//! splits the result into several atlases).
//!
//! Quirks of this xatlas version that are corrected here:
//! - its `conservative` padding is one-sided: a chart's bitmap is dilated by `padding` towards
//!   −x/−y only (the +x/+y side is clipped by the bitmap), and its UVs land `padding` texels
//!   up-left of the dilated bitmap. Two charts are therefore only `padding` empty texels apart
//!   (Chebyshev), and charts touch the page's top/left edge. We pass `2p` as xatlas' padding and
//!   shift everything by `p` texels, then size the page from the charts' actual extent plus `p`;
//! - it prints warnings to stdout with `printf`: printing is switched off;
//! - `AddMesh` with zero indices treats the vertices as a triangle soup: meshes without
//!   triangles are not added;
//! - ignored (zero-area) faces get uv `(0, 0)` on vertices of their own; here their corners
//!   collapse onto a UV of a neighbouring chart instead, as uvunwrap does;
//! - its tolerances are absolute (faces under 1.2e-7 units² are ignored, positions within 1e-4
//!   are welded, and its position hash overflows beyond ±2·10⁷): positions are translated to
//!   their bounding-box centre and scaled so the largest half-extent is 1000 units.
//!
//! Not corrected (measured by `unwrap_compare`): it scales each chart by
//! `surface area / parametric area × texelsPerUnit` instead of the square root of that ratio,
//! so curved (LSCM) charts get that ratio too much texel area (typically 1.1–1.6×); and it
//! stretches every chart non-uniformly to whole texels. Invalid parameterizations it leaves
//! (flips, folds) are caught by `run`'s validation, which then falls back to uvunwrap.

use std::collections::HashMap;
use std::ptr::NonNull;
use std::sync::Once;

use anyhow::{Context, bail};

use super::xatlas_ffi as ffi;
use super::{
    Atlas, AtlasVertex, MeshInput, Trial, UnwrapError, UnwrapOptions, UnwrappedMesh, empty_atlas, fit_density,
    fmt_density,
};

/// Switches xatlas' process-global printing off, once, before any atlas is created.
fn silence() {
    static SILENCE: Once = Once::new();
    SILENCE.call_once(|| {
        // SAFETY: a null print function is checked before every use in xatlas.cpp.
        unsafe { ffi::SetPrint(None, false) }
    });
}

/// One xatlas atlas, destroyed on drop. Not `Send`/`Sync`: xatlas isn't thread-safe per atlas
/// (separate atlases on separate threads are fine).
pub(crate) struct XAtlas {
    raw: NonNull<ffi::Atlas>,
    meshes: u32,
    charted: bool,
}

/// One output mesh of a packing, copied out of xatlas.
pub(crate) struct PackedMesh {
    /// Output vertices; `uv` in texels of the packed page.
    pub vertices: Vec<ffi::Vertex>,
    /// Triangles in input order, indexing `vertices`.
    pub indices: Vec<u32>,
    /// Per chart of this mesh, the indices (into `vertices`) of its triangles.
    pub charts: Vec<Vec<u32>>,
}

/// A packing copied out of xatlas.
pub(crate) struct Packed {
    /// Number of atlases (pages); 1 with `resolution = 0`.
    pub atlas_count: u32,
    pub chart_count: u32,
    pub meshes: Vec<PackedMesh>,
}

impl XAtlas {
    /// A new, empty atlas.
    pub fn new() -> Self {
        silence();
        // SAFETY: Create has no preconditions; it aborts rather than return null on OOM, but
        // check anyway.
        let raw = unsafe { ffi::Create() };
        XAtlas { raw: NonNull::new(raw).expect("xatlas::Create returned null"), meshes: 0, charted: false }
    }

    /// Adds a mesh: `positions` (any units), a triangle list `indices` (non-empty, a multiple of
    /// 3, each `< positions.len()`), and optional per-triangle ignore flags.
    pub fn add_mesh(&mut self, positions: &[[f32; 3]], indices: &[u32], ignore: Option<&[bool]>) -> anyhow::Result<()> {
        // Zero indices would make xatlas read the vertices as an unindexed triangle soup.
        if indices.is_empty() || !indices.len().is_multiple_of(3) {
            bail!("xatlas: invalid index count {}", indices.len());
        }
        if let Some(f) = ignore
            && f.len() != indices.len() / 3
        {
            bail!("xatlas: {} ignore flags for {} faces", f.len(), indices.len() / 3);
        }
        let decl = ffi::MeshDecl {
            vertexCount: u32::try_from(positions.len()).context("too many vertices")?,
            vertexPositionData: positions.as_ptr().cast(),
            vertexPositionStride: std::mem::size_of::<[f32; 3]>() as u32,
            indexCount: u32::try_from(indices.len()).context("too many indices")?,
            indexData: indices.as_ptr().cast(),
            indexFormat: ffi::INDEX_FORMAT_UINT32,
            faceIgnoreData: ignore.map_or(std::ptr::null(), |f| f.as_ptr()),
            ..ffi::MeshDecl::default()
        };
        // SAFETY: the atlas is live; the declaration's pointers cover `vertexCount` positions,
        // `indexCount` u32 indices and `indexCount / 3` bools, and xatlas copies them before
        // returning. `bool` is one byte in both languages.
        let error = unsafe { ffi::AddMesh(self.raw.as_ptr(), &decl) };
        if error != ffi::ADD_MESH_SUCCESS {
            // SAFETY: StringForEnum returns a static NUL-terminated string for any value.
            let text = unsafe { std::ffi::CStr::from_ptr(ffi::StringForAddMeshError(error)) };
            bail!("xatlas::AddMesh failed for mesh {}: {} (error {error})", self.meshes, text.to_string_lossy());
        }
        self.meshes += 1;
        Ok(())
    }

    /// Segments all meshes into charts and parameterizes them (call once, after all
    /// [`add_mesh`](Self::add_mesh) calls, before [`pack`](Self::pack)).
    pub fn chart(&mut self, options: ffi::ChartOptions) -> anyhow::Result<()> {
        if self.meshes == 0 {
            bail!("xatlas: no meshes to chart");
        }
        // SAFETY: live atlas with at least one mesh; no callbacks.
        unsafe {
            ffi::ComputeCharts(self.raw.as_ptr(), options, None, std::ptr::null_mut());
            ffi::ParameterizeCharts(self.raw.as_ptr(), None, None, std::ptr::null_mut());
        }
        self.charted = true;
        Ok(())
    }

    /// Number of charts after [`chart`](Self::chart).
    pub fn chart_count(&self) -> u32 {
        // SAFETY: live atlas; plain field read.
        unsafe { (*self.raw.as_ptr()).chartCount }
    }

    /// Packs the charts (may be called repeatedly) and copies the result out.
    pub fn pack(&mut self, options: ffi::PackOptions) -> anyhow::Result<Packed> {
        if !self.charted {
            bail!("xatlas: pack before chart");
        }
        // SAFETY: live, charted atlas; no callbacks.
        unsafe { ffi::PackCharts(self.raw.as_ptr(), options, None, std::ptr::null_mut()) };
        // SAFETY: after PackCharts the atlas holds `meshCount` output meshes whose arrays have
        // the stated lengths (null only when empty); everything is copied before the next call
        // into xatlas can free it.
        unsafe { self.copy_out() }
    }

    /// Copies the output meshes out of the atlas.
    ///
    /// # Safety
    /// Only right after `PackCharts`, while nothing else can touch the atlas.
    unsafe fn copy_out(&self) -> anyhow::Result<Packed> {
        /// A slice from an xatlas array, empty when null.
        unsafe fn slice<'a, T>(ptr: *const T, len: u32) -> &'a [T] {
            if ptr.is_null() || len == 0 {
                &[]
            } else {
                // SAFETY: caller guarantees `ptr` points at `len` initialized values.
                unsafe { std::slice::from_raw_parts(ptr, len as usize) }
            }
        }
        // SAFETY: see `pack`.
        let a = unsafe { &*self.raw.as_ptr() };
        if a.meshCount != self.meshes || a.meshes.is_null() {
            bail!(
                "xatlas: {} output meshes for {} inputs",
                if a.meshes.is_null() { 0 } else { a.meshCount },
                self.meshes
            );
        }
        let meshes = unsafe { slice(a.meshes, a.meshCount) }
            .iter()
            .map(|m| PackedMesh {
                vertices: unsafe { slice(m.vertexArray, m.vertexCount) }.to_vec(),
                indices: unsafe { slice(m.indexArray, m.indexCount) }.to_vec(),
                charts: unsafe { slice(m.chartArray, m.chartCount) }
                    .iter()
                    .map(|c| unsafe { slice(c.indexArray, c.indexCount) }.to_vec())
                    .collect(),
            })
            .collect();
        Ok(Packed { atlas_count: a.atlasCount, chart_count: a.chartCount, meshes })
    }
}

impl Drop for XAtlas {
    fn drop(&mut self) {
        // SAFETY: created by Create, destroyed exactly once; nothing borrowed from it survives
        // (`pack` copies everything out).
        unsafe { ffi::Destroy(self.raw.as_ptr()) }
    }
}

/// Largest half-extent of the normalized positions handed to xatlas (see the module docs).
const NORMALIZED_HALF_EXTENT: f64 = 1000.0;

/// A page of a packing trial: the xatlas result and its page in our conventions.
struct Page {
    packed: Packed,
    /// Shift (texels) added to xatlas' UVs so charts are `padding` from the top/left edge.
    shift: f32,
}

/// Unwraps with xatlas (input already validated).
pub(super) fn unwrap(meshes: &[MeshInput], options: &UnwrapOptions) -> anyhow::Result<Atlas> {
    let size = options.max_atlas_size;
    let pad = options.padding;
    let (normalized, scale) = normalize(meshes);

    let mut xa = XAtlas::new();
    // Input mesh index of each mesh added to xatlas.
    let mut added = Vec::new();
    for (mi, m) in meshes.iter().enumerate() {
        if m.indices.is_empty() {
            continue;
        }
        xa.add_mesh(&normalized[mi], m.indices, None)?;
        added.push(mi);
    }
    if added.is_empty() {
        return Ok(empty_atlas(meshes));
    }
    xa.chart(ffi::ChartOptions::default())?;
    if xa.chart_count() == 0 {
        // Every face was ignored as degenerate.
        return Ok(empty_atlas(meshes));
    }

    // Normalized surface area, for the first density estimate and a cheap "cannot fit" test.
    let area_n: f64 = super::total_area(meshes) * scale * scale;
    let requested = options.texels_per_unit.map(|t| t as f64 / scale);
    // xatlas' own estimate assumes 75% utilization; padding lowers it.
    let estimate = (0.6 * (size as f64).powi(2) / area_n).sqrt();
    let fitted = fit_density(|d| pack_trial(&mut xa, area_n, d, size, pad), requested, estimate, size)?
        .ok_or(UnwrapError::DoesNotFit { charts: xa.chart_count(), size, padding: pad })?;
    let density = fitted.density * scale;
    let mut notices = Vec::new();
    if let Some(t) = options.texels_per_unit
        && density < t as f64 * (1.0 - 1e-6)
    {
        notices.push(format!(
            "density lowered from {} to {} texels/m to fit {size}²",
            fmt_density(t as f64),
            fmt_density(density)
        ));
    }
    let Trial { width, height, result: page } = fitted.trial;
    let out = convert(meshes, &added, &page, width, height);
    Ok(Atlas {
        width,
        height,
        texels_per_unit: density as f32,
        chart_count: page.packed.chart_count,
        utilization: 0.0,
        meshes: out,
        notices,
    })
}

/// Normalizes positions for xatlas' absolute tolerances: bounding-box centre (of the indexed
/// vertices) to the origin, largest half-extent to [`NORMALIZED_HALF_EXTENT`]. Gives the
/// positions and the scale from world metres to normalized units.
fn normalize(meshes: &[MeshInput]) -> (Vec<Vec<[f32; 3]>>, f64) {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for m in meshes {
        for &i in m.indices {
            let p = m.positions[i as usize];
            for k in 0..3 {
                lo[k] = lo[k].min(p[k] as f64);
                hi[k] = hi[k].max(p[k] as f64);
            }
        }
    }
    let half = (0..3).map(|k| 0.5 * (hi[k] - lo[k])).fold(0.0, f64::max);
    let centre: [f64; 3] = std::array::from_fn(|k| 0.5 * (lo[k] + hi[k]));
    let scale = if half > 0.0 && half.is_finite() { NORMALIZED_HALF_EXTENT / half } else { 1.0 };
    let normalized: Vec<Vec<[f32; 3]>> = meshes
        .iter()
        .map(|m| {
            m.positions.iter().map(|p| std::array::from_fn(|k| ((p[k] as f64 - centre[k]) * scale) as f32)).collect()
        })
        .collect();
    (normalized, scale)
}

/// One packing trial at `density_n` texels per normalized unit: the page size it needs
/// (charts' extent plus `pad` on each side) and the packing.
fn pack_trial(xa: &mut XAtlas, area_n: f64, density_n: f64, size: u32, pad: u32) -> anyhow::Result<Trial<Page>> {
    let s = size as f64;
    if area_n * density_n * density_n > 1.05 * s * s {
        // More chart area than the page has texels: don't spend a packing on it.
        let side = (area_n.sqrt() * density_n).min(u32::MAX as f64 / 4.0) as u32;
        return Ok(Trial {
            width: side,
            height: side,
            result: Page { packed: Packed { atlas_count: 0, chart_count: 0, meshes: Vec::new() }, shift: 0.0 },
        });
    }
    let packed = xa.pack(ffi::PackOptions {
        // xatlas' default: random placement trials per chart (fixed seed: deterministic).
        attempts: 4096,
        texelsPerUnit: density_n as f32,
        // 0: a single page that grows to fit; never several atlases.
        resolution: 0,
        // Charts beyond the page can't fit anyway; bound their bitmaps (a chart scaled
        // down to this still makes the page too large, so it never yields a fit).
        maxChartSize: size + 1,
        blockAlign: false,
        conservative: true,
        // One-sided dilation (see the module docs): 2p gives 2p empty texels between charts.
        padding: 2 * pad,
    })?;
    if packed.atlas_count > 1 {
        bail!("xatlas produced {} atlases", packed.atlas_count);
    }
    // Actual chart extent (texels), then `pad` on each side.
    let shift = pad as f32;
    let (mut max_u, mut max_v) = (0.0f32, 0.0f32);
    for m in &packed.meshes {
        for v in &m.vertices {
            if v.atlasIndex >= 0 {
                max_u = max_u.max(v.uv[0] + shift);
                max_v = max_v.max(v.uv[1] + shift);
            }
        }
    }
    let side = |max: f32| (max.ceil() as u32).saturating_add(pad).max(1);
    Ok(Trial { width: side(max_u), height: side(max_v), result: Page { packed, shift } })
}

/// Converts xatlas' meshes to ours: normalized UVs, global chart ids, ignored faces collapsed
/// onto a neighbouring UV.
fn convert(meshes: &[MeshInput], added: &[usize], page: &Page, width: u32, height: u32) -> Vec<UnwrappedMesh> {
    let mut out = vec![UnwrappedMesh::default(); meshes.len()];
    let mut chart_base = 0u32;
    let (w, h) = (width as f32, height as f32);
    for (pm, &mi) in page.packed.meshes.iter().zip(added) {
        let n = pm.vertices.len();
        let mut chart_of = vec![u32::MAX; n];
        for (ci, tri_indices) in pm.charts.iter().enumerate() {
            for &v in tri_indices {
                if let Some(c) = chart_of.get_mut(v as usize) {
                    *c = chart_base + ci as u32;
                }
            }
        }
        chart_base += pm.charts.len() as u32;
        let mut vertices: Vec<AtlasVertex> = pm
            .vertices
            .iter()
            .zip(&chart_of)
            .map(|(v, &chart)| AtlasVertex {
                xref: v.xref,
                uv: if chart == u32::MAX {
                    [0.0, 0.0]
                } else {
                    [(v.uv[0] + page.shift) / w, (v.uv[1] + page.shift) / h]
                },
                chart,
            })
            .collect();
        // First charted output vertex of each input vertex, for ignored faces.
        let mut anchor_of: HashMap<u32, u32> = HashMap::new();
        for (i, v) in vertices.iter().enumerate() {
            if v.chart != u32::MAX {
                anchor_of.entry(v.xref).or_insert(i as u32);
            }
        }
        let mut indices = Vec::with_capacity(pm.indices.len());
        let mut collapsed: HashMap<(u32, u32), u32> = HashMap::new();
        for tri in pm.indices.chunks_exact(3) {
            let charted = tri.iter().all(|&i| vertices.get(i as usize).is_some_and(|v| v.chart != u32::MAX));
            if charted {
                indices.extend_from_slice(tri);
                continue;
            }
            // An ignored face: all corners onto one UV of a chart sharing one of its vertices.
            let anchor = tri.iter().find_map(|&i| {
                let xref = vertices.get(i as usize)?.xref;
                anchor_of.get(&xref).copied()
            });
            for &i in tri {
                let Some(v) = vertices.get(i as usize).copied() else {
                    indices.push(0);
                    continue;
                };
                let key = (v.xref, anchor.unwrap_or(u32::MAX));
                let index = *collapsed.entry(key).or_insert_with(|| {
                    vertices.push(AtlasVertex {
                        xref: v.xref,
                        uv: anchor.map_or([0.0, 0.0], |a| vertices[a as usize].uv),
                        chart: u32::MAX,
                    });
                    (vertices.len() - 1) as u32
                });
                indices.push(index);
            }
        }
        // Drop vertices no triangle uses any more (the ones xatlas gave ignored faces).
        let mut used = vec![u32::MAX; vertices.len()];
        let mut kept = Vec::with_capacity(vertices.len());
        for i in indices.iter_mut() {
            let slot = &mut used[*i as usize];
            if *slot == u32::MAX {
                *slot = kept.len() as u32;
                kept.push(vertices[*i as usize]);
            }
            *i = *slot;
        }
        out[mi] = UnwrappedMesh { vertices: kept, indices };
    }
    out
}
