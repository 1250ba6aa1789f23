// Bare kernels of the direct pass's two parts (benches/table4/ceiling.rs),
// after texel.wgsl, materials.wgsl and trace.wgsl: the light loop with
// nothing but each pair's cosine and power, and shadow rays cast by
// trace.wgsl's walk with nothing around them.

struct BareParams {
    point_count: u32,
    row_stride: u32,
    light_count: u32,
    first_ray: u32,        // rays of this dispatch: first_ray .. first_ray + rays
    rays: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(0) @binding(0) var<uniform> bare: BareParams;
// As solve_direct's: direction and cos α; L·Ω and Ω; sin α.
@group(0) @binding(1) var<uniform> lights: array<vec4f, 3072>;
@group(0) @binding(2) var<storage, read> points: array<Texel>;
@group(0) @binding(3) var<storage, read_write> sums: array<vec4f>;
// Rays cast, rays that met nothing, nodes and triangles visited.
@group(0) @binding(4) var<storage, read_write> counts: array<atomic<u32>, 3>;

fn point_index(id: vec3u) -> u32 {
    return id.x + id.y * bare.row_stride;
}

fn mix_bits(x: u32) -> u32 {
    var h = x * 747796405u + 2891336453u;
    h = ((h >> ((h >> 28u) + 4u)) ^ h) * 277803737u;
    return (h >> 22u) ^ h;
}

// Every light of the batch at one point: one cosine, one multiply-add.
@compute @workgroup_size(64)
fn light_loop(@builtin(global_invocation_id) id: vec3u) {
    let i = point_index(id);
    if (i >= bare.point_count) {
        return;
    }
    let n = points[i].normal;
    var e = vec3f(0.0);
    for (var k = 0u; k < bare.light_count; k++) {
        let head = lights[3u * k];
        e += lights[3u * k + 1u].rgb * max(dot(n, head.xyz), 0.0);
    }
    sums[i] += vec4f(e, 0.0);
}

// `bare.rays` shadow rays from one point, each towards a light drawn at
// random and jittered over its cone, mirrored above the face where it
// points below: every ray walks, so every lane is busy.
@compute @workgroup_size(64)
fn shadow_rays(@builtin(global_invocation_id) id: vec3u) {
    let i = point_index(id);
    if (i >= bare.point_count) {
        return;
    }
    let p = points[i];
    let o = ray_origin(p.position, p.face_normal);
    var open = 0u;
    for (var r = bare.first_ray; r < bare.first_ray + bare.rays; r++) {
        let h = mix_bits(mix_bits(i) ^ r);
        let head = lights[3u * (h % bare.light_count)];
        let u = vec2f(f32(h & 0xffffu), f32(h >> 16u)) / 65536.0;
        let cos_t = 1.0 - u.x * (1.0 - head.w);
        let sin_t = sqrt(max(1.0 - cos_t * cos_t, 0.0));
        let frame = basis(head.xyz);
        let phi = 6.2831853 * u.y;
        var d = normalize(frame[0] * (sin_t * cos(phi)) + frame[1] * (sin_t * sin(phi)) + frame[2] * cos_t);
        let below = dot(d, p.face_normal);
        d = normalize(d - p.face_normal * (2.0 * min(below, 0.0) - 1e-3));
        open += select(1u, 0u, occluded(o, d, 3.0e38, p.triangle, true));
    }
    atomicAdd(&counts[0], bare.rays);
    atomicAdd(&counts[1], open);
    atomicAdd(&counts[2], trace_visits);
}
