// One batch of shots (design notes, algorithm step 4): every receiver texel
// i gathers from each shooter j of the batch
//     L_lm,i += F_ij ΔL_j,   L_i, ΔL_i += ρ_i F_ij ΔL_j,
// with visibility from the shooter's hemicube. Texels of a patch that shot
// have their unshot light cleared (and then take what a curved patch gives
// itself, `near_light`). Gathering per texel in a fixed order
// keeps bakes identical run to run: `main` sums the far field over the
// batch's shooters, then `near_field` the near field of the receivers `main`
// listed, each in slot order.
//
// The form factor: the seed's bounded disc formula (its eq. 2)
//     F_ij = cos θ_i cos θ_j A_j / (π r² + A_j)
// stays finite as r → 0, but it is exact only on the disc's axis and
// everywhere else biased low by A_j/(π r²): measured in a closed room, 0.16 %
// of each shot's light was lost, which a near-white room amplifies 20–100×.
// So near the shooter (r < NEAR_FIELD patch radii) the patch's parallelogram
// is integrated exactly (Lambert's contour integral, bounded at r → 0 too),
// and beyond that the disc term A_j/(π r²) ≤ 1/16 is dropped (measured:
// mean error in a ρ = 0.95 closed room −0.7 %, against −3.0 % with it).
//
// Even so the discretized form factors of one shooter do not sum to the
// share of its hemisphere the scene covers (patches at a chart's border or
// a room's corner lost up to half their light in a closed room, 4 % of all
// of it), and a near-white room multiplies that loss by up to 1/(1 − ρ).
// So each patch, the first time it shoots, measures Σ_i F_ij A_i / A_j over
// all receivers, near and far field apart (`measure`), and the covered
// share of its hemicube, counting only surfaces it sees from the front
// (`finish`). From then on its far-field form factors are scaled so that
// the sum is that share: every shot delivers exactly the share of its
// light the scene catches, and receivers next to the patch, whose polygon
// form factors are exact, are not over-lit to make up for others.

@group(0) @binding(0) var<uniform> params: BounceParams;
// Every receiver texel, as four layers of records (`receiver`).
@group(0) @binding(1) var receivers: texture_2d_array<u32>;
// The batch's shooters and their light by sub-cells
// (solve_patch_power.wgsl) are uniform buffers: a CPU driver gathers a
// uniform array's elements for all lanes at once, where it reads a storage
// or workgroup array indexed by a loop counter lane by lane (on lavapipe
// that was most of a shot's gather).
struct ShooterCells {
    items: array<vec4f, SHOOTER_CELLS>,
}
@group(0) @binding(3) var<uniform> shooters: ShooterBatch;
@group(0) @binding(4) var<storage, read_write> lightmap: array<vec4f>;
@group(0) @binding(5) var<storage, read_write> unshot: array<vec4f>;
@group(0) @binding(6) var depth: texture_depth_2d;
// Per patch: the factor its far-field form factors are scaled by, 0 until measured.
@group(0) @binding(7) var<storage, read_write> patch_scale: array<f32>;
// Near-field, then far-field Σ F_ij A_i / A_j per shooter slot and texel chunk (measure pass).
@group(0) @binding(8) var<storage, read_write> partials: array<f32>;
// Receivers with a shooter of the batch in their near field, listed by
// `main` for `near_field` (the list's order varies; each texel's sum does not).
@group(0) @binding(10) var<storage, read_write> near_list: NearList;

// Per slot: each sub-cell's unshot power and area, then their centroids.
@group(0) @binding(11) var<uniform> shooter_cells: ShooterCells;
// Per patch: its slot + 1 when it shoots in this batch, else 0 (solve_select).
@group(0) @binding(14) var<storage, read> chosen: array<u32>;
// Per group of 64 receivers in `members`' order (a workgroup of `main`):
// the slots that may light one of them (solve_shooter_cull).
@group(0) @binding(15) var<storage, read> group_shooters: array<vec2<u32>>;
// The receivers in the order `main` and `measure` take them: by patch,
// so that a group of 64 lies in one or two atlas cells, whose bounds
// leave out more shooters than a run along an atlas row.
@group(0) @binding(16) var<storage, read> members: array<u32>;
// The groups of 64 that `main` gathers this batch, one a workgroup
// (solve_shooter_cull): the word the cull counts in as it fills the list,
// their count, then the groups.
struct GatheredGroups {
    filling: u32,
    count: u32,
    groups: array<u32>,
}
@group(0) @binding(17) var<storage, read> gathered: GatheredGroups;

