// Ray casts against the scene's hierarchy and triangles (trace::GpuScene). Needs materials.wgsl.

// Ray casts against the scene as src/trace/gpu_scene.rs lays it out: one
// Rgba32Uint texture of 4-word records (nodes depth-first with escape
// links, triangles, per-node bounding spheres and convex polygons, cut-out
// UVs). A CPU driver fetches texels several times faster than storage
// buffers; the walk is stackless, so no per-lane array is indexed.

// Mirrors `gpu_scene::SceneLayout`.
struct SceneLayout {
    node_count: u32,
    triangle_base: u32,    // first triangle record (three per triangle)
    extra_base: u32,       // first node extra record (two per node)
    uv_base: u32,          // first cut-out UV record (three per cut-out triangle)
    scale: f32,            // largest absolute vertex coordinate, metres
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(1) @binding(0) var scene_records: texture_2d<u32>;
@group(1) @binding(1) var<uniform> scene: SceneLayout;
@group(1) @binding(2) var<storage, read> materials: array<Material>;
@group(1) @binding(3) var textures: texture_2d_array<f32>;
@group(1) @binding(4) var texture_sampler: sampler;

// Records per texture row: 1 << ROW_SHIFT (`gpu_scene::ROW`).
const ROW_SHIFT: u32 = 12u;
const NO_LEAF: u32 = 0xffffffffu;
const CUT_OUT: u32 = 0x80000000u;
// Longest walk of one ray, in nodes. A CPU driver stops every loop of a
// shader after 65,535 turns in all; a walk this long only happens in a
// degenerate hierarchy, and is reported (`trace_cut`), never silent.
const MAX_VISITS: u32 = 16384u;
// Barycentric overlap of neighbouring triangles, so no ray slips between two.
const EDGE_OVERLAP: f32 = 1e-6;

// Set when a walk stopped at MAX_VISITS (its ray counted as blocked).
var<private> trace_cut: bool;
// Nodes and triangles this invocation's walks visited (for the report).
var<private> trace_visits: u32;

fn record(i: u32) -> vec4<u32> {
    return textureLoad(scene_records, vec2<u32>(i & ((1u << ROW_SHIFT) - 1u), i >> ROW_SHIFT), 0);
}

fn record_point(i: u32) -> vec3f {
    return bitcast<vec3f>(record(i).xyz);
}

// A node: its box, where the walk goes past it, and its leaf word
// (first triangle | count << 28, or NO_LEAF).
struct BoxNode {
    lo: vec3f,
    escape: u32,
    hi: vec3f,
    leaf: u32,
}

fn box_node(i: u32) -> BoxNode {
    let a = record(2u * i);
    let b = record(2u * i + 1u);
    return BoxNode(bitcast<vec3f>(a.xyz), a.w, bitcast<vec3f>(b.xyz), b.w);
}

// Where the ray o + t·d (with 1/d in `inv`) is inside the box, as
// (t_near, t_far); empty when t_near > t_far.
fn box_span(n: BoxNode, o: vec3f, inv: vec3f, t_max: f32) -> vec2f {
    let t0 = (n.lo - o) * inv;
    let t1 = (n.hi - o) * inv;
    let near = max(max(min(t0.x, t1.x), min(t0.y, t1.y)), max(min(t0.z, t1.z), 0.0));
    // Ize's conservative far distance, so rounding never loses a box the ray touches.
    let far = min(min(max(t0.x, t1.x), max(t0.y, t1.y)), min(max(t0.z, t1.z), t_max)) * 1.0000004;
    return vec2f(near, far);
}

// 1/d with zero components made tiny, so no slab gives NaN.
fn inverse_direction(d: vec3f) -> vec3f {
    let tiny = 1e-30;
    return 1.0 / select(d, select(vec3f(-tiny), vec3f(tiny), d >= vec3f(0.0)), abs(d) < vec3f(tiny));
}

// Möller–Trumbore: (t, u, v) of the ray's hit with triangle (a, b, c), or
// t = -1 when it misses (either side counts).
fn triangle_hit(o: vec3f, d: vec3f, a: vec3f, b: vec3f, c: vec3f) -> vec3f {
    let e1 = b - a;
    let e2 = c - a;
    let p = cross(d, e2);
    let det = dot(e1, p);
    let inv_det = 1.0 / det;
    let s = o - a;
    let u = dot(s, p) * inv_det;
    let q = cross(s, e1);
    let v = dot(d, q) * inv_det;
    let t = dot(e2, q) * inv_det;
    let inside = u >= -EDGE_OVERLAP && v >= -EDGE_OVERLAP && u + v <= 1.0 + EDGE_OVERLAP && det != 0.0;
    return select(vec3f(-1.0, 0.0, 0.0), vec3f(t, u, v), inside);
}

// Whether the hit at barycentrics (u, v) of cut-out triangle `k` falls in
// one of its material's holes (alpha under the cut-off).
fn in_cut_out(k: u32, material_word: u32, u: f32, v: f32) -> bool {
    let m = materials[material_word & ~CUT_OUT];
    let first = scene.uv_base + record(scene.triangle_base + 3u * k + 2u).w;
    let w = vec3f(1.0 - u - v, u, v);
    let uv = bitcast<vec4f>(record(first)) * w.x + bitcast<vec4f>(record(first + 1u)) * w.y
        + bitcast<vec4f>(record(first + 2u)) * w.z;
    let coordinates = texture_coordinates(m.base_texture, uv.xy, uv.zw);
    let alpha = m.base_color.a * sample_texture(textures, texture_sampler, m.base_texture, coordinates, 0.0).a;
    return alpha < m.emission.w;
}

// Whether the scene has cut-out triangles: pipelines for a scene without
// leave the alpha test out (a CPU driver runs every line of a shader for
// every ray, taken or not).
override CUT_OUTS: bool = true;

// Where a walk stopped: the node to visit next, and the triangles of the
// leaf it is in the middle of (`triangle` up to `triangle_end`).
struct Walk {
    node: u32,
    triangle: u32,
    triangle_end: u32,
    visits: u32,
}

// Walks on from `walk` until the ray o + t·d (1/d in `inv`), 0 < t < t_max,
// meets a triangle other than `skip`: an opaque one ends the walk
// (returns 1), a cut-out one pauses it (returns 2), none ends it at the
// tree's end (returns 0). A walk that met a triangle can be resumed, and
// `pending` holds the hit (triangle in leaf order, u, v, t). One
// node or one triangle a turn, so no turn holds a loop of its own (a CPU
// driver runs a loop's body at least once per turn, needed or not).
fn walk_ray(o: vec3f, d: vec3f, inv: vec3f, t_max: f32, skip: u32, walk: ptr<function, Walk>, pending: ptr<function, vec4f>) -> u32 {
    var outcome = 0u;
    loop {
        let testing = (*walk).triangle < (*walk).triangle_end;
        if ((!testing && (*walk).node >= scene.node_count) || outcome != 0u) {
            break;
        }
        if ((*walk).visits == MAX_VISITS) {
            trace_cut = true;
            outcome = 1u;
            break;
        }
        (*walk).visits += 1u;
        let base = select(2u * (*walk).node, scene.triangle_base + 3u * (*walk).triangle, testing);
        let r0 = record(base);
        let r1 = record(base + 1u);
        let r2 = record(base + 2u);
        // As a triangle.
        let h = triangle_hit(o, d, bitcast<vec3f>(r0.xyz), bitcast<vec3f>(r1.xyz), bitcast<vec3f>(r2.xyz));
        let met = testing && r0.w != skip && h.x > 0.0 && h.x < t_max;
        let cut_out = CUT_OUTS && (r1.w & CUT_OUT) != 0u;
        *pending = select(*pending, vec4f(bitcast<f32>((*walk).triangle), h.y, h.z, h.x), met);
        outcome = select(outcome, select(1u, 2u, cut_out), met);
        // As a node.
        let span = box_span(BoxNode(bitcast<vec3f>(r0.xyz), r0.w, bitcast<vec3f>(r1.xyz), r1.w), o, inv, t_max);
        let enter = span.x <= span.y;
        let leaf = r1.w != NO_LEAF;
        let first = r1.w & 0x0fffffffu;
        let node_next = select(r0.w, select((*walk).node + 1u, r0.w, leaf), enter);
        (*walk).triangle = select(select((*walk).triangle, first, enter && leaf), (*walk).triangle + 1u, testing);
        (*walk).triangle_end = select(select((*walk).triangle_end, first + (r1.w >> 28u), enter && leaf), (*walk).triangle_end, testing);
        (*walk).node = select(node_next, (*walk).node, testing);
    }
    return outcome;
}

// Whether anything solid lies on the ray o + t·d, 0 < t < t_max, other
// than triangle `skip` (the texel's own, by its id). Any hit will do; a
// hit in a cut-out's hole lets the ray through. A ray not `wanted` takes no
// walk (false): its lane waits for the others.
fn occluded(o: vec3f, d: vec3f, t_max: f32, skip: u32, wanted: bool) -> bool {
    let inv = inverse_direction(d);
    var walk = Walk(select(scene.node_count, 0u, wanted), 0u, 0u, 0u);
    var pending = vec4f(0.0);
    var outcome = walk_ray(o, d, inv, t_max, skip, &walk, &pending);
    if (CUT_OUTS) {
        // Through the holes: test the cut-out met, and walk on if the ray
        // passes. The loop only turns again while some ray met a hole.
        while (outcome == 2u) {
            let k = bitcast<u32>(pending.x);
            let material = record(scene.triangle_base + 3u * k + 1u).w;
            if (in_cut_out(k, material, pending.y, pending.z)) {
                outcome = walk_ray(o, d, inv, t_max, skip, &walk, &pending);
            } else {
                outcome = 1u;
            }
        }
    }
    trace_visits += walk.visits;
    return outcome != 0u;
}

// The nearest solid surface on the ray o + t·d, t > 0: (triangle in leaf
// order, u, v, t), with t < 0 where the ray leaves the scene. Holes of
// cut-outs let it through. The walk goes on past each hit with the ray cut
// short there, so what is left of the tree is pruned by the nearest so far.
fn closest_hit(o: vec3f, d: vec3f) -> vec4f {
    let inv = inverse_direction(d);
    var walk = Walk(0u, 0u, 0u, 0u);
    var pending = vec4f(0.0);
    var nearest = vec4f(0.0, 0.0, 0.0, -1.0);
    var t_max = 3.0e38;
    loop {
        let outcome = walk_ray(o, d, inv, t_max, 0xffffffffu, &walk, &pending);
        // A walk stopped at MAX_VISITS met nothing: it ends (`trace_cut` says so).
        if (outcome == 0u || walk.visits == MAX_VISITS) {
            break;
        }
        let k = bitcast<u32>(pending.x);
        var solid = true;
        if (CUT_OUTS && outcome == 2u) {
            solid = !in_cut_out(k, record(scene.triangle_base + 3u * k + 1u).w, pending.y, pending.z);
        }
        if (solid) {
            nearest = pending;
            t_max = pending.w;
        }
    }
    trace_visits += walk.visits;
    return nearest;
}

// A ray origin off the surface at `p` along its face normal `face`: clear
// of the f32 rounding of the surface's position, whatever the scene's size.
fn ray_origin(p: vec3f, face: vec3f) -> vec3f {
    let magnitude = max(max(abs(p.x), abs(p.y)), max(abs(p.z), 1e-3 * scene.scale));
    return p + face * (1e-5 * magnitude);
}
