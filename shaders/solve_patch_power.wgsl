// Per-patch unshot light (design notes, algorithm step 4): each patch sums
// ΔL·A over its texels (a GPU reduction; the seed reads a 1×1 buffer). One
// invocation per patch, members in a fixed order, so the sums are
// deterministic. Once the batch's shooters are chosen, `shooter_cells` sums
// each shooter's light by parts of its patch, for the near field.

@group(0) @binding(0) var<uniform> params: BounceParams;
@group(0) @binding(1) var<storage, read> texels: array<Texel>;
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
// patch, integrated part by part.
@group(0) @binding(8) var<storage, read_write> shooter_cells: array<vec4f>;
// Per texel: the share of its area that bounces light (src/solve/overlaps.rs):
// its unshot light counts for that share of its area.
@group(0) @binding(9) var<storage, read> shares: array<f32>;

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
    for (var m = 0u; m < own.count; m++) {
        let i = members[own.first + m];
        let u = unshot[i];
        let texel = texels[i];
        let area = texel.area * shares[i];
        power += u.rgb * area;
        received += u.w;
        let w = luminance(u.rgb) * area;
        weighted += w * texel.position;
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

// One workgroup per shooter slot, one invocation per sub-cell; run before
// the shoot pass clears the shooters' unshot light.
@compute @workgroup_size(16)
fn shooter_cells_of_batch(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_index) c: u32) {
    let k = group.x;
    let s = shooters.items[k];
    var power = vec3f(0.0);
    var area = 0.0;
    var centroid = vec3f(0.0);
    var normal = vec3f(0.0);
    if (s.patch_index != NO_TRIANGLE) {
        let own = patches[s.patch_index];
        for (var m = 0u; m < own.count; m++) {
            let i = members[own.first + m];
            let texel = texels[i];
            if (sub_cell(texel, params) == c) {
                // Light by the bouncing area, over the whole area: a sub-cell
                // where two surfaces coincide has half the radiance of each.
                power += unshot[i].rgb * texel.area * shares[i];
                area += texel.area;
                centroid += texel.position * texel.area;
                normal += texel.normal * texel.area;
            }
        }
    }
    let base = k * SUB_CELL_ROWS * SUB_CELL_COUNT;
    shooter_cells[base + c] = vec4f(power, area);
    shooter_cells[base + SUB_CELL_COUNT + c] = vec4f(select(vec3f(0.0), centroid / area, area > 0.0), 0.0);
    let facing = select(vec3f(0.0), normalize(normal), dot(normal, normal) > 0.0);
    if (area > 0.0 && dot(facing, s.normal) < FLAT_COS) {
        atomicOr(&curved, 1u);
    }
    workgroupBarrier();
    let is_curved = f32(atomicLoad(&curved));
    shooter_cells[base + 2u * SUB_CELL_COUNT + c] = vec4f(facing, select(0.0, is_curved, c == 0u));
}