// Per patch: the covered share of its texels' hemispheres (select's);
// `finish` measures it where no direct pass did (`measure_coverage`).
@group(0) @binding(18) var<storage, read_write> patch_coverage: array<f32>;

// The batch's shooters' scales by slot, as `finish` leaves them: read by
// `main` as a uniform buffer, for the reason the shooters are one, and
// written by `finish` (each in a group of its own).
struct SlotScales {
    items: array<vec4f, MAX_SHOOTERS / 4u>,
}
@group(1) @binding(0) var<uniform> slot_scales: SlotScales;
@group(1) @binding(1) var<storage, read_write> slot_scales_out: array<f32, MAX_SHOOTERS>;

// Receiver texel `i`. Its share of the area that bounces light is 1
// unless another surface lies on or over it (src/solve/overlaps.rs): where
// two surfaces coincide, each receives the place's light but counts for
// half its area.
fn receiver(i: u32) -> Receiver {
    return load_receiver(receivers, i, params.receiver_row_shift);
}

fn slot_scale(k: u32) -> f32 {
    return slot_scales.items[k / 4u][k % 4u];
}

struct NearList {
    count: atomic<u32>,
    // Three words an entry: the texel's index, then the set of slots in
    // whose near field it is, its own curved patch's included.
    entries: array<u32>,
}

const SHOOTER_CELLS: u32 = MAX_SHOOTERS * SUB_CELL_ROWS * SUB_CELL_COUNT;
// Texels one measure workgroup sums (64 invocations × 64 texels).
const MEASURE_CHUNK: u32 = 4096u;
// Bounds on the far-field scale: a patch that needs more has geometry the
// texels do not describe (its hemicube and its receivers disagree), and is
// left nearer its own estimate.
const MIN_SCALE: f32 = 0.25;
const MAX_SCALE: f32 = 4.0;
// Receivers closer than this many patch radii use the exact polygon form factor.
const NEAR_FIELD: f32 = 4.0;

// The hemicube's origin: the centroid lifted off the patch's own surface.
fn hemicube_origin(s: Shooter) -> vec3f {
    return lifted_origin(s.position, s.normal, s.lift);
}

// The direction (shooter's frame, not normalized) through the centre of
// hemicube texel `xy` of `face`, whose viewport is `view`.
fn hemicube_texel_direction(xy: vec2<i32>, view: vec4f, face: u32) -> vec3f {
    let uv = ((vec2f(xy) + 0.5 - view.xy) / view.zw) * vec2f(2.0, -2.0) + vec2f(-1.0, 1.0);
    // In the face's frame (across, up, forward), as `hemicube_face_frame`;
    // a half face's v spans only the upper half.
    let up = select(0.5 * (uv.y + 1.0), uv.y, face == 0u);
    let forward = select(1.0, -1.0, face == 2u || face == 4u);
    let sideways = select(vec3f(forward, uv.x, up), vec3f(uv.x, forward, up), face >= 3u);
    return select(sideways, vec3f(uv.x, up, 1.0), face == 0u);
}

// Whether the receiver at `distance` from the hemicube's origin is seen
// from it, given the `stored` distance of the first surface through its
// hemicube texel. As for shadow maps: where the stored surface is the
// receiver's own plane (its distance along the texel's centre ray, worked
// out exactly), the texel shows the receiver; anything else must not be in
// front of it. A bias growing with the receiver's tilt would let light
// through walls that meet it.
fn visible_from_shooter(
    distance: f32,
    stored: f32,
    xy: vec2<i32>,
    view: vec4f,
    face: u32,
    m: mat3x3f,
    origin: vec3f,
    texel: Texel,
    size: f32,
) -> bool {
    let footprint = distance * 2.0 / size;
    if (distance <= stored + 0.25 * footprint) {
        return true;
    }
    let ray = normalize(m * hemicube_texel_direction(xy, view, face));
    let facing = dot(texel.face_normal, ray);
    // The ray must meet the plane from the receiver's front: from behind, the
    // plane is a zero-thickness wall between them, not the receiver's face.
    if (facing > -1e-4) {
        return false;
    }
    let plane = dot(texel.face_normal, texel.position - origin) / facing;
    return abs(stored - plane) <= 0.5 * footprint;
}

