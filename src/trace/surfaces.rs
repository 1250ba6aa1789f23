//! A scene's surfaces as CPU rays meet them: every triangle in f64 in a BVH
//! (`rays`), each with its material's alpha cut-out and, where a material
//! samples a texture or the mesh has vertex colours, its UV sets and colours
//! at the corners.
//!
//! Two kinds of cast. Those that pass through alpha cut-outs (`closest`,
//! `occluded_within`, `blocked`, `first_surface`) are the reference path
//! tracer's and the shadow rays of punctual lights and probes. The
//! geometry-only ones (`blocks`, `first_hit`, `any_blocker`, `blocks_where`,
//! `any_near_above`) treat a cut-out as solid surface: the solve's
//! supersample fix-up drops a sub-sample behind a hole as it does behind a
//! wall, which costs only some smoothing, and the shooter patches and the
//! contact fix-up ask what geometry is there.

use std::sync::Arc;

use glam::{DVec2, DVec3};

use crate::scene::{LinearImage, Material, Scene, ScenePrimitive};
use crate::trace::rays::{Bvh, Hit, NO_TEXCOORDS, Triangle, every_hit};
use crate::trace::texture::{self, Texture};

/// Which of the scene's images the surfaces keep.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Textures {
    /// Only those that cut out a material's holes: enough for every cast.
    CutOuts,
    /// Every decoded image a material samples, and every vertex-coloured
    /// triangle's corners: what shading a hit needs.
    All,
}

/// What decides whether a material's surface is there at a point.
#[derive(Clone, Debug)]
struct CutOut {
    /// baseColorFactor alpha, as given: compared (× the base texture's
    /// alpha) with the cut-off unchanged, as the bake's casters do.
    alpha: f64,
    /// alphaMode MASK's cut-off (`Material::cutoff`); a negative or NaN one
    /// is opaque, as in the casters (`is_masked`).
    cutoff: f64,
    base_texture: Option<Texture>,
}

/// A triangle's TEXCOORD_0 and TEXCOORD_1 at its three vertices (source
/// order, as `Triangle::v0`, `e1`, `e2`): `[set][vertex]`.
type TriangleTexcoords = [[[f32; 2]; 3]; 2];

/// The scene's triangles, ready for CPU rays. Build once per bake (or per
/// reference) and share.
pub struct Surfaces {
    pub(crate) bvh: Bvh,
    /// Per material (the scene's, then glTF's default one): its cut-out, if any.
    cut_outs: Vec<Option<CutOut>>,
    /// The decoded images kept (`Textures`), shared with the scene.
    pub(crate) images: Vec<Arc<LinearImage>>,
    /// For each scene image, its index among `images` (`None`: read as white).
    pub(crate) image_slots: Vec<Option<usize>>,
    /// UV sets of the triangles that need them (`Triangle::texcoords`).
    texcoords: Vec<TriangleTexcoords>,
    /// COLOR_0 (RGB clamped to [0, 1], white where absent) at the same
    /// triangles' corners, same index.
    colors: Vec<[DVec3; 3]>,
    /// Largest absolute vertex coordinate, metres (1 for an empty scene).
    pub(crate) scale: f64,
}

impl Surfaces {
    /// A BVH over every non-degenerate triangle of `scene`, with the images
    /// its cut-outs read.
    pub fn new(scene: &Scene) -> Surfaces {
        Surfaces::build(scene, Textures::CutOuts)
    }

