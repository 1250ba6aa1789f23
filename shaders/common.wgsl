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


// --- solve: progressive refinement of bounced and emitted light ---

// A shooter patch. Mirrors `patches::Patch`.
struct Patch {
    position: vec3f,     // area-weighted centroid, world
    area: f32,           // m²
    normal: vec3f,       // unit mean normal
    first: u32,          // first member in the member list
    rect_centre: vec3f,  // the parallelogram its atlas cell maps to: centre,
    count: u32,          // member texels
    half_u: vec3f,       // half of one side,
    lift: f32,           // how far its own surface rises above the centroid's tangent plane
    half_v: vec3f,       // half of the other side
    radius: f32,         // centre to farthest corner
}

// A patch chosen to shoot in this batch. Mirrors `bounce::Shooter`.
struct Shooter {
    position: vec3f,     // centroid, world
    area: f32,
    normal: vec3f,
    patch_index: u32,    // NO_TRIANGLE when the slot is unused
    radiance: vec3f,     // unshot radiance ΔL it shoots, rgb
    radius: f32,         // near-field reach: receivers closer use the exact polygon form factor
    rect_centre: vec3f,
    lift: f32,           // the hemicube sits this far above the centroid
    half_u: vec3f,
    rect_area: f32,
    half_v: vec3f,
    _pad: u32,
}

// A receiver this close to a near shooter's plane, in receiver offsets
// (half texels), is in contact with it.
const CONTACT: f32 = 0.1;

// Shooter slots per batch (`bounce::MAX_SHOOTERS`): a near-field
// receiver's slots are the bits of one u32.
const MAX_SHOOTERS: u32 = 32u;

// A batch's shooters, as a uniform buffer.
struct ShooterBatch {
    items: array<Shooter, MAX_SHOOTERS>,
}

// Mirrors `bounce::BounceParams`.
struct BounceParams {
    texel_count: u32,
    patch_count: u32,
    shooter_count: u32,    // slots per batch
    row_stride: u32,       // invocations per dispatch row
    face_size: f32,        // hemicube face width, texels
    tiles_per_row: u32,    // hemicubes per row of the depth atlas
    far: f32,              // distance that maps to depth 1, metres
    near: f32,             // near plane, metres
    receiver_offset: f32,  // receivers test a point this far along their face normal, metres
    max_slope: f32,
    chunk_count: u32,      // workgroups of MEASURE_CHUNK texels in the measure pass
    atlas_width: u32,      // texels per atlas row (a texel's index is x + y · width)
    cell: u32,             // side of the atlas cell patches are cut from, texels
    in_plane: f32,         // a receiver this close to a shooter's plane lies in it, metres (rounding)
    _pad: u32,
}

// A shooter patch is split into SUB_CELLS × SUB_CELLS parts of its atlas
// cell: where in the patch its unshot light is, for the near field.
const SUB_CELLS: u32 = 4u;
const SUB_CELL_COUNT: u32 = 16u;
// The sub-cell of its patch a texel lies in: its place in the patch's atlas
// cell, SUB_CELLS to a side.
fn sub_cell(texel: Texel, bounce: BounceParams) -> u32 {
    let row_column = quotient_remainder(texel.index, bounce.atlas_width);
    let x = quotient_remainder(row_column.y, bounce.cell).y;
    let y = quotient_remainder(row_column.x, bounce.cell).y;
    let cx = quotient_remainder(x * SUB_CELLS, bounce.cell).x;
    let cy = quotient_remainder(y * SUB_CELLS, bounce.cell).x;
    return cy * SUB_CELLS + cx;
}

// (n / d, n % d) for d > 0 and a quotient under 2^22 (an atlas row or
// column), by a float estimate put right: a CPU driver divides integers
// by a value it cannot see lane by lane, as slowly as a dozen float
// operations each.
fn quotient_remainder(n: u32, d: u32) -> vec2<u32> {
    var q = i32(floor(f32(n) / f32(d)));
    let r = i32(n) - q * i32(d);
    q += select(0, -1, r < 0) + select(0, 1, r >= i32(d));
    return vec2<u32>(u32(q), u32(i32(n) - q * i32(d)));
}