// F_ij from shooter `s` in slot `k` to receiver `texel` (not of the
// shooter's own patch): in x when the receiver is in the near field (exact
// polygon form factor), in y when it is not (point form factor, the part the
// normalization scales).
fn shot_form_factor(texel: Texel, s: Shooter, k: u32) -> vec2f {
    let g = shot_geometry(texel, s, k);
    if (g.x > 0.0) {
        return vec2f(near_form_factor(texel, s, k), 0.0);
    }
    return g;
}

// Where a receiver texel takes its visibility: half a texel off the
// surface, which keeps its own depth from hiding it in the shooter's
// hemicube. Its form factors are taken at the surface itself, where the
// lightmap texel is: from the lifted point a floor sees everything low
// (a wall's foot, a ball's underside) under a flatter angle, and its
// bounced light came out 5–10 % dark per half texel of lift.
fn receiver_point(texel: Texel) -> vec3f {
    return texel.position + texel.face_normal * params.receiver_offset;
}

// Whether receiver `texel` sees shooter `s` (slot `k`, visibility from its
// hemicube; 0 where the receiver does not see the shooter's front), and how:
// x = 1 in the near field, where the exact polygon form factor is needed;
// else y is the point form factor.
fn shot_geometry(texel: Texel, s: Shooter, k: u32) -> vec2f {
    let p = texel.position;
    let to_shooter = s.position - p;
    // Only the shooter's front side emits; a receiver in its plane (within
    // rounding, which `solve_shooter_cull` allows for) takes nothing.
    let height = -dot(to_shooter, s.normal);
    if (height <= params.in_plane) {
        return vec2f(0.0);
    }
    let r2 = dot(to_shooter, to_shooter);
    let r = sqrt(r2);
    // A receiver facing away from the patch's centroid gets nothing, also
    // in the near field: a curved patch's parallelogram would otherwise
    // hover over its neighbours on a convex surface and light them.
    let cos_i = dot(texel.normal, to_shooter) / r;
    if (!(cos_i > 0.0)) {
        return vec2f(0.0);
    }

    // Visibility from the shooter's hemicube. A receiver below the
    // hemicube's origin is too close to the shooter's plane for anything
    // to come between them.
    let size = params.face_size;
    let m = basis(s.normal);
    let from_origin = receiver_point(texel) - hemicube_origin(s);
    let local = vec3f(dot(from_origin, m[0]), dot(from_origin, m[1]), dot(from_origin, m[2]));
    if (local.z > params.near) {
        let distance = length(local);
        let face = hemicube_face_of(local);
        let uvw = hemicube_face(local, face);
        let view = hemicube_viewport(k, face, size, params.tiles_per_row);
        let pixel = view.xy + vec2f(uvw.x * 0.5 + 0.5, 0.5 - uvw.y * 0.5) * view.zw;
        let xy = vec2<i32>(clamp(floor(pixel), view.xy, view.xy + view.zw - 1.0));
        let stored = textureLoad(depth, xy, 0) * params.far;
        if (!visible_from_shooter(distance, stored, xy, view, face, m, hemicube_origin(s), texel, size)) {
            return vec2f(0.0);
        }
    }

    if (r < NEAR_FIELD * s.radius) {
        // A receiver (nearly) in the shooter's plane: a contact (a box's
        // underside on the floor), which the shooter's patch, lit beside the
        // contact, must not light as if it glowed all over. (Its exact form
        // factor tends to 1 there; at any distance it is 0 in the plane.)
        return vec2f(select(1.0, 0.0, height <= CONTACT * params.receiver_offset), 0.0);
    }
    return vec2f(0.0, cos_i * (height / r) * s.area / (PI * r2));
}

// Close to the shooter the disc formula fails (a floor texel next to a wall
// would miss most of the wall): the patch is integrated exactly. A flat
// patch is its parallelogram, scaled to the patch's true area. A curved
// one is integrated part by part (`sub_cell_form_factor`): one flat
// parallelogram standing in for a patch on a curved surface (a statue's
// flank, 20 cm across) hovered in front of its neighbours a few
// centimetres away and lit them up to 4× too bright.
fn near_form_factor(texel: Texel, s: Shooter, k: u32) -> f32 {
    if (!is_curved(k)) {
        return flat_form_factor(texel, s);
    }
    var f = 0.0;
    for (var c = 0u; c < SUB_CELL_COUNT; c++) {
        f += sub_cell_form_factor(texel, s, k, c);
    }
    return min(f, 1.0);
}

