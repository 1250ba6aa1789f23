// Which opaque casters each hemicube face of the batch can see (design
// notes, algorithm step 4), listed so that the hemicube pass draws only
// those. A face sees part of the scene (in Table 4's, the lists hold 10–19 %
// of the triangle-face pairs), but a draw pays for every triangle it names:
// a CPU driver shades and sets up each one before its clipper drops it,
// single-threaded, and that was most of the bounce pass.
//
// A triangle is left out of a face's list only when all three corners lie
// beyond one plane of the face's frustum, by a margin over rounding, or
// when it is on a solid's far side from an eye outside the solid's bounds
// (`surfaces::solids`): a ray from there meets the solid's near side first.
// So the list draws every fragment of the scene that the depth test would
// keep, but for pixels on a solid's outline, where the far side ties with
// the near one and the marks in the depths' low bits picked either. The
// lists' order varies with the GPU's scheduling; the hemicube pass's depth
// test does not hang on it (`hemicube_depth`). A list that would overflow
// falls back to every opaque caster.

struct CullParams {
    triangles: u32,    // opaque caster triangles, first in `culled`
    capacity: u32,     // triangles one face's list holds
    lists_first: u32,  // where the lists start in `culled`, in indices
    faces: u32,        // five per shooter slot
    near: f32,         // the hemicube's near plane (`BounceParams`)
    row_stride: u32,   // invocations per dispatch row
    _pad: vec2u,
}

// A face's indirect draw (`DrawIndexedIndirectArgs`), then the count of
// triangles its list was given this batch: `DRAW_WORDS` words per face.
const DRAW_WORDS: u32 = 8u;
const DRAW_COUNT: u32 = 5u;
// Caster vertices as words (`CasterIn`, 36 bytes): the position comes first.
const CASTER_WORDS: u32 = 9u;

@group(0) @binding(0) var<uniform> cull: CullParams;
@group(0) @binding(1) var<storage, read> caster_words: array<f32>;
// The batch's hemicube faces, five per slot: a uniform buffer, which a CPU
// driver reads once for all lanes, where it reads a storage buffer's
// elements lane by lane (every triangle reads every face).
struct FaceBatch {
    items: array<HemicubeFace, FACES>,
}
const FACES: u32 = 5u * MAX_SHOOTERS;
@group(0) @binding(2) var<uniform> faces: FaceBatch;
// The casters' indices (opaque, then alpha-MASK), then a list per face.
@group(0) @binding(3) var<storage, read_write> culled: array<u32>;
@group(0) @binding(4) var<storage, read_write> draws: array<atomic<u32>>;
// Each opaque triangle's solid (NOT_SOLID: none), and the solids.
@group(0) @binding(5) var<storage, read> triangle_solid: array<u32>;
@group(0) @binding(6) var<storage, read> solids: array<Solid>;

const NOT_SOLID: u32 = 0xffffffffu;

struct Solid {
    lo: vec3f,
    outside_facing: f32,  // 1: the outside is the front, -1: the back
    hi: vec3f,
    _pad: f32,
}

// Whether the triangle (corners `p`, front normal `n`, on `solid`) is on the
// solid's far side from `eye`, clearly so: an eye outside the bounds, and
// the triangle turned away from it by more than rounding. The bounds are
// widened by twice the near plane: the solid's near side is then beyond it
// wherever a face can see it (|x|, |y| ≤ z), so clipping never opens it.
fn on_far_side(solid: u32, s: Solid, p: array<vec3f, 3>, n: vec3f, eye: vec3f) -> bool {
    if (solid == NOT_SOLID) {
        return false;
    }
    if (all(eye >= s.lo - 2.0 * cull.near) && all(eye <= s.hi + 2.0 * cull.near)) {
        return false;
    }
    let to_eye = eye - p[0];
    return dot(n, to_eye) * s.outside_facing < -1e-4 * length(n) * length(to_eye);
}

fn caster_position(index: u32) -> vec3f {
    let w = index * CASTER_WORDS;
    return vec3f(caster_words[w], caster_words[w + 1u], caster_words[w + 2u]);
}