// One edge's term of Lambert's contour integral, for corner vectors a, b
// seen from the receiver.
fn edge_term(a: vec3f, b: vec3f, n: vec3f) -> f32 {
    if (dot(a, a) <= 0.0 || dot(b, b) <= 0.0) {
        return 0.0;
    }
    let ua = normalize(a);
    let ub = normalize(b);
    let c = cross(ua, ub);
    let length_c = length(c);
    if (length_c <= 1e-9) {
        return 0.0;
    }
    return atan2(length_c, dot(ua, ub)) * dot(n, c) / length_c;
}

// Edge a→b of the polygon clipped to the receiver's upper hemisphere
// (da = a·n, db = b·n): adds its terms and remembers where the outline
// leaves and re-enters the hemisphere. Written without arrays, which a CPU
// driver would keep in memory per lane.
fn clipped_edge(a: vec3f, b: vec3f, n: vec3f, exit: ptr<function, vec3f>, entry: ptr<function, vec3f>) -> f32 {
    let da = dot(a, n);
    let db = dot(b, n);
    if (da >= 0.0 && db >= 0.0) {
        return edge_term(a, b, n);
    }
    if (da >= 0.0) {
        let x = a + (b - a) * (da / (da - db));
        *exit = x;
        return edge_term(a, x, n);
    }
    if (db >= 0.0) {
        let x = a + (b - a) * (da / (da - db));
        *entry = x;
        return edge_term(x, b, n);
    }
    return 0.0;
}

// The form factor from a point at p with unit normal n to the
// parallelogram centre ± u ± v (Lambert's contour integral; Baum, Rushmeier
// & Winget 1989), clipped to the point's upper hemisphere. Exact and bounded
// at any distance, including a receiver touching the shooter.
fn parallelogram_form_factor(p: vec3f, n: vec3f, centre: vec3f, u: vec3f, v: vec3f) -> f32 {
    let c = centre - p;
    let c0 = c - u - v;
    let c1 = c + u - v;
    let c2 = c + u + v;
    let c3 = c - u + v;
    let above = u32(dot(c0, n) >= 0.0) + u32(dot(c1, n) >= 0.0) + u32(dot(c2, n) >= 0.0) + u32(dot(c3, n) >= 0.0);
    if (above == 0u) {
        return 0.0;
    }
    var exit = vec3f(0.0);
    var entry = vec3f(0.0);
    var sum = clipped_edge(c0, c1, n, &exit, &entry);
    sum += clipped_edge(c1, c2, n, &exit, &entry);
    sum += clipped_edge(c2, c3, n, &exit, &entry);
    sum += clipped_edge(c3, c0, n, &exit, &entry);
    // Close the outline along the horizon where the polygon was cut.
    if (above < 4u) {
        sum += edge_term(exit, entry, n);
    }
    return abs(sum) / (2.0 * PI);
}

// The unit vector in the plane across `normal` nearest `towards` (any one
// where `towards` is along the normal).
fn tangent_along(normal: vec3f, towards: vec3f) -> vec3f {
    let t = towards - normal * dot(towards, normal);
    return select(basis(normal)[0], normalize(t), dot(t, t) > 1e-12 * dot(towards, towards) + 1e-30);
}

// The form factor from a point at p with unit normal n to a square of
// `area` at `centroid`, facing `normal`, one side along `towards`; 0 for a
// point not in front of it. Stands in for a part of a curved shooter patch.
fn square_form_factor(p: vec3f, n: vec3f, centroid: vec3f, normal: vec3f, area: f32, towards: vec3f) -> f32 {
    if (!(area > 0.0 && dot(p - centroid, normal) > 0.0)) {
        return 0.0;
    }
    let u = tangent_along(normal, towards) * (0.5 * sqrt(area));
    return parallelogram_form_factor(p, n, centroid, u, cross(normal, u));
}

// What is kept per sub-cell of a batch's shooter (solve_patch_power.wgsl's
// `shooter_cells`): three rows of SUB_CELL_COUNT vectors per slot.
const SUB_CELL_ROWS: u32 = 3u;

