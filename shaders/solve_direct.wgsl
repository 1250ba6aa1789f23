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
        let ls = light_space(p, w, params.centre, params.radius);
        let pixel = vec2f(ls.x * 0.5 + 0.5, 0.5 - ls.y * 0.5) * size;
        let xy = vec2<i32>(clamp(floor(pixel), vec2f(0.0), vec2f(size - 1.0)));
        let tile = vec2<i32>(i32(k % params.tiles_per_row), i32(k / params.tiles_per_row)) * i32(size);
        let stored = textureLoad(depth_maps, xy + tile, 0);
        // Slope-scaled bias: a tilted surface's depth changes across a shadow-map texel.
        let cos_f = abs(dot(face, w));
        let tangent = min(sqrt(max(1.0 - cos_f * cos_f, 0.0)) / max(cos_f, 1e-4), params.max_slope);
        let bias = (params.constant_bias + params.slope_bias * tangent) / (2.0 * params.radius);
        let weight = light.power.w * cos_n;
        facing += weight;
        if (ls.z <= stored + bias) {
            sum += light.power.rgb * cos_n;
        } else {
            blocked += weight;
        }
    }
    irradiance[i] += vec4f(sum, 0.0);
    coverage[i] += vec2f(blocked, facing);
}
