// Turns what texelize_raster left per texel (nearest triangle, clamped
// barycentrics, covered area) into the radiosity element: world position,
// normals, albedo, emission. One invocation per texel of a band of rows.

struct AttributeParams {
    width: u32,
    height: u32,
    first_row: u32,
    rows: u32,
    inset: f32,   // how far inside the chart border texels take their data, texels
    _pad0: f32,
    _pad1: f32,
    _pad2: f32,
}

struct Vertex {
    position: vec3f,
    _pad0: f32,
    normal: vec3f,   // zero when the primitive has no normals (flat shading)
    _pad1: f32,
    uv0: vec2f,
    uv1: vec2f,  // the source's own TEXCOORD_1, for textures that read it
}

struct Triangle {
    corners: vec3<u32>,
    material: u32,
    face_normal: vec3f,  // from the winding, world space; zero if degenerate
    border_edges: u32,   // bit k: edge k → k+1 lies on the chart's border
}

@group(0) @binding(0) var<uniform> params: AttributeParams;
@group(0) @binding(1) var triangle_ids: texture_2d<u32>;
@group(0) @binding(2) var barycentrics: texture_2d<f32>;
@group(0) @binding(3) var areas: texture_2d<f32>;
@group(0) @binding(4) var<storage, read> vertices: array<Vertex>;
@group(0) @binding(5) var<storage, read> triangles: array<Triangle>;
@group(0) @binding(6) var<storage, read> materials: array<Material>;
// One entry per texel of the band, row-major.
@group(0) @binding(7) var<storage, read_write> texels: array<Texel>;
// Lightmap-space corners of each triangle (texel units), for the footprint.
@group(0) @binding(8) var<storage, read> corners: array<vec2f>;
@group(0) @binding(9) var textures: texture_2d_array<f32>;
@group(0) @binding(10) var texture_sampler: sampler;

// The mip level at which texture `t` shows the footprint of one lightmap
// texel of triangle `t_index`: the texel averages what it covers.
fn footprint_lod(t: TextureRef, t_index: u32, va: Vertex, vb: Vertex, vc: Vertex) -> f32 {
    let a = corners[3u * t_index];
    let e1 = corners[3u * t_index + 1u] - a;
    let e2 = corners[3u * t_index + 2u] - a;
    let det = e1.x * e2.y - e1.y * e2.x;
    if (abs(det) < 1e-12) {
        return 0.0;
    }
    let ta = texture_coordinates(t, va.uv0, va.uv1);
    let f1 = texture_coordinates(t, vb.uv0, vb.uv1) - ta;
    let f2 = texture_coordinates(t, vc.uv0, vc.uv1) - ta;
    // J = [f1 f2] · [e1 e2]⁻¹ maps one atlas texel step to texture coordinates.
    let dx = (f1 * e2.y - f2 * e1.y) / det;
    let dy = (f2 * e1.x - f1 * e2.x) / det;
    let size = f32(textureDimensions(textures).x);
    return log2(max(max(length(dx), length(dy)) * size, 1e-6));
}

