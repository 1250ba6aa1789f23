//! Known answers for the near field's form factors (include/form_factor.wgsl),
//! run on the GPU as the gather runs them: a point and a rectangle parallel
//! or perpendicular to its plane, in the closed forms of Howell's catalogue
//! of radiation configuration factors (B-3 and B-2 for a differential
//! element), a rectangle cut by the point's horizon, one wholly below it,
//! and a square standing in for a patch part.

use std::f64::consts::PI;

use super::shaders::{FORM_FACTOR, TEXEL};
use super::{Gpu, bind_buffers, read_buffer, storage_entry};

/// One evaluation: the receiver (position, normal) and the parallelogram
/// centre ± u ± v; for `square`, `u` holds the square's normal and area and
/// `v` the direction one side points along.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Case {
    p: [f32; 4],
    n: [f32; 4],
    centre: [f32; 4],
    u: [f32; 4],
    v: [f32; 4],
}

const BODY: &str = "
struct Case { p: vec4f, n: vec4f, centre: vec4f, u: vec4f, v: vec4f }
@group(0) @binding(0) var<storage, read> cases: array<Case>;
@group(0) @binding(1) var<storage, read_write> results: array<f32>;

@compute @workgroup_size(1)
fn parallelogram(@builtin(global_invocation_id) id: vec3u) {
    let c = cases[id.x];
    results[id.x] = parallelogram_form_factor(c.p.xyz, c.n.xyz, c.centre.xyz, c.u.xyz, c.v.xyz);
}

@compute @workgroup_size(1)
fn square(@builtin(global_invocation_id) id: vec3u) {
    let c = cases[id.x];
    results[id.x] = square_form_factor(c.p.xyz, c.n.xyz, c.centre.xyz, c.u.xyz, c.u.w, c.v.xyz);
}
";

/// Runs entry point `entry` over `cases` and reads back one value each.
fn evaluate(gpu: &Gpu, entry: &str, cases: &[Case]) -> Vec<f32> {
    let source = [TEXEL.source, FORM_FACTOR.source, BODY].join("\n");
    let module = gpu.device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("form factor cases"),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    let stages = wgpu::ShaderStages::COMPUTE;
    let layout = gpu.bind_group_layout(
        "form factor cases",
        &[
            // 0: the cases, 1: one result per case.
            storage_entry(0, true, stages),
            storage_entry(1, false, stages),
        ],
    );
    let pipeline_layout = gpu.device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("form factor cases"),
        bind_group_layouts: &[Some(&layout)],
        immediate_size: 0,
    });
    let pipeline = gpu.device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some("form factor cases"),
        layout: Some(&pipeline_layout),
        module: &module,
        entry_point: Some(entry),
        compilation_options: Default::default(),
        cache: None,
    });
    let input = gpu.storage_buffer("cases", cases, wgpu::BufferUsages::empty());
    let output = gpu.storage_buffer("results", &vec![f32::NAN; cases.len()], wgpu::BufferUsages::COPY_SRC);
    let group = bind_buffers(gpu, "form factor cases", &layout, &[&input, &output]);
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups(cases.len() as u32, 1, 1);
    }
    gpu.queue.submit([encoder.finish()]);
    read_buffer(gpu, &output, cases.len()).expect("read-back")
}

fn case(p: [f32; 3], n: [f32; 3], centre: [f32; 3], u: [f32; 4], v: [f32; 3]) -> Case {
    let w = |a: [f32; 3]| [a[0], a[1], a[2], 0.0];
    Case { p: w(p), n: w(n), centre: w(centre), u, v: w(v) }
}

/// From a point to an a × b rectangle parallel to its plane at height h,
/// one corner straight above it (Howell B-3, differential element).
fn parallel_corner(a: f64, b: f64, h: f64) -> f64 {
    let (x, y) = (a / h, b / h);
    let (sx, sy) = ((1.0 + x * x).sqrt(), (1.0 + y * y).sqrt());
    (x / sx * (y / sx).atan() + y / sy * (x / sy).atan()) / (2.0 * PI)
}