// a > b by more than rounding in the vertex shader could account for.
fn clearly_above(a: f32, b: f32) -> bool {
    return a - b > 1e-5 * (abs(a) + abs(b));
}

// Bit 5·face + k set where `local` (in the shooter's frame) lies beyond
// plane k of that face's frustum, as `face_vertex` in solve_hemicube.wgsl
// projects it: |x| ≤ z, then 0 ≤ y ≤ z on a half face (−z ≤ y ≤ z on the
// top face), then z ≥ near.
fn outside_planes(local: vec3f) -> u32 {
    var bits = 0u;
    for (var face = 0u; face < 5u; face++) {
        let f = hemicube_face_frame(local, face);
        let lowest_y = select(0.0, -f.z, face == 0u);
        let beyond = vec4<bool>(clearly_above(f.x, f.z), clearly_above(-f.z, f.x), clearly_above(f.y, f.z),
                                clearly_above(lowest_y, f.y));
        let planes = dot(select(vec4u(0u), vec4u(1u, 2u, 4u, 8u), beyond), vec4u(1u))
            | select(0u, 16u, clearly_above(cull.near, f.z));
        bits |= planes << (5u * face);
    }
    return bits;
}

// One opaque triangle against every face of the batch.
@compute @workgroup_size(64)
fn cull_triangles(@builtin(global_invocation_id) id: vec3u) {
    let triangle = id.x + id.y * cull.row_stride;
    if (triangle >= cull.triangles) {
        return;
    }
    let corners = vec3u(culled[3u * triangle], culled[3u * triangle + 1u], culled[3u * triangle + 2u]);
    let p = array<vec3f, 3>(caster_position(corners.x), caster_position(corners.y), caster_position(corners.z));
    let n = cross(p[1] - p[0], p[2] - p[0]);
    let solid = triangle_solid[triangle];
    // Read once, not once per shooter.
    var bounds = Solid();
    if (solid != NOT_SOLID) {
        bounds = solids[solid];
    }
    for (var first = 0u; first < cull.faces; first += 5u) {
        let shooter = faces.items[first];
        let m = basis(shooter.normal);
        let origin = lifted_origin(shooter.position, shooter.normal, shooter.lift);
        if (on_far_side(solid, bounds, p, n, origin)) {
            continue;
        }
        var all_beyond = 0x1ffffffu;
        for (var k = 0u; k < 3u; k++) {
            let d = p[k] - origin;
            all_beyond &= outside_planes(vec3f(dot(d, m[0]), dot(d, m[1]), dot(d, m[2])));
        }
        var visible = 0u;
        for (var face = 0u; face < 5u; face++) {
            visible |= select(0u, 1u << face, extractBits(all_beyond, 5u * face, 5u) == 0u);
        }
        // One turn per face seen: a CPU driver runs a loop's turn for all
        // lanes, and a turn per face would pay the list's atomics five times.
        loop {
            if (visible == 0u) {
                break;
            }
            let list = first + firstTrailingBit(visible);
            visible &= visible - 1u;
            let at = atomicAdd(&draws[list * DRAW_WORDS + DRAW_COUNT], 1u);
            if (at < cull.capacity) {
                let to = cull.lists_first + 3u * (list * cull.capacity + at);
                culled[to] = corners.x;
                culled[to + 1u] = corners.y;
                culled[to + 2u] = corners.z;
            }
        }
    }
}

// Each face's draw from its list's count, which it resets for the next batch.
@compute @workgroup_size(64)
fn write_draws(@builtin(global_invocation_id) id: vec3u) {
    let list = id.x;
    if (list >= cull.faces) {
        return;
    }
    let at = list * DRAW_WORDS;
    let count = atomicExchange(&draws[at + DRAW_COUNT], 0u);
    let listed = count <= cull.capacity;
    atomicStore(&draws[at], select(3u * cull.triangles, 3u * count, listed));  // index count
    atomicStore(&draws[at + 1u], 1u);  // instance count
    atomicStore(&draws[at + 2u], select(0u, cull.lists_first + 3u * list * cull.capacity, listed));  // first index
    atomicStore(&draws[at + 3u], 0u);  // base vertex
    atomicStore(&draws[at + 4u], 0u);  // first instance (the face's attributes are bound at an offset)
}