// Barycentric weights of the point nearest `centre` in triangle t with its
// chart-border edges moved `params.inset` texels inwards (inner edges stay:
// the chart goes on across them). Where the triangle is too thin for that,
// its incentre.
fn inset_weights(centre: vec2f, t: u32) -> vec3f {
    let tri = triangles[t];
    let a = corners[3u * t];
    let b = corners[3u * t + 1u];
    let c = corners[3u * t + 2u];
    let twice_area = (b.x - a.x) * (c.y - a.y) - (c.x - a.x) * (b.y - a.y);
    if (abs(twice_area) <= 1e-12) {
        return closest_barycentric(centre, a, b, c);
    }
    // Each edge as a line n·p = d with n pointing into the triangle.
    var pts = array<vec2f, 3>(a, b, c);
    var normals: array<vec2f, 3>;
    var offsets: array<f32, 3>;
    for (var k = 0u; k < 3u; k++) {
        let p0 = pts[k];
        let p1 = pts[(k + 1u) % 3u];
        let e = p1 - p0;
        var n = normalize(vec2f(-e.y, e.x));
        if (twice_area < 0.0) {
            n = -n;
        }
        let shift = select(0.0, params.inset, (tri.border_edges & (1u << k)) != 0u);
        normals[k] = n;
        offsets[k] = dot(n, p0) + shift;
    }
    // The shrunk triangle's corners: where consecutive edge lines meet.
    var inner: array<vec2f, 3>;
    for (var k = 0u; k < 3u; k++) {
        let n0 = normals[(k + 2u) % 3u];
        let n1 = normals[k];
        let d0 = offsets[(k + 2u) % 3u];
        let d1 = offsets[k];
        let det = n0.x * n1.y - n0.y * n1.x;
        inner[k] = vec2f(d0 * n1.y - d1 * n0.y, n0.x * d1 - n1.x * d0) / det;
    }
    let inner_area = (inner[1].x - inner[0].x) * (inner[2].y - inner[0].y) - (inner[2].x - inner[0].x) * (inner[1].y - inner[0].y);
    var target_point: vec2f;
    if (inner_area * twice_area <= 0.0) {
        // Too thin to keep half a texel from its borders: use the incentre.
        let sides = vec3f(length(b - c), length(c - a), length(a - b));
        target_point = (sides.x * a + sides.y * b + sides.z * c) / (sides.x + sides.y + sides.z);
    } else {
        let w = closest_barycentric(centre, inner[0], inner[1], inner[2]);
        target_point = w.x * inner[0] + w.y * inner[1] + w.z * inner[2];
    }
    return closest_barycentric(target_point, a, b, c);
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= params.width || id.y >= params.rows) {
        return;
    }
    let x = id.x;
    let y = id.y + params.first_row;
    let slot = id.x + id.y * params.width;
    var texel: Texel;
    texel.index = x + y * params.width;
    texel.triangle = NO_TRIANGLE;
    let id_plus_one = textureLoad(triangle_ids, vec2<u32>(x, y), 0).x;
    if (id_plus_one == 0u) {
        texels[slot] = texel;
        return;
    }
    let t = id_plus_one - 1u;
    let tri = triangles[t];
    let nearest = textureLoad(barycentrics, vec2<u32>(x, y), 0);
    var w = vec3f(1.0 - nearest.x - nearest.y, nearest.x, nearest.y);
    let covered = textureLoad(areas, vec2<u32>(x, y), 0).xy;
    // A texel whose centre lies outside its chart (or on its border: then the
    // chart covers at most half of it) takes its data from a point half a
    // texel inside the chart, not from the edge itself: an edge point lies on
    // the geometry that meets it (a wall on a floor) and would see half its
    // sky cut off, or tunnel under it. Texels whose centre is inside keep it,
    // also when it lies on an edge between two triangles.
    if (nearest.z > 1e-3 || covered.y < 0.501) {
        w = inset_weights(vec2f(f32(x) + 0.5, f32(y) + 0.5), t);
    }
    let va = vertices[tri.corners.x];
    let vb = vertices[tri.corners.y];
    let vc = vertices[tri.corners.z];

    var normal = w.x * va.normal + w.y * vb.normal + w.z * vc.normal;
    var face = tri.face_normal;
    if (dot(normal, normal) < 1e-12) {
        normal = face;
    }
    if (dot(normal, normal) < 1e-12) {
        // Degenerate triangle without normals: any unit vector keeps the math finite.
        normal = vec3f(0.0, 1.0, 0.0);
    }
    normal = normalize(normal);
    // Shading normals decide which side receives; keep the geometric normal on that side.
    if (dot(face, normal) < 0.0) {
        face = -face;
    }
    if (dot(face, face) < 1e-12) {
        face = normal;
    }

    let material = materials[tri.material];
    let uv0 = w.x * va.uv0 + w.y * vb.uv0 + w.z * vc.uv0;
    let uv1 = w.x * va.uv1 + w.y * vb.uv1 + w.z * vc.uv1;
    let base_uv = texture_coordinates(material.base_texture, uv0, uv1);
    let base = material.base_color * sample_texture(
        textures, texture_sampler, material.base_texture, base_uv,
        footprint_lod(material.base_texture, t, va, vb, vc));
    let emissive_uv = texture_coordinates(material.emissive_texture, uv0, uv1);
    let emissive = sample_texture(
        textures, texture_sampler, material.emissive_texture, emissive_uv,
        footprint_lod(material.emissive_texture, t, va, vb, vc));
    texel.position = w.x * va.position + w.y * vb.position + w.z * vc.position;
    texel.area = covered.x;
    texel.normal = normal;
    texel.face_normal = face;
    texel.triangle = t;
    texel.albedo = clamp(base.rgb, vec3f(0.0), vec3f(1.0));
    texel.emission = max(material.emission.rgb * emissive.rgb, vec3f(0.0));
    texels[slot] = texel;
}
