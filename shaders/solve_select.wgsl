// Picks the batch's shooters: the patches with the most power Σ ΔL·A to
// shoot (luminance, in magnitude: unshot light, owed light and the light
// shot ahead, `to_shoot`), one argmax round per slot in a single workgroup,
// ties to the lower index. Also totals the unshot, unsettled and received
// power for the convergence trace. Runs entirely on the GPU: no read-back between shots.
//
// Each invocation keeps the best of its own patches (every THREADS-th);
// a round reduces those in two flat steps (GROUPS bests, then one) rather
// than a tree, and only the invocation whose patch won looks again: three
// barriers a round instead of ten, which is what a round costs on a CPU
// driver, where each barrier switches between all of a workgroup's
// invocations.

@group(0) @binding(0) var<uniform> params: BounceParams;
@group(0) @binding(1) var<storage, read> patches: array<Patch>;
@group(0) @binding(2) var<storage, read> patch_power: array<vec4f>;
// Per patch: its slot + 1 once chosen in this batch, else 0 (read by
// solve_shoot).
@group(0) @binding(3) var<storage, read_write> chosen: array<u32>;
@group(0) @binding(4) var<storage, read_write> shooters: array<Shooter>;
@group(0) @binding(5) var<storage, read_write> stats: BounceStats;
@group(0) @binding(6) var<storage, read> patch_origin: array<vec4f>;
// Per patch: how much of its texels' hemispheres the scene covers (1
// without a direct pass): an upper bound of the share of its light that lands.
@group(0) @binding(7) var<storage, read> patch_coverage: array<f32>;
// The batch's hemicube faces, five per slot, for the hemicube pass.
@group(0) @binding(8) var<storage, read_write> hemicube_faces: array<HemicubeFace>;
// Per patch: Σ albedo·A over its texels (rgb).
@group(0) @binding(9) var<storage, read> patch_albedo: array<vec4f>;
// Per patch: the light per unit albedo it would shoot ahead now (for the
// next batch's origins, solve_patch_power.wgsl).
@group(0) @binding(10) var<storage, read_write> patch_overshoot: array<vec4f>;

const THREADS: u32 = 64u;
const GROUPS: u32 = 8u;
const PER_GROUP: u32 = THREADS / GROUPS;
// Per invocation, the best of its patches not yet chosen.
var<workgroup> best_power: array<f32, THREADS>;
var<workgroup> best_index: array<u32, THREADS>;
// Per group of PER_GROUP invocations, the best of theirs; [0], the round's.
var<workgroup> group_power: array<f32, GROUPS>;
var<workgroup> group_index: array<u32, GROUPS>;
var<workgroup> sum_unshot: array<vec3f, THREADS>;
var<workgroup> sum_received: array<f32, THREADS>;
var<workgroup> sum_landing: array<f32, THREADS>;
var<workgroup> sum_unsettled: array<f32, THREADS>;

