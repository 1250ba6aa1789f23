// Orthographic depth maps of the scene along −ω for each light of a batch
// (design notes, algorithm step 3). One render pass per array layer; the
// draw's instance index names the light slot.

@group(0) @binding(0) var<uniform> params: DirectParams;
@group(0) @binding(1) var<uniform> lights: LightBatch;

@vertex
fn vs_depth(@location(0) position: vec3f, @builtin(instance_index) slot: u32) -> @builtin(position) vec4f {
    let ls = light_space(position, lights.items[slot].direction.xyz, params.centre, params.radius);
    return vec4f(ls.x, ls.y, ls.z, 1.0);
}
