//! Triangles in f64 and a bounding volume hierarchy over them.
//!
//! The tree is `trace::bvh`'s (binned SAH, built the same on every run, so
//! every traversal is too).
//! Traversal is front-to-back with a shrinking interval for closest hits and
//! stops at the first hit for occlusion. A caller may reject hits (alpha
//! cut-outs) with a test that runs before a hit shortens the ray. Box tests use the conservative
//! far-distance scaling of Ize ("Robust BVH Ray Traversal", JCGT 2013) and
//! triangles use Möller–Trumbore in f64 with a tiny barycentric tolerance so
//! that rays cannot slip through the shared edge of two triangles.

use glam::DVec3;

use crate::trace::bvh::{Node, Tree};

/// A triangle ready for intersection: `v0 + u·e1 + v·e2`.
#[derive(Clone, Debug)]
pub(crate) struct Triangle {
    pub v0: DVec3,
    pub e1: DVec3,
    pub e2: DVec3,
    /// Unit normal of the front winding (mirroring already applied).
    pub face: DVec3,
    /// Per-vertex shading normals when the mesh has them (may be zero vectors).
    pub normals: Option<[DVec3; 3]>,
    /// Index into the material table of `trace::Surfaces`.
    pub material: u32,
    /// Index into `Scene::primitives`.
    pub primitive: u32,
    /// Index into the per-triangle UV sets and vertex colours of
    /// `trace::Surfaces`, or [`NO_TEXCOORDS`] where the material samples no
    /// texture and the primitive has no COLOR_0.
    pub texcoords: u32,
}

/// `Triangle::texcoords` of a triangle that needs none.
pub(crate) const NO_TEXCOORDS: u32 = u32::MAX;

/// The hit filter of [`Bvh::closest`] and [`Bvh::occluded`] that keeps every hit.
pub(crate) fn every_hit(_: &Triangle, _: f64, _: f64) -> bool {
    true
}

impl Triangle {
    /// The unit normal of the front side at barycentrics (u, v): the face
    /// normal, flipped to agree with the interpolated shading normal where
    /// that is usable (non-zero and not perpendicular to the face).
    pub(crate) fn front_normal(&self, u: f64, v: f64) -> DVec3 {
        front_normal(self.face, self.normals.map(|n| n[0] * (1.0 - u - v) + n[1] * u + n[2] * v))
    }

    /// The point at barycentrics (u, v).
    pub(crate) fn point(&self, u: f64, v: f64) -> DVec3 {
        self.v0 + self.e1 * u + self.e2 * v
    }

    fn bounds(&self) -> (DVec3, DVec3) {
        let (a, b, c) = (self.v0, self.v0 + self.e1, self.v0 + self.e2);
        (a.min(b).min(c), a.max(b).max(c))
    }
}

/// The face normal `face` flipped to the side of `shading` (when given and
/// usable), per the project's front-side convention.
pub(crate) fn front_normal(face: DVec3, shading: Option<DVec3>) -> DVec3 {
    match shading {
        Some(s) if s.dot(face) < 0.0 => -face,
        _ => face,
    }
}

/// Where a ray met a triangle.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Hit {
    pub t: f64,
    /// Index into [`Bvh::triangles`].
    pub triangle: u32,
    pub u: f64,
    pub v: f64,
}

/// The hierarchy and its triangles (reordered to match the leaves).
pub(crate) struct Bvh {
    pub triangles: Vec<Triangle>,
    nodes: Vec<Node>,
}

/// One cast as `Bvh::traverse_from` passes it down: the ray (with its
/// inverse direction), the triangle it leaves, which hits count and whether
/// any hit will do.
struct Cast<'a, F> {
    origin: DVec3,
    direction: DVec3,
    inv: DVec3,
    skip: Option<u32>,
    any: bool,
    solid: &'a F,
}

/// Relative tolerance on barycentrics: edges overlap by this fraction.
const BARY_EPS: f64 = 1e-10;
/// Rays closer to parallel with a triangle than this cosine miss it.
const PARALLEL_EPS: f64 = 1e-15;
/// Ize's conservative factor: 1 + 2γ₃ with γ₃ = 3u/(1 − 3u).
const FAR_SCALE: f64 = 1.0 + 2.0 * (3.0 * f64::EPSILON * 0.5) / (1.0 - 3.0 * f64::EPSILON * 0.5);
const STACK: usize = 96;

