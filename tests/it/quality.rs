//! Lightmap quality as a viewer sees it, each a number with a threshold:
//! UV seams agree after stitching, bilinear filtering at chart edges reads
//! only the chart's own texels (no black rims, no neighbour's light), and a
//! lit plane shows no acne.

use crate::common;

use bake::Baked;
use bake::environment::{EnvironmentMap, LightMode};
use bake::export::lightmap::{self, Image};
use bake::export::seams;
use bake::fixtures::{MeshData, Placement, SceneBuilder};
use glam::{Vec2, Vec3};

/// The exported HDR lightmap of a bake (dilated, stitched unless `stitch` is false).
fn exported(baked: &Baked, stitch: bool) -> (Image, Vec<seams::SeamEdge>) {
    let edges = seams::find(&baked.scene, &baked.atlas);
    let used = if stitch { edges.clone() } else { Vec::new() };
    let (image, _, _) = lightmap::images(&baked.texels, &baked.solution.lightmap, &[], 4, &used);
    (image, edges)
}

/// Bilinear lookup as a viewer's sampler does it (texel centres at
/// (x + ½)/width, clamped at the page edge): the value and the taps read.
fn bilinear(image: &Image, uv: Vec2) -> ([f32; 3], Vec<usize>) {
    let p = uv * Vec2::new(image.width as f32, image.height as f32) - 0.5;
    let (x0, y0) = (p.x.floor(), p.y.floor());
    let (fx, fy) = (p.x - x0, p.y - y0);
    let mut value = [0.0f32; 3];
    let mut taps = Vec::new();
    for (dx, dy, w) in
        [(0, 0, (1.0 - fx) * (1.0 - fy)), (1, 0, fx * (1.0 - fy)), (0, 1, (1.0 - fx) * fy), (1, 1, fx * fy)]
    {
        if w <= 0.0 {
            continue;
        }
        let x = (x0 as i64 + dx).clamp(0, image.width as i64 - 1);
        let y = (y0 as i64 + dy).clamp(0, image.height as i64 - 1);
        let i = (y * image.width as i64 + x) as usize;
        for (v, c) in value.iter_mut().zip(image.pixels[i]) {
            *v += w * c;
        }
        taps.push(i);
    }
    (value, taps)
}

/// Points inside every charted triangle (page coordinates), each with its
/// chart and whether it lies within a texel of the triangle's edges.
fn samples(baked: &Baked) -> Vec<(Vec2, u32, bool)> {
    let size = Vec2::new(baked.atlas.width as f32, baked.atlas.height as f32);
    let mut out = Vec::new();
    for mesh in &baked.atlas.meshes {
        // Chart borders: edges (atlas vertex pairs) only one triangle has.
        let mut uses = std::collections::HashMap::new();
        for triangle in mesh.indices.chunks_exact(3) {
            for (p, q) in [(0, 1), (1, 2), (2, 0)] {
                *uses.entry((triangle[p].min(triangle[q]), triangle[p].max(triangle[q]))).or_insert(0) += 1;
            }
        }
        for triangle in mesh.indices.chunks_exact(3) {
            let border = |p: usize, q: usize| uses[&(triangle[p].min(triangle[q]), triangle[p].max(triangle[q]))] == 1;
            let v = [0, 1, 2].map(|k| mesh.vertices[triangle[k] as usize]);
            if v[0].chart == u32::MAX {
                continue;
            }
            let uv = v.map(|v| Vec2::from(v.uv));
            let px = uv.map(|u| u * size);
            let twice_area = (px[1] - px[0]).perp_dot(px[2] - px[0]).abs();
            if twice_area < 1e-3 {
                continue;
            }
            // A barycentric grid of about four points per texel.
            let n = ((twice_area.sqrt() * 2.0).ceil() as u32).clamp(2, 64);
            for i in 0..n {
                for j in 0..n - i {
                    let (b1, b2) = ((i as f32 + 1.0 / 3.0) / n as f32, (j as f32 + 1.0 / 3.0) / n as f32);
                    let b0 = 1.0 - b1 - b2;
                    // Distance to each chart-border edge in texels:
                    // barycentric × twice the area / edge length.
                    let near_edge = [(b0, 1, 2), (b1, 2, 0), (b2, 0, 1)]
                        .into_iter()
                        .any(|(b, p, q)| border(p, q) && b * twice_area / (px[q] - px[p]).length().max(1e-6) < 1.0);
                    out.push((uv[0] * b0 + uv[1] * b1 + uv[2] * b2, v[0].chart, near_edge));
                }
            }
        }
    }
    out
}

fn luminance(c: [f32; 3]) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

