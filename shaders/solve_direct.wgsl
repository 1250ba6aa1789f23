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


// Largest shadow-filter radius, shadow-map texels (about two lightmap
// texels): wider penumbrae are left to the sum over the other lights. Wider
// filters measured worse against the reference and, inside closed rooms,
// let light in past zero-thickness walls.
const MAX_FILTER: f32 = 4.0;
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

// A receiver texel as one light's shadow map sees it.
struct Receiver {
    pixel: vec2f,          // shadow-map position of the test point (lifted off the surface)
    z: f32,                // its depth
    bias: f32,             // depth tolerance
    surface_pixel: vec2f,  // shadow-map position of the surface point itself
    surface_z: f32,        // its depth
    _pad: f32,
    slope: vec2f,          // the surface plane's depth change per shadow-map texel
    tile: vec2<i32>,       // the light's tile in the depth atlas
    front: bool,           // the light is on the front of the receiver's geometric face
}

// Whether the receiver is lit as seen by the shadow-map texel holding `at`
// (pixel units). The depth map holds the depth of the first surface at each
// texel's centre. Where that is the receiver's own plane (carried from the
// receiver to the centre along `slope`: receiver-plane depth bias), the
// texel shows the receiver itself: lit, at any tilt, with no large constant
// bias. Anything else there is compared with the receiver's own depth: in
// front of it, it blocks. A plain slope-scaled bias would let light through
// geometry that meets the receiver (a wall under a ceiling, a box on a
// floor), and carrying the plane alone would see through such a corner
// wherever the plane, extended, passes in front of the other surface.
fn lit_at(at: vec2f, r: Receiver) -> bool {
    return lit_at_depth(at, r, r.z);
}

// As `lit_at`, for a point of the ray from the receiver at depth `z` rather
// than the receiver itself.
fn lit_at_depth(at: vec2f, r: Receiver, z: f32) -> bool {
    let size = params.map_size;
    let cell = clamp(floor(at), vec2f(0.0), vec2f(size - 1.0));
    let stored = textureLoad(depth_maps, vec2<i32>(cell) + r.tile, 0);
    if (z <= stored + r.bias) {
        return true;
    }
    // Only a plane facing the light can be the receiver seen from it (from
    // behind, a zero-thickness wall stands between them).
    if (!r.front) {
        return false;
    }
    // The receiver's plane, carried to this texel's centre. A curved surface
    // leaves its tangent plane quadratically: the tolerance grows with the
    // distance carried (a texel of depth at 4 texels, 16 at 16).
    let carried = cell + 0.5 - r.surface_pixel;
    let plane = r.surface_z + dot(r.slope, carried);
    let tolerance = params.plane_tolerance * (1.0 + dot(carried, carried) / 8.0);
    if (abs(stored - plane) > tolerance) {
        return false;
    }
    // Depth alone cannot tell the receiver's own tilted plane from another
    // surface meeting it (a floor under a wall): their depths agree along
    // the line where they meet. The stored surface's slope on both sides of
    // this texel must be the receiver's: at such a junction one side is not.
    let lo = vec2f(0.0);
    let hi = vec2f(size - 1.0);
    let left = textureLoad(depth_maps, vec2<i32>(clamp(cell - vec2f(1.0, 0.0), lo, hi)) + r.tile, 0);
    let right = textureLoad(depth_maps, vec2<i32>(clamp(cell + vec2f(1.0, 0.0), lo, hi)) + r.tile, 0);
    let up = textureLoad(depth_maps, vec2<i32>(clamp(cell - vec2f(0.0, 1.0), lo, hi)) + r.tile, 0);
    let down = textureLoad(depth_maps, vec2<i32>(clamp(cell + vec2f(0.0, 1.0), lo, hi)) + r.tile, 0);
    let mine = vec3f(r.slope * size, -1.0);
    return same_slope(mine, vec2f(right - stored, down - stored) * size)
        && same_slope(mine, vec2f(stored - left, stored - up) * size);
}

// Whether a stored surface with depth slope `theirs` (per texel, scaled to
// texels of depth) is parallel to the receiver's plane within about 25°.
fn same_slope(mine: vec3f, theirs: vec2f) -> bool {
    let other = vec3f(theirs, -1.0);
    return dot(mine, other) >= 0.9 * length(mine) * length(other);
}

// Depth of the first surface at the centre of the texel holding `at`.
fn stored_depth(at: vec2f, tile: vec2<i32>) -> f32 {
    let size = params.map_size;
    return textureLoad(depth_maps, vec2<i32>(clamp(floor(at), vec2f(0.0), vec2f(size - 1.0))) + tile, 0);
}

