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
// The batch's shadow maps, tiled `tiles_per_row` to a row, in two layers:
// the first surface along each light (FRONT), and the nearest surface
// behind it (BEHIND: the end of the solid a ray entering the first would
// pass through).
@group(0) @binding(4) var depth_maps: texture_depth_2d_array;
const FRONT: u32 = 0u;
const BEHIND: u32 = 1u;


// Longest sideways march of a shadow ray, shadow-map texels: a light
// so wide that its rays leave the blocker further out than this (cube:4's
// lights are 0.08 sr; a budget light of 0.06 sr a few metres from a wall
// at 512² maps) keeps a penumbra this wide, too sharp.
const MAX_MARCH: f32 = 24.0;
// Blocker-search taps: at least 8, more as the search widens so that taps
// stay about three shadow-map texels apart, up to 32.
const MIN_SEARCH_TAPS: u32 = 8u;
const MAX_SEARCH_TAPS: u32 = 32u;
// Share of the depth bias by which a surface seen from behind may lie behind
// the receiver and still cover it, or must lie in front of it where it is in
// the receiver's plane: rounding only, since it is not the receiver's own
// surface. A receiver touching it at an angle (a ring's underside on the
// floor, texels on the circle where they meet) lies on it.
const COVER_TOLERANCE: f32 = 0.125;
// Depth slopes (tangents of the tilt from the light's axis, to within one
// in 1 + |tangent| by this share) at which a surface seen from behind is in
// the receiver's plane: about a degree near normal incidence.
const COPLANAR_SLOPE: f32 = 0.02;
// Shadow rays (filter taps) per light where the search found a blocker.
const MAX_RAYS: u32 = 16u;
// Widest penumbra the percentage-closer filter takes, shadow-map texels
// (about two lightmap texels); wider ones are marched.
const PCF_LIMIT: f32 = 4.0;
// Spacing of the points tested along a shadow ray, shadow-map texels: a
// wall seen edge-on is a band a texel or two wide, and a ray must not step
// over it.
const MARCH_SPACING: f32 = 1.0;
// Height above the receiver's tangent plane, shadow-map texels, below which
// the wide blocker search takes a surface for the receiver's own (or one it
// lies on): such a surface can only hide the part of a light below the
// receiver's horizon, which the cosine already weighs.
const ABOVE_PLANE: f32 = 0.25;

// Tap j of n on a golden-angle spiral filling the unit disc, turned by
// `spin` (computed, not read from an array: a CPU driver would keep an
// indexed array in memory per lane).
fn spiral(j: u32, n: u32, spin: f32) -> vec2f {
    return ring_tap(j, n, 0.0, 1.0, spin);
}

// Tap j of n on a golden-angle spiral filling the ring between radii
// `inner` and `outer` evenly, turned by `spin`.
fn ring_tap(j: u32, n: u32, inner: f32, outer: f32, spin: f32) -> vec2f {
    let r = sqrt(mix(inner * inner, outer * outer, (f32(j) + 0.5) / f32(n)));
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
    rise: vec3f,           // height above the receiver's tangent plane per shadow-map texel (x, y) and unit of depth
}

// What one turn of a blocker search's or a shadow ray's loop settles for
// its tap or point. A turn reads the depth at a shadow-map texel and the
// four beside it (`read_cross`). Where the surface there meets the
// receiver's plane, that can leave open whether it is the plane
// (`plane_near`); a second turn then reads the depths two texels out
// (ASK_FAR). A CPU driver reads every texture a turn names for all its
// lanes, whether a lane needs it or not, and few taps need those.
const CLEAR: u32 = 0u;
const BLOCKED: u32 = 1u;
// A march's point behind the first surface: the second layer decides.
const BEHIND_FIRST: u32 = 2u;
const ASK_FAR: u32 = 3u;

// The depth a layer holds at a shadow-map texel, and at the four texels
// some distance out along x and y: left, right, above, below.
struct Cross {
    centre: f32,
    arms: vec4f,
}

// The depths at texel `cell` of the light's tile and `reach` texels out
// from it, clamped to the map.
fn read_cross(layer: u32, cell: vec2<i32>, tile: vec2<i32>, reach: i32) -> Cross {
    let arms = vec4f(
        layer_depth_at(layer, cell - vec2<i32>(reach, 0), tile),
        layer_depth_at(layer, cell + vec2<i32>(reach, 0), tile),
        layer_depth_at(layer, cell - vec2<i32>(0, reach), tile),
        layer_depth_at(layer, cell + vec2<i32>(0, reach), tile),
    );
    return Cross(layer_depth_at(layer, cell, tile), arms);
}

