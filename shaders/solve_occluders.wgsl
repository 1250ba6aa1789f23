// What can block a point's light (the direct pass, solve_direct.wgsl,
// casts rays only where something can): one walk of the scene's hierarchy
// per point, from above the plane of its own face. Geometry at or below
// that plane never meets a ray that leaves the face, so it is skipped whole.
// What is above is summed up as
// - up to POLYGONS convex polygons, exactly (a floor, a wall, a table top:
//   a node whose triangles tile one), so a ray towards one needs no walk;
// - up to CONES cones from the point that hold everything else; more are
//   merged, and a cone too wide to help leaves every direction open
//   (`ALL_DIRECTIONS`).

@group(0) @binding(0) var<uniform> params: OccluderParams;
@group(0) @binding(1) var<storage, read> points: array<Texel>;
@group(0) @binding(2) var<storage, read_write> occluders: array<Occluders>;

// Mirrors `occluders::OccluderParams`.
struct OccluderParams {
    point_count: u32,
    row_stride: u32,
    _pad0: u32,
    _pad1: u32,
}

// A node whose bounding sphere is further than this many radii away is
// summed up as the sphere's cone; a nearer one is opened.
const CONE_DISTANCE: f32 = 1.2;
// A polygon whose bounding sphere is wider than this (sine of the angle
// it fills) is kept as a polygon; a smaller one goes into the cones.
const BIG_POLYGON: f32 = 0.5;
// Longest walk, in nodes; past it every direction counts as open to a
// blocker. Walks that long follow a surface that crosses the point's plane
// again and again (a rolling terrain): what they find seldom spares a ray,
// and they cost more than the rays they spare.
const MAX_WALK: u32 = 512u;
// Cones as wide as this (sine of the half-angle) help no more: the point's
// every direction is left to the rays.
const WIDEST_CONE: f32 = 0.995;
// Added to a merged cone's sine: rounding may turn its axis by a few units
// in the last place, and a cone a hair too narrow would miss a blocker.
const MERGE_SLACK: f32 = 1e-5;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x + id.y * params.row_stride;
    if (i >= params.point_count) {
        return;
    }
    let p = points[i];
    occluders[i] = summarize(ray_origin(p.position, p.face_normal), p.face_normal, p.triangle);
}

var<private> cones: array<vec4f, CONES>;   // axis, sine of the half-angle
var<private> cone_count: u32;
var<private> polygons: vec2<u32>;
var<private> polygon_count: u32;
var<private> every_direction: bool;

// The blockers above the plane through `o` facing `face`.
fn summarize(o: vec3f, face: vec3f, skip: u32) -> Occluders {
    cone_count = 0u;
    polygon_count = 0u;
    polygons = vec2<u32>(NO_POLYGON);
    every_direction = false;
    let plane = dot(o, face);
    var i = 0u;
    var visits = 0u;
    while (i < scene.node_count && !every_direction) {
        if (visits == MAX_WALK) {
            every_direction = true;
            break;
        }
        visits += 1u;
        let n = box_node(i);
        let upper = select(n.lo, n.hi, face > vec3f(0.0));
        let lower = select(n.hi, n.lo, face > vec3f(0.0));
        // Entirely at or below the plane: nothing a ray from `o` can meet.
        if (dot(upper, face) <= plane) {
            i = n.escape;
            continue;
        }
        let sphere = bitcast<vec4f>(record(scene.extra_base + 2u * i));
        let to_centre = sphere.xyz - o;
        let distance = length(to_centre);
        // A polygon that fills much of the view is tested exactly: a cone
        // around it would hold most directions.
        let polygon = record(scene.extra_base + 2u * i + 1u);
        if (polygon.w != 0u && polygon_count < POLYGONS && sphere.w > BIG_POLYGON * distance) {
            polygons[polygon_count] = i;
            polygon_count += 1u;
            i = n.escape;
            continue;
        }
        let above = max(dot(lower, face), dot(sphere.xyz, face) - sphere.w) > plane;
        if (above && distance > CONE_DISTANCE * sphere.w) {
            add_cone(to_centre / distance, sphere.w / distance);
            i = n.escape;
            continue;
        }
        if (n.leaf == NO_LEAF) {
            i += 1u;
            continue;
        }
        let first = n.leaf & 0x0fffffffu;
        let end = first + (n.leaf >> 28u);
        for (var k = first; k < end; k++) {
            let base = scene.triangle_base + 3u * k;
            let a = record(base);
            let corners = array<vec3f, 3>(bitcast<vec3f>(a.xyz), record_point(base + 1u), record_point(base + 2u));
            let top = max(max(dot(corners[0], face), dot(corners[1], face)), dot(corners[2], face));
            if (a.w != skip && top > plane) {
                triangle_cone(o, corners[0], corners[1], corners[2]);
            }
        }
        i = n.escape;
    }
    var out: Occluders;
    out.cones = array<vec4f, CONES>(vec4f(0.0, 0.0, 1.0, 2.0), vec4f(0.0, 0.0, 1.0, 2.0), vec4f(0.0, 0.0, 1.0, 2.0), vec4f(0.0, 0.0, 1.0, 2.0));
    for (var c = 0u; c < cone_count; c++) {
        // Stored as the cosine and sine of the half-angle.
        out.cones[c] = vec4f(cones[c].xyz, sqrt(max(1.0 - cones[c].w * cones[c].w, 0.0)));
        out.sines[c] = cones[c].w;
    }
    out.polygons = polygons;
    out.flags = select(0u, ALL_DIRECTIONS, every_direction);
    out.visits = visits;
    return out;
}