/// From a point to a rectangle in a plane perpendicular to its own, at
/// distance c, a wide along that plane from the foot of the point and b
/// high above it (Howell B-2, differential element).
fn perpendicular_corner(a: f64, b: f64, c: f64) -> f64 {
    let (x, y) = (a / c, b / c);
    let s = (1.0 + y * y).sqrt();
    (x.atan() - (x / s).atan() / s) / (2.0 * PI)
}

fn assert_close(got: f32, want: f64, what: &str) {
    let error = (got as f64 - want).abs();
    assert!(error <= 2e-6 + 1e-5 * want.abs(), "{what}: {got} against {want}");
}

#[test]
fn parallelogram_form_factors_match_the_closed_forms() {
    let gpu = Gpu::new(None).expect("an adapter");
    let up = [0.0, 1.0, 0.0];
    let (a, b, h, c) = (0.7f32, 1.9f32, 0.45f32, 0.6f32);
    let cases = [
        // A corner rectangle above the point, and a centred square (four corners).
        case([0.0; 3], up, [a / 2.0, h, b / 2.0], [a / 2.0, 0.0, 0.0, 0.0], [0.0, 0.0, b / 2.0]),
        case([0.0; 3], up, [0.0, h, 0.0], [a, 0.0, 0.0, 0.0], [0.0, 0.0, a]),
        // A wall c away, a wide and b high from the point's floor.
        case([0.0; 3], up, [a / 2.0, b / 2.0, c], [a / 2.0, 0.0, 0.0, 0.0], [0.0, b / 2.0, 0.0]),
        // The same wall reaching as far below the floor: the horizon cuts it.
        case([0.0; 3], up, [a / 2.0, 0.0, c], [a / 2.0, 0.0, 0.0, 0.0], [0.0, b, 0.0]),
        // Wholly below the point's horizon.
        case([0.0; 3], up, [0.0, -h, 0.0], [a, 0.0, 0.0, 0.0], [0.0, 0.0, a]),
        // A huge ceiling just above: nearly the whole hemisphere.
        case([0.0; 3], up, [0.0, 1e-3, 0.0], [1e3, 0.0, 0.0, 0.0], [0.0, 0.0, 1e3]),
    ];
    let got = evaluate(&gpu, "parallelogram", &cases);
    let (a, b, h, c) = (a as f64, b as f64, h as f64, c as f64);
    assert_close(got[0], parallel_corner(a, b, h), "corner rectangle above");
    assert_close(got[1], 4.0 * parallel_corner(a, a, h), "centred square above");
    assert_close(got[2], perpendicular_corner(a, b, c), "wall beside");
    assert_close(got[3], perpendicular_corner(a, b, c), "wall cut by the horizon");
    assert_eq!(got[4], 0.0, "below the horizon");
    assert_close(got[5], 1.0, "ceiling");
}

#[test]
fn a_square_stands_in_for_the_parallelogram_of_its_corners_and_only_from_its_front() {
    let gpu = Gpu::new(None).expect("an adapter");
    let (down, h, side) = ([0.0, -1.0, 0.0], 0.8f32, 0.5f32);
    let area = side * side;
    let square =
        |p: [f32; 3], n: [f32; 3]| case(p, n, [0.0, h, 0.0], [down[0], down[1], down[2], area], [1.0, 0.0, 0.0]);
    // From below (its front), and from above facing it (behind it).
    let got = evaluate(&gpu, "square", &[square([0.0; 3], [0.0, 1.0, 0.0]), square([0.0, 2.0 * h, 0.0], down)]);
    assert_close(got[0], 4.0 * parallel_corner(side as f64 / 2.0, side as f64 / 2.0, h as f64), "square in front");
    assert_eq!(got[1], 0.0, "a point behind the square sees none of it");
}