    /// As [`Surfaces::new`], keeping the images and corners that `textures` names.
    pub(crate) fn build(scene: &Scene, textures: Textures) -> Surfaces {
        let (images, image_slots) = usable_images(scene, textures);
        let default_material = Material::default();
        let materials: Vec<&Material> = scene.materials.iter().chain(std::iter::once(&default_material)).collect();
        let cut_outs: Vec<Option<CutOut>> = materials.iter().map(|m| cut_out(m, &image_slots)).collect();
        // Per material: whether its triangles' UV sets are read (vertex
        // colours add some with `Textures::All`).
        let textured: Vec<bool> = match textures {
            Textures::CutOuts => {
                cut_outs.iter().map(|c| c.as_ref().is_some_and(|c| c.base_texture.is_some())).collect()
            }
            Textures::All => materials.iter().map(|m| samples_an_image(m, &image_slots)).collect(),
        };
        let needs_corners = |material: u32, p: &ScenePrimitive| {
            textured[material as usize] || (textures == Textures::All && p.colors.is_some())
        };
        let mut texcoords = Vec::new();
        let mut colors = Vec::new();
        let triangles: Vec<Triangle> = scene_triangles(scene)
            .into_iter()
            .map(|(pi, t, mut tri)| {
                let primitive = &scene.primitives[pi];
                if needs_corners(tri.material, primitive) {
                    tri.texcoords = texcoords.len() as u32;
                    texcoords.push(triangle_texcoords(primitive, t));
                    colors.push(triangle_colors(primitive, t));
                }
                tri
            })
            .collect();
        let scale = triangles
            .iter()
            .flat_map(|t| [t.v0, t.v0 + t.e1, t.v0 + t.e2])
            .map(|v| v.abs().max_element())
            .fold(0.0f64, f64::max);
        let scale = if scale > 0.0 && scale.is_finite() { scale } else { 1.0 };
        Surfaces { bvh: Bvh::new(triangles), cut_outs, images, image_slots, texcoords, colors, scale }
    }

    /// The triangles (degenerate ones left out), in the BVH's order.
    pub(crate) fn triangles(&self) -> &[Triangle] {
        &self.bvh.triangles
    }

    /// Whether `tri` is cut out at barycentrics (u, v): its material has a
    /// cut-off and base colour alpha × the base texture's alpha falls below
    /// it (the bake's casters' test, so NaN alpha is solid).
    pub(crate) fn is_cut_out(&self, tri: &Triangle, u: f64, v: f64) -> bool {
        let Some(c) = &self.cut_outs[tri.material as usize] else {
            return false;
        };
        let texture_alpha = match &c.base_texture {
            Some(t) => t.sample(&self.images, self.texcoords_at(tri, u, v)).w,
            None => 1.0,
        };
        c.alpha * texture_alpha < c.cutoff
    }

    /// Whether a hit at barycentrics (u, v) of `tri` is surface, not a hole.
    pub(crate) fn solid(&self, tri: &Triangle, u: f64, v: f64) -> bool {
        !self.is_cut_out(tri, u, v)
    }

    /// TEXCOORD_0 and TEXCOORD_1 of `tri` at barycentrics (u, v); zero for a
    /// triangle without stored coordinates.
    pub(crate) fn texcoords_at(&self, tri: &Triangle, u: f64, v: f64) -> [DVec2; 2] {
        let Some(sets) = self.texcoords.get(tri.texcoords as usize) else {
            return [DVec2::ZERO; 2];
        };
        sets.map(|[a, b, c]| {
            let [a, b, c] = [a, b, c].map(|p| DVec2::new(p[0] as f64, p[1] as f64));
            a * (1.0 - u - v) + b * u + c * v
        })
    }

    /// COLOR_0 at `tri`'s corners, for a triangle whose corners are kept.
    pub(crate) fn corner_colors(&self, tri: &Triangle) -> Option<&[DVec3; 3]> {
        self.colors.get(tri.texcoords as usize)
    }

    /// The closest surface (not a cut-out, not `skip`) along the ray.
    pub(crate) fn closest(&self, origin: DVec3, direction: DVec3, skip: Option<u32>) -> Option<Hit> {
        self.bvh.closest(origin, direction, f64::INFINITY, skip, &|tri, u, v| self.solid(tri, u, v))
    }

    /// Whether a surface other than `skip` and its cut-outs blocks the ray
    /// closer than `distance`.
    pub(crate) fn occluded_within(&self, origin: DVec3, direction: DVec3, distance: f64, skip: Option<u32>) -> bool {
        self.bvh.occluded(origin, direction, distance, skip, &|tri, u, v| self.solid(tri, u, v))
    }

    /// Whether a surface (not a cut-out) blocks the ray closer than
    /// `distance`: shadow rays to a punctual light.
    pub(crate) fn blocked(&self, origin: DVec3, direction: DVec3, distance: f64) -> bool {
        self.occluded_within(origin, direction, distance, None)
    }

    /// The first surface (not a cut-out) along the ray closer than
    /// `distance`: how far, and its triangle's front normal there.
    pub(crate) fn first_surface(&self, origin: DVec3, direction: DVec3, distance: f64) -> Option<(f64, DVec3)> {
        let hit = self.bvh.closest(origin, direction, distance, None, &|tri, u, v| self.solid(tri, u, v))?;
        Some((hit.t, self.bvh.triangles[hit.triangle as usize].front_normal(hit.u, hit.v)))
    }