// How much of a distant light of angular radius atan(tan_alpha) reaches the
// receiver (percentage-closer soft shadows, Fernando 2005): a blocker search
// over the largest possible penumbra, then a filter as wide as the penumbra
// the nearest blocker casts.
fn light_visibility(r: Receiver, tan_alpha: f32, spin: f32) -> f32 {
    let size = params.map_size;
    let depth_to_texels = 2.0 * params.radius * tan_alpha / (2.0 * params.radius / size);
    let reach = r.z * depth_to_texels;
    if (reach < 0.75) {
        return select(0.0, 1.0, lit_at(r.pixel, r));
    }
    let search = min(reach, MAX_FILTER);
    // The nearest blocker (deepest stored depth) sets the penumbra: an
    // average would let a far blocker widen the filter of a receiver that a
    // near one (a wall beside it) already shades, and light would leak in.
    var blockers = 0.0;
    var blocker_depth = 0.0;
    for (var j = 0u; j <= SEARCH_TAPS; j++) {
        // Tap SEARCH_TAPS is the centre.
        let at = r.pixel + select(spiral(j, SEARCH_TAPS, spin) * search, vec2f(0.0), j == SEARCH_TAPS);
        if (!lit_at(at, r)) {
            blockers += 1.0;
            blocker_depth = max(blocker_depth, stored_depth(at, r.tile));
        }
    }
    if (blockers == 0.0) {
        return 1.0;
    }
    let penumbra = clamp((r.z - blocker_depth) * depth_to_texels, 0.5, MAX_FILTER);
    // Each tap stands for a ray from the receiver that reaches the blocker's
    // depth at the tap: it must clear what lies on its way there too. (The
    // tap alone would see past a floor seen edge-on, a band a texel or two
    // wide, into a sealed room; with taps at most MAX_FILTER texels out,
    // three points on the way are a texel apart.)
    var lit = 0.0;
    for (var j = 0u; j < FILTER_TAPS; j++) {
        let offset = spiral(j, FILTER_TAPS, spin + 1.0) * penumbra;
        if (lit_at(r.pixel + offset, r)
            && lit_at_depth(r.pixel + 0.25 * offset, r, mix(r.z, blocker_depth, 0.25))
            && lit_at_depth(r.pixel + 0.5 * offset, r, mix(r.z, blocker_depth, 0.5))
            && lit_at_depth(r.pixel + 0.75 * offset, r, mix(r.z, blocker_depth, 0.75))) {
            lit += 1.0;
        }
    }
    return lit / f32(FILTER_TAPS);
}

// Shadow-map position (pixels) and depth of world point `q` for the light
// whose basis is `m` (as `light_space` in common.wgsl, with the basis given).
fn shadow_map_position(q: vec3f, m: mat3x3f) -> vec3f {
    let d = q - params.centre;
    let ls = vec3f(dot(d, m[0]), dot(d, m[1]), 0.5 * params.radius - 0.5 * dot(d, m[2])) / params.radius;
    return vec3f(vec2f(ls.x * 0.5 + 0.5, 0.5 - ls.y * 0.5) * params.map_size, ls.z);
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
        let tile = vec2<i32>(i32(k % params.tiles_per_row), i32(k / params.tiles_per_row)) * i32(size);
        let lifted = shadow_map_position(p, m);
        let surface = shadow_map_position(texel.position, m);
        let bias = params.constant_bias / (2.0 * params.radius);
        // The receiver plane's depth per shadow-map texel (x right, y down).
        let f_dot_w = select(-1.0, 1.0, dot(face, w) >= 0.0) * max(abs(dot(face, w)), 1.0 / params.max_slope);
        let slope = vec2f(dot(face, m[0]), -dot(face, m[1])) / f_dot_w * (texel_world * 0.5 / params.radius);
        let receiver = Receiver(lifted.xy, lifted.z, bias, surface.xy, surface.z, 0.0, slope, tile, dot(face, w) > 0.0);
        let visible = light_visibility(receiver, light.direction.w, spin);
        sum += light.power.rgb * cos_n * visible;
        // Coverage counts only directions in front of the geometric face: a
        // light behind the facet but in front of the shading normal is cut
        // off by the texel's own surface, which is no other surface seen (a
        // lone faceted sphere sees nothing but sky).
        if (receiver.front) {
            let weight = light.power.w * cos_n;
            facing += weight;
            blocked += weight * (1.0 - visible);
        }
    }
    irradiance[i] += vec4f(sum, 0.0);
    coverage[i] += vec2f(blocked, facing);
}
