// Texels: PI, NO_TRIANGLE, the Texel struct, closest_barycentric and the light-space basis. Needs no include.

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

// Barycentric weights of the point of triangle (a, b, c) closest to p
// (Ericson, Real-Time Collision Detection, 5.1.5).
fn closest_barycentric(p: vec2f, a: vec2f, b: vec2f, c: vec2f) -> vec3f {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = dot(ab, ap);
    let d2 = dot(ac, ap);
    if (d1 <= 0.0 && d2 <= 0.0) { return vec3f(1.0, 0.0, 0.0); }
    let bp = p - b;
    let d3 = dot(ab, bp);
    let d4 = dot(ac, bp);
    if (d3 >= 0.0 && d4 <= d3) { return vec3f(0.0, 1.0, 0.0); }
    let vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
        let v = d1 / (d1 - d3);
        return vec3f(1.0 - v, v, 0.0);
    }
    let cp = p - c;
    let d5 = dot(ab, cp);
    let d6 = dot(ac, cp);
    if (d6 >= 0.0 && d5 <= d6) { return vec3f(0.0, 0.0, 1.0); }
    let vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
        let w = d2 / (d2 - d6);
        return vec3f(1.0 - w, 0.0, w);
    }
    let va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return vec3f(0.0, 1.0 - w, w);
    }
    let denom = 1.0 / (va + vb + vc);
    let v = vb * denom;
    let w = vc * denom;
    return vec3f(1.0 - v - w, v, w);
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