// The cone from `o` around a triangle: about the mean of its corners'
// directions, as wide as the widest.
fn triangle_cone(o: vec3f, a: vec3f, b: vec3f, c: vec3f) {
    let da = normalize(a - o);
    let db = normalize(b - o);
    let dc = normalize(c - o);
    let mean = da + db + dc;
    let length_mean = length(mean);
    if (length_mean < 1e-3) {
        every_direction = true;
        return;
    }
    let axis = mean / length_mean;
    let cosine = min(min(dot(axis, da), dot(axis, db)), dot(axis, dc));
    if (cosine <= 0.0) {
        every_direction = true;
        return;
    }
    add_cone(axis, sqrt(max(1.0 - cosine * cosine, 0.0)));
}

// Adds a cone (unit axis, sine of its half-angle), merging it into the
// nearest one when all slots are taken.
fn add_cone(axis: vec3f, sine: f32) {
    if (sine >= WIDEST_CONE) {
        every_direction = true;
        return;
    }
    if (cone_count < CONES) {
        cones[cone_count] = vec4f(axis, sine);
        cone_count += 1u;
        return;
    }
    var nearest = 0u;
    var best = -2.0;
    for (var c = 0u; c < CONES; c++) {
        let d = dot(cones[c].xyz, axis);
        if (d > best) {
            best = d;
            nearest = c;
        }
    }
    cones[nearest] = merged(cones[nearest], vec4f(axis, sine));
}

// The narrowest cone around two cones (axis, sine of the half-angle),
// through the angle-sum formulas rather than the angles themselves: no
// inverse trigonometric functions in a step that most nodes of a walk take,
// and no arccosine of nearly parallel axes, which f32 resolves poorly.
// α, β are the cones' half-angles, γ the angle between their axes.
fn merged(a: vec4f, b: vec4f) -> vec4f {
    let sa = a.w;
    let ca = sqrt(max(1.0 - sa * sa, 0.0));
    let sb = b.w;
    let cb = sqrt(max(1.0 - sb * sb, 0.0));
    let cg = dot(a.xyz, b.xyz);
    let sg = length(cross(a.xyz, b.xyz));
    // One holds the other: γ + β ≤ α, cos(γ + β) ≥ cos α (α < 90°, so a sum
    // past 180° fails too).
    if (cg * cb - sg * sb >= ca) {
        return a;
    }
    if (cg * ca - sg * sa >= cb) {
        return b;
    }
    // θ = γ + α + β, the merged cone's full angle.
    let c_ab = ca * cb - sa * sb;
    let s_ab = sa * cb + ca * sb;
    let c_full = cg * c_ab - sg * s_ab;
    let s_full = sg * c_ab + cg * s_ab;
    // Half-angle sine and cosine, each from the form that keeps its
    // precision at that end (1 − cos θ loses it for small θ).
    let small = c_full >= 0.0;
    let sine = select(sqrt(max(0.5 * (1.0 - c_full), 0.0)), s_full / sqrt(2.0 * (1.0 + c_full)), small);
    let cosine = select(s_full / sqrt(max(2.0 * (1.0 - c_full), 1e-30)), sqrt(0.5 * (1.0 + c_full)), small);
    if (s_full < 0.0 || sine >= WIDEST_CONE) {
        every_direction = true;
        return a;
    }
    // Turn a's axis towards b's by θ/2 − α, until the cone reaches both
    // far edges.
    let s_turn = sine * ca - cosine * sa;
    let c_turn = cosine * ca + sine * sa;
    let across = b.xyz - cg * a.xyz;
    let towards_b = across / max(length(across), 1e-30);
    let axis = normalize(c_turn * a.xyz + s_turn * towards_b);
    return vec4f(axis, sine + MERGE_SLACK);
}
