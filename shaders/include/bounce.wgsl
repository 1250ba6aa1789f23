// Progressive-refinement records and helpers: Patch, Shooter, ShooterBatch, BounceParams, BounceStats, sub-cells, luminance, indirect dispatches. Needs texel.wgsl.

// A shooter patch. Mirrors `patches::Patch`.
struct Patch {
    position: vec3f,     // area-weighted centroid, world
    area: f32,           // m²
    normal: vec3f,       // unit mean normal
    first: u32,          // first member in the member list
    rect_centre: vec3f,  // the parallelogram its atlas cell maps to: centre,
    count: u32,          // member texels
    half_u: vec3f,       // half of one side,
    lift: f32,           // how far its own surface rises above the centroid's tangent plane
    half_v: vec3f,       // half of the other side
    radius: f32,         // centre to farthest corner
}

// A patch chosen to shoot in this batch. Mirrors `bounce::Shooter`.
struct Shooter {
    position: vec3f,     // centroid, world
    area: f32,
    normal: vec3f,
    patch_index: u32,    // NO_TRIANGLE when the slot is unused
    radiance: vec3f,     // unshot radiance ΔL it shoots, rgb
    radius: f32,         // near-field reach: receivers closer use the exact polygon form factor
    rect_centre: vec3f,
    lift: f32,           // the hemicube sits this far above the centroid
    half_u: vec3f,
    rect_area: f32,
    half_v: vec3f,
    _pad: u32,
    // Light it shoots ahead of receiving it, per unit albedo (L_lm, rgb):
    // its texels are left this much times their albedo in debt.
    overshoot: vec3f,
    _pad2: u32,
}

// A receiver this close to a near shooter's plane, in receiver offsets
// (half texels), is in contact with it.
const CONTACT: f32 = 0.1;

// Shooter slots per batch (`bounce::MAX_SHOOTERS`). A set of slots (those
// that may light a group of receivers, those a receiver is near) is a
// vec2<u32>: slot k is bit k % 32 of word k / 32.
const MAX_SHOOTERS: u32 = 64u;

// The set of slot `k` alone.
fn slot_bit(k: u32) -> vec2<u32> {
    let bit = 1u << (k & 31u);
    return select(vec2<u32>(bit, 0u), vec2<u32>(0u, bit), k >= 32u);
}

fn no_slots(slots: vec2<u32>) -> bool {
    return all(slots == vec2<u32>(0u));
}

// The lowest slot of a set that has one. A loop takes a set's slots one a
// turn, from both words in one loop: a CPU driver runs a loop's turns for
// all of a SIMD group's lanes until the busiest is done, and the busiest in
// each word of two loops need not be the same lane.
fn first_slot(slots: vec2<u32>) -> u32 {
    return select(32u + firstTrailingBit(slots.y), firstTrailingBit(slots.x), slots.x != 0u);
}

// The set without its lowest slot.
fn without_first(slots: vec2<u32>) -> vec2<u32> {
    return select(vec2<u32>(0u, slots.y & (slots.y - 1u)), vec2<u32>(slots.x & (slots.x - 1u), slots.y), slots.x != 0u);
}

// A batch's shooters, as a uniform buffer.
struct ShooterBatch {
    items: array<Shooter, MAX_SHOOTERS>,
}

// Mirrors `bounce::BounceParams`.
struct BounceParams {
    texel_count: u32,
    patch_count: u32,
    shooter_count: u32,    // slots per batch
    row_stride: u32,       // invocations per dispatch row (`with_row_stride`; 0 in the shared buffer)
    face_size: f32,        // hemicube face width, texels
    tiles_per_row: u32,    // hemicubes per row of the depth atlas
    far: f32,              // distance that maps to depth 1, metres
    near: f32,             // near plane, metres
    receiver_offset: f32,  // receivers test a point this far along their face normal, metres
    max_slope: f32,
    chunk_count: u32,      // workgroups of MEASURE_CHUNK texels in the measure pass
    atlas_width: u32,      // texels per atlas row (a texel's index is x + y · width)
    cell: u32,             // side of the atlas cell patches are cut from, texels
    in_plane: f32,         // a receiver this close to a shooter's plane lies in it, metres (rounding)
    receiver_row_shift: u32,  // receivers per row of the gather's receiver texture, as a shift
    // 1 where no direct pass measured the scene's coverage: `finish` writes
    // each patch's measured covered share into `patch_coverage` instead.
    measure_coverage: u32,
    // The light a surface of full coverage will still receive (L_lm, rgb)
    // per unit of unshot power Σ ΔL·A: the ambient term's factor.
    overshoot: vec4f,
}

