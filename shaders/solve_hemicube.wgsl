// Hemicube depth maps, one per shooter of the batch (design notes, algorithm
// step 4). The seed projects the hemisphere in one pass (its Table 3), but a
// nonlinear projection bends triangle edges that the rasterizer draws
// straight; five perspective faces are exact. Depth is the true distance
// from the shooter, written per fragment.

@group(0) @binding(0) var<uniform> params: BounceParams;
@group(0) @binding(2) var<storage, read> materials: array<Material>;
@group(0) @binding(3) var textures: texture_2d_array<f32>;
@group(0) @binding(4) var texture_sampler: sampler;

// A caster vertex. Mirrors `casters::CasterVertex`.
struct CasterIn {
    @location(0) position: vec3f,
    @location(1) material: u32,
    @location(2) uv0: vec2f,
    @location(3) uv1: vec2f,
    @location(4) sheet: u32,                        // 1 on an open surface (solve::surfaces)
}

// What a caster's fragment needs to test its material's alpha cut-out.
struct CasterOut {
    @builtin(position) clip: vec4f,
    @location(0) local: vec3f,                      // position in the shooter's frame (hemicubes)
    @location(1) @interpolate(flat) material: u32,
    @location(2) uv0: vec2f,
    @location(3) uv1: vec2f,
    @location(4) @interpolate(flat) face: u32,     // hemicube face (hemicubes)
    @location(5) @interpolate(flat) sheet: u32,    // as CasterIn's (depth maps)
}

// The instance's shooter and face (`HemicubeFace`), as instance attributes:
// a CPU driver fetches them once per draw, where reading the shooter from a
// buffer by instance index cost a load per vertex and lane.
struct FaceIn {
    @location(5) position: vec3f,
    @location(6) lift: f32,
    @location(7) normal: vec3f,
    @location(8) face: u32,
}

// The shooter's frame at a caster vertex, and its clip position on the face.
struct FaceVertex {
    clip: vec4f,
    local: vec3f,  // position in the shooter's frame
}

fn face_vertex(position: vec3f, view: FaceIn) -> FaceVertex {
    let face = view.face;
    let m = basis(view.normal);
    let d = position - lifted_origin(view.position, view.normal, view.lift);
    let local = vec3f(dot(d, m[0]), dot(d, m[1]), dot(d, m[2]));
    // The face's frame, as receivers project into it (`hemicube_face`): a
    // half face's viewport holds only the upper half of its frustum.
    let f = hemicube_face_frame(local, face);
    let y = select(2.0 * f.y - f.z, f.y, face == 0u);
    // z = w − near keeps 0 ≤ z ≤ w exactly for points in front of the near plane.
    return FaceVertex(vec4f(f.x, y, f.z - params.near, f.z), local);
}

// What an opaque caster's fragment needs (a CPU driver sets up and stores
// every output of a vertex shader, read or not).
struct OpaqueOut {
    @builtin(position) clip: vec4f,
    @location(0) local: vec3f,
    @location(4) @interpolate(flat) face: u32,
}

@vertex
fn vs_hemicube(in: CasterIn, view: FaceIn) -> OpaqueOut {
    let v = face_vertex(in.position, view);
    return OpaqueOut(v.clip, v.local, view.face);
}

@vertex
fn vs_hemicube_masked(in: CasterIn, view: FaceIn) -> CasterOut {
    let v = face_vertex(in.position, view);
    var out: CasterOut;
    out.clip = v.clip;
    out.local = v.local;
    out.material = in.material;
    out.uv0 = in.uv0;
    out.uv1 = in.uv1;
    out.face = view.face;
    return out;
}

// The distance from the shooter, with its last bit set where the shooter
// sees the surface's back (`seen_from_front` in solve_shoot.wgsl reads it):
// light that lands on a back face reaches no texel, so the form factors'
// normalization (solve_shoot's `finish`) must not count it as caught.
fn hemicube_depth(local: vec3f, face: u32, front_facing: bool) -> f32 {
    // Faces 0, 1 and 4 project with a mirror (their clip-space map has a
    // positive determinant while looking along +w), so the rasterizer's
    // counter-clockwise "front" is the surface's back there.
    let mirrored = face == 0u || face == 1u || face == 4u;
    let seen_from_front = front_facing != mirrored;
    let depth = clamp(length(local) / params.far, 0.0, 1.0);
    // The side bit also makes a back face lie one step behind a front face
    // at the same depth: the depth test keeps the same fragment in whatever
    // order the culled lists draw them (a surface drawn twice, facing both
    // ways, would otherwise show the first drawn).
    let sided = bitcast<f32>((bitcast<u32>(depth) & ~1u) | select(1u, 0u, seen_from_front));
    return select(sided, 1.0, depth >= 1.0);
}

@fragment
fn fs_hemicube(in: OpaqueOut, @builtin(front_facing) front_facing: bool) -> @builtin(frag_depth) f32 {
    return hemicube_depth(in.local, in.face, front_facing);
}

// Alpha-MASK triangles: cut-out fragments let light through.
@fragment
fn fs_hemicube_masked(in: CasterOut, @builtin(front_facing) front_facing: bool) -> @builtin(frag_depth) f32 {
    let m = materials[in.material];
    let uv = texture_coordinates(m.base_texture, in.uv0, in.uv1);
    let alpha = m.base_color.a * sample_texture_grad(textures, texture_sampler, m.base_texture, uv, dpdx(uv), dpdy(uv)).a;
    if (alpha < m.emission.w) {
        discard;
    }
    return hemicube_depth(in.local, in.face, front_facing);
}