impl Bvh {
    /// Builds the hierarchy (deterministically) over `triangles`.
    pub(crate) fn new(triangles: Vec<Triangle>) -> Bvh {
        let boxes: Vec<(DVec3, DVec3)> = triangles.iter().map(Triangle::bounds).collect();
        let Tree { nodes, order } = Tree::build(&boxes, crate::trace::bvh::MAX_LEAF);
        let mut slots: Vec<Option<Triangle>> = triangles.into_iter().map(Some).collect();
        let triangles = order.iter().map(|&i| slots[i as usize].take().expect("each triangle once")).collect();
        Bvh { triangles, nodes }
    }

    fn box_entry(node: &Node, origin: DVec3, inv: DVec3, t_max: f64) -> Option<f64> {
        let t0 = (node.lo - origin) * inv;
        let t1 = (node.hi - origin) * inv;
        let near = t0.min(t1);
        let far = t0.max(t1);
        let t_near = near.x.max(near.y).max(near.z).max(0.0);
        let t_far = far.x.min(far.y).min(far.z).min(t_max) * FAR_SCALE;
        (t_near <= t_far).then_some(t_near)
    }

    fn inverse(direction: DVec3) -> DVec3 {
        let inv = |d: f64| {
            if d.abs() > 1e-300 { 1.0 / d } else { 1e300f64.copysign(d) }
        };
        DVec3::new(inv(direction.x), inv(direction.y), inv(direction.z))
    }

    /// Möller–Trumbore: the hit (t, u, v) of the ray with triangle `t` for
    /// 0 < t < `t_max`.
    fn triangle_hit(tri: &Triangle, origin: DVec3, direction: DVec3, t_max: f64) -> Option<(f64, f64, f64)> {
        let p = direction.cross(tri.e2);
        let det = tri.e1.dot(p);
        // |det| = |e1 × e2| · |cos|: reject rays (nearly) in the plane.
        if det.abs() <= PARALLEL_EPS * tri.e1.cross(tri.e2).length() || !det.is_finite() {
            return None;
        }
        let inv_det = 1.0 / det;
        let s = origin - tri.v0;
        let u = s.dot(p) * inv_det;
        if !(-BARY_EPS..=1.0 + BARY_EPS).contains(&u) {
            return None;
        }
        let q = s.cross(tri.e1);
        let v = direction.dot(q) * inv_det;
        if v < -BARY_EPS || u + v > 1.0 + BARY_EPS {
            return None;
        }
        let t = tri.e2.dot(q) * inv_det;
        (t > 0.0 && t < t_max).then_some((t, u, v))
    }

    /// The closest hit of the ray `origin + t·direction`, 0 < t < `t_max`,
    /// ignoring triangle `skip` (the one the ray leaves from), from either
    /// side, counting only the hits (triangle, u, v) that `solid` accepts: the
    /// ray goes on through the others (alpha cut-outs). The test runs inside
    /// the traversal, after a triangle is hit and before it shortens the ray,
    /// so nothing behind a rejected hit is missed. [`every_hit`] accepts all.
    pub(crate) fn closest(
        &self,
        origin: DVec3,
        direction: DVec3,
        t_max: f64,
        skip: Option<u32>,
        solid: &impl Fn(&Triangle, f64, f64) -> bool,
    ) -> Option<Hit> {
        self.traverse(origin, direction, t_max, skip, false, solid)
    }

    /// Some hit on the ray within 0 < t < `t_max` (except `skip`) that
    /// `solid` accepts, the first the traversal finds: not always the closest.
    pub(crate) fn any_hit(
        &self,
        origin: DVec3,
        direction: DVec3,
        t_max: f64,
        skip: Option<u32>,
        solid: &impl Fn(&Triangle, f64, f64) -> bool,
    ) -> Option<Hit> {
        self.traverse(origin, direction, t_max, skip, true, solid)
    }

    /// Whether anything `solid` accepts lies on the ray within 0 < t < `t_max`
    /// (except `skip`).
    pub(crate) fn occluded(
        &self,
        origin: DVec3,
        direction: DVec3,
        t_max: f64,
        skip: Option<u32>,
        solid: &impl Fn(&Triangle, f64, f64) -> bool,
    ) -> bool {
        self.any_hit(origin, direction, t_max, skip, solid).is_some()
    }

