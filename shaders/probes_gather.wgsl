// Light probes (src/probes/gather.rs): at each probe point the light
// arriving from every direction, summed into the six faces of an ambient
// cube (+X, -X, +Y, -Y, +Z, -Z), each the cosine-weighted sum over its
// hemisphere. The environment comes as the bake's lights, one shadow ray
// each; everything else as the solved surfaces' outgoing radiance, read
// from the lightmap where a gather ray first meets a surface. A workgroup
// takes one probe and a share of its rays, and sums its lanes in a fixed
// order, so the result does not depend on scheduling.

@group(0) @binding(0) var<uniform> params: ProbeParams;
@group(0) @binding(1) var<storage, read> probes: array<vec4f>;
@group(0) @binding(2) var<storage, read> lights: array<ProbeLight>;
@group(0) @binding(3) var<storage, read> directions: array<vec4f>;
// Per texel triangle id, its three corners' lightmap UVs in the order the
// trace records hold its corners.
@group(0) @binding(4) var<storage, read> triangle_uvs: array<vec2f>;
// Outgoing radiance (albedo · L_lm + emission) per atlas texel, charts
// grown by a ring so a hit on a chart's edge never reads an empty texel.
@group(0) @binding(5) var<storage, read> radiance: array<vec4f>;
// Per (probe, workgroup): the six faces' sums, then (back-face hits,
// walks cut short, 0, 0).
@group(0) @binding(6) var<storage, read_write> probe_sums: array<ProbeSums>;

// Mirrors `gather::ProbeParams`.
struct ProbeParams {
    probe_count: u32,
    light_count: u32,
    ray_count: u32,     // gather directions
    groups: u32,        // workgroups per probe
    atlas_width: u32,
    atlas_height: u32,
    _pad0: u32,
    _pad1: u32,
}

// Mirrors `gather::ProbeLight`: an environment light (`environment::Light`).
struct ProbeLight {
    direction: vec3f,
    solid_angle: f32,
    radiance: vec3f,
    _pad: f32,
}

// Mirrors `gather::ProbeSums`.
struct ProbeSums {
    faces: array<vec4f, 6>,
    counts: vec4f,
}

const LANES: u32 = 64u;

var<workgroup> shared_sums: array<ProbeSums, LANES>;

// Adds light `value` arriving along -d (from direction d) to the faces it
// reaches, weighted by the cosine of each.
fn add_to_faces(sums: ptr<function, ProbeSums>, d: vec3f, value: vec3f) {
    let positive = max(d, vec3f(0.0));
    let negative = max(-d, vec3f(0.0));
    (*sums).faces[0] += vec4f(value * positive.x, 0.0);
    (*sums).faces[1] += vec4f(value * negative.x, 0.0);
    (*sums).faces[2] += vec4f(value * positive.y, 0.0);
    (*sums).faces[3] += vec4f(value * negative.y, 0.0);
    (*sums).faces[4] += vec4f(value * positive.z, 0.0);
    (*sums).faces[5] += vec4f(value * negative.z, 0.0);
}

// The outgoing radiance of the surface a gather ray met at `hit`
// (`closest_hit`'s), or -1 in w where the ray met its back.
fn surface_radiance(d: vec3f, hit: vec4f) -> vec4f {
    let k = bitcast<u32>(hit.x);
    let base = scene.triangle_base + 3u * k;
    let a = record(base);
    let b = record_point(base + 1u);
    let c = record_point(base + 2u);
    let v0 = bitcast<vec3f>(a.xyz);
    if (dot(cross(b - v0, c - v0), d) >= 0.0) {
        return vec4f(0.0, 0.0, 0.0, -1.0);
    }
    let id = a.w;
    let w = vec3f(1.0 - hit.y - hit.z, hit.y, hit.z);
    let uv = triangle_uvs[3u * id] * w.x + triangle_uvs[3u * id + 1u] * w.y + triangle_uvs[3u * id + 2u] * w.z;
    let size = vec2f(f32(params.atlas_width), f32(params.atlas_height));
    let texel = vec2<u32>(clamp(floor(uv * size), vec2f(0.0), size - 1.0));
    return vec4f(radiance[texel.x + texel.y * params.atlas_width].rgb, 1.0);
}

// One lane's share of probe `probe`'s rays: ray j is light j, then
// gather direction j - light_count.
fn lane_sums(p: vec3f, lane: u32) -> ProbeSums {
    var sums: ProbeSums;
    let stride = LANES * params.groups;
    let total = params.light_count + params.ray_count;
    // Each gather ray stands for an equal share of the sphere.
    let share = 4.0 * PI / f32(max(params.ray_count, 1u));
    var back = 0.0;
    for (var j = lane; j < total; j += stride) {
        if (j < params.light_count) {
            let light = lights[j];
            if (!occluded(p, light.direction, 3.0e38, 0xffffffffu, true)) {
                add_to_faces(&sums, light.direction, light.radiance * light.solid_angle);
            }
        } else {
            let d = directions[j - params.light_count].xyz;
            let hit = closest_hit(p, d);
            if (hit.w >= 0.0) {
                let surface = surface_radiance(d, hit);
                back += select(0.0, 1.0, surface.w < 0.0);
                add_to_faces(&sums, d, max(surface.rgb, vec3f(0.0)) * share);
            }
        }
    }
    sums.counts = vec4f(back, select(0.0, 1.0, trace_cut), 0.0, 0.0);
    return sums;
}

@compute @workgroup_size(64)
fn main(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_index) local: u32) {
    let probe = group.x;
    let valid = probe < params.probe_count;
    var mine: ProbeSums;
    if (valid) {
        mine = lane_sums(probes[probe].xyz, group.y * LANES + local);
    }
    shared_sums[local] = mine;
    workgroupBarrier();
    // Pairwise, always in the same order.
    for (var half = LANES / 2u; half > 0u; half /= 2u) {
        if (local < half) {
            let other = shared_sums[local + half];
            for (var f = 0u; f < 6u; f++) {
                shared_sums[local].faces[f] += other.faces[f];
            }
            shared_sums[local].counts += other.counts;
        }
        workgroupBarrier();
    }
    if (local == 0u && valid) {
        probe_sums[probe * params.groups + group.y] = shared_sums[0];
    }
}
