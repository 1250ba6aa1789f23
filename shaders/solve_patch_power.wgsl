// Per-patch unshot light (design notes, algorithm step 4): each patch sums
// ΔL·A over its texels (a GPU reduction; the seed reads a 1×1 buffer). One
// invocation per patch, members in a fixed order, so the sums are
// deterministic. Once the batch's shooters are chosen, `shooter_cells` sums
// each shooter's light by parts of its patch, for the near field.

@group(0) @binding(0) var<uniform> params: BounceParams;
// Every receiver texel, as four layers of records (`load_receiver`).
@group(0) @binding(1) var receivers: texture_2d_array<u32>;
@group(0) @binding(2) var<storage, read> patches: array<Patch>;
@group(0) @binding(3) var<storage, read> members: array<u32>;
// Per texel: rgb = unshot radiance ΔL, w = luminance·area received in the last shoot.
@group(0) @binding(4) var<storage, read> unshot: array<vec4f>;
// Per patch: rgb = Σ ΔL·A, w = Σ received luminance·area.
@group(0) @binding(5) var<storage, read_write> patch_power: array<vec4f>;
// Per patch: where its unshot light is (its centroid weighted by unshot
// power; the area centroid when it has none). A patch a wall cuts through
// (a floor cell half inside a room) then shoots from its lit side.
@group(0) @binding(6) var<storage, read_write> patch_origin: array<vec4f>;
// The batch's shooters (chosen by solve_select), a uniform buffer as in
// solve_shoot.wgsl.
@group(0) @binding(7) var<uniform> shooters: ShooterBatch;
// Per shooter slot k and sub-cell c of its patch, at
// k·SUB_CELL_ROWS·SUB_CELL_COUNT + c: (Σ ΔL·A rgb, Σ A); SUB_CELL_COUNT
// further, the area centroid; twice that further, the unit area-weighted
// mean normal: where the patch's surface is and which way it faces, part by
// part, for the near field. The first normal's w is 1 where some sub-cell
// turns from the patch's normal by more than FLAT_COS allows: a curved
// patch, integrated part by part. The first centroid's w is the share of
// its light such a patch gives itself (`own_share`).
@group(0) @binding(8) var<storage, read_write> shooter_cells: array<vec4f>;
// Per patch p and sub-cell c, at 16 p + c: the first of the sub-cell's
// members (each patch's are sorted by sub-cell), the next entry its end
// but for the last sub-cell, whose run ends at the patch's end.
@group(0) @binding(9) var<storage, read> cell_starts: array<u32>;
// Per patch: the light per unit albedo it would have shot ahead in the
// last batch (solve_select.wgsl).
@group(0) @binding(10) var<storage, read> patch_overshoot: array<vec4f>;

// Receiver texel `i`, with the share of its area that bounces light
// (src/solve/overlaps.rs): its unshot light counts for that share of its area.
fn receiver(i: u32) -> Receiver {
    return load_receiver(receivers, i, params.receiver_row_shift);
}

// The members of sub-cell `c` of patch `j`: (first, end) in `members`.
fn cell_members(j: u32, c: u32) -> vec2<u32> {
    let own = patches[j];
    let at = j * SUB_CELL_COUNT + c;
    return vec2<u32>(cell_starts[at], select(cell_starts[at + 1u], own.first + own.count, c + 1u == SUB_CELL_COUNT));
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let j = id.x + id.y * params.row_stride;
    if (j >= params.patch_count) {
        return;
    }
    let own = patches[j];
    var power = vec3f(0.0);
    var received = 0.0;
    var weighted = vec3f(0.0);
    var weight = 0.0;
    let ahead = patch_overshoot[j].rgb;
    for (var m = own.first; m < own.first + own.count; m++) {
        let i = members[m];
        let u = unshot[i];
        let r = receiver(i);
        let area = r.texel.area * r.share;
        power += u.rgb * area;
        received += u.w;
        // Weighed by what it would shoot: light owed and light shot ahead
        // cancel where the ambient estimate was right.
        let w = abs(luminance(u.rgb + r.texel.albedo * ahead)) * area;
        weighted += w * r.texel.position;
        weight += w;
    }
    patch_power[j] = vec4f(power, received);
    if (weight > 0.0) {
        patch_origin[j] = vec4f(weighted / weight, weight);
    } else {
        patch_origin[j] = vec4f(own.position, 0.0);
    }
}

