//! The uvunwrap backend: the pure-Rust `uvunwrap` crate 0.3
//! (<https://crates.io/crates/uvunwrap>, <https://github.com/archonic/uvunwrap>, MIT): xatlas-style
//! chart growing, LSCM + ARAP parameterization (charts with flips, overlaps or too much
//! distortion are split and re-solved), conservative rasterization dilated by the padding, and
//! shape packing with 90° rotations.
//!
//! Its conventions already match ours: UVs in `[0, 1]` with `(0, 0)` the corner of texel row 0,
//! column 0; charts `2·padding` apart and `padding` from the edges (Chebyshev); global chart ids;
//! triangles in input order; deterministic for any thread count. Density fitting is its own
//! `Density::Auto`, which bisects re-packings of charts parameterized once.

use super::{Atlas, AtlasVertex, MeshInput, UnwrapError, UnwrapOptions, UnwrappedMesh, empty_atlas, fmt_density};

/// Unwraps with uvunwrap (input already validated).
pub(super) fn unwrap(meshes: &[MeshInput], options: &UnwrapOptions) -> anyhow::Result<Atlas> {
    let size = options.max_atlas_size;
    let inputs: Vec<uvunwrap::MeshInput> =
        meshes.iter().map(|m| uvunwrap::MeshInput::new(m.positions, m.indices)).collect();
    let with = |density| uvunwrap::Options { density, padding: options.padding, ..uvunwrap::Options::default() };
    let generate = |density| uvunwrap::generate(&inputs, &with(density));
    let fits = |a: &uvunwrap::Atlas| a.page_count <= 1 && a.width <= size && a.height <= size;
    let auto = uvunwrap::Density::Auto { page_size: size };

    let lowered = |from: f64, to: f64| {
        format!("density lowered from {} to {} texels/m to fit {size}²", fmt_density(from), fmt_density(to))
    };
    let mut notices = Vec::new();
    let atlas = match options.texels_per_unit {
        None => generate(auto)?,
        Some(t) => {
            // Skip the fixed-density attempt when the surface alone exceeds the page.
            let area = super::total_area(meshes);
            let hopeless = area * (t as f64).powi(2) > 1.05 * (size as f64).powi(2);
            let fixed = if hopeless {
                None
            } else {
                match generate(uvunwrap::Density::Fixed { texels_per_unit: t, page_size: None }) {
                    Ok(a) if fits(&a) => Some(a),
                    Ok(_) | Err(uvunwrap::Error::AtlasTooLarge { .. }) => None,
                    Err(e) => return Err(e.into()),
                }
            };
            match fixed {
                Some(a) => a,
                None => {
                    let a = generate(auto)?;
                    if a.texels_per_unit < t {
                        notices.push(lowered(t as f64, a.texels_per_unit as f64));
                        a
                    } else {
                        // The growing page came out oddly shaped although the density fits a
                        // square page: pack at the requested density on one fixed page.
                        match generate(uvunwrap::Density::Fixed { texels_per_unit: t, page_size: Some(size) }) {
                            Ok(f) if fits(&f) => f,
                            _ => {
                                notices.push(format!(
                                    "uvunwrap could not pack {} texels/m onto one {size}² page; \
                                     used its automatic density {} texels/m",
                                    fmt_density(t as f64),
                                    fmt_density(a.texels_per_unit as f64)
                                ));
                                a
                            }
                        }
                    }
                }
            }
        }
    };
    if atlas.chart_count == 0 {
        return Ok(empty_atlas(meshes));
    }
    if !fits(&atlas) {
        return Err(UnwrapError::DoesNotFit { charts: atlas.chart_count, size, padding: options.padding }.into());
    }
    let out = atlas
        .meshes
        .iter()
        .map(|m| UnwrappedMesh {
            vertices: m
                .vertices
                .iter()
                .map(|v| AtlasVertex { xref: v.xref, uv: v.uv, chart: v.chart.unwrap_or(u32::MAX) })
                .collect(),
            indices: m.indices.clone(),
        })
        .collect();
    Ok(Atlas {
        width: atlas.width,
        height: atlas.height,
        texels_per_unit: atlas.texels_per_unit,
        chart_count: atlas.chart_count,
        utilization: 0.0,
        meshes: out,
        notices,
    })
}