// The unshot light a near-field receiver takes from shooter `s` (slot
// `k`): as `near_form_factor`, a flat patch's by where on it its light is
// (`near_radiance`), a curved one's by each sub-cell's own but `skip`
// (SUB_CELL_COUNT: none). A curved patch's own texels are receivers too:
// where it is concave (the inside of a sphere, a bowl) one part lights
// another (left out, the glowing cap inside a sphere of 64 patches read 6 %
// low, its patches' light going to the rest). A flat or convex patch gives
// them none: no texel of it lies in front of another sub-cell's square.
fn near_light(texel: Texel, s: Shooter, k: u32, skip: u32) -> vec3f {
    if (!is_curved(k)) {
        return flat_form_factor(texel, s) * near_radiance(texel, s, k);
    }
    let base = k * SUB_CELL_ROWS * SUB_CELL_COUNT;
    var light = vec3f(0.0);
    var f = 0.0;
    for (var c = 0u; c < SUB_CELL_COUNT; c++) {
        if (c != skip) {
            let cell = shooter_cells.items[base + c];
            let fc = sub_cell_form_factor(texel, s, k, c);
            light += (fc / max(cell.w, 1e-30)) * cell.rgb;
            f += fc;
        }
    }
    // The squares of a curved patch seen from just under it (a ring's
    // underside millimetres over the floor) overlap in the receiver's view;
    // their form factors' sum past 1 would return more light than left.
    return light / max(f, 1.0);
}

// Whether the shooter in slot `k` is curved (solve_patch_power.wgsl
// marks it in its first sub-cell's normal).
fn is_curved(k: u32) -> bool {
    return shooter_cells.items[(k * SUB_CELL_ROWS + 2u) * SUB_CELL_COUNT].w != 0.0;
}

fn flat_form_factor(texel: Texel, s: Shooter) -> f32 {
    return parallelogram_form_factor(texel.position, texel.normal, s.rect_centre, s.half_u, s.half_v)
        * min(s.area / max(s.rect_area, 1e-30), 1.0);
}

// The form factor of sub-cell `c` of shooter `s` (slot `k`): a square of
// its own area at its centroid, facing its own mean normal, lighting only
// what lies in front of it. (Squares for a flat patch too left gaps and
// overlaps that darkened a ball's underside a centimetre over the floor by
// 5 %.)
fn sub_cell_form_factor(texel: Texel, s: Shooter, k: u32, c: u32) -> f32 {
    let base = k * SUB_CELL_ROWS * SUB_CELL_COUNT;
    let area = shooter_cells.items[base + c].w;
    let centroid = shooter_cells.items[base + SUB_CELL_COUNT + c].xyz;
    let facing = shooter_cells.items[base + 2u * SUB_CELL_COUNT + c].xyz;
    let normal = select(s.normal, facing, dot(facing, facing) > 0.0);
    return square_form_factor(texel.position, texel.normal, centroid, normal, area, s.half_u);
}