// A receiver texel as the gather reads it: its texel (position, area,
// shading and face normals, atlas index and albedo; the rest left 0), the
// share of its area that bounces light and its patch.
struct Receiver {
    texel: Texel,
    share: f32,
    patch_index: u32,
}

// Receiver `i` from the four layers of `records` (`resources::receiver_records`),
// 1 << `row_shift` receivers to a row. A CPU driver fetches texels several
// times faster than it reads a storage buffer's elements.
fn load_receiver(records: texture_2d_array<u32>, i: u32, row_shift: u32) -> Receiver {
    let xy = vec2<u32>(i & ((1u << row_shift) - 1u), i >> row_shift);
    let a = textureLoad(records, xy, 0, 0);
    let b = textureLoad(records, xy, 1, 0);
    let c = textureLoad(records, xy, 2, 0);
    let d = textureLoad(records, xy, 3, 0);
    var t: Texel;
    t.position = bitcast<vec3f>(a.xyz);
    t.area = bitcast<f32>(a.w);
    t.normal = bitcast<vec3f>(b.xyz);
    t.index = b.w;
    t.face_normal = bitcast<vec3f>(c.xyz);
    t.albedo = bitcast<vec3f>(d.xyz);
    return Receiver(t, bitcast<f32>(c.w), d.w);
}

// A shooter patch is split into SUB_CELLS × SUB_CELLS parts of its atlas
// cell: where in the patch its unshot light is, for the near field.
const SUB_CELLS: u32 = 4u;
const SUB_CELL_COUNT: u32 = 16u;
// The sub-cell of its patch a texel lies in: its place in the patch's atlas
// cell, SUB_CELLS to a side.
fn sub_cell(texel: Texel, bounce: BounceParams) -> u32 {
    let row_column = quotient_remainder(texel.index, bounce.atlas_width);
    let x = quotient_remainder(row_column.y, bounce.cell).y;
    let y = quotient_remainder(row_column.x, bounce.cell).y;
    let cx = quotient_remainder(x * SUB_CELLS, bounce.cell).x;
    let cy = quotient_remainder(y * SUB_CELLS, bounce.cell).x;
    return cy * SUB_CELLS + cx;
}

// (n / d, n % d) for d > 0 and a quotient under 2^22 (an atlas row or
// column), by a float estimate put right: a CPU driver divides integers
// by a value it cannot see lane by lane, as slowly as a dozen float
// operations each.
fn quotient_remainder(n: u32, d: u32) -> vec2<u32> {
    var q = i32(floor(f32(n) / f32(d)));
    let r = i32(n) - q * i32(d);
    q += select(0, -1, r < 0) + select(0, 1, r >= i32(d));
    return vec2<u32>(u32(q), u32(i32(n) - q * i32(d)));
}

// What is kept per sub-cell of a batch's shooter (solve_patch_power.wgsl's
// `shooter_cells`): three rows of SUB_CELL_COUNT vectors per slot.
const SUB_CELL_ROWS: u32 = 3u;

// Totals the select pass leaves for the CPU. Mirrors `bounce::Stats`.
struct BounceStats {
    unshot: vec4f,    // Σ ΔL·A over all patches (owed light negative), rgb; w = luminance
    received: vec4f,  // Σ received L_lm·A in the last shoot pass; w = luminance
    shot: vec4f,      // Σ ΔL·A of the shooters chosen now; w = luminance
    shooters: u32,    // shooters with power in this batch
    landing: f32,     // Σ |luminance(ΔL·A)| × the patch's coverage: the unsettled power weighted by where it can land
    unsettled: f32,   // Σ |luminance(ΔL·A)|: light unshot or owed
    _pad2: u32,
}

fn luminance(c: vec3f) -> f32 {
    return dot(c, vec3f(0.2126, 0.7152, 0.0722));
}

// Workgroups per dimension every adapter allows (WebGPU's minimum limit).
const MAX_GROUPS_PER_DIMENSION: u32 = 65535u;

// An indirect dispatch's workgroup counts (x, y, z) for `groups`
// workgroups, in rows of at most MAX_GROUPS_PER_DIMENSION: a pass reads
// its workgroup's place as x + y · num_workgroups.x.
fn dispatch_rows(groups: u32) -> vec3<u32> {
    let x = min(groups, MAX_GROUPS_PER_DIMENSION);
    return vec3<u32>(x, select(1u, (groups + x - 1u) / x, x > 0u), 1u);
}