// A patch whose sub-cells' mean normals all lie within about 2.5° of its
// own is flat.
const FLAT_COS: f32 = 0.999;

var<workgroup> curved: atomic<u32>;
// The batch's sub-cells, for `own_share`.
var<workgroup> cell_area: array<f32, SUB_CELL_COUNT>;
var<workgroup> cell_centroid: array<vec3f, SUB_CELL_COUNT>;
var<workgroup> cell_normal: array<vec3f, SUB_CELL_COUNT>;
var<workgroup> own_sums: array<f32, SUB_CELL_COUNT>;

// One workgroup per shooter slot, one invocation per sub-cell, which reads
// only its sub-cell's members; run before the shoot pass clears the
// shooters' unshot light.
@compute @workgroup_size(16)
fn shooter_cells_of_batch(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_index) c: u32) {
    let k = group.x;
    let s = shooters.items[k];
    var power = vec3f(0.0);
    var area = 0.0;
    var centroid = vec3f(0.0);
    var normal = vec3f(0.0);
    // The sub-cell's members (none in an unused slot).
    var run = vec2<u32>(0u);
    if (s.patch_index != NO_TRIANGLE) {
        run = cell_members(s.patch_index, c);
    }
    for (var m = run.x; m < run.y; m++) {
        let i = members[m];
        let r = receiver(i);
        let texel = r.texel;
        // Light by the bouncing area, over the whole area: a sub-cell
        // where two surfaces coincide has half the radiance of each.
        power += (unshot[i].rgb + texel.albedo * s.overshoot) * texel.area * r.share;
        area += texel.area;
        centroid += texel.position * texel.area;
        normal += texel.normal * texel.area;
    }
    let base = k * SUB_CELL_ROWS * SUB_CELL_COUNT;
    let at = select(vec3f(0.0), centroid / area, area > 0.0);
    shooter_cells[base + c] = vec4f(power, area);
    shooter_cells[base + SUB_CELL_COUNT + c] = vec4f(at, 0.0);
    let facing = select(vec3f(0.0), normalize(normal), dot(normal, normal) > 0.0);
    if (area > 0.0 && dot(facing, s.normal) < FLAT_COS) {
        atomicOr(&curved, 1u);
    }
    cell_area[c] = area;
    cell_centroid[c] = at;
    cell_normal[c] = select(s.normal, facing, dot(facing, facing) > 0.0);
    workgroupBarrier();
    let is_curved = atomicLoad(&curved) != 0u;
    shooter_cells[base + 2u * SUB_CELL_COUNT + c] = vec4f(facing, select(0.0, 1.0, is_curved && c == 0u));
    var own = 0.0;
    if (is_curved) {
        own = own_share(s, c, run);
    }
    own_sums[c] = own;
    workgroupBarrier();
    if (c == 0u) {
        var total = 0.0;
        for (var d = 0u; d < SUB_CELL_COUNT; d++) {
            total += own_sums[d];
        }
        shooter_cells[base + SUB_CELL_COUNT] = vec4f(at, total);
    }
}

// Invocation `c`'s part of Σ F_i A_i / A over the texels i of shooter `s`'s
// own (curved) patch, F_i the form factor of its other sub-cells' squares
// to texel i, as the near field lights them (solve_shoot.wgsl's
// `near_light`): the share of its light a patch gives itself where it is
// concave, which the shoot pass's `finish` counts as covered. Invocation
// `c` sums the texels of sub-cell `c`, `run` in `members`. Left in the
// first sub-cell's centroid's w.
fn own_share(s: Shooter, c: u32, run: vec2<u32>) -> f32 {
    var sum = 0.0;
    for (var m = run.x; m < run.y; m++) {
        let r = receiver(members[m]);
        let texel = r.texel;
        var f = 0.0;
        for (var d = 0u; d < SUB_CELL_COUNT; d++) {
            if (d != c) {
                f += square_form_factor(texel.position, texel.normal, cell_centroid[d], cell_normal[d], cell_area[d], s.half_u);
            }
        }
        sum += f * texel.area * r.share;
    }
    return sum / max(s.area, 1e-30);
}