// The far field of the receivers in the groups `solve_shooter_cull`
// listed (the others take no light, shoot none and have no record of
// light received to clear); receivers in some shooter's near field are
// listed for `near_field`. A CPU driver runs both sides of every branch
// for all lanes, so the exact polygon form factor, needed by a few texels
// near each shooter, would otherwise cost every texel-shooter pair.
@compute @workgroup_size(64)
fn main(
    @builtin(workgroup_id) workgroup: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let listed = workgroup.x + workgroup.y * groups.x;
    if (listed >= gathered.count) {
        return;
    }
    let j = gathered.groups[listed] * 64u + lid;
    if (j >= params.texel_count) {
        return;
    }
    let i = members[j];
    // The texel's own patch, if it shoots now, gives it nothing here (its
    // unshot light leaves; a curved one lights itself where it is concave,
    // `near_light`).
    let r = receiver(i);
    let chosen_as = chosen[r.patch_index];
    let shot = chosen_as != 0u;
    let own_slot = select(0u, chosen_as - 1u, shot);
    // Only the slots that may light the texel's group, in slot order.
    var slots = group_shooters[j / 64u];
    if (no_slots(slots) && !shot) {
        // Nothing reaches it and it keeps its light: only the record of
        // what it received is cleared, and its sums are never read.
        unshot[i].w = 0.0;
        return;
    }
    let texel = r.texel;
    var gathered = vec3f(0.0);
    var near_slots = vec2<u32>(0u);
    if (shot) {
        slots &= ~slot_bit(own_slot);
        if (is_curved(own_slot)) {
            near_slots = slot_bit(own_slot);
        }
    }
    for (var left = slots; !no_slots(left); left = without_first(left)) {
        let k = first_slot(left);
        let s = shooters.items[k];
        let g = shot_geometry(texel, s, k);
        if (g.x > 0.0) {
            near_slots |= slot_bit(k);
        } else {
            gathered += g.y * slot_scale(k) * s.radiance;
        }
    }
    lightmap[i] += vec4f(gathered, 0.0);
    var remaining = unshot[i].rgb;
    if (shot) {
        // What it shot ahead of receiving it is owed.
        remaining = -texel.albedo * shooters.items[own_slot].overshoot;
    }
    unshot[i] = vec4f(remaining + texel.albedo * gathered, luminance(gathered) * texel.area * r.share);
    if (!no_slots(near_slots)) {
        let at = 3u * atomicAdd(&near_list.count, 1u);
        near_list.entries[at] = i;
        near_list.entries[at + 1u] = near_slots.x;
        near_list.entries[at + 2u] = near_slots.y;
    }
}

// The unshot radiance a near-field receiver takes from shooter `s` (slot
// `k`): the mean of its sub-cells', each weighted by its (bounded) point form
// factor to the receiver. A patch lit only beside a contact then lights the
// contact's shadow by the dark sub-cells under it, not by the patch's mean;
// the exact polygon form factor still sets how much arrives. A patch lit
// evenly gives its mean.
fn near_radiance(texel: Texel, s: Shooter, k: u32) -> vec3f {
    let base = k * SUB_CELL_ROWS * SUB_CELL_COUNT;
    var sum = vec3f(0.0);
    var weight = 0.0;
    for (var c = 0u; c < SUB_CELL_COUNT; c++) {
        let cell = shooter_cells.items[base + c];
        let d = shooter_cells.items[base + SUB_CELL_COUNT + c].xyz - texel.position;
        let r2 = dot(d, d);
        // cos θ_i cos θ_j · A / (π r² + A), the cosines' 1/r² folded in,
        // per unit of the sub-cell's area A (its power is A times its
        // radiance): one division a sub-cell.
        let cosines = max(dot(texel.normal, d), 0.0) * max(-dot(s.normal, d), 0.0);
        let w = cosines / max(r2 * (PI * r2 + cell.w), 1e-30);
        if (cell.w > 0.0 && r2 > 0.0) {
            sum += w * cell.rgb;
            weight += w * cell.w;
        }
    }
    return select(s.radiance, sum / weight, weight > 0.0);
}

// The near-field pass's workgroup counts (x, y, z) for `near_field`.
@group(0) @binding(12) var<storage, read_write> near_args: array<u32, 3>;
// Sizes the near-field pass from the list `main` wrote, on the GPU: one
// workgroup per 64 listed receivers, in rows as `near_field` reads them.
@compute @workgroup_size(1)
fn near_dispatch() {
    let args = dispatch_rows((atomicLoad(&near_list.count) + 63u) / 64u);
    near_args = array<u32, 3>(args.x, args.y, args.z);
}

// The listed receivers' near-field light, added after `main`'s far field,
// in slot order: the same sums whatever order the list is in.
@compute @workgroup_size(64)
fn near_field(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let j = id.x + id.y * groups.x * 64u;
    if (j >= atomicLoad(&near_list.count)) {
        return;
    }
    let i = near_list.entries[3u * j];
    let slots = vec2<u32>(near_list.entries[3u * j + 1u], near_list.entries[3u * j + 2u]);
    let r = receiver(i);
    let texel = r.texel;
    var gathered = vec3f(0.0);
    for (var left = slots; !no_slots(left); left = without_first(left)) {
        let k = first_slot(left);
        let s = shooters.items[k];
        // A texel of the shooter's own (curved) patch takes none from its
        // own sub-cell: flat at its scale, it gives next to none, and its
        // square would hover over the texel.
        let skip = select(SUB_CELL_COUNT, sub_cell(texel, params), s.patch_index == r.patch_index);
        gathered += near_light(texel, s, k, skip);
    }
    lightmap[i] += vec4f(gathered, 0.0);
    unshot[i] += vec4f(texel.albedo * gathered, luminance(gathered) * texel.area * r.share);
}

