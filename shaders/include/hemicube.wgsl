// A shooter's hemicube: its lifted origin, HemicubeFace, the face frames and the depth-atlas viewports. Needs no include.

// `position` lifted `lift` along `normal` (as `hemicube_origin` in solve_shoot.wgsl).
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
