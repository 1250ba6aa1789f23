// Direct environment light (design notes, algorithm step 3): every point
// (texel or sub-sample) gathers, for each light k of the batch,
//     ΔE = L_k Ω_k max(0, n·ω_k) V_k(p)
// with V_k the share of the light's cone above the point's face that rays
// find open. Rays are cast only where something could block them
// (solve_occluders.wgsl sums up what): a light no blocker can reach is
// visible wherever its cone is above the face, which is a cap cut by a
// plane. Gathering per point, lights in order, keeps the sum's order fixed,
// so bakes are identical run to run.
//
// A CPU driver runs every line of a shader for every lane, taken or not,
// and a loop's body at least once; only the number of turns a loop takes
// follows the data. So the lights are sorted first, in one loop of simple
// arithmetic, into what each needs (nothing, the cap's share, a polygon
// test, a walk through the hierarchy; and for the last two, whether the
// cone crosses the face's horizon), and each kind is then gathered in a
// loop of its own that turns as often as its lane with the most needs and
// holds only what its kind needs (the walks: a turn a ray, whatever light
// it goes to).

@group(0) @binding(0) var<uniform> params: DirectParams;
// Three records a light: direction and cos α; L·Ω and Ω; sin α, rays, at
// each 32nd light which of its word's lights start a cluster, and the
// cluster's size and rays (size | rays << 16; `solve::light_clusters`).
@group(0) @binding(1) var<uniform> lights: array<vec4f, 3072>;
@group(0) @binding(2) var<storage, read> points: array<Texel>;
@group(0) @binding(3) var<storage, read> occluders: array<Occluders>;
// Irradiance E (rgb); coverage (blocked and total Ω cos θ over the
// lights in front of the face) and the luminance of the irradiance other
// surfaces block: two records a point, each point's batch added in place.
@group(0) @binding(4) var<storage, read_write> totals: array<vec4f>;
// With `params.listed`, the points to gather (else every point in turn).
@group(0) @binding(5) var<storage, read> point_list: array<u32>;
// [0]: bit 1 a ray's walk cut short; [1]: rays cast; [2]: nodes and
// triangles their walks visited; [3]: points a CPU driver's loop limit cut
// short, listed in `cut_points` (they add nothing; the host gathers the
// batch again in halves at them).
@group(0) @binding(6) var<storage, read_write> status: array<atomic<u32>, 4>;
@group(0) @binding(7) var<storage, read_write> cut_points: array<u32>;

// Mirrors `direct::DirectParams`.
struct DirectParams {
    point_count: u32,
    row_stride: u32,
    light_count: u32,      // lights in this batch
    first_light: u32,      // the batch's first light in the whole set
    _pad3: f32,
    listed: u32,           // 1: the points are `point_list`'s
    _pad1: u32,
    _pad2: u32,
}

// How far outside an edge of a polygon a ray still meets it, in the
// edge's length (f32 rounding of the crossing point is far smaller).
const POLYGON_SLACK: f32 = 1e-4;
const WALK_CUT: u32 = 2u;
// Lights a batch holds (`direct::MAX_BATCH`), 32 to a word of bits.
const WORDS: u32 = 32u;
// Lights whose rays `main` casts in one loop before adding what they found:
// their results wait in a private array, kept small (one for a whole batch
// made the shader far slower for a CPU driver to compile).
const FOUND: u32 = 64u;
// `next_bit` past the last light.
const NO_LIGHT: u32 = 0xffffffffu;

// A convex polygon above the point's face, in registers: its corners and
// the normal of its plane on the point's side (zero: no polygon).
struct Polygon {
    a: vec3f,
    b: vec3f,
    c: vec3f,
    d: vec3f,
    side: vec3f,
}

// The blockers of one point, in registers (a CPU driver keeps an indexed
// array in memory).
struct Blockers {
    axes: mat4x4f,         // the cones' axes in the columns' xyz, cos θ in w
    sines: vec4f,          // sin θ of each cone
    every: bool,           // every direction above the face may be blocked
    p0: Polygon,
    p1: Polygon,
}

