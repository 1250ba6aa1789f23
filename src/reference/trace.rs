//! The path tracer: one Monte Carlo sample of the lightmap value at a point.
//!
//! At every vertex (the query point first, then each surface hit) the
//! incident-light integral (1/π)∫L_in cos dω is estimated with techniques
//! combined by Veach's balance heuristic: a direction drawn from the
//! environment's importance table and a point drawn on an emissive triangle
//! (next-event estimation, each with a shadow ray), and a cosine-distributed
//! direction. The cosine direction also continues the path: if it escapes it
//! sees the environment, if it reaches the front of a surface that surface's
//! emission (both MIS-weighted against the light samples), plus the
//! surface's albedo times its own incident light, estimated recursively from
//! the new vertex. Albedo and emission are the material's factors times its
//! textures at the hit; every kind of ray passes through alpha cut-outs as if
//! the surface were absent.

use std::f64::consts::FRAC_1_PI;

use glam::DVec3;

use super::Reference;
use crate::trace::random::{Rng, cosine_hemisphere};

/// Surface interactions after which Russian roulette starts.
const ROULETTE_AFTER: u32 = 3;
/// An emitter's shadow ray stops this share of the distance short of the
/// point drawn, so that the emitter's own triangle (or its neighbour, met at
/// the shared edge) does not block it.
const SHADOW_SHORT: f64 = 1e-7;

/// Whether `direction` points behind the plane of unit normal `face`.
fn behind(face: Option<DVec3>, direction: DVec3) -> bool {
    face.is_some_and(|f| direction.dot(f) <= 0.0)
}

/// Balance-heuristic weight of a technique with density `a` against one with `b`.
fn balance(a: f64, b: f64) -> f64 {
    if a + b > 0.0 { a / (a + b) } else { 0.0 }
}

impl Reference {
    /// The punctual lights' share of L_lm at a vertex: (1/π) Σ E cos θ over
    /// the lights that reach it unblocked, from the front of its plane.
    fn punctual_light(&self, origin: DVec3, normal: DVec3, face: Option<DVec3>, skip: Option<u32>) -> DVec3 {
        let mut sum = DVec3::ZERO;
        for light in &self.lights {
            let Some(incident) = light.towards(origin) else { continue };
            let cos = incident.direction.dot(normal);
            if cos > 0.0
                && !behind(face, incident.direction)
                && !self.surfaces.occluded_within(origin, incident.direction, incident.distance, skip)
            {
                sum += incident.irradiance * (cos * FRAC_1_PI);
            }
        }
        sum
    }