var<workgroup> sums: array<f32, 64>;

// The sum of `value` over the workgroup's 64 invocations, in a fixed order;
// every invocation must call it.
fn workgroup_sum(value: f32, lid: u32) -> f32 {
    sums[lid] = value;
    for (var half = 32u; half > 0u; half >>= 1u) {
        workgroupBarrier();
        if (lid < half) {
            sums[lid] += sums[lid + half];
        }
    }
    workgroupBarrier();
    let total = sums[0];
    // Everyone has read it before the next call writes `sums` again.
    workgroupBarrier();
    return total;
}

var<workgroup> slots_to_measure: vec2<u32>;

// The slots whose patch has no scale yet (read by one invocation, so that
// the whole workgroup branches on them alike), of those from `first` to
// before `end`.
fn slots_needing_scale(lid: u32, first: u32, end: u32) -> vec2<u32> {
    if (lid == 0u) {
        var slots = vec2<u32>(0u);
        for (var k = first; k < min(end, params.shooter_count); k++) {
            let s = shooters.items[k];
            if (s.patch_index != NO_TRIANGLE && patch_scale[s.patch_index] <= 0.0) {
                slots |= slot_bit(k);
            }
        }
        slots_to_measure = slots;
    }
    return workgroupUniformLoad(&slots_to_measure);
}

// Slots one measure workgroup sums for (`shoot::measure_slots_for`): 8 or all
// 64. The sums are the same either way.
override MEASURE_SLOTS: u32 = 8u;
// Texels one invocation of the measure pass sums (`MEASURE_CHUNK` / 64).
const MEASURE_TURNS: u32 = MEASURE_CHUNK / 64u;

// Workgroup (chunk, group of MEASURE_SLOTS slots): Σ F_ij A_i / A_j over the
// chunk's texels, for each of the group's slots whose patch has no scale
// yet. An invocation reads a texel once for the group's slots (a CPU driver
// reads storage arrays lane by lane; once per slot, that was most of the
// pass), and sums each slot's texels in a fixed order, like the rest.
@compute @workgroup_size(64)
fn measure(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let base = group.y * MEASURE_SLOTS;
    let slots = slots_needing_scale(lid, base, base + MEASURE_SLOTS);
    if (no_slots(slots)) {
        return;
    }
    var near = array<f32, MAX_SHOOTERS>();
    var far = array<f32, MAX_SHOOTERS>();
    // The receivers in a slot's near field, by their turn in the chunk:
    // their exact form factors are summed after the far field, where they
    // cost the few lanes that have them rather than every pair.
    var near_turns = array<u32, MEASURE_TURNS>();
    var near_slots = array<vec2<u32>, MEASURE_TURNS>();
    var near_count = 0u;
    let first = group.x * MEASURE_CHUNK;
    let end = min(first + MEASURE_CHUNK, params.texel_count);
    for (var turn = 0u; first + lid + turn * 64u < end; turn++) {
        let j = first + lid + turn * 64u;
        let r = receiver(members[j]);
        let texel = r.texel;
        let own_patch = r.patch_index;
        let share = r.share;
        var listed = vec2<u32>(0u);
        let lit = slots & group_shooters[j / 64u];
        for (var left = lit; !no_slots(left); left = without_first(left)) {
            let k = first_slot(left);
            let s = shooters.items[k];
            if (own_patch != s.patch_index) {
                let g = shot_geometry(texel, s, k);
                if (g.x > 0.0) {
                    listed |= slot_bit(k);
                } else {
                    far[k - base] += g.y * texel.area * share;
                }
            }
        }
        if (!no_slots(listed)) {
            near_turns[near_count] = turn;
            near_slots[near_count] = listed;
            near_count++;
        }
    }
    for (var n = 0u; n < near_count; n++) {
        let r = receiver(members[first + lid + near_turns[n] * 64u]);
        let texel = r.texel;
        let share = r.share;
        for (var left = near_slots[n]; !no_slots(left); left = without_first(left)) {
            let k = first_slot(left);
            near[k - base] += near_form_factor(texel, shooters.items[k], k) * texel.area * share;
        }
    }
    for (var left = slots; !no_slots(left); left = without_first(left)) {
        let k = first_slot(left);
        let sum = vec2f(near[k - base], far[k - base]) / max(shooters.items[k].area, 1e-30);
        // Near-field sums first, then far-field ones.
        for (var part = 0u; part < 2u; part++) {
            let total = workgroup_sum(sum[part], lid);
            if (lid == 0u) {
                partials[(part * MAX_SHOOTERS + k) * params.chunk_count + group.x] = total;
            }
        }
    }
}