fn blockers_of(i: u32, o: vec3f) -> Blockers {
    let s = occluders[i];
    return Blockers(
        mat4x4f(s.cones[0], s.cones[1], s.cones[2], s.cones[3]),
        s.sines,
        (s.flags & ALL_DIRECTIONS) != 0u,
        polygon_of(s.polygons.x, o),
        polygon_of(s.polygons.y, o),
    );
}

fn polygon_of(node: u32, o: vec3f) -> Polygon {
    let header = record(scene.extra_base + 2u * select(node, 0u, node == NO_POLYGON) + 1u);
    let a = record_point(header.w);
    let normal = bitcast<vec3f>(header.xyz);
    let side = select(-normal, normal, dot(o - a, normal) >= 0.0);
    return Polygon(
        a,
        record_point(header.w + 1u),
        record_point(header.w + 2u),
        record_point(header.w + 3u),
        select(side, vec3f(0.0), node == NO_POLYGON),
    );
}

// Whether the ray o + t·d, t > 0, meets the polygon: it heads for the
// polygon's plane and crosses it inside all four edges, or within a
// hair (POLYGON_SLACK of an edge's length) outside one, so that no ray
// slips between two polygons that share an edge.
fn meets(poly: Polygon, o: vec3f, d: vec3f) -> bool {
    let towards = dot(d, poly.side);
    let q = o + d * (dot(poly.a - o, poly.side) / towards);
    let ab = poly.b - poly.a;
    let bc = poly.c - poly.b;
    let cd = poly.d - poly.c;
    let da = poly.a - poly.d;
    let edges = vec4f(
        dot(cross(ab, q - poly.a), poly.side),
        dot(cross(bc, q - poly.b), poly.side),
        dot(cross(cd, q - poly.c), poly.side),
        dot(cross(da, q - poly.d), poly.side),
    );
    let slack = POLYGON_SLACK * vec4f(dot(ab, ab), dot(bc, bc), dot(cd, cd), dot(da, da));
    // The outline winds about the plane's normal, which `side` may flip.
    let inside = all(edges >= -slack) || all(edges <= slack);
    return towards < 0.0 && inside;
}

// Whether the cone about `w` (cosine `ca`, sine `sa` of its half-angle)
// meets one of the blockers' cones: the angle between their axes is under
// the sum of their half-angles, cos(θ + α) = cos θ cos α − sin θ sin α.
fn meets_a_cone(b: Blockers, w: vec3f, ca: f32, sa: f32) -> bool {
    let axes = vec4f(dot(w, b.axes[0].xyz), dot(w, b.axes[1].xyz), dot(w, b.axes[2].xyz), dot(w, b.axes[3].xyz));
    let reach = vec4f(b.axes[0].w, b.axes[1].w, b.axes[2].w, b.axes[3].w) * ca - b.sines * sa;
    return b.every || ca <= 0.0 || any(axes > reach);
}

// Whether the cone about `w` reaches the plane of the polygon from the
// point's side (the polygon may still be elsewhere on it).
fn reaches_plane(poly: Polygon, w: vec3f, sa: f32) -> bool {
    return any(poly.side != vec3f(0.0)) && dot(w, poly.side) < sa;
}

// Whether a ray along `d` may meet a blocker held by the cones.
fn in_a_cone(b: Blockers, d: vec3f) -> bool {
    let axes = vec4f(dot(d, b.axes[0].xyz), dot(d, b.axes[1].xyz), dot(d, b.axes[2].xyz), dot(d, b.axes[3].xyz));
    return b.every || any(axes > vec4f(b.axes[0].w, b.axes[1].w, b.axes[2].w, b.axes[3].w));
}

fn hash(x: u32) -> u32 {
    var h = x * 747796405u + 2891336453u;
    h = ((h >> ((h >> 28u) + 4u)) ^ h) * 277803737u;
    return (h >> 22u) ^ h;
}

