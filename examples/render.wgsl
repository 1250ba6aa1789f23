// What a glTF viewer draws for bake's default material (KHR_materials_unlit):
// baseColorFactor × baseColorTexture through its UV set, no lighting.

struct Camera {
    view_projection: mat4x4f,
}

struct Material {
    factor: vec4f,
    // KHR_texture_transform rows (xyz used), and whether a texture is bound (w of row0).
    row0: vec4f,
    row1: vec4f,
}

@group(0) @binding(0) var<uniform> camera: Camera;
@group(1) @binding(0) var<uniform> material: Material;
@group(1) @binding(1) var base_color: texture_2d<f32>;
@group(1) @binding(2) var linear_clamp: sampler;

struct VertexOut {
    @builtin(position) clip: vec4f,
    @location(0) uv: vec2f,
}

@vertex
fn vs_main(@location(0) position: vec3f, @location(1) uv: vec2f) -> VertexOut {
    var out: VertexOut;
    out.clip = camera.view_projection * vec4f(position, 1.0);
    out.uv = vec2f(dot(material.row0.xyz, vec3f(uv, 1.0)), dot(material.row1.xyz, vec3f(uv, 1.0)));
    return out;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4f {
    var colour = material.factor;
    if (material.row0.w > 0.5) {
        colour *= textureSample(base_color, linear_clamp, in.uv);
    }
    // The target is sRGB: the hardware encodes, as a viewer's output does.
    return vec4f(colour.rgb, 1.0);
}
