// Hemicube depth maps, one per shooter of the batch (design notes, algorithm
// step 4). The seed projects the hemisphere in one pass (its Table 3), but a
// nonlinear projection bends triangle edges that the rasterizer draws
// straight; five perspective faces are exact. Depth is the true distance
// from the shooter, written per fragment.

@group(0) @binding(0) var<uniform> params: BounceParams;
@group(0) @binding(2) var<storage, read> materials: array<Material>;
@group(0) @binding(3) var textures: texture_2d_array<f32>;
@group(0) @binding(4) var texture_sampler: sampler;

// The instance's shooter and face (`HemicubeFace`), as instance attributes:
// a CPU driver fetches them once per draw, where reading the shooter from a
// buffer by instance index cost a load per vertex and lane.
struct FaceIn {
    @location(5) position: vec3f,
    @location(6) lift: f32,
    @location(7) normal: vec3f,
    @location(8) face: u32,
}

@vertex
fn vs_hemicube(in: CasterIn, view: FaceIn) -> CasterOut {
    let position = in.position;
    let face = view.face;
    let m = basis(view.normal);
    let d = position - lifted_origin(view.position, view.normal, view.lift);
    let local = vec3f(dot(d, m[0]), dot(d, m[1]), dot(d, m[2]));
    // The face's frame, as receivers project into it (`hemicube_face`): a
    // half face's viewport holds only the upper half of its frustum.
    let f = hemicube_face_frame(local, face);
    let y = select(2.0 * f.y - f.z, f.y, face == 0u);
    var out: CasterOut;
    // z = w − near keeps 0 ≤ z ≤ w exactly for points in front of the near plane.
    out.clip = vec4f(f.x, y, f.z - params.near, f.z);
    out.local = local;
    out.material = in.material;
    out.uv0 = in.uv0;
    out.uv1 = in.uv1;
    out.face = face;
    return out;
}

// Depth, and whether the shooter sees the surface's front: light that lands
// on a back face reaches no texel, so the form factors' normalization
// (solve_shoot's `finish`) must not count it as caught.
struct HemicubeOut {
    @builtin(frag_depth) depth: f32,
    @location(0) front: vec4f,
}

fn hemicube_out(in: CasterOut, front_facing: bool) -> HemicubeOut {
    // Faces 0, 1 and 4 project with a mirror (their clip-space map has a
    // positive determinant while looking along +w), so the rasterizer's
    // counter-clockwise "front" is the surface's back there.
    let mirrored = in.face == 0u || in.face == 1u || in.face == 4u;
    var out: HemicubeOut;
    out.depth = clamp(length(in.local) / params.far, 0.0, 1.0);
    out.front = vec4f(select(0.0, 1.0, front_facing != mirrored));
    return out;
}

@fragment
fn fs_hemicube(in: CasterOut, @builtin(front_facing) front_facing: bool) -> HemicubeOut {
    return hemicube_out(in, front_facing);
}

// Alpha-MASK triangles: cut-out fragments let light through.
@fragment
fn fs_hemicube_masked(in: CasterOut, @builtin(front_facing) front_facing: bool) -> HemicubeOut {
    let m = materials[in.material];
    let uv = texture_coordinates(m.base_texture, in.uv0, in.uv1);
    let alpha = m.base_color.a * sample_texture_grad(textures, texture_sampler, m.base_texture, uv, dpdx(uv), dpdy(uv)).a;
    if (alpha < m.emission.w) {
        discard;
    }
    return hemicube_out(in, front_facing);
}