// The depth of a layer at texel `at` of the light's tile, clamped to the map.
fn layer_depth_at(layer: u32, at: vec2<i32>, tile: vec2<i32>) -> f32 {
    let hi = vec2<i32>(i32(params.map_size) - 1);
    return textureLoad(depth_maps, clamp(at, vec2<i32>(0), hi) + tile, layer, 0);
}

// Whether the receiver is lit as seen by the shadow-map texel `cell`, which
// holds the first surface at depth `near.centre` (its neighbours' depths
// `near.arms`): CLEAR, BLOCKED, or ASK_FAR. The depth map holds the depth
// of the first surface at each texel's centre. Where that is the
// receiver's own plane (carried from the receiver to the centre along
// `slope`: receiver-plane depth bias), the texel shows the receiver
// itself: lit, at any tilt, with no large constant bias. Anything else
// there is compared with the receiver's own depth: in front of it, it
// blocks. A plain slope-scaled bias would let light through geometry that
// meets the receiver (a wall under a ceiling, a box on a floor), and
// carrying the plane alone would see through such a corner wherever the
// plane, extended, passes in front of the other surface.
fn tap_verdict(cell: vec2<i32>, near: Cross, r: Receiver) -> u32 {
    let stored = near.centre;
    if (r.z <= stored + r.bias && !covers_receiver(vec2f(cell), stored, stored_slope(stored, near.arms), r)) {
        return CLEAR;
    }
    return by_plane(plane_near(vec2f(cell), stored, near.arms, r));
}

// Whether the surface at a tap `sideways` shadow-map texels from the
// receiver (texel `cell`, depths `near`) is out of reach of every ray
// within the light's cone (which moves `depth_to_texels` sideways per unit
// of depth), so no blocker of this light: one further out than its depth
// in front of the receiver lets a ray reach, however far in front it lies
// (a wall seen at a grazing angle, the receiver's own surface curving up),
// or one hardly above the receiver's tangent plane (ABOVE_PLANE). The
// surface's depth change across the texel and a texel of sideways slack
// keep a slanted or edge-on surface that reaches into the cone.
fn beyond_cone(cell: vec2<i32>, near: Cross, r: Receiver, sideways: f32, depth_to_texels: f32) -> bool {
    let stored = near.centre;
    let height = dot(r.rise, vec3f(vec2f(cell) + 0.5 - r.surface_pixel, stored - r.surface_z));
    let slope = stored_slope(stored, near.arms);
    let nearest_part = stored - max(abs(slope.x), abs(slope.y));
    let reachable = sideways <= (r.z - nearest_part) * depth_to_texels + 1.0;
    return height <= ABOVE_PLANE || !reachable;
}

// What a blocker search found: whether a tap was blocked, and the depth
// of the deepest blocker (the disc) or the shallowest (the ring).
struct Search {
    blocked: bool,
    depth: f32,
}

// A blocker search of `taps` taps around the receiver: on the disc of
// radius `outer` (`disc`; taps as `tap_verdict` takes them, then the
// centre), or on the ring between `inner` and `outer` (leaving out what is
// `beyond_cone`).
// The ring's depth starts at the receiver's own.
fn search_blockers(
    r: Receiver,
    disc: bool,
    taps: u32,
    inner: f32,
    outer: f32,
    spin: f32,
    depth_to_texels: f32,
) -> Search {
    var found = Search(false, select(r.z, 0.0, disc));
    // Past the last tap on the disc comes its centre.
    let turns = select(taps, taps + 1u, disc);
    var j = 0u;
    var far_turn = false;
    var near: Cross;
    while (j < turns) {
        let tap = select(ring_tap(j, taps, inner, outer, spin), spiral(j, taps, spin) * outer, disc);
        let cell = map_cell(r.pixel + select(tap, vec2f(0.0), disc && j == taps));
        let read = read_cross(FRONT, cell, r.tile, select(1, 2, far_turn));
        var verdict: u32;
        if (far_turn) {
            verdict = select(BLOCKED, CLEAR, plane_far(vec2f(cell), near.centre, near.arms, read.arms, r));
        } else {
            near = read;
            let out_of_reach = !disc && beyond_cone(cell, read, r, length(tap), depth_to_texels);
            verdict = select(tap_verdict(cell, read, r), CLEAR, out_of_reach);
        }
        if (verdict == BLOCKED) {
            found.blocked = true;
            found.depth = select(min(found.depth, near.centre), max(found.depth, near.centre), disc);
        }
        far_turn = verdict == ASK_FAR;
        j += select(1u, 0u, far_turn);
    }
    return found;
}

