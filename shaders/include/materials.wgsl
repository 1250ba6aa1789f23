// Materials and their texture sampling (mirrors gpu::materials). Needs no include.

// A texture a material samples: uv' = (row0 · (u, v, 1), row1 · (u, v, 1));
// info = (array layer or NO_TEXTURE, TEXCOORD set, wrap s, wrap t).
struct TextureRef {
    row0: vec4f,
    row1: vec4f,
    info: vec4<u32>,
}

struct Material {
    base_color: vec4f,
    emission: vec4f,       // rgb; w = alpha cut-off of a MASK material, −1 otherwise
    base_texture: TextureRef,
    emissive_texture: TextureRef,
}

const NO_TEXTURE: u32 = 0xffffffffu;

// glTF wrap modes the sampler (which repeats) does not do itself. Clamped
// and mirrored coordinates stay half a texel of level `size` inside the
// edge, so the repeating bilinear filter never reaches across.
fn wrap_coordinate(c: f32, mode: u32, size: f32) -> f32 {
    let edge = 0.5 / size;
    if (mode == 33071u) {
        return clamp(c, edge, 1.0 - edge);
    }
    if (mode == 33648u) {
        let t = fract(c * 0.5) * 2.0;
        return clamp(select(t, 2.0 - t, t > 1.0), edge, 1.0 - edge);
    }
    return c;
}

// The texture coordinates `t` reads at a point with these UV sets.
fn texture_coordinates(t: TextureRef, uv0: vec2f, uv1: vec2f) -> vec2f {
    let uv = vec3f(select(uv0, uv1, t.info.y == 1u), 1.0);
    return vec2f(dot(t.row0.xyz, uv), dot(t.row1.xyz, uv));
}

// The texture's linear RGBA at texture coordinates `uv` and mip level `lod`
// (white where the material has no such texture).
fn sample_texture(textures: texture_2d_array<f32>, s: sampler, t: TextureRef, uv: vec2f, lod: f32) -> vec4f {
    if (t.info.x == NO_TEXTURE) {
        return vec4f(1.0);
    }
    // Trilinear filtering also reads the next coarser level: keep clear of its edge.
    let size = f32(textureDimensions(textures).x) / exp2(ceil(clamp(lod, 0.0, 16.0)));
    let wrapped = vec2f(wrap_coordinate(uv.x, t.info.z, size), wrap_coordinate(uv.y, t.info.w, size));
    return textureSampleLevel(textures, s, wrapped, t.info.x, lod);
}

// Like sample_texture, with explicit texture-coordinate gradients (a
// fragment shader passes dpdx/dpdy of `uv`).
fn sample_texture_grad(textures: texture_2d_array<f32>, s: sampler, t: TextureRef, uv: vec2f, ddx: vec2f, ddy: vec2f) -> vec4f {
    if (t.info.x == NO_TEXTURE) {
        return vec4f(1.0);
    }
    let dims = f32(textureDimensions(textures).x);
    let lod = log2(max(max(length(ddx), length(ddy)) * dims, 1e-6));
    let size = dims / exp2(ceil(clamp(lod, 0.0, 16.0)));
    let wrapped = vec2f(wrap_coordinate(uv.x, t.info.z, size), wrap_coordinate(uv.y, t.info.w, size));
    return textureSampleGrad(textures, s, wrapped, t.info.x, ddx, ddy);
}
