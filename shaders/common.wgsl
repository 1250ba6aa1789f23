// Shared by every pass (prepended by src/gpu/shaders.rs).

const PI: f32 = 3.14159265358979;
const NO_TRIANGLE: u32 = 0xffffffffu;

// One covered lightmap texel: the radiosity element. Mirrors `texelize::Texel`.
struct Texel {
    position: vec3f,     // world space, metres
    area: f32,           // world area the texel covers, m²
    normal: vec3f,       // shading normal (unit)
    index: u32,          // x + y * atlas width
    face_normal: vec3f,  // geometric normal of its triangle, on the shading normal's side
    triangle: u32,       // global triangle id, NO_TRIANGLE if not covered
    albedo: vec3f,       // diffuse reflectance, linear RGB
    chart: u32,
    emission: vec3f,     // emitted radiance, linear RGB
    primitive: u32,
}

// An orthonormal basis around unit vector n (Duff et al. 2017, "Building an
// Orthonormal Basis, Revisited"): columns t, b, n. Used by both the depth
// pass and the receivers, so their light spaces agree bit for bit.
fn basis(n: vec3f) -> mat3x3f {
    let s = select(-1.0, 1.0, n.z >= 0.0);
    let a = -1.0 / (s + n.z);
    let b = n.x * n.y * a;
    let t = vec3f(1.0 + s * n.x * n.x * a, s * b, -s * n.x);
    let bt = vec3f(b, s + n.y * n.y * a, -n.y);
    return mat3x3f(t, bt, n);
}

// Orthographic light space for a distant light from direction `towards_light`
// over the scene's bounding sphere (centre, radius): x, y in [-1, 1] across
// the sphere, z in [0, 1] from the near plane (light side) to the far plane.
fn light_space(p: vec3f, towards_light: vec3f, centre: vec3f, radius: f32) -> vec3f {
    let m = basis(towards_light);
    let d = p - centre;
    return vec3f(dot(d, m[0]) / radius, dot(d, m[1]) / radius, 0.5 - 0.5 * dot(d, towards_light) / radius);
}

// --- solve: direct environment light ---

// Mirrors `direct::DirectParams`.
struct DirectParams {
    centre: vec3f,         // bounding-sphere centre of the scene, world
    radius: f32,           // its radius (with margin), metres
    map_size: f32,         // shadow-map width = height, texels
    light_count: u32,      // lights in this batch
    texel_count: u32,
    row_stride: u32,       // invocations per dispatch row
    tiles_per_row: u32,    // shadow maps per row of the batch's depth atlas
    normal_offset: f32,    // metres
    constant_bias: f32,    // metres
    slope_bias: f32,       // metres per unit of tan(θ)
    max_slope: f32,        // cap on tan(θ)
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

// A distant light: unit direction towards it, and L·Ω (rgb).
struct DirectLight {
    direction: vec4f,
    power: vec4f,
}

const MAX_BATCH: u32 = 256u;

struct LightBatch {
    items: array<DirectLight, MAX_BATCH>,
}