// Whether the first-layer depth `stored` is of a surface the light sees
// from behind (marked by `with_facing` in solve_depth.wgsl).
fn seen_from_behind(stored: f32) -> bool {
    return (bitcast<u32>(stored) & 1u) != 0u;
}

// Whether a depth of either layer is of an open surface (solve::surfaces):
// a sheet of zero thickness, with open space on both sides, not a solid's
// skin or a sealed room's wall, whose inside is closed to the light.
fn on_sheet(stored: f32) -> bool {
    return (bitcast<u32>(stored) & 2u) != 0u;
}

// Whether the surface the depth map holds at texel `cell` (depth `stored`,
// slope `slope` as `stored_slope` gives it) turns its back to the light in
// front of the receiver's surface point, or at it: a surface the receiver
// nearly touches or touches, seen from behind (the floor under a ball
// resting on it, lit from below). It is never the receiver itself (a light
// behind the receiver's own face is blocked by it anyway), so it is not
// carried along the receiver's plane and needs only a rounding tolerance
// (whose sign its slope sets); but the test point, lifted a shadow-map
// texel off the surface, may have passed it. The stored surface is carried
// to the receiver's own map position along its slope (from its smoother
// side): a floor seen at a grazing angle changes depth across a texel by
// far more than the millimetre under the ball.
fn covers_receiver(cell: vec2f, stored: f32, slope: vec2f, r: Receiver) -> bool {
    let there = stored + dot(slope, r.surface_pixel - (cell + 0.5));
    // A surface in the receiver's own plane (a box's bottom face on the
    // floor) must lie in front of it to cover it, as a path tracer finds:
    // the two coincide. One that meets the receiver at an angle covers it
    // at the receiver's own depth (a ring's underside on the floor).
    let coplanar = all(abs(slope - r.slope) <= COPLANAR_SLOPE * (abs(r.slope) + 1.0 / params.map_size));
    let reach = select(COVER_TOLERANCE, -COVER_TOLERANCE, coplanar) * r.bias;
    return seen_from_behind(stored) && there < r.surface_z + reach;
}

// The stored surface's depth change per texel along x and y, from the side
// of the texel (depth `stored`, neighbours `n` as `read_cross` gives them a
// texel out) where it changes less: at a silhouette the other side is
// another surface.
fn stored_slope(stored: f32, n: vec4f) -> vec2f {
    return vec2f(smoother(n.x, stored, n.y), smoother(n.z, stored, n.w));
}

// The depth change across `mid` from whichever side changes less (`before`
// and `after` are the neighbours' depths).
fn smoother(before: f32, mid: f32, after: f32) -> f32 {
    return select(after - mid, mid - before, abs(mid - before) < abs(after - mid));
}

// The shadow-map texel holding `at` (pixel units), clamped to the map.
fn map_cell(at: vec2f) -> vec2<i32> {
    let size = params.map_size;
    return vec2<i32>(clamp(floor(at), vec2f(0.0), vec2f(size - 1.0)));
}

// Whether the surface a depth layer holds at texel `cell` (depth `stored`,
// its neighbours' `n` as `read_cross` gives them a texel out) is the
// receiver's own plane: PLANE_YES, PLANE_NO, or ASK_FAR where that takes
// the depths two texels out (`plane_far`).
const PLANE_NO: u32 = 0u;
const PLANE_YES: u32 = 1u;

fn plane_near(cell: vec2f, stored: f32, n: vec4f, r: Receiver) -> u32 {
    // Only a plane facing the light can be the receiver seen from it (from
    // behind, a zero-thickness wall stands between them), and only a surface
    // seen from the front.
    if (!r.front || seen_from_behind(stored)) {
        return PLANE_NO;
    }
    // The receiver's plane, carried to this texel's centre.
    let carried = cell + 0.5 - r.surface_pixel;
    let plane = r.surface_z + dot(r.slope, carried);
    if (abs(stored - plane) > plane_tolerance(cell, r)) {
        return PLANE_NO;
    }
    return select(ASK_FAR, PLANE_YES, all(sides_without_junction(cell, stored, n, r)));
}