    /// The hit of triangle `i` if it counts: not `skip`, within `t_max`, and `solid`.
    #[inline(always)]
    fn leaf_hit(
        &self,
        i: u32,
        origin: DVec3,
        direction: DVec3,
        t_max: f64,
        skip: Option<u32>,
        solid: &impl Fn(&Triangle, f64, f64) -> bool,
    ) -> Option<Hit> {
        if Some(i) == skip {
            return None;
        }
        let tri = &self.triangles[i as usize];
        let (t, u, v) = Self::triangle_hit(tri, origin, direction, t_max)?;
        solid(tri, u, v).then_some(Hit { t, triangle: i, u, v })
    }

    /// Front-to-back traversal: the closest solid hit, or with `any` the first found.
    fn traverse(
        &self,
        origin: DVec3,
        direction: DVec3,
        t_max: f64,
        skip: Option<u32>,
        any: bool,
        solid: &impl Fn(&Triangle, f64, f64) -> bool,
    ) -> Option<Hit> {
        if self.triangles.is_empty() {
            return None;
        }
        let inv = Self::inverse(direction);
        let mut best: Option<Hit> = None;
        let mut t_max = t_max;
        let mut stack = [0u32; STACK];
        let mut len = 0usize;
        Self::box_entry(&self.nodes[0], origin, inv, t_max)?;
        let mut current = 0u32;
        loop {
            let node = &self.nodes[current as usize];
            if node.count > 0 {
                for i in node.start..node.start + node.count {
                    if let Some(hit) = self.leaf_hit(i, origin, direction, t_max, skip, solid) {
                        t_max = hit.t;
                        best = Some(hit);
                        if any {
                            return best;
                        }
                    }
                }
            } else {
                let (l, r) = (node.start, node.start + 1);
                let tl = Self::box_entry(&self.nodes[l as usize], origin, inv, t_max);
                let tr = Self::box_entry(&self.nodes[r as usize], origin, inv, t_max);
                match (tl, tr) {
                    (Some(a), Some(b)) => {
                        let (near, far) = if a <= b { (l, r) } else { (r, l) };
                        if len < STACK {
                            stack[len] = far;
                            len += 1;
                        } else {
                            // Deeper than any SAH tree over 2^32 triangles gets;
                            // kept correct anyway by visiting `far` first now.
                            let cast = Cast { origin, direction, inv, skip, any, solid };
                            if let Some(h) = self.traverse_from(far, &cast, t_max) {
                                t_max = h.t;
                                best = Some(h);
                                if any {
                                    return best;
                                }
                            }
                        }
                        current = near;
                        continue;
                    }
                    (Some(_), None) => {
                        current = l;
                        continue;
                    }
                    (None, Some(_)) => {
                        current = r;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            // Pop the next node that the ray still reaches.
            loop {
                if len == 0 {
                    return best;
                }
                len -= 1;
                let n = stack[len];
                if Self::box_entry(&self.nodes[n as usize], origin, inv, t_max).is_some() {
                    current = n;
                    break;
                }
            }
        }
    }

    /// Whether some triangle comes within `radius` of `centre` on the side
    /// `face` points to (its plane through `centre` included), allowing for
    /// rounding. Conservative: a ray from `centre`, or from a point above it
    /// along `face`, into that side can meet a triangle within `radius` of
    /// `centre` only where this is true.
    pub(crate) fn any_near_above(&self, centre: DVec3, radius: f64, face: DVec3) -> bool {
        let Some(root) = self.nodes.first() else {
            return false;
        };
        // Rounding of the scene's coordinates and the barycentric overlap
        // of `triangle_hit`, both far under this.
        let slack = 1e-9 * (1.0 + radius + root.lo.abs().max(root.hi.abs()).max_element());
        let reaches = |lo: DVec3, hi: DVec3| {
            let top = DVec3::select(face.cmpgt(DVec3::ZERO), hi, lo);
            centre.clamp(lo, hi).distance(centre) <= radius + slack && (top - centre).dot(face) >= -slack
        };
        // Nodes to visit: a fixed array, and a list only past its depth (one
        // call per texel: no allocation in the common case).
        let (mut stack, mut len, mut deeper) = ([0u32; STACK], 1usize, Vec::new());
        loop {
            let n = match len {
                0 => match deeper.pop() {
                    Some(n) => n,
                    None => break,
                },
                _ => {
                    len -= 1;
                    stack[len]
                }
            };
            let node = &self.nodes[n as usize];
            if !reaches(node.lo, node.hi) {
                continue;
            }
            if node.count == 0 {
                for child in [node.start, node.start + 1] {
                    if len < STACK {
                        stack[len] = child;
                        len += 1;
                    } else {
                        deeper.push(child);
                    }
                }
                continue;
            }
            let leaf = &self.triangles[node.start as usize..(node.start + node.count) as usize];
            if leaf.iter().any(|t| {
                let (lo, hi) = t.bounds();
                let above = [t.v0, t.v0 + t.e1, t.v0 + t.e2].iter().any(|&v| (v - centre).dot(face) >= -slack);
                above && reaches(lo, hi)
            }) {
                return true;
            }
        }
        false
    }

    /// Recursive fallback for subtrees past the explicit stack's depth.
    fn traverse_from<F: Fn(&Triangle, f64, f64) -> bool>(&self, node: u32, cast: &Cast<F>, t_max: f64) -> Option<Hit> {
        let Cast { origin, direction, inv, skip, any, solid } = *cast;
        let n = &self.nodes[node as usize];
        Self::box_entry(n, origin, inv, t_max)?;
        let mut t_max = t_max;
        let mut best = None;
        if n.count > 0 {
            for i in n.start..n.start + n.count {
                if let Some(hit) = self.leaf_hit(i, origin, direction, t_max, skip, solid) {
                    t_max = hit.t;
                    best = Some(hit);
                    if any {
                        return best;
                    }
                }
            }
            return best;
        }
        for child in [n.start, n.start + 1] {
            if let Some(h) = self.traverse_from(child, cast, t_max) {
                t_max = h.t;
                best = Some(h);
                if any {
                    return best;
                }
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trace::random::Rng;

    fn random_triangles(n: usize, rng: &mut Rng) -> Vec<Triangle> {
        (0..n)
            .map(|i| {
                let c = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 10.0;
                let r = |rng: &mut Rng| DVec3::new(rng.next_f64() - 0.5, rng.next_f64() - 0.5, rng.next_f64() - 0.5);
                let (a, b, d) = (c + r(rng), c + r(rng), c + r(rng));
                Triangle {
                    v0: a,
                    e1: b - a,
                    e2: d - a,
                    face: (b - a).cross(d - a).normalize(),
                    normals: None,
                    material: i as u32 % 3,
                    primitive: 0,
                    texcoords: NO_TEXCOORDS,
                }
            })
            .collect()
    }

    #[test]
    fn nothing_near_above_means_no_short_ray_up_meets_a_triangle() {
        let mut rng = Rng::new(&[7]);
        let triangles = random_triangles(3000, &mut rng);
        let bvh = Bvh::new(triangles.clone());
        let unit =
            |rng: &mut Rng| DVec3::new(rng.next_f64() - 0.5, rng.next_f64() - 0.5, rng.next_f64() - 0.5).normalize();
        let (mut near, mut clear) = (0, 0);
        for k in 0..4000 {
            let radius = 0.2 + rng.next_f64();
            let face = unit(&mut rng);
            // Half the queries anywhere; half aimed: a ray from the centre
            // along `d` meets a triangle's point at up to the full radius,
            // up to grazing the plane of a triangle lying in it.
            let (centre, d, face) = if k % 2 == 0 {
                let centre = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 12.0 - 1.0;
                (centre, unit(&mut rng), face)
            } else {
                let t = &triangles[(rng.next_f64() * triangles.len() as f64) as usize];
                let (u, v) = (rng.next_f64(), rng.next_f64());
                let (u, v) = if u + v > 1.0 { (1.0 - u, 1.0 - v) } else { (u, v) };
                let (d, face) = if k % 4 == 1 {
                    let along = t.face.cross(unit(&mut rng)).normalize();
                    ((along + t.face * 1e-3 * rng.next_f64()).normalize(), t.face)
                } else {
                    (unit(&mut rng), face)
                };
                (t.point(u, v) - d * radius * (1.0 - 1e-3 * rng.next_f64()), d, face)
            };
            let d = if d.dot(face) < 0.0 { -d } else { d };
            let answer = bvh.any_near_above(centre, radius, face);
            (near, clear) = if answer { (near + 1, clear) } else { (near, clear + 1) };
            let lift = if k % 4 == 3 { 0.0 } else { 0.1 * radius * rng.next_f64() };
            let hit = bvh.closest(centre + face * lift, d, radius - lift, None, &every_hit);
            assert!(answer || hit.is_none(), "a ray from {centre} met a triangle the query missed");
        }
        // Both answers come up: the query is not trivially true.
        assert!(near > 100 && clear > 100, "{near} near, {clear} clear");
    }

    /// Depth of the deepest leaf.
    fn depth(bvh: &Bvh, node: u32) -> usize {
        let n = &bvh.nodes[node as usize];
        if n.count > 0 { 1 } else { 1 + depth(bvh, n.start).max(depth(bvh, n.start + 1)) }
    }

    #[test]
    fn a_tree_deeper_than_the_fixed_stack_is_searched_to_its_bottom() {
        // Triangles halving in size and distance towards the origin from −x:
        // each split cuts off the largest, so the tree is a chain, and the
        // walk keeps every cut-off leaf to visit on its way down.
        let triangles: Vec<Triangle> = (0..400)
            .map(|k| {
                let s = 0.5f64.powi(k);
                let a = DVec3::new(-1.4 * s, 0.0, 0.0);
                let (e1, e2) = (DVec3::new(0.4 * s, 0.0, 0.0), DVec3::new(0.0, 0.0, 0.4 * s));
                Triangle {
                    v0: a,
                    e1,
                    e2,
                    face: DVec3::Y,
                    normals: None,
                    material: 0,
                    primitive: 0,
                    texcoords: NO_TEXCOORDS,
                }
            })
            .collect();
        let bvh = Bvh::new(triangles);
        assert!(depth(&bvh, 0) > STACK, "the chain is only {} deep", depth(&bvh, 0));
        // Near the origin the walk goes down the whole chain (every box
        // there is within the query's rounding slack); far above, nothing.
        let origin = DVec3::new(0.0, 1e-12, 0.0);
        assert!(bvh.any_near_above(origin, 1e-12, DVec3::NEG_Y), "the triangles at the chain's bottom are found");
        assert!(
            !bvh.any_near_above(DVec3::new(-1.0, 0.5, -1.0), 0.5, DVec3::NEG_Y),
            "nothing reaches a point a metre off"
        );
    }

    #[test]
    fn bvh_agrees_with_brute_force() {
        let mut rng = Rng::new(&[42]);
        let triangles = random_triangles(3000, &mut rng);
        let bvh = Bvh::new(triangles.clone());
        for _ in 0..500 {
            let o = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 12.0 - 1.0;
            let d = DVec3::new(rng.next_f64() - 0.5, rng.next_f64() - 0.5, rng.next_f64() - 0.5).normalize();
            let brute = triangles
                .iter()
                .filter_map(|t| Bvh::triangle_hit(t, o, d, f64::INFINITY).map(|h| h.0))
                .fold(f64::INFINITY, f64::min);
            let hit = bvh.closest(o, d, f64::INFINITY, None, &every_hit).map_or(f64::INFINITY, |h| h.t);
            assert_eq!(hit, brute);
            assert_eq!(bvh.occluded(o, d, f64::INFINITY, None, &every_hit), brute.is_finite());
        }
    }

    #[test]
    fn rejected_hits_let_the_ray_through_to_the_next_solid_one() {
        let mut rng = Rng::new(&[43]);
        let triangles = random_triangles(3000, &mut rng);
        let bvh = Bvh::new(triangles.clone());
        // Material 0 is all holes; the others are cut out where u < 0.3.
        let solid = |t: &Triangle, u: f64, _: f64| t.material != 0 && u >= 0.3;
        let mut rejected = 0;
        for _ in 0..500 {
            let o = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 12.0 - 1.0;
            let d = DVec3::new(rng.next_f64() - 0.5, rng.next_f64() - 0.5, rng.next_f64() - 0.5).normalize();
            let hits: Vec<(f64, bool)> = triangles
                .iter()
                .filter_map(|t| Bvh::triangle_hit(t, o, d, f64::INFINITY).map(|(h, u, v)| (h, solid(t, u, v))))
                .collect();
            rejected += hits.iter().filter(|h| !h.1).count();
            let brute = hits.iter().filter(|h| h.1).map(|h| h.0).fold(f64::INFINITY, f64::min);
            let hit = bvh.closest(o, d, f64::INFINITY, None, &solid).map_or(f64::INFINITY, |h| h.t);
            assert_eq!(hit, brute);
            assert_eq!(bvh.occluded(o, d, f64::INFINITY, None, &solid), brute.is_finite());
        }
        assert!(rejected > 100, "only {rejected} hits were rejected");
    }
}