// The vector irradiance V = ∫ω dω of the cap about `c` (cosine `ca` ≥ 0,
// sine `sa` of its half-angle) cut to the side of its plane that the face
// normal `f` points to: from Stokes' theorem along the outline of the cut
// cap, an arc of its rim and one of the face's horizon (a whole cap gives
// π sin²α c).
fn cap_above(f: vec3f, c: vec3f, ca: f32, sa: f32) -> vec3f {
    let cos_f = dot(f, c);
    let sin_f = sqrt(max(1.0 - cos_f * cos_f, 0.0));
    // The rim crosses the plane where cos t = k (t about c, from u below).
    let k = cos_f * ca / max(sin_f * sa, 1e-30);
    let t0 = acos(clamp(k, -1.0, 1.0));
    let u = (cos_f * c - f) / max(sin_f, 1e-30);
    let v = cross(c, u);
    let rim = sa * (ca * sin(t0) * u + sa * (3.14159265 - t0) * c);
    let middle = ca * c + sa * cos(t0) * u;
    let horizon = asin(min(sa * sin(t0), 1.0)) * sign(dot(f, cross(middle, v))) * f;
    let whole = 3.14159265 * sa * sa * c;
    return select(select(rim + horizon, vec3f(0.0), k <= -1.0), whole, k >= 1.0);
}

// What light `l` (uniform radiance over its cone) gives the point, over its
// L·Ω: n·V/Ω for the part of the cone above the face (V its vector
// irradiance, `cap_above`). A cone wider than a hemisphere is the sphere
// less the cap about its opposite direction.
fn cap_factor(l: Light) -> f32 {
    let narrow = l.ca > 0.0;
    // (A vector `select` between ±direction miscompiled on lavapipe.)
    let cap = cap_above(l.face, l.direction * select(-1.0, 1.0, narrow), abs(l.ca), l.sa);
    let v = select(3.14159265 * l.face - cap, cap, narrow);
    return max(dot(l.normal, v), 0.0) / l.omega;
}

// Ray `j` over the cone about `w` (cosine `ca` of its half-angle, `frame`
// its basis): point j of the R2 sequence (Roberts 2018, the plastic
// number's additive recurrence), shifted by `jitter`, mapped to the cap by
// area. Every prefix of the sequence covers the cap evenly, so the first
// rays reach into every part of it and all of them are stratified.
fn cone_ray(frame: mat3x3f, ca: f32, j: u32, jitter: vec2f) -> vec3f {
    let r2 = fract(vec2f(0.7548776662, 0.5698402910) * f32(j + 1u) + jitter);
    let cos_t = 1.0 - r2.x * (1.0 - ca);
    let sin_t = sqrt(max(1.0 - cos_t * cos_t, 0.0));
    let phi = 6.2831853 * r2.y;
    return normalize(frame[0] * (sin_t * cos(phi)) + frame[1] * (sin_t * sin(phi)) + frame[2] * cos_t);
}

// What a point gathers: irradiance, and Ω cos θ over the lights in front of
// its face, blocked and in all.
struct Sums {
    irradiance: vec3f,
    blocked: f32,
    facing: f32,
    shadowed: f32,  // luminance of the irradiance other surfaces block
}

// A light as one turn of a gathering loop reads it.
struct Light {
    direction: vec3f,
    ca: f32,               // cosine of the cone's half-angle
    power: vec3f,          // L·Ω
    omega: f32,
    sa: f32,               // sine of the half-angle
    rays: u32,             // rays it gets where something may block it
    cluster_size: u32,     // lights in its cluster (1: none)
    cluster_rays: u32,     // rays the whole cluster gets
    cos_n: f32,            // cosine to the shading normal
    cos_f: f32,            // cosine to the face normal
    normal: vec3f,         // the point's shading normal
    face: vec3f,           // and face normal
}