    /// Whether some triangle may come within `radius` of `centre` on the
    /// side `face` points to (`Bvh::any_near_above`, conservative).
    pub(crate) fn any_near_above(&self, centre: DVec3, radius: f64, face: DVec3) -> bool {
        self.bvh.any_near_above(centre, radius, face)
    }

    /// Whether any triangle crosses the segment from `a` to `b` (ends excluded).
    pub(crate) fn blocks(&self, a: DVec3, b: DVec3) -> bool {
        self.bvh.occluded(a, b - a, 1.0, None, &every_hit)
    }

    /// The first triangle the ray `origin + t·direction` (0 < t < `t_max`)
    /// meets: its distance t, its primitive's index and its face normal.
    pub(crate) fn first_hit(&self, origin: DVec3, direction: DVec3, t_max: f64) -> Option<(f64, u32, DVec3)> {
        let hit = self.bvh.closest(origin, direction, t_max, None, &every_hit)?;
        let triangle = &self.bvh.triangles[hit.triangle as usize];
        Some((hit.t, triangle.primitive, triangle.face))
    }

    /// The primitive of some triangle on the ray from `origin` towards
    /// `direction` (any that blocks it, not always the first).
    pub(crate) fn any_blocker(&self, origin: DVec3, direction: DVec3) -> Option<u32> {
        let hit = self.bvh.any_hit(origin, direction, f64::INFINITY, None, &every_hit)?;
        Some(self.bvh.triangles[hit.triangle as usize].primitive)
    }

    /// Whether a triangle that `counts` accepts (given its primitive's index
    /// and its front normal) crosses the segment from `a` to `b` (ends
    /// excluded).
    pub(crate) fn blocks_where(&self, a: DVec3, b: DVec3, counts: impl Fn(u32, DVec3) -> bool) -> bool {
        self.bvh.occluded(a, b - a, 1.0, None, &|t: &Triangle, _, _| counts(t.primitive, t.face))
    }
}

/// `m`'s cut-out, with its base texture looked up in `image_slots`; `None`
/// for OPAQUE and BLEND (baked opaque) and for a negative or NaN cut-off.
fn cut_out(m: &Material, image_slots: &[Option<usize>]) -> Option<CutOut> {
    let cutoff = m.cutoff().filter(|&c| c >= 0.0).map(f64::from)?;
    Some(CutOut { alpha: m.base_color[3] as f64, cutoff, base_texture: texture(&m.base_color_texture, image_slots) })
}

/// The texture `t` refers to, if its image is among the kept ones.
pub(crate) fn texture(t: &Option<crate::scene::TextureRef>, image_slots: &[Option<usize>]) -> Option<Texture> {
    let t = t.as_ref()?;
    let image = image_slots.get(t.image).copied().flatten()?;
    Some(Texture::new(t, image))
}

/// Whether shading `m` samples one of the kept images.
fn samples_an_image(m: &Material, image_slots: &[Option<usize>]) -> bool {
    texture(&m.base_color_texture, image_slots).is_some() || texture(&m.emissive_texture, image_slots).is_some()
}

/// The triangles of `scene` in f64 with their front-side data, skipping
/// degenerate or non-finite ones; material indices refer to `scene.materials`
/// with `scene.materials.len()` for glTF's default material.
pub(crate) fn scene_triangles(scene: &Scene) -> Vec<(usize, usize, Triangle)> {
    let default_material = scene.materials.len() as u32;
    let mut out = Vec::with_capacity(scene.triangle_count());
    for (pi, p) in scene.primitives.iter().enumerate() {
        let material = p.material.filter(|&m| m < scene.materials.len()).map_or(default_material, |m| m as u32);
        let normals = p.normals.as_ref().filter(|n| n.len() == p.positions.len());
        let vec = |v: [f32; 3]| DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64);
        for t in 0..p.triangle_count() {
            let idx = [0, 1, 2].map(|k| p.indices[3 * t + k] as usize);
            if idx.iter().any(|&i| i >= p.positions.len()) {
                continue;
            }
            let [a, b, c] = idx.map(|i| vec(p.positions[i]));
            let (e1, e2) = (b - a, c - a);
            let cross = e1.cross(e2);
            let len = cross.length();
            if !(len > 0.0 && len.is_finite() && a.is_finite()) {
                continue;
            }
            let face = if p.mirrored { -cross / len } else { cross / len };
            let normals = normals.map(|n| {
                idx.map(|i| {
                    let v = vec(n[i]);
                    if v.is_finite() { v } else { DVec3::ZERO }
                })
            });
            out.push((
                pi,
                t,
                Triangle { v0: a, e1, e2, face, normals, material, primitive: pi as u32, texcoords: NO_TEXCOORDS },
            ));
        }
    }
    out
}