// Whether a hemicube depth is of a surface the shooter sees from the front:
// `hemicube_depth` (solve_hemicube.wgsl) clears the last bit there, and the
// cleared atlas (1.0) holds no surface.
fn seen_from_front(stored: f32) -> bool {
    return stored < 1.0 && (bitcast<u32>(stored) & 1u) == 0u;
}

// Workgroup per slot: the covered share of the hemicube (surfaces seen from
// the front, by their delta form factors) over the measured Σ F_ij A_i / A_j
// becomes the patch's scale.
@compute @workgroup_size(64)
fn finish(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let k = group.x;
    if (no_slots(slots_needing_scale(lid, k, k + 1u))) {
        // Scaled when it shot before (or an unused slot).
        let patch_index = shooters.items[k].patch_index;
        if (lid == 0u && patch_index != NO_TRIANGLE) {
            slot_scales_out[k] = patch_scale[patch_index];
        }
        return;
    }
    var measured = vec2f(0.0);
    for (var part = 0u; part < 2u; part++) {
        var sum = 0.0;
        for (var c = lid; c < params.chunk_count; c += 64u) {
            sum += partials[(part * MAX_SHOOTERS + k) * params.chunk_count + c];
        }
        measured[part] = workgroup_sum(sum, lid);
    }
    // What a curved patch gives itself (solve_patch_power.wgsl): its
    // hemicube, above the patch, sees past it what the patch covers from its
    // surface, so that light is part of the covered share, as the near field
    // is. (Summed in the measure pass, it cost every texel-slot pair the
    // sub-cells' form factors on a CPU driver: +35 % bounce time.)
    measured.x += shooter_cells.items[(k * SUB_CELL_ROWS + 1u) * SUB_CELL_COUNT].w;

    // Delta form factor of a pixel on a face at unit distance, direction d:
    // d.z dA / (π |d|⁴), with dA = (2/S)² on every face.
    let size = u32(params.face_size);
    var covered = 0.0;
    var total = 0.0;
    for (var face = 0u; face < 5u; face++) {
        let view = hemicube_viewport(k, face, params.face_size, params.tiles_per_row);
        let rows = select(size / 2u, size, face == 0u);
        for (var n = lid; n < size * rows; n += 64u) {
            let row_column = quotient_remainder(n, size);
            let xy = vec2<i32>(view.xy) + vec2<i32>(i32(row_column.y), i32(row_column.x));
            let d = hemicube_texel_direction(xy, view, face);
            let r2 = dot(d, d);
            let delta = d.z / (r2 * r2);
            total += delta;
            if (seen_from_front(textureLoad(depth, xy, 0))) {
                covered += delta;
            }
        }
    }
    covered = workgroup_sum(covered, lid);
    total = workgroup_sum(total, lid);
    if (lid == 0u) {
        let share = covered / max(total, 1e-30);
        var scale = 1.0;
        // Only the far field is scaled: the near field's polygon form factors
        // are exact, and scaling them would over-light the receivers next to
        // a patch whose share was lost elsewhere.
        if (measured.y > 0.0) {
            scale = clamp((share - measured.x) / measured.y, MIN_SCALE, MAX_SCALE);
        }
        patch_scale[shooters.items[k].patch_index] = scale;
        slot_scales_out[k] = scale;
        if (params.measure_coverage != 0u) {
            patch_coverage[shooters.items[k].patch_index] = share;
        }
    }
}
