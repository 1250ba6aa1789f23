//! Progressive-refinement radiosity against known answers: closed rooms
//! (L = Le/(1−ρ)), analytic form factors, colour bleeding and energy bounds.

mod common;

use bake::fixtures::{MeshData, Placement, SceneBuilder};
use bake::progress::Silent;
use bake::solve::Solution;
use glam::{Quat, Vec3};

/// Bakes a scene lit only by its emitters.
fn bake_emitters(builder: &SceneBuilder, atlas: u32, tweak: impl Fn(&mut bake::config::BakeOptions)) -> bake::Baked {
    let gpu = common::gpu();
    let mut options = common::options(atlas);
    tweak(&mut options);
    let baked = bake::bake_scene(&gpu, common::scene(builder, "room"), None, &options, &mut Silent).unwrap();
    common::assert_valid(&baked);
    baked
}

fn radiosity_mean(baked: &bake::Baked, solution: &Solution) -> [f64; 3] {
    let mut sum = [0.0f64; 3];
    let mut area = 0.0;
    for (i, t) in baked.texels.texels.iter().enumerate() {
        let l = solution.radiosity(&baked.texels, i);
        for c in 0..3 {
            sum[c] += l[c] as f64 * t.area as f64;
        }
        area += t.area as f64;
    }
    sum.map(|s| s / area)
}

/// A closed 2×2×2 m room whose six walls are separate quads facing inwards,
/// with the given (albedo, emission) per wall: floor, ceiling, ±X, ±Z.
fn room(walls: [(f32, f32); 6]) -> SceneBuilder {
    let mut builder = SceneBuilder::new();
    let rotations = [
        (Quat::IDENTITY, Vec3::new(0.0, -1.0, 0.0)),
        (Quat::from_rotation_x(180f32.to_radians()), Vec3::new(0.0, 1.0, 0.0)),
        (Quat::from_rotation_z(-90f32.to_radians()), Vec3::new(-1.0, 0.0, 0.0)),
        (Quat::from_rotation_z(90f32.to_radians()), Vec3::new(1.0, 0.0, 0.0)),
        (Quat::from_rotation_x(90f32.to_radians()), Vec3::new(0.0, 0.0, -1.0)),
        (Quat::from_rotation_x(-90f32.to_radians()), Vec3::new(0.0, 0.0, 1.0)),
    ];
    for (k, ((rotation, at), (albedo, emission))) in rotations.into_iter().zip(walls).enumerate() {
        builder.object(
            &format!("wall{k}"),
            &MeshData::plane(2.0, 2.0, 4),
            [albedo, albedo, albedo, 1.0],
            [emission; 3],
            Placement::at(at).rotated(rotation),
        );
    }
    builder
}

#[test]
fn closed_room_with_uniform_emission_reaches_le_over_one_minus_rho() {
    for (rho, tolerance) in [(0.5f32, 0.02f32), (0.95, 0.05)] {
        let baked = bake_emitters(&room([(rho, 1.0); 6]), 96, |_| {});
        let expected = 1.0 / (1.0 - rho);
        let bounce = baked.solution.bounce.as_ref().expect("the bounce pass ran");
        eprintln!(
            "ρ = {rho}: {} shots, stopped by {}, unshot {:.4}, ambient {:?}",
            bounce.shots, bounce.stopped_by, bounce.unshot_fraction, bounce.ambient
        );
        let mut worst = 0.0f32;
        for (texel, value) in baked.texels.texels.iter().zip(&baked.solution.lightmap) {
            // Incident light L_lm = (L − Le)/ρ = Le/(1−ρ) as well.
            let error = (value[0] / expected - 1.0).abs();
            worst = worst.max(error);
            assert!(error < tolerance, "ρ = {rho}: texel at {:?} has {}, expected {expected}", texel.position, value[0]);
        }
        eprintln!("ρ = {rho}: worst relative error {worst:.4}");
    }
}

#[test]
fn debug_room() {
    for (rho, tol) in [(0.95f32, 0.05), (0.95, 0.02), (0.99, 0.05)] {
        let t0 = std::time::Instant::now();
        let baked = bake_emitters(&room([(rho, 1.0); 6]), 96, |o| o.solve.bounce.tolerance = tol);
        let expected = 1.0 / (1.0 - rho);
        let mut worst = Vec::new();
        for (t, v) in baked.texels.texels.iter().zip(&baked.solution.lightmap) {
            worst.push((v[0] / expected - 1.0, t.position, t.area));
        }
        worst.sort_by(|a, b| a.0.partial_cmp(&b.0).unwrap());
        let b = baked.solution.bounce.as_ref().unwrap();
        let mean: f32 = worst.iter().map(|w| w.0).sum::<f32>() / worst.len() as f32;
        eprintln!("rho {rho} tol {tol}: shots {} {:.1}s ambient {:?} closure {:.5} min {:.4} max {:.4} mean {mean:.4} last trace {:?}", b.shots, t0.elapsed().as_secs_f64(), b.ambient, b.closure, worst[0].0, worst.last().unwrap().0, b.trace.last());
    }
}

