// Rasterizes triangles in lightmap-UV space (the seed's "geometry images").
//
// Conservative coverage without the hardware feature: each triangle is
// dilated by `params.dilation` texels in the vertex shader, and the fragment
// shader measures the distance from the texel centre to the real triangle.
// `fs_nearest` keeps, per texel, the triangle whose closest point is nearest
// (depth = distance, so a texel whose centre lies inside a triangle always
// wins) and its clamped barycentrics: border texels get valid data, never
// black. `fs_area` adds up the exact area of texel-square ∩ triangle, scaled
// to world units, with additive blending. Where a texel's data comes from for
// texels on a chart's border is decided by texelize_attributes, which knows
// how much of each texel the chart covers.

struct RasterParams {
    size: vec2f,       // atlas width, height in texels
    dilation: f32,     // texels; half the texel diagonal reaches every overlapped texel
    max_miter: f32,    // cap on how far a sharp corner moves, texels
    _inset: f32,
    _pad0: f32,
    _pad1: f32,
    _pad2: f32,
}

@group(0) @binding(0) var<uniform> params: RasterParams;
// Three corners per triangle, in texel units (x right, y down from the top-left corner).
@group(0) @binding(1) var<storage, read> corners: array<vec2f>;
// World area per texel² of UV area, one per triangle.
@group(0) @binding(2) var<storage, read> area_ratio: array<f32>;

struct VsOut {
    @builtin(position) clip: vec4f,
    @location(0) @interpolate(flat) a: vec2f,
    @location(1) @interpolate(flat) b: vec2f,
    @location(2) @interpolate(flat) c: vec2f,
    @location(3) @interpolate(flat) triangle: u32,
    @location(4) @interpolate(flat) ratio: f32,
}

fn cross2(u: vec2f, v: vec2f) -> f32 {
    return u.x * v.y - u.y * v.x;
}

// Unit normal of edge p→q pointing away from r.
fn outward(p: vec2f, q: vec2f, r: vec2f) -> vec2f {
    let e = q - p;
    var n = normalize(vec2f(e.y, -e.x));
    if (dot(n, r - p) > 0.0) {
        n = -n;
    }
    return n;
}

@vertex
fn vs_dilated(@builtin(vertex_index) vertex: u32) -> VsOut {
    let t = vertex / 3u;
    let k = vertex % 3u;
    var pts = array<vec2f, 3>(corners[3u * t], corners[3u * t + 1u], corners[3u * t + 2u]);
    let p = pts[k];
    let next = pts[(k + 1u) % 3u];
    let prev = pts[(k + 2u) % 3u];

    var out: VsOut;
    out.a = pts[0];
    out.b = pts[1];
    out.c = pts[2];
    out.triangle = t;
    out.ratio = area_ratio[t];

    var moved = p;
    let doubled_area = abs(cross2(pts[1] - pts[0], pts[2] - pts[0]));
    if (doubled_area > 1e-12) {
        let n1 = outward(p, next, prev);
        let n2 = outward(prev, p, next);
        let m = n1 + n2;
        // The offset lines of both edges meet at p + d (n1 + n2) / (1 + n1·n2).
        var offset = m * params.dilation / max(1.0 + dot(n1, n2), 1e-4);
        let len = length(offset);
        if (len > params.max_miter) {
            offset = offset * (params.max_miter / len);
        }
        moved = p + offset;
    }
    // Degenerate UV triangles keep their corners and rasterize nothing.
    out.clip = vec4f(moved.x / params.size.x * 2.0 - 1.0, 1.0 - moved.y / params.size.y * 2.0, 0.5, 1.0);
    return out;
}

struct NearestOut {
    @location(0) triangle: u32,   // triangle id + 1; 0 = not covered
    @location(1) bary: vec4f,     // weights of corners b and c of the nearest point; its distance (texels)
    @builtin(frag_depth) depth: f32,
}

@fragment
fn fs_nearest(in: VsOut) -> NearestOut {
    let p = in.clip.xy;  // texel centre, e.g. (3.5, 7.5)
    let w = closest_barycentric(p, in.a, in.b, in.c);
    let q = w.x * in.a + w.y * in.b + w.z * in.c;
    let distance = length(p - q);
    if (distance > params.dilation) {
        discard;
    }
    var out: NearestOut;
    out.triangle = in.triangle + 1u;
    out.bary = vec4f(w.yz, distance, 0.0);
    out.depth = distance / (2.0 * params.dilation);
    return out;
}

// Area of the unit texel square around p clipped by the triangle
// (Sutherland–Hodgman against its three edges), in texel². Works relative to
// p so that f32 keeps its precision far from the atlas origin.
fn covered_area(p: vec2f, a: vec2f, b: vec2f, c: vec2f) -> f32 {
    var poly: array<vec2f, 8>;
    var count = 4u;
    poly[0] = vec2f(-0.5, -0.5);
    poly[1] = vec2f(0.5, -0.5);
    poly[2] = vec2f(0.5, 0.5);
    poly[3] = vec2f(-0.5, 0.5);
    let orientation = sign(cross2(b - a, c - a));
    var tri = array<vec2f, 3>(a - p, b - p, c - p);
    for (var e = 0u; e < 3u; e++) {
        let s = tri[e];
        let edge = tri[(e + 1u) % 3u] - s;
        var next: array<vec2f, 8>;
        var n = 0u;
        for (var i = 0u; i < count; i++) {
            let cur = poly[i];
            let prv = poly[(i + count - 1u) % count];
            let dc = orientation * cross2(edge, cur - s);
            let dp = orientation * cross2(edge, prv - s);
            if (dc >= 0.0) {
                if (dp < 0.0 && n < 8u) {
                    next[n] = prv + (cur - prv) * (dp / (dp - dc));
                    n++;
                }
                if (n < 8u) {
                    next[n] = cur;
                    n++;
                }
            } else if (dp >= 0.0 && n < 8u) {
                next[n] = prv + (cur - prv) * (dp / (dp - dc));
                n++;
            }
        }
        poly = next;
        count = n;
        if (count < 3u) {
            return 0.0;
        }
    }
    var twice = 0.0;
    for (var i = 0u; i < count; i++) {
        twice += cross2(poly[i], poly[(i + 1u) % count]);
    }
    return abs(twice) * 0.5;
}

// Covered world area (x) and covered share of the texel square (y).
@fragment
fn fs_area(in: VsOut) -> @location(0) vec4f {
    let covered = covered_area(in.clip.xy, in.a, in.b, in.c);
    return vec4f(covered * in.ratio, covered, 0.0, 0.0);
}
