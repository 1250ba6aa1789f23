//! What one read or write costs a compute shader on this adapter: bare
//! kernels over 2,000,000 invocations (workgroups of 64), each reading or
//! writing one element the way the solve's passes do, timed by submission
//! (median of 15 after a warm-up). On a CPU driver (lavapipe) the answer
//! decides where per-texel data lives: it reads a storage buffer lane by
//! lane, whatever the index, and fetches texels several times faster.
//! Results go to stdout as markdown; compare rows of one run.
//!
//! ```text
//! cargo bench --bench gpu_reads
//! ```

use std::time::Instant;

use anyhow::Result;
use bake::gpu::Gpu;

const INVOCATIONS: u32 = 2_000_000;
const WIDTH: u32 = 2048;

/// (what it measures, the body run for invocation `i` at texel `xy`).
const KERNELS: &[(&str, &str)] = &[
    ("nothing (the dispatch itself)", ""),
    ("store one f32 to a storage buffer", "data[i].w = 0.0;"),
    ("store one vec4 to a storage buffer", "data[i] = vec4f(f32(i));"),
    ("load one f32 from a storage buffer", "data[i].w = data[4u * i].x;"),
    ("load one vec4 from a storage buffer", "let v = data[4u * i]; data[i].w = dot(v, v);"),
    ("read-modify-write one vec4 of a storage buffer", "data[i] = data[i] * 2.0 + 1.0;"),
    ("fetch one vec4 texel (textureLoad)", "data[i].w = textureLoad(records, xy, 0).x;"),
    (
        "fetch four vec4 texels",
        "let v = textureLoad(records, xy, 0) + textureLoad(records, xy + vec2(1u, 0u), 0) \
         + textureLoad(records, xy + vec2(2u, 0u), 0) + textureLoad(records, xy + vec2(3u, 0u), 0); \
         data[i].w = dot(v, v);",
    ),
];

fn main() -> Result<()> {
    let gpu = Gpu::new(None)?;
    let device = &gpu.device;
    println!("adapter: {}\n", gpu.adapter);
    println!("| kernel | ms | ns per invocation | over the bare dispatch (ns) |");
    println!("|---|---|---|---|");
    let data = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("gpu_reads data"),
        size: (INVOCATIONS as u64 * 4 + 16) * 16,
        usage: wgpu::BufferUsages::STORAGE,
        mapped_at_creation: false,
    });
    let texture = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("gpu_reads records"),
        size: wgpu::Extent3d { width: WIDTH, height: INVOCATIONS.div_ceil(WIDTH), depth_or_array_layers: 1 },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba32Float,
        usage: wgpu::TextureUsages::TEXTURE_BINDING,
        view_formats: &[],
    });
    let view = texture.create_view(&Default::default());
    let mut bare = None;
    for (name, body) in KERNELS {
        let seconds = time_kernel(&gpu, &data, &view, body);
        let per = seconds * 1e9 / INVOCATIONS as f64;
        let over = bare.map_or(String::new(), |b: f64| format!("{:.1}", per - b));
        bare.get_or_insert(per);
        println!("| {name} | {:.2} | {per:.1} | {over} |", seconds * 1e3);
    }
    Ok(())
}

/// Median seconds of one submission of `body` over every invocation.
fn time_kernel(gpu: &Gpu, data: &wgpu::Buffer, view: &wgpu::TextureView, body: &str) -> f64 {
    let device = &gpu.device;
    // Every kernel binds both, so one layout serves them all.
    let source = format!(
        "@group(0) @binding(0) var<storage, read_write> data: array<vec4f>;
         @group(0) @binding(1) var records: texture_2d<f32>;
         @compute @workgroup_size(64)
         fn main(@builtin(global_invocation_id) id: vec3u) {{
             let i = id.x + id.y * 65535u * 64u;
             if (i >= {INVOCATIONS}u) {{ return; }}
             let xy = vec2u(i % {WIDTH}u, i / {WIDTH}u);
             if (i == 0xffffffffu) {{ data[0] = textureLoad(records, xy, 0); }}
             {body}
         }}"
    );
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("gpu_reads"),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some("gpu_reads"),
        layout: None,
        module: &module,
        entry_point: Some("main"),
        compilation_options: Default::default(),
        cache: None,
    });
    let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("gpu_reads"),
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[
            wgpu::BindGroupEntry { binding: 0, resource: data.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(view) },
        ],
    });
    let groups = INVOCATIONS.div_ceil(64);
    let (x, y) = (groups.min(65535), groups.div_ceil(65535));
    let mut times: Vec<f64> = (0..16)
        .map(|_| {
            let start = Instant::now();
            let mut encoder = device.create_command_encoder(&Default::default());
            {
                let mut pass = encoder.begin_compute_pass(&Default::default());
                pass.set_pipeline(&pipeline);
                pass.set_bind_group(0, &group, &[]);
                pass.dispatch_workgroups(x, y, 1);
            }
            gpu.queue.submit([encoder.finish()]);
            gpu.wait().expect("the kernel finishes");
            start.elapsed().as_secs_f64()
        })
        .skip(1)
        .collect();
    times.sort_by(f64::total_cmp);
    times[times.len() / 2]
}