fn light_at(k: u32, p: Texel) -> Light {
    let head = lights[3u * k];
    let power = lights[3u * k + 1u];
    let extra = lights[3u * k + 2u];
    let cluster = bitcast<u32>(extra.w);
    return Light(
        head.xyz, head.w, power.rgb, power.w, extra.x, bitcast<u32>(extra.y), cluster & 0xffffu, cluster >> 16u,
        dot(p.normal, head.xyz), dot(p.face_normal, head.xyz), p.normal, p.face_normal,
    );
}

// Adds a light whose cone is wholly above the face, `open` of it open: a
// whole cone gives n·V/Ω = (1 + cos α)/2 · cos θ (`cap_factor` without its
// arcs). Coverage as in `add_light`: the cone is in front of the face.
fn add_plain_light(sums: ptr<function, Sums>, power: vec3f, ca: f32, omega: f32, cos_n: f32, open: f32) {
    (*sums).irradiance += plain_light(power, ca, cos_n) * open;
    let weight = omega * max(cos_n, 0.0);
    (*sums).facing += weight;
    (*sums).blocked += weight * (1.0 - open);
}

// The irradiance of a whole cone above the face.
fn plain_light(power: vec3f, ca: f32, cos_n: f32) -> vec3f {
    return power * (0.5 + 0.5 * ca) * max(cos_n, 0.0);
}

// `add_plain_light` for a light that rays found `open`: what they found
// blocked is counted too. (Apart: the loop over lights nothing blocks
// would pay for it at every pair.)
fn add_plain_light_seen(sums: ptr<function, Sums>, l: Light, open: f32) {
    add_plain_light(sums, l.power, l.ca, l.omega, l.cos_n, open);
    add_shadowed(sums, plain_light(l.power, l.ca, l.cos_n), open);
}

// Counts the share of `whole` irradiance that is not `open`, by luminance.
fn add_shadowed(sums: ptr<function, Sums>, whole: vec3f, open: f32) {
    (*sums).shadowed += dot(whole, vec3f(0.2126, 0.7152, 0.0722)) * (1.0 - open);
}

// Adds light `l`, of which `open` of the cone's part above the face is open.
fn add_light(sums: ptr<function, Sums>, l: Light, open: f32) {
    let whole = l.power * cap_factor(l);
    (*sums).irradiance += whole * open;
    add_shadowed(sums, whole, open);
    // Coverage counts only lights in front of the face, and only what other
    // surfaces block of them: the point's own surface is no other surface seen.
    let weight = select(0.0, l.omega * max(l.cos_n, 0.0), l.cos_f > 0.0);
    (*sums).facing += weight;
    (*sums).blocked += weight * (1.0 - open);
}

fn jitter_of(i: u32, k: u32) -> vec2f {
    let h = hash(hash(i * 0x9e3779b9u ^ (params.first_light + k)));
    return vec2f(f32(h & 0xffffu), f32(h >> 16u)) / 65536.0;
}

// Whether the batch's lights come in clusters (`solve::light_clusters`):
// pipelines for a set without leave out the loops over a cluster's lights
// (every loop turn counts towards a CPU driver's limit).
override CLUSTERS: bool = true;

// Rays a light gets first at a point (`ConeRays`).
const FIRST_RAYS: u32 = 8u;

var<private> rays_cast: u32;

// One light's rays at one point, or a cluster's (`solve::light_clusters`: lights
// too small to earn a ray each share theirs, taken in turn): where the next
// goes, and what the earlier ones found. The first few rays are spread over
// the whole cone; the rest are cast only where those disagree (a penumbra),
// since most lights are wholly open or wholly blocked. Where none of them
// leaves the face (a cone that reaches just above it), one more ray goes
// through the middle of the sliver above the face.
struct ConeRays {
    l: Light,              // the light, or the cluster's first
    head: u32,             // its index in the batch
    members: u32,          // the cluster's lights the rays go to, from the head's bit
    member_count: u32,
    member: u32,           // the member the next ray goes to, counted among `members`
    rays: u32,             // rays to cast where the first ones disagree
    jitter: vec2f,
    sliver: vec3f,
    next: u32,             // the next ray
    count: u32,            // rays to cast, so far
    open: u32,             // of the rays cast that leave the face, those that meet nothing
    leaving: u32,
}

