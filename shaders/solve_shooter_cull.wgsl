// Which of a batch's shooters each group of 64 receiver texels (one
// workgroup of `solve_shoot`'s `main`) can take light from, as a bit per
// slot. A CPU driver runs every branch of a shader for all lanes, so a pair
// that gets nothing costs as much as one that gets light; a loop over the
// set bits alone runs as many times as the group has shooters to take from.
// A floor takes nothing from its own plane's patches, nor the top of a ball
// from the floor under it.
//
// The test is conservative against `solve_shoot`'s `shot_geometry` (the
// group's bounding box and cone of normals hold every texel's, widened by
// half of `in_plane` for rounding): a slot left out gives none of its
// texels light.
//
// It also lists the groups `main` gathers at all, which it dispatches over:
// in an open scene about half the groups take light from no shooter of a
// batch, and a CPU driver pays each invocation's dispatch and reads even
// where it returns at once.

// A group's texels: the box of their positions and the cone of their
// shading normals (cos_spread −1: any direction). Mirrors
// `shooter_cull::ReceiverGroup`.
struct ReceiverGroup {
    lo: vec3f,
    cos_spread: f32,
    hi: vec3f,
    sin_spread: f32,
    axis: vec3f,
    _pad: f32,
}

@group(0) @binding(0) var<uniform> params: BounceParams;
@group(0) @binding(1) var<uniform> shooters: ShooterBatch;
@group(0) @binding(2) var<storage, read> groups: array<ReceiverGroup>;
// Per group: the slots that may light one of its texels (written).
@group(0) @binding(3) var<storage, read_write> group_shooters: array<vec2<u32>>;
// Per group: the lowest and highest patch of its texels (`members` runs by patch).
@group(0) @binding(4) var<storage, read> group_patches: array<vec2u>;
// Per group: 1 where its texels' record of light received (`unshot`'s w)
// may be other than 0: in the last batch a slot may have lit it, or a patch
// of its own shot (a curved one lights itself where it is concave,
// `near_light` in solve_shoot.wgsl).
@group(0) @binding(5) var<storage, read_write> group_received: array<u32>;
// The groups `solve_shoot`'s `main` gathers this batch (`GatheredGroups`
// there): their count as the list fills, the count for `main`, the list.
struct GroupList {
    filling: atomic<u32>,
    count: u32,
    groups: array<u32>,
}
@group(0) @binding(6) var<storage, read_write> gathered: GroupList;
// `main`'s workgroup counts (x, y, z) for `solve_shoot`'s `main`.
@group(0) @binding(7) var<storage, read_write> gather_args: array<u32, 3>;

// Whether shooter `s` can light any texel of group `g`: one must lie in
// front of its plane (by more than `params.in_plane`), and face its centroid.
fn may_light(g: ReceiverGroup, s: Shooter) -> bool {
    // What the test allows for rounding, metres.
    let margin = 0.5 * params.in_plane;
    let centre = 0.5 * (g.lo + g.hi);
    let half = 0.5 * (g.hi - g.lo);
    let highest = dot(centre - s.position, s.normal) + dot(half, abs(s.normal));
    if (highest <= params.in_plane - margin) {
        return false;
    }
    // The largest dot(n, s.position − p) over the cone's normals n and the
    // box's points p: over n for the centre, plus the box's half diagonal.
    let v = s.position - centre;
    let distance = length(v);
    let cos_v = dot(g.axis, v) / max(distance, 1e-30);
    var toward = distance;
    if (cos_v < g.cos_spread) {
        let sin_v = sqrt(max(1.0 - cos_v * cos_v, 0.0));
        toward = distance * (cos_v * g.cos_spread + sin_v * g.sin_spread);
    }
    return toward + length(half) + margin > 0.0;
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let g = id.x + id.y * params.row_stride;
    if (g >= arrayLength(&groups)) {
        return;
    }
    let group = groups[g];
    let patches = group_patches[g];
    var mask = vec2<u32>(0u);
    var shooting = false;
    for (var k = 0u; k < params.shooter_count; k++) {
        let s = shooters.items[k];
        if (s.patch_index != NO_TRIANGLE && may_light(group, s)) {
            mask |= slot_bit(k);
        }
        shooting = shooting || (s.patch_index >= patches.x && s.patch_index <= patches.y);
    }
    group_shooters[g] = mask;
    // `main` visits the group where a slot may light it, where a patch of
    // it shoots (its unshot light leaves), and where it clears the record
    // of what its texels received in the last batch.
    let lit = !no_slots(mask);
    if (lit || shooting || group_received[g] != 0u) {
        gathered.groups[atomicAdd(&gathered.filling, 1u)] = g;
    }
    group_received[g] = select(0u, 1u, lit || shooting);
}

// `main`'s workgroups from the list's length, on the GPU; the list empties
// for the next batch.
@compute @workgroup_size(1)
fn gather_dispatch() {
    let count = atomicExchange(&gathered.filling, 0u);
    gathered.count = count;
    let args = dispatch_rows(count);
    gather_args = array<u32, 3>(args.x, args.y, args.z);
}
