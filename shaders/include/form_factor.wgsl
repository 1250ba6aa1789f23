// Form factors to a parallelogram or square by Lambert's contour integral. Needs texel.wgsl.

// One edge's term of Lambert's contour integral, for corner vectors a, b
// seen from the receiver: the angle between them times the cosine of the
// normal with their plane's. Both are the same for a, b at any length, so
// neither is normalized: a CPU driver's near field waits mostly on its
// divisions (BENCHMARKS.md, stop 83). The corners are of order 1
// (`parallelogram_form_factor`), so the squares below stay in range.
fn edge_term(a: vec3f, b: vec3f, n: vec3f) -> f32 {
    let c = cross(a, b);
    let c2 = dot(c, c);
    // sin θ ≤ 1e-9, or a corner at the receiver: no term.
    if (!(c2 > 1e-18 * dot(a, a) * dot(b, b))) {
        return 0.0;
    }
    let length_c = sqrt(c2);
    return atan2(length_c, dot(a, b)) * dot(n, c) / length_c;
}

// Edge a→b of the polygon clipped to the receiver's upper hemisphere
// (da = a·n, db = b·n): adds its term and remembers where the outline
// leaves and re-enters the hemisphere. Written without arrays, which a CPU
// driver would keep in memory per lane, and with one `edge_term` for all
// three cases, as a CPU driver evaluates every branch taken by any lane.
fn clipped_edge(a: vec3f, b: vec3f, n: vec3f, exit: ptr<function, vec3f>, entry: ptr<function, vec3f>) -> f32 {
    let da = dot(a, n);
    let db = dot(b, n);
    // Where the edge crosses the horizon (used only when it does).
    let x = a + (b - a) * (da / (da - db));
    if (da >= 0.0 && db < 0.0) {
        *exit = x;
    }
    if (da < 0.0 && db >= 0.0) {
        *entry = x;
    }
    let term = edge_term(select(x, a, da >= 0.0), select(x, b, db >= 0.0), n);
    return select(0.0, term, da >= 0.0 || db >= 0.0);
}

// The form factor from a point at p with unit normal n to the
// parallelogram centre ± u ± v (Lambert's contour integral; Baum, Rushmeier
// & Winget 1989), clipped to the point's upper hemisphere. Exact and bounded
// at any distance, including a receiver touching the shooter.
fn parallelogram_form_factor(p: vec3f, n: vec3f, centre: vec3f, u_world: vec3f, v_world: vec3f) -> f32 {
    // Scaled to corners of order 1 (the form factor is scale-free), so that
    // `edge_term` needs no normalization at any scene scale.
    let extent = dot(centre - p, centre - p) + dot(u_world, u_world) + dot(v_world, v_world);
    if (!(extent > 0.0)) {
        return 0.0;
    }
    let scale = inverseSqrt(extent);
    let c = (centre - p) * scale;
    let u = u_world * scale;
    let v = v_world * scale;
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