// Totals the select pass leaves for the CPU. Mirrors `bounce::Stats`.
struct BounceStats {
    unshot: vec4f,    // Σ ΔL·A over all patches, rgb; w = luminance
    received: vec4f,  // Σ received L_lm·A in the last shoot pass; w = luminance
    shot: vec4f,      // Σ ΔL·A of the shooters chosen now; w = luminance
    shooters: u32,    // shooters with power in this batch
    landing: f32,     // Σ luminance(ΔL·A) × the patch's coverage: the unshot power weighted by where it can land
    _pad1: u32,
    _pad2: u32,
}

fn luminance(c: vec3f) -> f32 {
    return dot(c, vec3f(0.2126, 0.7152, 0.0722));
}

// The hemicube's origin: the centroid lifted off the patch's own surface.
fn hemicube_origin(s: Shooter) -> vec3f {
    return lifted_origin(s.position, s.normal, s.lift);
}

// `position` lifted `lift` along `normal` (as `hemicube_origin`).
fn lifted_origin(position: vec3f, normal: vec3f, lift: f32) -> vec3f {
    return position + normal * lift;
}

// One face of a shooter's hemicube as the hemicube pass draws it, at
// slot · 5 + face: written by solve_select, read as instance attributes
// (`FaceIn` in solve_hemicube.wgsl). Mirrors `bounce::HemicubeFace`.
struct HemicubeFace {
    position: vec3f,  // the shooter's, as in `Shooter`
    lift: f32,
    normal: vec3f,
    face: u32,
}

// Hemicube faces: 0 along the normal, 1..4 the half faces around it
// (+t, −t, +b, −b). Returns (u, v, forward) with u, v in [−1, 1] across the
// face's viewport; for half faces v spans only the half above the shooter's
// plane. The depth render and receivers both go through
// `hemicube_face_frame`, so they agree exactly.
fn hemicube_face(local: vec3f, face: u32) -> vec3f {
    let f = hemicube_face_frame(local, face);
    let v = select(2.0 * f.y / f.z - 1.0, f.y / f.z, face == 0u);
    return vec3f(f.x / f.z, v, f.z);
}

// `local` in `face`'s frame: (across, up, forward).
fn hemicube_face_frame(local: vec3f, face: u32) -> vec3f {
    // Faces 1 and 2 look along ±t, 3 and 4 along ±b; 2 and 4 backwards.
    let sideways = select(vec3f(local.y, local.z, local.x), vec3f(local.x, local.z, local.y), face >= 3u);
    let side = select(sideways, sideways * vec3f(1.0, 1.0, -1.0), face == 2u || face == 4u);
    return select(side, local, face == 0u);
}

// The face a direction (in the shooter's frame, local.z > 0) falls on.
fn hemicube_face_of(local: vec3f) -> u32 {
    let a = abs(local);
    let side = select(select(4u, 3u, local.y > 0.0), select(2u, 1u, local.x > 0.0), a.x >= a.y);
    return select(side, 0u, local.z >= a.x && local.z >= a.y);
}

// Top-left texel and size of `face` of hemicube `slot` in the depth atlas.
// A hemicube tile is 3S × S: the top face, then ±t stacked, then ±b stacked.
fn hemicube_viewport(slot: u32, face: u32, size: f32, tiles_per_row: u32) -> vec4f {
    // In floats, exact for slot counts this small: a CPU driver divides
    // integers lane by lane.
    let row = floor((f32(slot) + 0.5) / f32(tiles_per_row));
    let tile = vec2f((f32(slot) - row * f32(tiles_per_row)) * 3.0 * size, row * size);
    let column = f32((face + 1u) / 2u) * size;
    let lower = face != 0u && face % 2u == 0u;
    let corner = tile + vec2f(column, select(0.0, 0.5 * size, lower));
    return vec4f(corner, size, select(0.5 * size, size, face == 0u));
}

// --- materials (mirrors gpu::materials) ---

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

// --- shadow casters (mirrors solve::casters) ---

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