// A point or tap that only the plane test can clear: CLEAR on the
// receiver's plane, BLOCKED off it, ASK_FAR where `plane_near` left it open.
fn by_plane(plane: u32) -> u32 {
    return select(select(BLOCKED, CLEAR, plane == PLANE_YES), ASK_FAR, plane == ASK_FAR);
}

// How far a stored surface may lie from the receiver's plane carried to
// texel `cell` and still be it. A curved surface leaves its tangent plane
// quadratically: the tolerance grows with the distance carried (a texel of
// depth at 4 texels, 16 at 16).
fn plane_tolerance(cell: vec2f, r: Receiver) -> f32 {
    let carried = cell + 0.5 - r.surface_pixel;
    return params.plane_tolerance * (1.0 + dot(carried, carried) / 8.0);
}

// Depth alone cannot tell the receiver's own tilted plane from another
// surface meeting it (a floor under a wall): their depths agree along the
// line where they meet. The stored surface's slope on both sides of the
// texel must be the receiver's: at such a junction one side is not. A side
// whose neighbour lies behind the plane carried on (a convex edge, or the
// plane's own edge against what lies beyond), or holds a surface that does
// not continue into this texel (the edge of a blocker well in front: the
// floor seen past a ball's rim) is no junction: a surface meeting the
// receiver there lies in front of the plane and runs on into the texel
// where they meet.
//
// Which sides (right and down, then left and up) the depths a texel out
// (`n`) already show to be no junction: the surface keeps the receiver's
// slope towards the side, or a neighbour lies behind the plane carried on.
fn sides_without_junction(cell: vec2f, stored: f32, n: vec4f, r: Receiver) -> vec2<bool> {
    let size = params.map_size;
    let tolerance = plane_tolerance(cell, r);
    let mine = vec3f(r.slope * size, -1.0);
    let after = same_slope(mine, (n.yw - stored) * size) || any(n.yw > stored + r.slope + tolerance);
    let before = same_slope(mine, (n.xz - stored) * -1.0 * size) || any(n.xz > stored - r.slope + tolerance);
    return vec2<bool>(after, before);
}

// Whether the surface is the receiver's plane where `plane_near` left it
// open, from the depths two texels out (`far`, as `read_cross` gives them):
// a side is no junction either where a neighbour holds a surface that does
// not continue into the texel.
fn plane_far(cell: vec2f, stored: f32, n: vec4f, far: vec4f, r: Receiver) -> bool {
    let tolerance = plane_tolerance(cell, r);
    let sides = sides_without_junction(cell, stored, n, r);
    let after = sides.x || apart(stored, n.y, far.y, tolerance) || apart(stored, n.w, far.w, tolerance);
    let before = sides.y || apart(stored, n.x, far.x, tolerance) || apart(stored, n.z, far.z, tolerance);
    return after && before;
}

// Whether the surface of the neighbouring texel (depth `near`, and `far`
// one texel further out) does not continue into this texel (depth
// `stored`): a silhouette, in front or behind.
fn apart(stored: f32, near: f32, far: f32, tolerance: f32) -> bool {
    let continued = 2.0 * near - far;
    return abs(stored - continued) > 2.0 * tolerance + 0.5 * abs(near - far);
}

// Whether a stored surface with depth slope `theirs` (per texel, scaled to
// texels of depth) is parallel to the receiver's plane within about 25°.
fn same_slope(mine: vec3f, theirs: vec2f) -> bool {
    let other = vec3f(theirs, -1.0);
    return dot(mine, other) >= 0.9 * length(mine) * length(other);
}

// One depth layer where a shadow ray's point is: the texel holding it, the
// depths there and a texel out, the stored surface's slope, whether that
// surface is the receiver's own plane (PLANE_YES, PLANE_NO, or ASK_FAR),
// and the point's offset from the texel's centre.
struct LayerAt {
    cell: vec2<i32>,
    near: Cross,
    slope: vec2f,
    plane: u32,
    centre: vec2f,
}

fn layer_at(cell: vec2<i32>, near: Cross, at: vec2f, r: Receiver) -> LayerAt {
    let plane = plane_near(vec2f(cell), near.centre, near.arms, r);
    return LayerAt(cell, near, stored_slope(near.centre, near.arms), plane, at - (vec2f(cell) + 0.5));
}

