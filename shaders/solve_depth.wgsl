// Orthographic depth maps of the scene along −ω for each light of a batch
// (design notes, algorithm step 3), tiled into one depth atlas; the draw's
// instance index names the light slot. Triangles of alpha-MASK materials
// are drawn by `fs_depth_masked`, which discards their cut-out fragments so
// light passes through the holes.

@group(0) @binding(0) var<uniform> params: DirectParams;
@group(0) @binding(1) var<uniform> lights: LightBatch;
@group(0) @binding(2) var<storage, read> materials: array<Material>;
@group(0) @binding(3) var textures: texture_2d_array<f32>;
@group(0) @binding(4) var texture_sampler: sampler;

@vertex
fn vs_depth(in: CasterIn, @builtin(instance_index) slot: u32) -> CasterOut {
    let ls = light_space(in.position, lights.items[slot].direction.xyz, params.centre, params.radius);
    var out: CasterOut;
    out.clip = vec4f(ls.x, ls.y, ls.z, 1.0);
    out.local = vec3f(0.0);
    out.material = in.material;
    out.uv0 = in.uv0;
    out.uv1 = in.uv1;
    return out;
}

@fragment
fn fs_depth_masked(in: CasterOut) {
    let m = materials[in.material];
    let uv = texture_coordinates(m.base_texture, in.uv0, in.uv1);
    let alpha = m.base_color.a * sample_texture_grad(textures, texture_sampler, m.base_texture, uv, dpdx(uv), dpdy(uv)).a;
    if (alpha < m.emission.w) {
        discard;
    }
}