@compute @workgroup_size(THREADS)
fn main(@builtin(local_invocation_index) lid: u32) {
    var unshot = vec3f(0.0);
    var unsettled = 0.0;
    var received = 0.0;
    var landing = 0.0;
    for (var j = lid; j < params.patch_count; j += THREADS) {
        chosen[j] = 0u;
        unshot += patch_power[j].rgb;
        received += patch_power[j].w;
        let magnitude = abs(luminance(patch_power[j].rgb));
        unsettled += magnitude;
        landing += magnitude * patch_coverage[j];
    }
    sum_unshot[lid] = unshot;
    sum_received[lid] = received;
    sum_landing[lid] = landing;
    sum_unsettled[lid] = unsettled;
    storageBarrier();
    workgroupBarrier();
    for (var stride = THREADS / 2u; stride > 0u; stride /= 2u) {
        if (lid < stride) {
            sum_unshot[lid] += sum_unshot[lid + stride];
            sum_received[lid] += sum_received[lid + stride];
            sum_landing[lid] += sum_landing[lid + stride];
            sum_unsettled[lid] += sum_unsettled[lid + stride];
        }
        workgroupBarrier();
    }

    // What a surface of full coverage will still receive (L_lm): each
    // patch shoots its share of that too, ahead of receiving it, and is
    // chosen by what it would shoot.
    ambient = max(sum_unshot[0] * params.overshoot.rgb, vec3f(0.0));
    for (var j = lid; j < params.patch_count; j += THREADS) {
        patch_overshoot[j] = vec4f(ambient * patch_coverage[j], 0.0);
    }
    var shot = vec3f(0.0);
    var count = 0u;
    own_best(lid);
    for (var slot = 0u; slot < params.shooter_count; slot++) {
        workgroupBarrier();
        if (lid < GROUPS) {
            var power = best_power[lid * PER_GROUP];
            var index = best_index[lid * PER_GROUP];
            for (var k = lid * PER_GROUP + 1u; k < (lid + 1u) * PER_GROUP; k++) {
                if (better(best_power[k], best_index[k], power, index)) {
                    power = best_power[k];
                    index = best_index[k];
                }
            }
            group_power[lid] = power;
            group_index[lid] = index;
        }
        workgroupBarrier();
        if (lid == 0u) {
            for (var g = 1u; g < GROUPS; g++) {
                if (better(group_power[g], group_index[g], group_power[0], group_index[0])) {
                    group_power[0] = group_power[g];
                    group_index[0] = group_index[g];
                }
            }
        }
        workgroupBarrier();
        let winner = group_index[0];
        let shoots = winner != NO_TRIANGLE && group_power[0] > 0.0;
        if (lid == 0u) {
            var shooter: Shooter;
            shooter.patch_index = NO_TRIANGLE;
            if (shoots) {
                let chosen_patch = patches[winner];
                shooter.overshoot = ambient * patch_coverage[winner];
                let power = to_shoot(winner);
                shooter.position = patch_origin[winner].xyz;
                shooter.area = chosen_patch.area;
                shooter.normal = chosen_patch.normal;
                shooter.patch_index = winner;
                shooter.radiance = power / max(chosen_patch.area, 1e-30);
                shooter.radius = chosen_patch.radius;
                shooter.rect_centre = chosen_patch.rect_centre;
                // Lift the hemicube just off the surface (above a curved patch's
                // rise) so it does not see its own patch; receivers between the
                // surface and the hemicube count as seen.
                // The patch's rise is above its area centroid's plane; the
                // origin (weighted by unshot power) may lie below that.
                let below = dot(chosen_patch.position - shooter.position, chosen_patch.normal);
                shooter.lift = max(chosen_patch.lift + below, 0.0) + 0.02 * params.receiver_offset;
                shooter.half_u = chosen_patch.half_u;
                shooter.half_v = chosen_patch.half_v;
                shooter.rect_area = 4.0 * length(cross(chosen_patch.half_u, chosen_patch.half_v));
                shot += power;
                count += 1u;
            }
            shooters[slot] = shooter;
            for (var face = 0u; face < 5u; face++) {
                hemicube_faces[slot * 5u + face] = HemicubeFace(shooter.position, shooter.lift, shooter.normal, face);
            }
        }
        // The winner is one of its invocation's patches: that invocation
        // marks it chosen and looks again among the rest.
        if (shoots && lid == winner % THREADS) {
            chosen[winner] = slot + 1u;
            own_best(lid);
        }
    }
    if (lid == 0u) {
        stats.unshot = vec4f(sum_unshot[0], luminance(sum_unshot[0]));
        stats.received = vec4f(0.0, 0.0, 0.0, sum_received[0]);
        stats.landing = sum_landing[0];
        stats.unsettled = sum_unsettled[0];
        stats.shot = vec4f(shot, luminance(shot));
        stats.shooters = count;
    }
}

// The ambient light still to come (L_lm) at full coverage, this batch.
var<private> ambient: vec3f;

// What patch `j` shoots if chosen (Σ ΔL·A, rgb): its unshot light and,
// ahead, its share of the ambient light still to come.
fn to_shoot(j: u32) -> vec3f {
    return patch_power[j].rgb + patch_albedo[j].rgb * ambient * patch_coverage[j];
}

// Whether a patch of power `p` and index `i` goes before the best so far:
// more power, or as much and a lower index. NO_TRIANGLE (no patch) has
// power 0 and never wins over a patch with power.
fn better(p: f32, i: u32, power: f32, index: u32) -> bool {
    return p > power || (p == power && i < index);
}

// The best of invocation `lid`'s patches not yet chosen in this batch (only
// patches with power: a NaN or zero never shoots).
fn own_best(lid: u32) {
    var power = 0.0;
    var index = NO_TRIANGLE;
    for (var j = lid; j < params.patch_count; j += THREADS) {
        let p = abs(luminance(to_shoot(j)));
        if (chosen[j] == 0u && p > power) {
            power = p;
            index = j;
        }
    }
    best_power[lid] = power;
    best_index[lid] = index;
}