// Whether a shadow ray's point at depth `z` is clear of the scene, as far
// as the first layer (`front`, where the point is) tells: CLEAR, BLOCKED,
// BEHIND_FIRST, or ASK_FAR. A point at the end of a ray (`interior` false)
// is clear in front of the first surface the depth map holds there, or on
// the receiver's own plane (as `tap_verdict`). A point inside a marched
// ray (`interior`) is clear there too; behind the first surface,
// `behind_verdict` decides. Either is widened by the first
// surface's own depth change across a texel and by half the ray's depth
// step (`half_step`; 0 outside a march). The widening makes a ray crossing
// a thin slab between two points still have one point inside; taking half
// a step on each side, not a whole one behind, keeps the crossing where it
// is: a whole step behind moved each slab edge a step along the rays, and
// narrowed a wide penumbra, its lit side most (tests/shadow.rs, the wide
// sun). A march's last point, at the farthest blocker's depth, takes the
// half step in front too: it lies on that blocker where the ray meets it.
fn front_verdict(front: LayerAt, r: Receiver, z: f32, interior: bool, half_step: f32) -> u32 {
    // The surface's depth change across a texel. Inside a march, a point
    // within the texel's depth range (a surface seen at a grazing angle
    // spans many texels of depth) may be on either side: not clear, unless
    // the surface is the receiver's own plane.
    let stored = front.near.centre;
    let across = select(0.0, max(abs(front.slope.x), abs(front.slope.y)), interior);
    // At the receiver's own depth, a surface it nearly touches from behind
    // blocks however little it lies in front (`covers_receiver`).
    let covered = z >= r.z && covers_receiver(vec2f(front.cell), stored, front.slope, r);
    // A ray's last point against a sheet where the point is (below).
    let sheet_end = on_sheet(stored) && !interior;
    let surface = select(stored, stored + dot(front.slope, front.centre), sheet_end);
    if ((z <= surface + r.bias - across - half_step && !covered) || front.plane == PLANE_YES) {
        return CLEAR;
    }
    if (front.plane == ASK_FAR) {
        return ASK_FAR;
    }
    return select(BLOCKED, BEHIND_FIRST, interior);
}

// Whether a march's point at depth `z`, behind the first surface (`front`,
// where `front_verdict` left it), is clear, from the second layer there
// (`back`): CLEAR, BLOCKED, or ASK_FAR. It is clear unless it lies inside
// the solid the two layers
// bound: a point behind the second layer (widened as in `front_verdict`)
// passes behind the object, as a ray from the shadow of a post passes
// beside the post.
//
// Where the first surface is a sheet (an open surface, `on_sheet`), no
// solid lies behind it: the point is blocked only within the sheet's band,
// and then by what the second layer holds. A sheet there blocks within its
// band too, unless it is the receiver's plane. A closed surface there (a
// solid standing behind the sheet, a sealed room's wall) blocks from its
// band on: its far side is in no layer, and a ray from inside it must not
// get out.
fn behind_verdict(front: LayerAt, back: LayerAt, r: Receiver, z: f32, half_step: f32) -> u32 {
    let stored = front.near.centre;
    let behind = back.near.centre;
    let across = max(abs(front.slope.x), abs(front.slope.y));
    if (!on_sheet(stored)) {
        return select(CLEAR, BLOCKED, z <= behind + half_step + across + r.bias);
    }
    // The sheet's own depth where the point is: its band is narrow, and
    // its depth at the texel's centre may be a texel of slope off. Between
    // two points a texel apart (diagonally) the sheet's depth changes by up
    // to twice `across`: behind the sheet the band takes that much, so that
    // a ray crossing a sloped sheet (a floor seen from below, a room's walls
    // and floor beyond it) keeps a point in it.
    if (z <= stored + dot(front.slope, front.centre) + half_step + 2.0 * across + r.bias) {
        return BLOCKED;
    }
    let surface = behind + dot(back.slope, back.centre) + r.bias;
    let band = max(abs(back.slope.x), abs(back.slope.y)) + half_step;
    if (z <= surface - band) {
        return CLEAR;
    }
    // Beyond the band: open space behind a sheet, inside a closed surface.
    if (z > surface + band) {
        return select(BLOCKED, CLEAR, on_sheet(behind));
    }
    return by_plane(back.plane);
}

