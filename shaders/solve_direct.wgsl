// Direct environment light (design notes, algorithm step 3): every receiver
// texel gathers, for each light k of the batch,
//     ΔE = L_k Ω_k max(0, n·ω_k) V_k(p)
// with V from the light's depth map. Gathering per texel (no atomics) keeps
// the sum's order fixed, so bakes are identical run to run.

@group(0) @binding(0) var<uniform> params: DirectParams;
@group(0) @binding(1) var<uniform> lights: LightBatch;
@group(0) @binding(2) var<storage, read> texels: array<Texel>;
// Irradiance E per texel (rgb), accumulated over batches.
@group(0) @binding(3) var<storage, read_write> irradiance: array<vec4f>;
// Per texel: Σ Ω cos θ over the lights in front of it that geometry blocks
// (x), and over all lights in front of it (y). Their ratio is the share of
// the texel's hemisphere the scene covers: how much of the light it reflects
// lands on other surfaces. No texel blocked means no surface sees another.
@group(0) @binding(5) var<storage, read_write> coverage: array<vec2f>;
// The batch's shadow maps, tiled `tiles_per_row` to a row.
@group(0) @binding(4) var depth_maps: texture_depth_2d;


// Largest shadow-filter radius, shadow-map texels.
const MAX_FILTER: f32 = 16.0;
const SEARCH_TAPS: u32 = 8u;
const FILTER_TAPS: u32 = 16u;

// Tap j of n on a golden-angle spiral filling the unit disc, turned by
// `spin` (computed, not read from an array: a CPU driver would keep an
// indexed array in memory per lane).
fn spiral(j: u32, n: u32, spin: f32) -> vec2f {
    let r = sqrt((f32(j) + 0.5) / f32(n));
    let a = f32(j) * 2.39996323 + spin;
    return r * vec2f(cos(a), sin(a));
}

// Stored depth at shadow-map position `pixel` of the light's tile.
fn stored_depth(pixel: vec2f, tile: vec2<i32>, size: f32) -> f32 {
    let xy = vec2<i32>(clamp(floor(pixel), vec2f(0.0), vec2f(size - 1.0)));
    return textureLoad(depth_maps, xy + tile, 0);
}

// How much of a distant light of angular radius atan(tan_alpha) reaches the
// receiver at shadow-map position `pixel`, depth `z` (percentage-closer soft
// shadows, Fernando 2005): a blocker search over the largest possible
// penumbra, then a filter as wide as the penumbra the blockers found.
// `slope` is the receiver plane's depth change per texel, so taps away from
// the centre compare against the receiver's own depth there.
fn light_visibility(pixel: vec2f, z: f32, bias: f32, slope: vec2f, tan_alpha: f32, tile: vec2<i32>, spin: f32) -> f32 {
    let size = params.map_size;
    let depth_to_texels = 2.0 * params.radius * tan_alpha / (2.0 * params.radius / size);
    let reach = z * depth_to_texels;
    if (reach < 0.75) {
        return select(0.0, 1.0, z <= stored_depth(pixel, tile, size) + bias);
    }
    let search = min(reach, MAX_FILTER);
    var blockers = 0.0;
    var blocker_depth = 0.0;
    for (var j = 0u; j < SEARCH_TAPS; j++) {
        let offset = spiral(j, SEARCH_TAPS, spin) * search;
        let stored = stored_depth(pixel + offset, tile, size);
        if (z + dot(slope, offset) > stored + bias) {
            blockers += 1.0;
            blocker_depth += stored;
        }
    }
    let centre = stored_depth(pixel, tile, size);
    if (z > centre + bias) {
        blockers += 1.0;
        blocker_depth += centre;
    }
    if (blockers == 0.0) {
        return 1.0;
    }
    let penumbra = clamp((z - blocker_depth / blockers) * depth_to_texels, 0.5, MAX_FILTER);
    var lit = 0.0;
    for (var j = 0u; j < FILTER_TAPS; j++) {
        let offset = spiral(j, FILTER_TAPS, spin + 1.0) * penumbra;
        if (z + dot(slope, offset) <= stored_depth(pixel + offset, tile, size) + bias) {
            lit += 1.0;
        }
    }
    return lit / f32(FILTER_TAPS);
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x + id.y * params.row_stride;
    if (i >= params.texel_count) {
        return;
    }
    let texel = texels[i];
    let n = texel.normal;
    let face = texel.face_normal;
    // Offset along the geometric normal by a shadow-map texel: the receiver
    // then tests a point just off its own surface (no acne).
    let p = texel.position + face * params.normal_offset;
    let size = params.map_size;
    let texel_world = 2.0 * params.radius / size;
    // A fixed turn of the filter pattern per texel trades banding for fine noise.
    let spin = f32((texel.index * 2654435761u) >> 8u) * (6.2831853 / 16777216.0);
    var sum = vec3f(0.0);
    var blocked = 0.0;
    var facing = 0.0;
    for (var k = 0u; k < params.light_count; k++) {
        let light = lights.items[k];
        let w = light.direction.xyz;
        let cos_n = dot(n, w);
        if (cos_n <= 0.0) {
            continue;
        }
        let m = basis(w);
        let d = p - params.centre;
        let ls = vec3f(dot(d, m[0]), dot(d, m[1]), 0.5 * params.radius - 0.5 * dot(d, w)) / params.radius;
        let pixel = vec2f(ls.x * 0.5 + 0.5, 0.5 - ls.y * 0.5) * size;
        let tile = vec2<i32>(i32(k % params.tiles_per_row), i32(k / params.tiles_per_row)) * i32(size);
        // Slope-scaled bias: a tilted surface's depth changes across a shadow-map texel.
        let cos_f = max(abs(dot(face, w)), 1e-4);
        let tangent = min(sqrt(max(1.0 - cos_f * cos_f, 0.0)) / cos_f, params.max_slope);
        let bias = (params.constant_bias + params.slope_bias * tangent) / (2.0 * params.radius);
        // The receiver plane's depth per shadow-map texel (x right, y down).
        let f_dot_w = sign(dot(face, w)) * max(abs(dot(face, w)), 0.05);
        let slope = vec2f(dot(face, m[0]), -dot(face, m[1])) / f_dot_w * (texel_world * 0.5 / params.radius);
        let visible = light_visibility(pixel, ls.z, bias, slope, light.direction.w, tile, spin);
        let weight = light.power.w * cos_n;
        facing += weight;
        sum += light.power.rgb * cos_n * visible;
        blocked += weight * (1.0 - visible);
    }
    irradiance[i] += vec4f(sum, 0.0);
    coverage[i] += vec2f(blocked, facing);
}