    /// One path's estimate of L_lm at `position` (already offset off the
    /// surface) for the unit receiving `normal`, on a surface whose plane has
    /// the unit normal `face` (when it lies on one): directions behind that
    /// plane bring nothing.
    pub(super) fn sample_path(&self, position: DVec3, normal: DVec3, face: Option<DVec3>, rng: &mut Rng) -> DVec3 {
        let env = self.env.as_ref();
        let nee = env.is_some_and(|e| e.can_sample());
        let mut result = DVec3::ZERO;
        let mut beta = DVec3::ONE;
        let mut origin = position;
        let mut normal = normal;
        let mut skip: Option<u32> = None;
        // Only the query point's shading normal can lean past its plane; every
        // later vertex uses its triangle's own normal.
        let mut face = face;
        for bounce in 0..=self.max_bounces {
            result += beta * self.punctual_light(origin, normal, face, skip);
            // Next-event estimation towards the environment.
            if nee {
                let env = env.unwrap();
                let s = env.sample([rng.next_f64(), rng.next_f64(), rng.next_f64(), rng.next_f64()]);
                let cos = s.direction.dot(normal);
                if cos > 0.0
                    && s.pdf > 0.0
                    && !behind(face, s.direction)
                    && !self.surfaces.occluded_within(origin, s.direction, f64::INFINITY, skip)
                {
                    let pdf_cos = cos * FRAC_1_PI;
                    // (cos/π)/pdf × weight
                    let weight = pdf_cos / s.pdf * balance(s.pdf, pdf_cos);
                    result += beta * s.radiance * weight;
                }
            }
            if !self.emitters.is_empty() {
                result += beta * self.emitter_light(origin, normal, face, skip, rng);
            }
            // Continue along a cosine-distributed direction.
            let (direction, cos) = cosine_hemisphere(normal, rng.next_f64(), rng.next_f64());
            if cos <= 0.0 || behind(face, direction) {
                break;
            }
            let Some(hit) = self.surfaces.closest(origin, direction, skip) else {
                if let Some(env) = env {
                    let weight = if nee { balance(cos * FRAC_1_PI, env.pdf(direction)) } else { 1.0 };
                    result += beta * env.radiance(direction) * weight;
                }
                break;
            };
            let tri = &self.surfaces.triangles()[hit.triangle as usize];
            let material = &self.materials[tri.material as usize];
            let mut n = tri.front_normal(hit.u, hit.v);
            if direction.dot(n) >= 0.0 {
                // The back side: black unless the material is double-sided.
                if !material.double_sided {
                    break;
                }
                n = -n;
            }
            let surface = self.surface_at(tri, hit.u, hit.v);
            if surface.emission != DVec3::ZERO {
                let cos_emitter = direction.dot(tri.face).abs();
                let pdf_light =
                    self.emitters.pdf_solid_angle(self.surfaces.triangles(), hit.triangle, hit.t, cos_emitter);
                result += beta * surface.emission * balance(cos * FRAC_1_PI, pdf_light);
            }
            if bounce == self.max_bounces {
                break;
            }
            let albedo = surface.albedo;
            let peak = albedo.max_element();
            if peak <= 0.0 {
                break;
            }
            beta *= albedo;
            if bounce + 1 >= ROULETTE_AFTER {
                let survive = peak.min(1.0);
                if rng.next_f64() >= survive {
                    break;
                }
                beta /= survive;
            }
            origin = tri.point(hit.u, hit.v) + n * self.surface_offset;
            normal = n;
            skip = Some(hit.triangle);
            face = None;
        }
        result
    }

    /// Next-event estimation towards the emitters at a vertex: one point
    /// drawn on an emissive triangle, its emission if the point sees its
    /// front (either side of a double-sided one) unblocked, weighted
    /// against the cosine ray's chance of finding it.
    fn emitter_light(
        &self,
        origin: DVec3,
        normal: DVec3,
        face: Option<DVec3>,
        skip: Option<u32>,
        rng: &mut Rng,
    ) -> DVec3 {
        let triangles = self.surfaces.triangles();
        let s = self.emitters.sample([rng.next_f64(), rng.next_f64(), rng.next_f64()]);
        if Some(s.triangle) == skip {
            return DVec3::ZERO;
        }
        let tri = &triangles[s.triangle as usize];
        let to = tri.point(s.u, s.v) - origin;
        let distance = to.length();
        let direction = to / distance;
        let cos = direction.dot(normal);
        let cos_emitter = direction.dot(tri.face).abs();
        if !(cos > 0.0 && cos_emitter > 0.0) || behind(face, direction) {
            return DVec3::ZERO;
        }
        let from_behind = direction.dot(tri.front_normal(s.u, s.v)) >= 0.0;
        if (from_behind && !self.materials[tri.material as usize].double_sided) || !self.surfaces.solid(tri, s.u, s.v) {
            return DVec3::ZERO;
        }
        let emission = self.surface_at(tri, s.u, s.v).emission;
        if emission == DVec3::ZERO
            || self.surfaces.occluded_within(origin, direction, distance * (1.0 - SHADOW_SHORT), skip)
        {
            return DVec3::ZERO;
        }
        let pdf_light = self.emitters.pdf_solid_angle(triangles, s.triangle, distance, cos_emitter);
        let pdf_cos = cos * FRAC_1_PI;
        emission * (pdf_cos / pdf_light) * balance(pdf_light, pdf_cos)
    }
}
