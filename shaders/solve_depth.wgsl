// Orthographic depth maps of the scene along −ω for each light of a batch
// (design notes, algorithm step 3), tiled into one depth atlas; the draw's
// instance names the light slot. Triangles of alpha-MASK materials
// are drawn by `fs_depth_masked`, which discards their cut-out fragments so
// light passes through the holes. Both layers mark in their depths' two
// lowest bits the surfaces whose back faces the light and those on an open
// surface, a sheet (`with_facing`).

@group(0) @binding(0) var<uniform> params: DirectParams;
@group(0) @binding(1) var<uniform> lights: LightBatch;
@group(0) @binding(2) var<storage, read> materials: array<Material>;
@group(0) @binding(3) var textures: texture_2d_array<f32>;
@group(0) @binding(4) var texture_sampler: sampler;

// The instance's light, as an instance attribute: a CPU driver fetches it
// once per draw, where `lights.items[instance]` costs a load per vertex.
struct LightIn {
    @location(5) direction: vec4f,
}

fn light_clip(position: vec3f, light: LightIn) -> vec4f {
    return vec4f(light_space(position, light.direction.xyz, params.centre, params.radius), 1.0);
}

@vertex
fn vs_depth(in: CasterIn, light: LightIn) -> CasterOut {
    var out: CasterOut;
    out.clip = light_clip(in.position, light);
    out.local = vec3f(0.0);
    out.material = in.material;
    out.uv0 = in.uv0;
    out.uv1 = in.uv1;
    out.sheet = in.sheet;
    return out;
}

// What an opaque caster's fragment needs: a CPU driver sets up and
// interpolates every output of a vertex shader, read or not.
struct OpaqueOut {
    @builtin(position) clip: vec4f,
    @location(5) @interpolate(flat) sheet: u32,
}

@vertex
fn vs_depth_opaque(in: CasterIn, light: LightIn) -> OpaqueOut {
    return OpaqueOut(light_clip(in.position, light), in.sheet);
}

// Whether the fragment falls in a cut-out of its alpha-MASK material.
fn cut_out(in: CasterOut) -> bool {
    let m = materials[in.material];
    let uv = texture_coordinates(m.base_texture, in.uv0, in.uv1);
    let alpha = m.base_color.a * sample_texture_grad(textures, texture_sampler, m.base_texture, uv, dpdx(uv), dpdy(uv)).a;
    return alpha < m.emission.w;
}

// The fragment's depth with its lowest bit set where the light sees the
// triangle's back (`seen_from_behind` in solve_direct.wgsl), and the next
// where the triangle lies on an open surface (`on_sheet`). The
// casters are wound so that their front is the side their lightmap texels
// face; the light-space frame keeps handedness, so that side faces the
// light exactly where the rasterizer calls it front-facing. Three units in
// the last place move no surface past another that matters.
fn with_facing(clip: vec4f, sheet: u32, front: bool) -> f32 {
    let marks = select(1u, 0u, front) | (min(sheet, 1u) << 1u);
    return bitcast<f32>((bitcast<u32>(clip.z) & ~3u) | marks);
}

@fragment
fn fs_depth(in: OpaqueOut, @builtin(front_facing) front: bool) -> @builtin(frag_depth) f32 {
    return with_facing(in.clip, in.sheet, front);
}

@fragment
fn fs_depth_masked(in: CasterOut, @builtin(front_facing) front: bool) -> @builtin(frag_depth) f32 {
    if (cut_out(in)) {
        discard;
    }
    return with_facing(in.clip, in.sheet, front);
}

// The second layer: the nearest surface behind the first (depth peeling).
// With the first it bounds the solid a shadow ray may pass through: a ray
// between the two is inside an object (or under a zero-thickness surface,
// whose second layer is whatever lies below it); a ray deeper than the
// second passes behind the object, as a ray from the shadow of a post passes
// beside the post. Drawn with the same vertex shader, so a surface lands on
// the same depth in both passes and is peeled exactly.
@group(1) @binding(0) var front_depth: texture_depth_2d;

fn behind_front(position: vec4f) -> bool {
    return position.z > textureLoad(front_depth, vec2<i32>(position.xy), 0) + 1.0 / params.map_size;
}

@fragment
fn fs_depth_peel(in: OpaqueOut, @builtin(front_facing) front: bool) -> @builtin(frag_depth) f32 {
    if (!behind_front(in.clip)) {
        discard;
    }
    return with_facing(in.clip, in.sheet, front);
}

@fragment
fn fs_depth_peel_masked(in: CasterOut, @builtin(front_facing) front: bool) -> @builtin(frag_depth) f32 {
    // Derivatives first, while the quad is whole.
    let cut = cut_out(in);
    if (cut || !behind_front(in.clip)) {
        discard;
    }
    return with_facing(in.clip, in.sheet, front);
}