// The rays of light `k` (`members` 1), or of the cluster it heads: as many
// as its members the point gathers this way have earned, at least one.
fn cone_rays(l: Light, k: u32, i: u32, members: u32) -> ConeRays {
    // (In floats and by a product: a CPU driver divides integers lane by lane.)
    let count = countOneBits(members);
    let share = max(u32(ceil(f32(l.cluster_rays * count) / f32(l.cluster_size))), 1u);
    let rays = select(l.rays, share, l.cluster_size > 1u);
    let first = (hash(hash(i * 0x85ebca6bu ^ (params.first_light + k)) ^ 0x68bc21ebu) >> 16u) * count >> 16u;
    // The sliver's ray goes through the first member that walks (the light
    // itself, alone), which may cross the horizon where the head does not.
    let lead = k + firstTrailingBit(members);
    let sliver = sliver_ray(l.face, lights[3u * lead], lights[3u * lead + 2u].x);
    return ConeRays(l, k, members, count, first, rays, jitter_of(i, k), sliver, 0u, min(rays, FIRST_RAYS), 0u, 0u);
}

// Which bit of `mask` (at most eight set) is its `q`-th set one, from the lowest.
fn nth_bit(mask: u32, q: u32) -> u32 {
    let low4 = countOneBits(mask & 0xfu);
    var base = select(0u, 4u, q >= low4);
    var rest = select(q, q - low4, q >= low4);
    let low2 = countOneBits((mask >> base) & 0x3u);
    let high2 = rest >= low2;
    base += select(0u, 2u, high2);
    rest = select(rest, rest - low2, high2);
    return base + select(0u, 1u, rest >= ((mask >> base) & 1u));
}

// Ray `next` goes to the members in turn, to a point of the R2 sequence
// over that member's cone.
fn next_direction(c: ConeRays) -> vec3f {
    let member = lights[3u * (c.head + nth_bit(c.members, c.member))];
    return select(cone_ray(basis(member.xyz), member.w, c.next, c.jitter), c.sliver, c.next == c.rays);
}

// Counts the ray just cast; true when it was the light's last.
fn count_ray(c: ptr<function, ConeRays>, leaves: bool, blocked: bool) -> bool {
    let j = (*c).next;
    let rays = (*c).rays;
    (*c).leaving += select(0u, 1u, leaves);
    (*c).open += select(0u, 1u, leaves && !blocked);
    // After the first rays, on to the rest only in a penumbra.
    let split = (*c).open != 0u && (*c).open != (*c).leaving;
    var count = select((*c).count, rays, j + 1u == FIRST_RAYS && split);
    // None left the face: the rest of the rays, then the sliver's, once
    // (it may graze the face and not leave it either).
    let last = j + 1u == count;
    count = select(count, select(rays, rays + 1u, count == rays), last && (*c).leaving == 0u && j < rays);
    (*c).count = count;
    (*c).next = j + 1u;
    (*c).member = select((*c).member + 1u, 0u, (*c).member + 1u == (*c).member_count);
    return j + 1u >= count;
}

// Of the rays that leave the face, the share that met nothing.
fn share_open(open: u32, leaving: u32) -> f32 {
    return select(f32(open) / f32(leaving), 0.0, leaving == 0u);
}

// Of light `l`'s rays at point `i` that leave the face, the share that
// meet neither polygon (for a light no other blocker reaches: no walk).
fn polygon_visibility(l: Light, k: u32, i: u32, p: Texel, o: vec3f, b: Blockers) -> f32 {
    var c = cone_rays(l, k, i, 1u);
    loop {
        let d = next_direction(c);
        if (count_ray(&c, dot(d, p.face_normal) > 0.0, meets(b.p0, o, d) || meets(b.p1, o, d))) {
            break;
        }
    }
    return share_open(c.open, c.leaving);
}

