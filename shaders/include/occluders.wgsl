// The Occluders record and its constants: what can block a point's light. Needs no include.

// What can block a point's light, as the occluder pass sums it up
// (solve_occluders.wgsl) and the direct pass reads it (solve_direct.wgsl).

const CONES: u32 = 4u;
const POLYGONS: u32 = 2u;
const NO_POLYGON: u32 = 0xffffffffu;
// `Occluders::flags`: the cones could not hold the blockers; a ray is cast
// in every direction above the face.
const ALL_DIRECTIONS: u32 = 1u;

// Mirrors `occluders::Occluders`.
struct Occluders {
    // Cones from the point that hold every blocker but the polygons: unit
    // axis and the cosine of the half-angle (2 for an unused slot) ...
    cones: array<vec4f, CONES>,
    // ... and the sines.
    sines: vec4f,
    // Nodes whose triangles tile a convex polygon above the face (NO_POLYGON: none).
    polygons: vec2<u32>,
    flags: u32,
    // Nodes the walk visited (for the report).
    visits: u32,
}