// How much of a distant light of angular radius atan(tan_alpha) reaches the
// receiver. A blocker search within PCF_LIMIT texels finds the nearest
// blocker; where the light is wide enough for its rays to spread further, a
// second, wider search finds the farthest. Penumbrae up to PCF_LIMIT texels
// are filtered (percentage-closer soft shadows); wider ones are marched,
// ray by ray, through both depth layers (`ray_visibility`).
fn light_visibility(r: Receiver, tan_alpha: f32, nearest_depth: f32, spin: f32) -> f32 {
    let size = params.map_size;
    // Sideways shadow-map texels a rim ray moves per unit of depth.
    let depth_to_texels = tan_alpha * size;
    // How far sideways a rim ray has moved where it leaves the scene: no
    // blocker lies further out.
    let reach = max(r.z - nearest_depth, 0.0) * depth_to_texels;
    // The nearest blocker (deepest stored depth) within the filter's reach
    // sets a percentage-closer filter's width. A light narrower than that
    // (reach under 0.75 texel) takes the centre tap alone. The centre is the
    // loop's last tap, not a test of its own before it: a CPU driver runs
    // every test written, whether a lane needs it or not, but a loop only as
    // long as one of its lanes does.
    let near_search = min(reach, PCF_LIMIT);
    let taps = select(MIN_SEARCH_TAPS, 0u, reach < 0.75);
    let near = search_blockers(r, true, taps, 0.0, near_search, spin, depth_to_texels);
    let near_blocked = near.blocked;
    var nearest = near.depth;
    if (reach < 0.75) {
        return select(1.0, 0.0, near_blocked);
    }
    if (!near_blocked && reach <= PCF_LIMIT) {
        return 1.0;
    }
    var span = 0.0;
    if (reach > PCF_LIMIT) {
        // The farthest blocker over the widest footprint the light's rays
        // can have says whether the penumbra is wider than the filter takes;
        // where the first search found none, whether the receiver is in the
        // outer part of a wide penumbra at all.
        let search = min(reach, MAX_MARCH);
        // Where the first search found nothing, only the ring beyond it is
        // searched, and sparsely: a receiver in the outer part of a wide
        // penumbra has its blocker over much of that ring, and one that a
        // sparse search misses lies where little of the light is hidden.
        let inner = select(0.0, near_search, !near_blocked);
        let dense = clamp(u32(search * search / 3.0), MIN_SEARCH_TAPS, MAX_SEARCH_TAPS);
        let search_taps = select(MIN_SEARCH_TAPS, dense, near_blocked);
        let far = search_blockers(r, false, search_taps, inner, search, spin + 2.0, depth_to_texels);
        let far_blocked = far.blocked;
        var farthest = far.depth;
        // A penumbra wider than MAX_MARCH is marched narrower than it is,
        // its inner part too dark; lighting its outer part beyond the first
        // search keeps its sum (an independent tracer agrees better so).
        if (!near_blocked) {
            if (!far_blocked || (r.z - farthest) * depth_to_texels > MAX_MARCH) {
                return 1.0;
            }
            nearest = farthest;
        }
        farthest = min(farthest, nearest);
        span = (r.z - farthest) * depth_to_texels;
    }
    // A blocker close enough for a narrow penumbra (a contact, a wall
    // beside the receiver) keeps the filter: its taps are sealed against
    // walls seen edge-on, which matters most there. Both kinds of ray take
    // one call: a CPU driver would run every call written.
    let nearest_span = (r.z - nearest) * depth_to_texels;
    let filtered = span <= PCF_LIMIT || nearest_span <= PCF_LIMIT;
    let march_span = min(span, MAX_MARCH);
    let radius = select(march_span, clamp(nearest_span, 0.5, PCF_LIMIT), filtered);
    let end_depth = select(r.z - march_span / depth_to_texels, nearest, filtered);
    return ray_visibility(r, !filtered, radius, end_depth, spin);
}