// Of light `l`'s rays at point `i` that leave the face, the share that
// meet nothing: the polygons first, then the hierarchy (a cluster's rays
// are cast in `main`'s loop of walks).
fn cone_visibility(l: Light, k: u32, i: u32, p: Texel, o: vec3f, b: Blockers) -> f32 {
    var c = cone_rays(l, k, i, 1u);
    loop {
        if (cast_ray(&c, p, o, b)) {
            break;
        }
    }
    return share_open(c.open, c.leaving);
}

// Casts `c`'s next ray: the polygons first, then the hierarchy. True when
// it was the light's last.
fn cast_ray(c: ptr<function, ConeRays>, p: Texel, o: vec3f, b: Blockers) -> bool {
    let d = next_direction(*c);
    let leaves = dot(d, p.face_normal) > 0.0;
    let hits_polygon = meets(b.p0, o, d) || meets(b.p1, o, d);
    let traced = leaves && !hits_polygon && in_a_cone(b, d);
    rays_cast += select(0u, 1u, traced);
    let blocked = hits_polygon || occluded(o, d, 3.0e38, p.triangle, traced);
    return count_ray(c, leaves, blocked);
}

// The rays of light `k` (NO_LIGHT: none) at point `i`, or of the cluster
// it heads, to its members among `walking` (`cone_rays`).
fn walk_rays(k: u32, i: u32, p: Texel, walking: ptr<function, array<u32, WORDS>>) -> ConeRays {
    let light = select(k, 0u, k == NO_LIGHT);
    let l = light_at(light, p);
    return cone_rays(l, light, i, max(select(1u, members_walking(light, l, walking), CLUSTERS), 1u));
}

// The members of the cluster light `head` (`l`) starts that walk, a bit
// each from the head's.
fn members_walking(head: u32, l: Light, walking: ptr<function, array<u32, WORDS>>) -> u32 {
    return ((*walking)[head >> 5u] >> (head & 31u)) & ((1u << l.cluster_size) - 1u);
}

// A ray through the middle of the part of a light's cone above the face
// `face`, for a cone that reaches only a little above it: halfway between
// the cone's highest point and the horizon below it. `head` is the light's
// first record (direction, cos α), `sa` sin α.
fn sliver_ray(face: vec3f, head: vec4f, sa: f32) -> vec3f {
    let cos_f = dot(face, head.xyz);
    let up = normalize(face - cos_f * head.xyz);
    let top = head.w * head.xyz + sa * up;
    let horizon = normalize(head.xyz - cos_f * face);
    return normalize(top + horizon);
}

// Turns of a loop over the set bits of a batch's words, lowest first: the
// word being taken, its index, and which later words have bits left (a
// mask: a loop looking for the next word would run at least once a turn).
struct BitWalk {
    word: u32,
    index: u32,
    words: u32,
}

// The lights of a batch's words from the first; `words` says which have bits set.
fn bit_walk(words: u32) -> BitWalk {
    return BitWalk(0u, 0u, words);
}

// Of a word's lights, the first of each cluster that has a light in
// `lights`: each light's bit moves down to its cluster's start (`starts`;
// a cluster never spans two words and holds at most eight lights).
fn cluster_heads(lights: u32, starts: u32) -> u32 {
    var heads = lights & starts;
    var moving = lights;
    for (var step = 1u; step < 8u; step++) {
        moving = (moving & ~starts) >> 1u;
        heads |= moving & starts;
    }
    return heads;
}