/// The scene's decoded, well-formed images that some material samples
/// (with `Textures::CutOuts`, only those that cut out a material's holes),
/// shared with the scene, and for each scene image its index among them
/// (`None`: sampled as white).
fn usable_images(scene: &Scene, textures: Textures) -> (Vec<Arc<LinearImage>>, Vec<Option<usize>>) {
    let mut sampled = vec![false; scene.images.len()];
    for m in &scene.materials {
        let sampled_here = match (textures, m.cutoff()) {
            (Textures::All, _) => [&m.base_color_texture, &m.emissive_texture],
            (Textures::CutOuts, Some(_)) => [&m.base_color_texture, &None],
            (Textures::CutOuts, None) => [&None, &None],
        };
        for t in sampled_here.into_iter().flatten() {
            if let Some(s) = sampled.get_mut(t.image) {
                *s = true;
            }
        }
    }
    let mut images = Vec::new();
    let slots = scene
        .images
        .iter()
        .zip(sampled)
        .map(|(image, sampled)| {
            let image = image.as_ref().filter(|i| sampled && texture::is_usable(i))?;
            images.push(Arc::clone(image));
            Some(images.len() - 1)
        })
        .collect();
    (images, slots)
}

/// The UV sets of triangle `t` of `p`. A set the primitive lacks (or whose
/// length does not match its positions) is zero, as the bake's vertex
/// buffers fill it (texelize and solve::casters).
fn triangle_texcoords(p: &ScenePrimitive, t: usize) -> TriangleTexcoords {
    let corners = [0, 1, 2].map(|k| p.indices[3 * t + k] as usize);
    [&p.uv0, &p.uv1].map(|set| match set.as_ref().filter(|uv| uv.len() == p.positions.len()) {
        Some(uv) => corners.map(|i| uv[i]),
        None => [[0.0; 2]; 3],
    })
}

/// COLOR_0 at triangle `t`'s corners of `p` (source order), clamped to
/// [0, 1] as the bake's texelize pass does; white where the primitive has
/// none (or one of another length).
fn triangle_colors(p: &ScenePrimitive, t: usize) -> [DVec3; 3] {
    let corners = [0, 1, 2].map(|k| p.indices[3 * t + k] as usize);
    match p.colors.as_ref().filter(|c| c.len() == p.positions.len()) {
        Some(c) => corners.map(|i| DVec3::from_array(c[i].map(f64::from)).clamp(DVec3::ZERO, DVec3::ONE)),
        None => [DVec3::ONE; 3],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn primitive(uv0: Option<Vec<[f32; 2]>>, uv1: Option<Vec<[f32; 2]>>) -> ScenePrimitive {
        ScenePrimitive {
            node: 0,
            instance: None,
            mesh: 0,
            primitive: 0,
            positions: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 1.0]],
            normals: None,
            uv0,
            uv1,
            colors: None,
            indices: vec![0, 1, 2, 2, 1, 3],
            repeats: Vec::new(),
            mirrored: false,
            material: None,
            drawn_material: None,
        }
    }

    #[test]
    fn texcoords_follow_the_source_corners_and_missing_sets_are_zero() {
        let uv = vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]];
        let p = primitive(Some(uv.clone()), None);
        assert_eq!(triangle_texcoords(&p, 1), [[uv[2], uv[1], uv[3]], [[0.0; 2]; 3]]);
        let p = primitive(None, Some(uv.clone()));
        assert_eq!(triangle_texcoords(&p, 0), [[[0.0; 2]; 3], [uv[0], uv[1], uv[2]]]);
        // A set that does not match the positions is left out too.
        let p = primitive(Some(uv[..3].to_vec()), None);
        assert_eq!(triangle_texcoords(&p, 0), [[[0.0; 2]; 3]; 2]);
    }
}
