// Picks the batch's shooters: the patches with the largest unshot power
// Σ ΔL·A (luminance), one argmax round per slot in a single workgroup, ties
// to the lower index. Also totals the unshot and received power for the
// convergence trace. Runs entirely on the GPU: no read-back between shots.

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

const THREADS: u32 = 256u;
var<workgroup> best_power: array<f32, THREADS>;
var<workgroup> best_index: array<u32, THREADS>;
var<workgroup> sum_unshot: array<vec3f, THREADS>;
var<workgroup> sum_received: array<f32, THREADS>;
var<workgroup> sum_landing: array<f32, THREADS>;

@compute @workgroup_size(256)
fn main(@builtin(local_invocation_index) lid: u32) {
    var unshot = vec3f(0.0);
    var received = 0.0;
    var landing = 0.0;
    for (var j = lid; j < params.patch_count; j += THREADS) {
        chosen[j] = 0u;
        unshot += patch_power[j].rgb;
        received += patch_power[j].w;
        landing += luminance(patch_power[j].rgb) * patch_coverage[j];
    }
    sum_unshot[lid] = unshot;
    sum_received[lid] = received;
    sum_landing[lid] = landing;
    storageBarrier();
    workgroupBarrier();
    for (var stride = THREADS / 2u; stride > 0u; stride /= 2u) {
        if (lid < stride) {
            sum_unshot[lid] += sum_unshot[lid + stride];
            sum_received[lid] += sum_received[lid + stride];
            sum_landing[lid] += sum_landing[lid + stride];
        }
        workgroupBarrier();
    }

    var shot = vec3f(0.0);
    var count = 0u;
    for (var slot = 0u; slot < params.shooter_count; slot++) {
        var power = 0.0;
        var index = NO_TRIANGLE;
        for (var j = lid; j < params.patch_count; j += THREADS) {
            let p = luminance(patch_power[j].rgb);
            if (chosen[j] == 0u && p > power) {
                power = p;
                index = j;
            }
        }
        best_power[lid] = power;
        best_index[lid] = index;
        workgroupBarrier();
        for (var stride = THREADS / 2u; stride > 0u; stride /= 2u) {
            if (lid < stride) {
                let other = lid + stride;
                let better = best_power[other] > best_power[lid]
                    || (best_power[other] == best_power[lid] && best_index[other] < best_index[lid]);
                if (better) {
                    best_power[lid] = best_power[other];
                    best_index[lid] = best_index[other];
                }
            }
            workgroupBarrier();
        }
        let winner = best_index[0];
        if (lid == 0u) {
            var shooter: Shooter;
            shooter.patch_index = NO_TRIANGLE;
            if (winner != NO_TRIANGLE && best_power[0] > 0.0) {
                let chosen_patch = patches[winner];
                let power = patch_power[winner].rgb;
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
                chosen[winner] = slot + 1u;
                shot += power;
                count += 1u;
            }
            shooters[slot] = shooter;
            for (var face = 0u; face < 5u; face++) {
                hemicube_faces[slot * 5u + face] = HemicubeFace(shooter.position, shooter.lift, shooter.normal, face);
            }
        }
        storageBarrier();
        workgroupBarrier();
    }
    if (lid == 0u) {
        stats.unshot = vec4f(sum_unshot[0], luminance(sum_unshot[0]));
        stats.received = vec4f(0.0, 0.0, 0.0, sum_received[0]);
        stats.landing = sum_landing[0];
        stats.shot = vec4f(shot, luminance(shot));
        stats.shooters = count;
    }
}