// The next light, or NO_LIGHT when they are all taken.
fn next_bit(walk: ptr<function, BitWalk>, bits: ptr<function, array<u32, WORDS>>) -> u32 {
    if ((*walk).word == 0u && (*walk).words != 0u) {
        (*walk).index = firstTrailingBit((*walk).words);
        (*walk).words &= (*walk).words - 1u;
        (*walk).word = (*bits)[(*walk).index];
    }
    if ((*walk).word == 0u) {
        return NO_LIGHT;
    }
    let bit = firstTrailingBit((*walk).word);
    (*walk).word &= (*walk).word - 1u;
    return 32u * (*walk).index + bit;
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let n = id.x + id.y * params.row_stride;
    if (n >= params.point_count) {
        return;
    }
    let i = select(n, point_list[n], params.listed != 0u);
    let p = points[i];
    let o = ray_origin(p.position, p.face_normal);
    let b = blockers_of(i, o);
    var sums = Sums(vec3f(0.0), 0.0, 0.0, 0.0);
    // Sorting: a light wholly above the face that no blocker can reach is
    // gathered here; the others go to the loops below.
    var crossing: array<u32, WORDS>;
    var polygons: array<u32, WORDS>;
    // Lights anything may block, by their clusters' first lights, and themselves.
    var walks: array<u32, WORDS>;
    var walking: array<u32, WORDS>;
    // Lights something may block that cross the face's horizon: with
    // clusters they walk with theirs (among `walking`, added by the exact
    // share of their cone above the face), else one by one.
    var blocked_crossing: array<u32, WORDS>;
    // Which of each kind's words have any.
    var crossing_words = 0u;
    var polygon_words = 0u;
    var walk_words = 0u;
    var blocked_crossing_words = 0u;
    var k = 0u;
    for (var w = 0u; w < WORDS; w++) {
        var crossing_bits = 0u;
        var polygon_bits = 0u;
        var walking_bits = 0u;
        var blocked_crossing_bits = 0u;
        for (var bit = 0u; bit < 32u && k < params.light_count; bit++) {
            let head = lights[3u * k];
            let power = lights[3u * k + 1u];
            let ca = head.w;
            let extra = lights[3u * k + 2u];
            let sa = extra.x;
            let cos_n = dot(p.normal, head.xyz);
            let cos_f = dot(p.face_normal, head.xyz);
            // Some of the cone above the face (a cone wider than a hemisphere always).
            let lit = cos_f > -sa || ca <= 0.0;
            let walk = lit && meets_a_cone(b, head.xyz, ca, sa);
            let polygon = lit && !walk && (reaches_plane(b.p0, head.xyz, sa) || reaches_plane(b.p1, head.xyz, sa));
            let crosses = lit && !walk && !polygon && cos_f < sa;
            let plain = lit && !walk && !polygon && !crosses;
            add_plain_light(&sums, select(vec3f(0.0), power.rgb, plain), ca, select(0.0, power.w, plain), cos_n, 1.0);
            // The whole cone above the face: the plain factor, times what rays find open.
            let above = ca > 0.0 && cos_f >= sa;
            crossing_bits |= select(0u, 1u << bit, crosses);
            polygon_bits |= select(0u, 1u << bit, polygon && above);
            let crossing_walk = (walk || polygon) && !above;
            walking_bits |= select(0u, 1u << bit, (walk && above) || (CLUSTERS && crossing_walk));
            blocked_crossing_bits |= select(0u, 1u << bit, crossing_walk);
            k += 1u;
        }
        crossing[w] = crossing_bits;
        polygons[w] = polygon_bits;
        if (CLUSTERS) {
            walks[w] = cluster_heads(walking_bits, bitcast<u32>(lights[3u * 32u * w + 2u].z));
        } else {
            walks[w] = walking_bits;
        }
        walking[w] = walking_bits;
        blocked_crossing[w] = blocked_crossing_bits;
        crossing_words |= select(0u, 1u << w, crossing_bits != 0u);
        polygon_words |= select(0u, 1u << w, polygon_bits != 0u);
        walk_words |= select(0u, 1u << w, walking_bits != 0u);
        blocked_crossing_words |= select(0u, 1u << w, blocked_crossing_bits != 0u && !CLUSTERS);
    }
    // Lights only the point's own surface hides part of.
    var finished = 0u;
    var bits = bit_walk(crossing_words);
    loop {
        let light = next_bit(&bits, &crossing);
        if (light == NO_LIGHT) {
            finished += 1u;
            break;
        }
        add_light(&sums, light_at(light, p), 1.0);
    }
    // Lights only the polygons may block.
    bits = bit_walk(polygon_words);
    loop {
        let light = next_bit(&bits, &polygons);
        if (light == NO_LIGHT) {
            finished += 1u;
            break;
        }
        let l = light_at(light, p);
        add_plain_light_seen(&sums, l, polygon_visibility(l, light, i, p, o, b));
    }
    // Lights anything may block, a cluster's together: their rays in one
    // loop over FOUND lights at a time, each light's result kept (rays open
    // and rays leaving the face, a half word each) and then added in the
    // lights' order. A loop per light would turn as often as its lane with
    // the most rays, and the lights' loop as often as its lane with the most
    // lights; this one turns as often as its lane with the most rays in all.
    var found: array<u32, FOUND>;
    var rays_walk = bit_walk(walk_words);
    bits = bit_walk(walk_words);
    var next = next_bit(&rays_walk, &walks);
    var c = walk_rays(next, i, p, &walking);
    loop {
        var taken = 0u;
        loop {
            if (next == NO_LIGHT || taken == FOUND) {
                break;
            }
            if (cast_ray(&c, p, o, b)) {
                found[taken] = c.open | (c.leaving << 16u);
                taken += 1u;
                next = next_bit(&rays_walk, &walks);
                c = walk_rays(next, i, p, &walking);
            }
        }
        for (var n = 0u; n < taken; n++) {
            let light = next_bit(&bits, &walks);
            let l = light_at(light, p);
            let open = share_open(found[n] & 0xffffu, found[n] >> 16u);
            if (CLUSTERS) {
                let shift = light & 31u;
                let members = members_walking(light, l, &walking);
                // Members above the face, then those across its horizon (few,
                // and their share of the cone above the face costs more).
                var across = members & (blocked_crossing[light >> 5u] >> shift);
                var above = members & ~across;
                loop {
                    if (above == 0u) {
                        break;
                    }
                    let member = firstTrailingBit(above);
                    above &= above - 1u;
                    add_plain_light_seen(&sums, light_at(light + member, p), open);
                }
                loop {
                    if (across == 0u) {
                        break;
                    }
                    let member = firstTrailingBit(across);
                    across &= across - 1u;
                    add_light(&sums, light_at(light + member, p), open);
                }
            } else {
                add_plain_light_seen(&sums, l, open);
            }
        }
        if (next == NO_LIGHT) {
            finished += 1u;
            break;
        }
    }
    // Without clusters, lights something may block that cross the face's
    // horizon (few: the polygons' lights among them walk too, finding
    // nothing in the cones).
    bits = bit_walk(blocked_crossing_words);
    loop {
        let light = next_bit(&bits, &blocked_crossing);
        if (light == NO_LIGHT) {
            finished += 1u;
            break;
        }
        let l = light_at(light, p);
        add_light(&sums, l, cone_visibility(l, light, i, p, o, b));
    }
    if (trace_cut) {
        atomicOr(&status[0], WALK_CUT);
    }
    // Cut short: nothing is added, and the point is gathered again.
    if (k < params.light_count || finished < 4u) {
        cut_points[atomicAdd(&status[3], 1u)] = i;
        return;
    }
    if (rays_cast > 0u) {
        atomicAdd(&status[1], rays_cast);
        atomicAdd(&status[2], trace_visits);
    }
    totals[2u * i] += vec4f(sums.irradiance, 0.0);
    totals[2u * i + 1u] += vec4f(sums.blocked, sums.facing, sums.shadowed, 0.0);
}