#[test]
fn uv_seams_agree_after_stitching() {
    let gpu = common::gpu();
    let mut builder = SceneBuilder::new();
    builder.object("ground", &MeshData::plane(8.0, 8.0, 4), [0.6, 0.6, 0.6, 1.0], [0.0; 3], Placement::default());
    builder.object(
        "sphere",
        &MeshData::sphere(0.8, 32, 16),
        [0.8, 0.8, 0.8, 1.0],
        [0.0; 3],
        Placement::at(Vec3::new(-1.2, 0.8, 0.0)),
    );
    builder.object(
        "torus",
        &MeshData::torus(0.9, 0.35, 32, 16),
        [0.8, 0.5, 0.3, 1.0],
        [0.0; 3],
        Placement::at(Vec3::new(1.3, 0.35, 0.0)),
    );
    let sun_and_sky = EnvironmentMap::sun_and_sky([0.5, 0.6, 0.8], [0.4, 0.7, 0.3], 1e3, 1f32.to_radians());
    let lights = common::lights(&sun_and_sky, LightMode::Budget { count: 256 });
    // The seams are what is tested, not the bounced light's last per cent.
    let mut options = common::options(192);
    options.solve.bounce.max_shots = Some(512);
    let baked = common::bake(&gpu, &builder, &lights, &options);
    let (raw, edges) = exported(&baked, false);
    let (stitched, _) = exported(&baked, true);
    let before = seams::seam_error(&raw, &edges);
    let after = seams::seam_error(&stitched, &edges);
    eprintln!(
        "{} seam edges; relative difference across them: mean {:.3}% max {:.2}% before, mean {:.4}% max {:.3}% after",
        edges.len(),
        100.0 * before.mean,
        100.0 * before.max,
        100.0 * after.mean,
        100.0 * after.max
    );
    // The sphere's and the torus's UV0 seams and the unwrap's own cuts.
    assert!(edges.len() > 50, "{}", edges.len());
    assert!(after.mean < 0.02, "mean seam error {:.4} after stitching", after.mean);
    assert!(after.mean < 0.25 * before.mean, "stitching did not close the seams: {before:?} → {after:?}");
    // Stitching moves texels near seams only and keeps their light: it
    // redistributes across the seam, it does not add or remove.
    let changed: Vec<(f32, f32)> = raw
        .pixels
        .iter()
        .zip(&stitched.pixels)
        .filter(|(a, b)| a != b)
        .map(|(a, b)| (luminance(*a), luminance(*b)))
        .collect();
    let (sum_before, sum_after) = changed.iter().fold((0.0, 0.0), |s, c| (s.0 + c.0 as f64, s.1 + c.1 as f64));
    eprintln!("{} texels moved; their total light {sum_before:.3} → {sum_after:.3}", changed.len());
    assert!(changed.len() < raw.pixels.len() / 4);
    assert!((sum_after / sum_before - 1.0).abs() < 0.02, "{sum_before} → {sum_after}");
}

#[test]
fn chart_edges_filter_to_their_own_chart_with_no_black_rim() {
    let gpu = common::gpu();
    let mut builder = SceneBuilder::new();
    builder.object("sphere", &MeshData::sphere(1.0, 24, 12), [0.5, 0.5, 0.5, 1.0], [0.0; 3], Placement::default());
    builder.object(
        "torus",
        &MeshData::torus(1.0, 0.3, 24, 12),
        [0.5, 0.5, 0.5, 1.0],
        [0.0; 3],
        Placement::at(Vec3::new(4.0, 0.0, 0.0)),
    );
    let lights = common::lights(&EnvironmentMap::constant([1.0; 3]), LightMode::Budget { count: 256 });
    let baked = common::bake(&gpu, &builder, &lights, &common::options(128));
    let (image, _) = exported(&baked, true);
    let (mut border, mut border_dark, mut interior, mut interior_dark) = (0usize, 0usize, 0usize, 0usize);
    let mut foreign = 0usize;
    let mut unwritten = 0usize;
    for (uv, chart, near_edge) in samples(&baked) {
        let (value, taps) = bilinear(&image, uv);
        unwritten += taps.iter().filter(|&&i| !image.written[i]).count();
        foreign += taps.iter().filter(|&&i| image.written[i] && image.chart[i] != chart).count();
        // Open sky gives the sphere L_lm = 1 and the torus at least its
        // outer half's; a dark sample is one under a quarter of that.
        let dark = luminance(value) < 0.25;
        if near_edge {
            border += 1;
            border_dark += dark as usize;
        } else {
            interior += 1;
            interior_dark += dark as usize;
        }
    }
    let (border_share, interior_share) = (border_dark as f64 / border as f64, interior_dark as f64 / interior as f64);
    eprintln!(
        "{border} samples within a texel of a chart edge, {:.3}% dark; {interior} inside, {:.3}% dark; \
         {foreign} taps of another chart, {unwritten} unwritten",
        100.0 * border_share,
        100.0 * interior_share
    );
    assert!(border > 1000 && interior > 1000);
    assert_eq!(unwritten, 0, "bilinear filtering read unwritten (black) texels");
    assert_eq!(foreign, 0, "bilinear filtering read another chart's texels");
    assert!(border_share <= interior_share + 0.001, "black rims: {border_share} against {interior_share}");
}

#[test]
fn an_open_plane_under_a_constant_sky_shows_no_acne() {
    let gpu = common::gpu();
    let mut builder = SceneBuilder::new();
    builder.object("plane", &MeshData::plane(4.0, 4.0, 8), [0.5, 0.5, 0.5, 1.0], [0.0; 3], Placement::default());
    let lights = common::lights(&EnvironmentMap::constant([1.0; 3]), LightMode::Budget { count: 512 });
    let baked = common::bake(&gpu, &builder, &lights, &common::options(128));
    let values: Vec<f64> = common::values_of(&baked, 0).iter().map(|(_, v)| *v as f64).collect();
    let mean = values.iter().sum::<f64>() / values.len() as f64;
    let deviation = (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / values.len() as f64).sqrt();
    eprintln!("{} texels: mean {mean:.4} (upper hemisphere of L = 1: 1), relative std dev {:.4}%", values.len(), {
        100.0 * deviation / mean
    });
    assert!(deviation / mean < 0.005, "relative std dev {}", deviation / mean);
    assert!((mean - 1.0).abs() < 0.01, "{mean}");
}