// The share of MAX_RAYS shadow rays, spread over the light's disc, that
// reach the light. One loop serves both kinds of ray, so that a CPU driver,
// which runs every branch for every lane, pays for one of them.
//
// Filtered (`march` false): percentage-closer soft shadows (Fernando 2005)
// for penumbrae at most PCF_LIMIT texels wide, a filter as wide as the
// penumbra the nearest blocker casts (`end_depth`, the deepest stored
// depth): an average would let a far blocker widen the filter of a
// receiver that a near one (a wall beside it) already shades, and light
// would leak in. Each tap stands for a ray from the receiver that reaches
// the blocker's depth at the tap, and must clear what lies on its way there
// too: the tap alone would see past a floor seen edge-on, a band a texel or
// two wide, into a sealed room. With taps at most PCF_LIMIT texels out,
// three points on the way are a texel apart.
//
// Marched (`march`): wider penumbrae. Each ray is marched through both
// depth layers from the receiver to the farthest blocker's depth
// (`end_depth`, nearer if the march would leave MAX_MARCH), and is lit if
// no point of it lies inside a solid. A long blocker (a post) then gives
// each ray the depth it meets, and a ray from the middle of its shadow may
// pass behind it: the penumbra widens away from the contact and the core
// lightens, as they do.
fn ray_visibility(r: Receiver, march: bool, radius: f32, end_depth: f32, spin: f32) -> f32 {
    var lit = 0.0;
    for (var i = 0u; i < MAX_RAYS; i++) {
        // The even rays first, then the odd ones: each half spans the whole
        // disc, and where the first half agrees (umbra, or the light's whole
        // disc in view) the second is not traced.
        if (i == MAX_RAYS / 2u && (lit == 0.0 || lit == f32(MAX_RAYS / 2u))) {
            return lit / f32(MAX_RAYS / 2u);
        }
        let j = select(2u * i, 2u * i + 1u - MAX_RAYS, i >= MAX_RAYS / 2u);
        let offset = spiral(j, MAX_RAYS, spin + 1.0) * radius;
        // A march's points are MARCH_SPACING apart from the receiver itself
        // (a surface just above it, such as the side of a box it stands
        // under, is crossed before the first step), then its end.
        let steps = max(2u, u32(ceil(length(offset) / MARCH_SPACING)));
        let step_depth = (r.z - end_depth) / f32(steps);
        let points = select(4u, steps + 1u, march);
        var clear = true;
        // From the far end back: a ray is most often blocked there, where
        // it meets the blockers the search found (a sheet's band is only
        // there), and the loop ends at its first blocked point. A point
        // behind the first surface takes another turn of the loop, reading
        // the second layer; one a layer's plane test leaves open, another
        // reading its depths two texels out (as the searches' taps).
        var k = 0u;
        var behind = false;
        var far_turn = false;
        var front: LayerAt;
        var here: LayerAt;
        while (k < points && clear) {
            let s = points - 1u - k;
            // The filter's points are a quarter, half and three quarters of
            // the way to the blocker, then the tap at the receiver's depth.
            // A march's last point sees, along the light's own direction,
            // all that lies beyond the blockers the search found.
            let t = select(f32(s + 1u) * 0.25, f32(s) / f32(steps), march);
            let last = s + 1u == points;
            let z = select(mix(r.z, end_depth, t), select(r.z, end_depth, march), last);
            let at = select(r.pixel + t * offset, r.pixel + offset, last);
            let half_step = select(0.0, 0.5 * step_depth, march);
            let cell = map_cell(at);
            let read = read_cross(select(FRONT, BEHIND, behind), cell, r.tile, select(1, 2, far_turn));
            if (far_turn) {
                let on_plane = plane_far(vec2f(cell), here.near.centre, here.near.arms, read.arms, r);
                here.plane = select(PLANE_NO, PLANE_YES, on_plane);
            } else {
                here = layer_at(cell, read, at, r);
            }
            var verdict: u32;
            if (behind) {
                verdict = behind_verdict(front, here, r, z, half_step);
            } else {
                verdict = front_verdict(here, r, z, march && !last, half_step);
                front = here;
            }
            // The point stays for the turn it is owed: the second layer's,
            // or its layer's depths two texels out.
            clear = verdict != BLOCKED;
            far_turn = verdict == ASK_FAR;
            behind = verdict == BEHIND_FIRST || (behind && far_turn);
            k += select(1u, 0u, behind || far_turn);
        }
        if (clear) {
            lit += 1.0;
        }
    }
    return lit / f32(MAX_RAYS);
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
        let rise = vec3f(dot(face, m[0]), -dot(face, m[1]), -size * dot(face, w));
        let receiver =
            Receiver(lifted.xy, lifted.z, bias, surface.xy, surface.z, 0.0, slope, tile, dot(face, w) > 0.0, rise);
        let visible = light_visibility(receiver, light.direction.w, light.nearest.x, spin);
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