fn polygon_ff(p: Vec3, n: Vec3, corners: &[Vec3]) -> f32 {
    // clip to upper hemisphere
    let mut poly = Vec::new();
    for k in 0..corners.len() {
        let a = corners[k] - p;
        let b = corners[(k + 1) % corners.len()] - p;
        let (da, db) = (a.dot(n), b.dot(n));
        if da >= 0.0 { poly.push(a); }
        if (da >= 0.0) != (db >= 0.0) { poly.push(a + (b - a) * (da / (da - db))); }
    }
    let mut sum = 0.0;
    for k in 0..poly.len() {
        let a = poly[k].normalize();
        let b = poly[(k + 1) % poly.len()].normalize();
        let c = a.cross(b);
        let l = c.length();
        if l > 1e-9 { sum += l.atan2(a.dot(b)) * n.dot(c) / l; }
    }
    sum.abs() / std::f32::consts::TAU
}

#[test]
fn debug_patches() {
    let baked = bake_emitters(&room([(0.5, 1.0); 6]), 96, |_| {});
    let tpu = baked.atlas.texels_per_unit;
    let patches = bake::solve::patches::build(&baked.texels, 1024, 1.0 / tpu);
    // the bad texel
    let (i, t) = baked.texels.texels.iter().enumerate().min_by(|a, b| (a.1.position() - Vec3::new(0.9659227, 0.03657743, -1.0)).length().partial_cmp(&(b.1.position() - Vec3::new(0.9659227, 0.03657743, -1.0)).length()).unwrap()).unwrap();
    let p = t.position() + Vec3::from(t.face_normal) * 0.5 / tpu;
    let n = t.normal();
    eprintln!("texel {i} at {:?} n {:?} p {:?} value {:?}", t.position, n, p, baked.solution.lightmap[i]);
    let wall = [Vec3::new(1.0, -1.0, -1.0), Vec3::new(1.0, 1.0, -1.0), Vec3::new(1.0, 1.0, 1.0), Vec3::new(1.0, -1.0, 1.0)];
    eprintln!("exact FF to x=1 wall {:.4}", polygon_ff(p, n, &wall));
    let mut sum = 0.0; let mut sum_disc = 0.0; let mut total_area = 0.0; let mut rect_area_total = 0.0;
    for pa in &patches.patches {
        let c = Vec3::from(pa.position);
        if (c.x - 1.0).abs() > 1e-3 { continue; }
        total_area += pa.area;
        let (u, v, rc) = (Vec3::from(pa.half_u), Vec3::from(pa.half_v), Vec3::from(pa.rect_centre));
        let ra = 4.0 * u.cross(v).length();
        rect_area_total += ra;
        let corners = [rc - u - v, rc + u - v, rc + u + v, rc - u + v];
        sum += polygon_ff(p, n, &corners) * (pa.area / ra).min(1.0);
        let d = c - p; let r2 = d.length_squared(); let r = r2.sqrt();
        let ci = n.dot(d) / r; let cj = -Vec3::from(pa.normal).dot(d) / r;
        if ci > 0.0 && cj > 0.0 { sum_disc += ci * cj * pa.area / (std::f32::consts::PI * r2 + pa.area); }
    }
    eprintln!("patches on x=1: area {total_area:.4} rect area {rect_area_total:.4}; sum exact {sum:.4} disc {sum_disc:.4}");
}

#[test]
fn debug_rects() {
    let baked = bake_emitters(&room([(0.5, 1.0); 6]), 96, |_| {});
    let tpu = baked.atlas.texels_per_unit;
    let patches = bake::solve::patches::build(&baked.texels, 1024, 1.0 / tpu);
    eprintln!("tpu {tpu} cell {}", patches.cell);
    let mut shown = 0;
    for pa in &patches.patches {
        let c = Vec3::from(pa.position);
        if (c.x - 1.0).abs() > 1e-3 { continue; }
        let (u, v, rc) = (Vec3::from(pa.half_u), Vec3::from(pa.half_v), Vec3::from(pa.rect_centre));
        let ra = 4.0 * u.cross(v).length();
        if ra / pa.area < 1.2 && pa.area > 0.0 { continue; }
        shown += 1; if shown > 6 { break; }
        eprintln!("patch area {:.5} rect {:.5} centre {:?} u {:?} v {:?}", pa.area, ra, rc, u, v);
        for m in 0..pa.count { let t = &baked.texels.texels[patches.members[(pa.first + m) as usize] as usize]; eprintln!("   texel x{} y{} pos {:?} area {:.5}", t.x(baked.texels.width), t.y(baked.texels.width), t.position, t.area); }
    }
}

#[test]
fn debug_edge_texels() {
    let baked = bake_emitters(&room([(0.5, 1.0); 6]), 96, |_| {});
    let w = baked.texels.width;
    let target = Vec3::new(-0.89276785, 1.0000001, -1.0);
    let (i, t) = baked.texels.texels.iter().enumerate().min_by(|a, b| (a.1.position() - target).length().partial_cmp(&(b.1.position() - target).length()).unwrap()).unwrap();
    let (x, y) = (t.x(w), t.y(w));
    eprintln!("texel {i} at x{x} y{y} pos {:?} area {} tri {} prim {} n {:?}", t.position, t.area, t.triangle, t.primitive, t.normal);
    for dy in -2i32..=2 { let mut line = String::new(); for dx in -2i32..=2 {
        let (nx, ny) = (x as i32 + dx, y as i32 + dy);
        match baked.texels.texels.iter().find(|t| t.x(w) as i32 == nx && t.y(w) as i32 == ny) {
            Some(t) => line += &format!(" [{:.3},{:.3},{:.3} a{:.4} p{}]", t.position[0], t.position[1], t.position[2], t.area, t.primitive),
            None => line += " [                 empty        ]",
        } } eprintln!("{line}"); }
}
