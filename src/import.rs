//! Import stage: a glTF file in, a `Scene` out: every static triangle
//! primitive reachable from the default scene (or the first), node
//! transforms applied, each GPU instance (EXT_mesh_gpu_instancing) as a
//! primitive of its own, with its material. A morphing mesh is baked at its
//! static weights and an animated node in its rest pose, each with a
//! notice. The KHR_lights_punctual lights the nodes place are collected
//! too (`Scene::lights`). What cannot be baked (points, lines, skinned meshes) is left out
//! with a notice, never silently, and so is what lets most light through
//! (clear glass, see `see_through`).
//!
//! Transforms are composed and applied in f64 and positions stored in f32
//! relative to `Scene::origin` (see `scene::choose_origin`): f32 world
//! coordinates 100 km out are 8 mm apart, too coarse for shadow tests.

use std::path::Path;
use std::sync::Arc;

use anyhow::{Context, Result, anyhow, bail, ensure};
use glam::{DMat3, DMat4, DVec3};
use gltf::mesh::Mode;

use crate::asset::{SourceAsset, accessor, hierarchy, instancing, ktx2, morph, quoted_name};
use crate::scene::{
    AlphaMode, LightKind, LinearImage, Material, PunctualLight, Scene, ScenePrimitive, TextureRef, choose_origin,
};
use crate::{limits, repeats};

/// What one input may ask of a run.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ImportOptions {
    /// The most triangles the scene may hold once node and GPU instances
    /// are expanded (`--max-triangles`); more is refused before they are read.
    pub max_triangles: u64,
}

impl Default for ImportOptions {
    fn default() -> Self {
        ImportOptions { max_triangles: limits::DEFAULT_MAX_TRIANGLES }
    }
}

/// Loads `path` (`.gltf` or `.glb`) into a `Scene` with the default budget. Errors name the file.
pub fn load(path: &Path) -> Result<Scene> {
    load_with(path, &ImportOptions::default())
}

/// Loads `path` into a `Scene` within `options`' budget. Errors name the file.
pub fn load_with(path: &Path, options: &ImportOptions) -> Result<Scene> {
    let run = || -> Result<Scene> { from_asset_with(SourceAsset::load(path)?, options) };
    run().with_context(|| format!("input '{}'", path.display()))
}

/// Builds a `Scene` from an already loaded asset, with the default budget.
#[cfg(feature = "internals")]
pub fn from_asset(source: SourceAsset) -> Result<Scene> {
    from_asset_with(source, &ImportOptions::default())
}

/// Builds a `Scene` from an already loaded asset within `options`' budget.
pub fn from_asset_with(source: SourceAsset, options: &ImportOptions) -> Result<Scene> {
    let document = &source.document;
    let gltf_scene = document
        .default_scene()
        .or_else(|| document.scenes().next())
        .ok_or_else(|| anyhow!("the file has no scene to bake"))?;
    hierarchy::check_trees(document, &gltf_scene)?;
    let [triangles, vertices, drawings] = drawn_counts(&source.json, &gltf_scene);
    if triangles > options.max_triangles {
        bail!(
            "the scene draws {triangles} triangles (node and GPU instances expanded), more than the budget of {} \
             (--max-triangles): raise --max-triangles to bake it",
            options.max_triangles
        );
    }
    // Each drawing of a primitive reads its whole POSITION accessor, which
    // its indices may use only a few of, or share with other primitives.
    let max_vertices = options.max_triangles.saturating_mul(VERTICES_PER_TRIANGLE);
    if vertices > max_vertices {
        bail!(
            "the scene's primitives read {vertices} vertices (node and GPU instances expanded), more than the \
             budget of {max_vertices} ({VERTICES_PER_TRIANGLE} a triangle of --max-triangles): raise \
             --max-triangles to bake it"
        );
    }
    // Each drawing becomes a mesh of its own in the output, with its own
    // lightmap region (a GPU instance too): one triangle drawn 100,000 times
    // from a 1.2 MB file took 2.4 GB and wrote 134 MB of glTF.
    let max_drawings = options.max_triangles / TRIANGLES_PER_DRAWING;
    if drawings > max_drawings {
        bail!(
            "the scene draws {drawings} primitives (node and GPU instances expanded, each a mesh of its own in the \
             output), more than the budget of {max_drawings} (one per {TRIANGLES_PER_DRAWING} triangles of \
             --max-triangles): raise --max-triangles to bake it"
        );
    }

    let mut notices = Vec::new();
    let materials: Vec<Material> = document.materials().map(|m| material(&source.json, m)).collect();
    // Per material, the notice that leaves its primitives out (`see_through`).
    let left_out: Vec<Option<String>> =
        materials.iter().enumerate().map(|(m, parsed)| see_through(&source.json, m, parsed)).collect();
    let animated = morph::animated_nodes(&source.json);
    let Walked { gathered, mut lights, moved } = walk_nodes(&source, &gltf_scene, &left_out, &animated, &mut notices)?;
    notices.extend(rest_pose_notices(document, &animated, moved));
    if gathered.is_empty() {
        bail!("the scene has no triangle geometry to bake");
    }
    let (origin, primitives) = finish_primitives(gathered, &mut notices)?;
    for light in &mut lights {
        light.position -= DVec3::from(origin);
    }

    let mut used: Vec<usize> = primitives.iter().filter_map(|p| p.material).collect();
    used.sort();
    used.dedup();
    check_emission(&materials, &used)?;
    notices.extend(material_notices(&source, &materials, &used));
    // The images of the materials a baked file draws with too, for what shows it.
    let mut shown: Vec<usize> =
        used.iter().copied().chain(primitives.iter().filter_map(|p| p.drawn_material)).collect();
    shown.sort();
    shown.dedup();
    let (images, image_notices) = decode_images(&source, &materials, &shown);
    notices.extend(image_notices);
    let name = source.path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "scene".into());
    Ok(Scene { name, source, origin, primitives, materials, images, lights, notices })
}

/// Animated glTF nodes by index, with the properties their channels move.
type Animated = std::collections::BTreeMap<usize, std::collections::BTreeSet<String>>;

/// What walking the scene's node tree finds.
struct Walked {
    gathered: Vec<Gathered>,
    /// Punctual lights, positioned in world coordinates until the origin is known.
    lights: Vec<PunctualLight>,
    /// Animated nodes with baked geometry at or below them (the nearest such node).
    moved: std::collections::BTreeSet<usize>,
}

/// Walks `gltf_scene`'s nodes depth first, in document order, composing transforms and
/// gathering their meshes' primitives and their lights.
fn walk_nodes(
    source: &SourceAsset,
    gltf_scene: &gltf::Scene,
    left_out: &[Option<String>],
    animated: &Animated,
    notices: &mut Vec<String>,
) -> Result<Walked> {
    let mut walked = Walked { gathered: Vec::new(), lights: Vec::new(), moved: Default::default() };
    // Each node with its parent's world transform and its nearest animated ancestor.
    let mut stack: Vec<(gltf::Node, DMat4, Option<usize>)> =
        gltf_scene.nodes().map(|n| (n, DMat4::IDENTITY, None)).collect();
    stack.reverse();
    while let Some((node, parent, animated_above)) = stack.pop() {
        let local = node.transform().matrix().map(|column| column.map(f64::from));
        let world = parent * DMat4::from_cols_array_2d(&local);
        let animated_above = Some(node.index()).filter(|n| animated.contains_key(n)).or(animated_above);
        let baked_here = node.mesh().is_some() && node.skin().is_none() || node.light().is_some();
        if let (true, Some(animated)) = (baked_here, animated_above) {
            walked.moved.insert(animated);
        }
        if let Some(light) = node.light() {
            walked.lights.extend(punctual_light(&node, &light, world, notices)?);
        }
        collect_instances(source, left_out, &node, world, &mut walked.gathered, notices)?;
        for child in node.children().collect::<Vec<_>>().into_iter().rev() {
            stack.push((child, world, animated_above));
        }
    }
    Ok(walked)
}

/// Gathers `node`'s mesh (if any) once, or once per GPU instance (EXT_mesh_gpu_instancing).
fn collect_instances(
    source: &SourceAsset,
    left_out: &[Option<String>],
    node: &gltf::Node,
    world: DMat4,
    gathered: &mut Vec<Gathered>,
    notices: &mut Vec<String>,
) -> Result<()> {
    let Some(mesh) = node.mesh() else { return Ok(()) };
    match instancing::read(source, node.index())? {
        None => collect_mesh(source, left_out, node, None, world, gathered, notices)?,
        Some(instances) => {
            notices.push(format!(
                "{} is drawn as {} GPU instances ({}): each is baked with its own lightmap region and \
                 written as a child node of its own, since instances share one set of UVs",
                describe(node, &mesh, None),
                instances.placements.len(),
                instancing::EXTENSION
            ));
            for (k, placement) in instances.placements.iter().enumerate() {
                let world = world * placement.matrix();
                collect_mesh(source, left_out, node, Some(k), world, gathered, notices)?;
            }
        }
    }
    Ok(())
}

/// One notice per animated node in `moved`: what is below it is baked in its rest pose.
fn rest_pose_notices(
    document: &gltf::Document,
    animated: &Animated,
    moved: std::collections::BTreeSet<usize>,
) -> Vec<String> {
    let mut notices = Vec::new();
    for node in moved {
        let name = quoted_name(document.nodes().nth(node).and_then(|n| n.name()));
        let properties: Vec<&str> = animated[&node].iter().map(String::as_str).collect();
        notices.push(format!(
            "node {node}{name} is animated ({}): it and the nodes below it are baked in their rest pose, so their \
             lightmaps, and the light and shadow they cast on the rest, hold in that pose only",
            properties.join(", ")
        ));
    }
    notices
}

/// The KHR_lights_punctual light `light` where `node` (of world transform
/// `world`) places it, in world coordinates; `None` for one that gives no
/// light, or none anywhere (a node scaled to nothing, as animators hide
/// things: with a notice). Errors name the light and the node.
fn punctual_light(
    node: &gltf::Node,
    light: &gltf::khr_lights_punctual::Light,
    world: DMat4,
    notices: &mut Vec<String>,
) -> Result<Option<PunctualLight>> {
    use gltf::khr_lights_punctual::Kind;
    let (name, node_name) = (quoted_name(light.name()), quoted_name(node.name()));
    let what = format!("light {}{name} on node {}{node_name}", light.index(), node.index());
    let intensity = DVec3::from(light.color().map(f64::from)) * light.intensity() as f64;
    if !intensity.is_finite() || intensity.min_element() < 0.0 {
        bail!("{what}: colour × intensity {intensity} is negative or not finite");
    }
    if intensity.max_element() > limits::MAX_LIGHT {
        bail!(
            "{what}: colour × intensity {} is more than the {:.0e} bake accepts (f32 headroom, README 'Bad input')",
            limits::figure(intensity.max_element()),
            limits::MAX_LIGHT
        );
    }
    let range = light.range();
    if let Some(range) = range.filter(|r| !(r.is_finite() && *r > 0.0)) {
        bail!("{what}: range {} is not a positive distance", limits::figure_f32(range));
    }
    let range = range.map(f64::from);
    let kind = match light.kind() {
        Kind::Directional => LightKind::Directional,
        Kind::Point => LightKind::Point,
        Kind::Spot { inner_cone_angle, outer_cone_angle } => {
            // Checked as the file's f32s: π/2 written as an f32 is a little
            // over the f64 π/2, and is the spec's own bound.
            let (inner, outer) = (inner_cone_angle, outer_cone_angle);
            if !(0.0 <= inner && inner < outer && outer <= std::f32::consts::FRAC_PI_2) {
                bail!(
                    "{what}: spot cone angles inner {} and outer {} are not 0 ≤ inner < outer ≤ π/2",
                    limits::figure_f32(inner),
                    limits::figure_f32(outer)
                );
            }
            let outer = f64::from(outer).min(std::f64::consts::FRAC_PI_2);
            LightKind::Spot { inner_cone: f64::from(inner), outer_cone: outer }
        }
    };
    // A light shines along its node's −Z, from its node's origin.
    let position = world.transform_point3(DVec3::ZERO);
    let direction = world.transform_vector3(DVec3::NEG_Z).try_normalize();
    let (Some(direction), true) = (direction, position.is_finite()) else {
        notices.push(format!(
            "{what}: the node's transform gives it no position or direction (it scales it to nothing or overflows): \
             left out of the bake"
        ));
        return Ok(None);
    };
    if intensity == DVec3::ZERO {
        return Ok(None);
    }
    Ok(Some(PunctualLight {
        node: node.index(),
        light: light.index(),
        label: what,
        kind,
        position,
        direction,
        intensity,
        range,
    }))
}

/// The vertex budget per triangle of the triangle budget: a triangle list
/// needs at most three.
const VERTICES_PER_TRIANGLE: u64 = 3;

/// The drawing budget per triangle of the triangle budget.
const TRIANGLES_PER_DRAWING: u64 = 64;

/// The triangles `scene` draws, the vertices it reads and the primitives it
/// draws once node and GPU instances are expanded, from the accessors'
/// declared counts: known before anything is read, so a small file drawing
/// one mesh from thousands of nodes is refused at once.
fn drawn_counts(json: &serde_json::Value, scene: &gltf::Scene) -> [u64; 3] {
    let mut total = [0u64; 3];
    // The nodes form trees (`hierarchy::check_trees`): each is visited once.
    let mut stack: Vec<gltf::Node> = scene.nodes().collect();
    while let Some(node) = stack.pop() {
        if let Some(mesh) = node.mesh().filter(|_| node.skin().is_none()) {
            let copies = declared_instances(json, node.index());
            for (sum, count) in total.iter_mut().zip(mesh_counts(&mesh)) {
                *sum = sum.saturating_add(count.saturating_mul(copies));
            }
        }
        stack.extend(node.children());
    }
    total
}

/// The triangles one drawing of `mesh` holds, the vertices it reads and
/// its triangle primitives, by the declared counts.
fn mesh_counts(mesh: &gltf::Mesh) -> [u64; 3] {
    let primitive_counts = |p: gltf::Primitive| {
        let vertices = p.get(&gltf::Semantic::Positions).map_or(0, |a| a.count() as u64);
        let drawn = p.indices().map_or(vertices, |a| a.count() as u64);
        match p.mode() {
            Mode::Triangles => [drawn / 3, vertices, 1],
            Mode::TriangleStrip | Mode::TriangleFan => [drawn.saturating_sub(2), vertices, 1],
            _ => [0, 0, 0],
        }
    };
    mesh.primitives().map(primitive_counts).fold([0; 3], |a, b| [0, 1, 2].map(|i| a[i].saturating_add(b[i])))
}

/// How many GPU instances (EXT_mesh_gpu_instancing) node `node` declares; 1 without the extension.
fn declared_instances(json: &serde_json::Value, node: usize) -> u64 {
    let pointer = format!("/nodes/{node}/extensions/{}/attributes", instancing::EXTENSION);
    let Some(attributes) = json.pointer(&pointer).and_then(serde_json::Value::as_object) else { return 1 };
    let count = |a: &serde_json::Value| json.pointer(&format!("/accessors/{}/count", a.as_u64()?))?.as_u64();
    attributes.values().find_map(count).unwrap_or(1)
}

fn describe(node: &gltf::Node, mesh: &gltf::Mesh, instance: Option<usize>) -> String {
    let (node_name, mesh_name) = (quoted_name(node.name()), quoted_name(mesh.name()));
    let instance = instance.map(|k| format!(", instance {k}")).unwrap_or_default();
    format!("mesh {}{mesh_name} on node {}{node_name}{instance}", mesh.index(), node.index())
}

/// A primitive as read, with its world positions in f64 until the scene's origin is known.
struct Gathered {
    primitive: ScenePrimitive,
    world: Vec<DVec3>,
    what: String,
}

/// Chooses the scene's origin from the f64 world bounds, stores every
/// position relative to it in f32, and finds each primitive's repeated
/// triangles (with a notice).
fn finish_primitives(gathered: Vec<Gathered>, notices: &mut Vec<String>) -> Result<([f64; 3], Vec<ScenePrimitive>)> {
    check_extent(&gathered)?;
    let mut points = gathered.iter().flat_map(|g| g.world.iter().copied());
    let first = points.next().unwrap_or(DVec3::ZERO);
    let (lo, hi) = points.fold((first, first), |(lo, hi), p| (lo.min(p), hi.max(p)));
    let origin = choose_origin(lo, hi);
    let mut primitives = Vec::with_capacity(gathered.len());
    for Gathered { mut primitive, world, what } in gathered {
        primitive.positions = world.iter().map(|&p| (p - origin).as_vec3().to_array()).collect();
        if let Some(i) = primitive.positions.iter().position(|p| p.iter().any(|c| !c.is_finite())) {
            bail!("{what}: vertex {i} is beyond f32's range from the scene's origin: the node transform overflows");
        }
        primitive.repeats = repeats::find(&primitive.positions, &primitive.indices);
        if !primitive.repeats.is_empty() {
            notices.push(format!(
                "{what}: {} of its {} triangles repeat another of its triangles (same corners, same facing): \
                 each copy shares the first one's lightmap texels",
                primitive.repeats.len(),
                primitive.triangle_count()
            ));
        }
        primitives.push(primitive);
    }
    // Nothing to lay out in a lightmap: refused here, before the unwrap and
    // texelize stages divide by the scene's area.
    if !primitives.iter().any(has_area) {
        bail!("no triangle has any area (the corners of each coincide or lie on one line): nothing to lightmap");
    }
    Ok((origin.to_array(), primitives))
}

/// Refuses a scene longer than [`limits::MAX_SCENE_EXTENT`] along a world
/// axis (a stray vertex, a node scaled by 10³⁰), or whose longest side is
/// under [`limits::MIN_SCENE_EXTENT`] (a node scaled by 10⁻¹²), naming the
/// vertices at both ends: its areas and distances would leave f32's range in
/// the solve. A scene of no extent at all has no area, refused as such later.
fn check_extent(gathered: &[Gathered]) -> Result<()> {
    let spans = [0, 1, 2].map(|axis| axis_span(gathered, axis));
    let refuse = |span: &AxisSpan, what: &str, bound: String| {
        let name = ["x", "y", "z"][span.axis];
        let end = |(at, g, v): (f64, usize, usize)| {
            format!("vertex {v} of {} at {name} = {}", gathered[g].what, limits::figure(at))
        };
        let (extent, low, high) = (limits::figure(span.extent()), end(span.low), end(span.high));
        anyhow!("{what} {extent} m along {name}, {bound}: from {low} to {high}")
    };
    if let Some(long) = spans.iter().find(|span| span.extent() > limits::MAX_SCENE_EXTENT) {
        let bound =
            format!("more than the {:.0e} m bake accepts (f32 headroom, README 'Bad input')", limits::MAX_SCENE_EXTENT);
        return Err(refuse(long, "the scene spans", bound));
    }
    let longest = spans.iter().max_by(|a, b| a.extent().total_cmp(&b.extent())).expect("three axes");
    if longest.extent() > 0.0 && longest.extent() < limits::MIN_SCENE_EXTENT {
        let bound = format!(
            "less than the {:.0e} m bake accepts (glTF lengths are metres; f32 headroom, README 'Bad input')",
            limits::MIN_SCENE_EXTENT
        );
        return Err(refuse(longest, "the scene's longest side spans", bound));
    }
    Ok(())
}

/// The lowest and highest vertex along one world axis, each as
/// (coordinate, primitive, vertex).
struct AxisSpan {
    axis: usize,
    low: (f64, usize, usize),
    high: (f64, usize, usize),
}

impl AxisSpan {
    fn extent(&self) -> f64 {
        self.high.0 - self.low.0
    }
}

fn axis_span(gathered: &[Gathered], axis: usize) -> AxisSpan {
    let mut span = AxisSpan { axis, low: (f64::INFINITY, 0, 0), high: (f64::NEG_INFINITY, 0, 0) };
    for (g, gathered) in gathered.iter().enumerate() {
        for (v, p) in gathered.world.iter().enumerate() {
            if p[axis] < span.low.0 {
                span.low = (p[axis], g, v);
            }
            if p[axis] > span.high.0 {
                span.high = (p[axis], g, v);
            }
        }
    }
    span
}

/// Refuses a used material whose emission (factor × KHR_materials_emissive_strength)
/// is negative, not finite or over [`limits::MAX_LIGHT`], naming it.
fn check_emission(materials: &[Material], used: &[usize]) -> Result<()> {
    for &m in used {
        let material = &materials[m];
        if let Some(&bad) = material.emission.iter().find(|&&e| !limits::light_in_range(f64::from(e))) {
            bail!(
                "material {m} '{}': emission (emissiveFactor × KHR_materials_emissive_strength) {} is not a \
                 radiance bake accepts: finite, ≥ 0 and at most {:.0e} (README 'Bad input')",
                material.name.as_deref().unwrap_or("unnamed"),
                limits::figure(f64::from(bad)),
                limits::MAX_LIGHT
            );
        }
    }
    Ok(())
}

/// Whether any triangle of `primitive` has a non-zero area in f32 positions.
fn has_area(primitive: &ScenePrimitive) -> bool {
    let corner = |i: u32| DVec3::from(primitive.positions[i as usize].map(f64::from));
    primitive.indices.chunks_exact(3).any(|t| {
        let [a, b, c] = [corner(t[0]), corner(t[1]), corner(t[2])];
        (b - a).cross(c - a).length_squared() > 0.0
    })
}

fn collect_mesh(
    source: &SourceAsset,
    left_out: &[Option<String>],
    node: &gltf::Node,
    instance: Option<usize>,
    world: DMat4,
    gathered: &mut Vec<Gathered>,
    notices: &mut Vec<String>,
) -> Result<()> {
    let Some(mesh) = &node.mesh() else { return Ok(()) };
    let what = describe(node, mesh, instance);
    if node.skin().is_some() {
        notices.push(format!("{what} is skinned (not static): left out of the bake"));
        return Ok(());
    }
    let weights = morph::weights(node, mesh).with_context(|| what.clone())?;
    // One notice for a node's instances: they all draw its weights.
    if !weights.is_empty() && instance.unwrap_or(0) == 0 {
        notices.push(format!(
            "{what} has {} morph targets: baked at its weights {weights:?}; the targets are kept, and its lightmap \
             holds for these weights only",
            weights.len()
        ));
    }
    let placed = PlacedMesh { source, node, mesh, instance, world, weights };
    for primitive in mesh.primitives() {
        let what = format!("{what}, primitive {}", primitive.index());
        let mode = primitive.mode();
        if !matches!(mode, Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan) {
            notices.push(format!("{what} draws {mode:?}, not triangles: left out of the bake"));
            continue;
        }
        let Some(position_accessor) = primitive.get(&gltf::Semantic::Positions) else {
            notices.push(format!("{what} has no POSITION attribute: left out of the bake"));
            continue;
        };
        let material =
            material_before_a_bake(&source.json, mesh.index(), primitive.index()).or(primitive.material().index());
        if let Some(notice) = material.and_then(|m| left_out.get(m).cloned().flatten()) {
            // One notice per material, however many panes use it.
            if !notices.contains(&notice) {
                notices.push(notice);
            }
            continue;
        }
        let drawn = primitive.indices().unwrap_or_else(|| position_accessor.clone()).count();
        if mode == Mode::Triangles && drawn % 3 != 0 {
            // The spec asks for whole triangles; engines draw those there are.
            let rest = if drawn % 3 == 1 { "the last vertex is" } else { "the last 2 vertices are" };
            notices.push(format!(
                "{what} draws {drawn} vertices, not a multiple of 3: {} triangles are baked and {rest} left out, \
                 as engines leave them",
                drawn / 3
            ));
        }
        let read = placed.read(&primitive, &position_accessor, material, &what).with_context(|| what.clone())?;
        if read.primitive.indices.is_empty() {
            notices.push(format!("{what} has no triangles: left out of the bake"));
            continue;
        }
        gathered.push(read);
    }
    Ok(())
}

/// One drawing of a mesh: on `node` (GPU `instance`), at `world`, morphed by `weights`.
struct PlacedMesh<'a> {
    source: &'a SourceAsset,
    node: &'a gltf::Node<'a>,
    mesh: &'a gltf::Mesh<'a>,
    instance: Option<usize>,
    world: DMat4,
    weights: Vec<f32>,
}

impl PlacedMesh<'_> {
    /// Reads one triangle primitive's vertices into world space and its indices into a list.
    fn read(
        &self,
        primitive: &gltf::Primitive,
        position_accessor: &gltf::Accessor,
        material: Option<usize>,
        what: &str,
    ) -> Result<Gathered> {
        let local = self.morphed(primitive, "POSITION", position_accessor, 3)?;
        if let Some(i) = local.iter().position(|c| !c.is_finite()) {
            bail!("POSITION {} is not finite ({:?})", i / 3, &local[i / 3 * 3..i / 3 * 3 + 3]);
        }
        let count = local.len() / 3;
        let world: Vec<DVec3> = local
            .chunks_exact(3)
            .map(|p| self.world.transform_point3(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)))
            .collect();
        if let Some(i) = world.iter().position(|p| !p.is_finite()) {
            bail!("world position of vertex {i} is not finite: the node transform overflows");
        }
        let normal_matrix = DMat3::from_mat4(self.world).inverse().transpose();
        let normals = self.attribute(primitive, gltf::Semantic::Normals, "NORMAL", &[3], count)?.map(|(local, _)| {
            local
                .chunks_exact(3)
                .map(|n| {
                    let n = normal_matrix * DVec3::new(n[0] as f64, n[1] as f64, n[2] as f64);
                    // Zero, NaN or infinite normals fall back to the face normal later.
                    n.try_normalize().unwrap_or(DVec3::ZERO).as_vec3().to_array()
                })
                .collect()
        });
        let pairs = |(values, _): (Vec<f32>, usize)| values.chunks_exact(2).map(|c| [c[0], c[1]]).collect();
        let uv0 = self.attribute(primitive, gltf::Semantic::TexCoords(0), "TEXCOORD_0", &[2], count)?.map(pairs);
        let uv1 = self.attribute(primitive, gltf::Semantic::TexCoords(1), "TEXCOORD_1", &[2], count)?.map(pairs);
        let colors = self
            .attribute(primitive, gltf::Semantic::Colors(0), "COLOR_0", &[3, 4], count)?
            .map(|(values, width)| values.chunks_exact(width).map(|c| [c[0], c[1], c[2]]).collect());
        let drawn = match primitive.indices() {
            Some(a) => accessor::read_indices(self.source, &a)?,
            None => (0..count as u32).collect(),
        };
        if let Some(&bad) = drawn.iter().find(|&&i| i as usize >= count) {
            bail!("index {bad} is past the vertex count {count}");
        }
        let indices = triangle_list(primitive.mode(), &drawn);
        let baked = ScenePrimitive {
            node: self.node.index(),
            instance: self.instance,
            mesh: self.mesh.index(),
            primitive: primitive.index(),
            // Filled in by `finish_primitives` once the scene's origin is known.
            positions: Vec::new(),
            repeats: Vec::new(),
            normals,
            uv0,
            uv1,
            colors,
            indices,
            mirrored: DMat3::from_mat4(self.world).determinant() < 0.0,
            material,
            drawn_material: primitive.material().index(),
        };
        Ok(Gathered { primitive: baked, world, what: what.to_string() })
    }

    /// An attribute's `width`-component values, displaced by the morph targets at the weights.
    fn morphed(
        &self,
        primitive: &gltf::Primitive,
        attribute: &str,
        accessor: &gltf::Accessor,
        width: usize,
    ) -> Result<Vec<f32>> {
        let found = accessor.dimensions().multiplicity();
        ensure!(found == width, "{attribute} has {found} components, {width} expected");
        let mut values = accessor::read_floats(self.source, accessor).context(attribute.to_string())?;
        morph::displace(
            self.source,
            self.mesh.index(),
            primitive.index(),
            &self.weights,
            attribute,
            width,
            &mut values,
        )?;
        Ok(values)
    }

    /// An optional vertex attribute, morphed, with its width (one of `widths`); one entry
    /// per each of the `count` positions.
    fn attribute(
        &self,
        primitive: &gltf::Primitive,
        semantic: gltf::Semantic,
        attribute: &str,
        widths: &[usize],
        count: usize,
    ) -> Result<Option<(Vec<f32>, usize)>> {
        let Some(a) = primitive.get(&semantic) else { return Ok(None) };
        let width = a.dimensions().multiplicity();
        if !widths.contains(&width) {
            bail!("{attribute} has {width} components ({widths:?} expected)");
        }
        let values = self.morphed(primitive, attribute, &a, width)?;
        if values.len() != count * width {
            bail!("{attribute} has {} entries for {count} positions", values.len() / width);
        }
        Ok(Some((values, width)))
    }
}

/// Below this fraction of light passing, a surface is baked as opaque; at
/// or above it, as absent. Shadows are all or nothing, so this is the choice
/// nearer the truth either way.
const SEE_THROUGH: f64 = 0.5;

/// The notice for a material that lets most light through, whose
/// primitives are left out of the bake (`None` for any other, and for one
/// that glows): clear glass (KHR_materials_transmission), or a blend whose
/// base colour alpha is under [`SEE_THROUGH`], which a texture or `COLOR_0`
/// can only lower. Left out, a window lets the sun into the room, untinted
/// and without the few percent its faces reflect, and keeps its own
/// material, which viewers draw as glass; baked, it would shut the light
/// out and show as an opaque pane. Reads the material as the bake does
/// (`material`): a specular-glossiness blend's alpha is its diffuse alpha.
fn see_through(json: &serde_json::Value, m: usize, parsed: &Material) -> Option<String> {
    let material = json.pointer(&format!("/materials/{m}"))?;
    let what = format!("material {m} '{}'", parsed.name.as_deref().unwrap_or("unnamed"));
    let after = "its primitives are left out of the bake (light passes them, untinted) and keep their material";
    // A glowing bulb or lamp cover modelled as glass lights the room: it stays.
    if parsed.emission.iter().any(|&e| e > 0.0) {
        return None;
    }
    let transmission = material.pointer("/extensions/KHR_materials_transmission/transmissionFactor");
    let transmission = transmission.and_then(serde_json::Value::as_f64).unwrap_or(0.0);
    if transmission >= SEE_THROUGH {
        let texture = match material.pointer("/extensions/KHR_materials_transmission/transmissionTexture") {
            Some(_) => ", its transmission texture not read",
            None => "",
        };
        return Some(format!(
            "{what} transmits light (KHR_materials_transmission, factor {transmission}{texture}): {after}"
        ));
    }
    let alpha = parsed.base_color[3];
    (parsed.alpha == AlphaMode::Blend && f64::from(alpha) < SEE_THROUGH)
        .then(|| format!("{what} is alpha-blended at alpha {alpha}, mostly see-through: {after}"))
}

/// In a file bake wrote, the material a primitive had before: the one its
/// `pbr+lightmap` variant maps it to. Its default material shows the baked
/// light, which is no albedo to bake again.
fn material_before_a_bake(json: &serde_json::Value, mesh: usize, primitive: usize) -> Option<usize> {
    let variants = json.pointer("/extensions/KHR_materials_variants/variants")?.as_array()?;
    let lightmapped = variants.iter().position(|v| v["name"] == crate::asset::VARIANT_LIGHTMAPPED)?;
    let pointer = format!("/meshes/{mesh}/primitives/{primitive}/extensions/KHR_materials_variants/mappings");
    let mappings = json.pointer(&pointer)?.as_array()?;
    let mapping = mappings
        .iter()
        .find(|m| m["variants"].as_array().is_some_and(|v| v.iter().any(|v| v.as_u64() == Some(lightmapped as u64))))?;
    let material = mapping["material"].as_u64()? as usize;
    json["materials"].get(material).map(|_| material)
}

/// Strips and fans as a plain triangle list, keeping each triangle's facing.
fn triangle_list(mode: Mode, drawn: &[u32]) -> Vec<u32> {
    match mode {
        // glTF spec: strip triangle i is (i, i+1+i%2, i+2-i%2); fan triangle i is (i+1, i+2, 0).
        Mode::TriangleStrip => (0..drawn.len().saturating_sub(2))
            .flat_map(|i| [drawn[i], drawn[i + 1 + i % 2], drawn[i + 2 - i % 2]])
            .collect(),
        Mode::TriangleFan => {
            (0..drawn.len().saturating_sub(2)).flat_map(|i| [drawn[i + 1], drawn[i + 2], drawn[0]]).collect()
        }
        _ => drawn[..drawn.len() - drawn.len() % 3].to_vec(),
    }
}

/// What the bake does not follow in the used materials, one notice each:
/// blending is cut where a texture's alpha is under one half, else baked as
/// opaque, and so is transmission that lets less than [`SEE_THROUGH`] of the
/// light pass (or varies it by a texture); a texture
/// with only an AVIF image as if it were absent.
fn material_notices(source: &SourceAsset, materials: &[Material], used: &[usize]) -> Vec<String> {
    let mut notices = Vec::new();
    for &m in used {
        let name = materials[m].name.as_deref().unwrap_or("unnamed");
        if source.json.pointer(&format!("/materials/{m}/extensions/KHR_materials_unlit")).is_some() {
            notices.push(format!(
                "material {m} '{name}' is unlit (KHR_materials_unlit): its primitives keep it and show its own \
                 colour, as before; in the bake they cast shadows and reflect its base colour"
            ));
        }
        if materials[m].alpha == AlphaMode::Blend {
            notices.push(match materials[m].cutoff() {
                Some(cutoff) => format!(
                    "material {m} '{name}' is alpha-blended: baked as a cut-out, light passes where its alpha is \
                     under {cutoff} and is stopped elsewhere (partial transparency is not baked)"
                ),
                None => format!("material {m} '{name}' is alpha-blended at a constant alpha: baked as opaque"),
            });
        }
        for (extension, factor) in [
            ("KHR_materials_transmission", "transmissionFactor"),
            ("KHR_materials_diffuse_transmission", "diffuseTransmissionFactor"),
        ] {
            let Some(settings) = source.json.pointer(&format!("/materials/{m}/extensions/{extension}")) else {
                continue;
            };
            // A texture alone leaves the factor at 0: nothing is transmitted.
            if settings.get(factor).and_then(serde_json::Value::as_f64).is_some_and(|f| f > 0.0) {
                notices.push(format!(
                    "material {m} '{name}' transmits light ({extension}): baked as opaque, so light that would pass \
                     through it is missing behind it"
                ));
            }
        }
        let material = source.document.materials().nth(m).expect("a used material exists");
        let textures = [("base colour", base_colour(&material).1), ("emissive", material.emissive_texture())];
        for (kind, info) in textures.into_iter().filter_map(|(kind, info)| Some((kind, info?))) {
            let set = texture_set(&info);
            if set > MAX_TEXTURE_SET {
                notices.push(format!(
                    "material {m} '{name}': its {kind} texture {} samples TEXCOORD_{set}, which bake does not read \
                     (only TEXCOORD_0 and TEXCOORD_1): baked with its colour factors alone",
                    info.texture().index()
                ));
            } else if let Err(extension) = texture_image(&source.json, &info.texture()) {
                notices.push(format!(
                    "material {m} '{name}': its {kind} texture {} has only an extension's image ({extension}), \
                     which bake cannot decode: baked with its colour factors alone",
                    info.texture().index()
                ));
            }
        }
    }
    notices
}

fn material(json: &serde_json::Value, m: gltf::Material) -> Material {
    let strength = m.emissive_strength().unwrap_or(1.0);
    let (base_color, base_color_texture) = base_colour(&m);
    Material {
        name: m.name().map(str::to_string),
        base_color,
        base_color_texture: base_color_texture.and_then(|info| texture_ref(json, &info)),
        emission: m.emissive_factor().map(|e| e * strength),
        emissive_texture: m.emissive_texture().and_then(|info| texture_ref(json, &info)),
        alpha: match m.alpha_mode() {
            gltf::material::AlphaMode::Opaque => AlphaMode::Opaque,
            gltf::material::AlphaMode::Mask => AlphaMode::Mask(m.alpha_cutoff().unwrap_or(0.5)),
            gltf::material::AlphaMode::Blend => AlphaMode::Blend,
        },
        double_sided: m.double_sided(),
    }
}

/// The material's base colour factor and texture: the diffuse ones of
/// KHR_materials_pbrSpecularGlossiness where the material has them (what
/// the viewers that read the extension show; an exporter's metal-rough
/// fallback beside it may be anything), else pbrMetallicRoughness's.
fn base_colour<'a>(m: &gltf::Material<'a>) -> ([f32; 4], Option<gltf::texture::Info<'a>>) {
    match m.pbr_specular_glossiness() {
        Some(sg) => (sg.diffuse_factor(), sg.diffuse_texture()),
        None => (m.pbr_metallic_roughness().base_color_factor(), m.pbr_metallic_roughness().base_color_texture()),
    }
}

/// The image a texture samples: its own `source` (PNG or JPEG), else the
/// WebP image of EXT_texture_webp or the KTX2 image of KHR_texture_basisu.
/// Err names the extension whose image is all it has and bake cannot decode
/// (EXT_texture_avif's AVIF).
fn texture_image(json: &serde_json::Value, texture: &gltf::Texture) -> Result<usize, String> {
    if let Some(image) = texture.source() {
        return Ok(image.index());
    }
    let extensions = json.pointer(&format!("/textures/{}/extensions", texture.index()));
    let extensions = extensions.and_then(serde_json::Value::as_object);
    // The asset's load checked that the image exists.
    let decodable = ["EXT_texture_webp", "KHR_texture_basisu"];
    let image = decodable.iter().find_map(|name| extensions?.get(*name)?.get("source")?.as_u64());
    match image {
        Some(image) => Ok(image as usize),
        None => Err(extensions.map(|e| e.keys().cloned().collect::<Vec<_>>().join(", ")).unwrap_or_default()),
    }
}

/// A texture reference with KHR_texture_transform folded into one affine map:
/// uv' = T · R · S · uv (the extension's order), R turning by `rotation`
/// as the extension's reference code does. `None` for a texture whose only
/// image bake cannot decode (see `texture_image`).
fn texture_ref(json: &serde_json::Value, info: &gltf::texture::Info) -> Option<TextureRef> {
    let sampler = info.texture().sampler();
    let wrap = [sampler.wrap_s().as_gl_enum(), sampler.wrap_t().as_gl_enum()];
    let mut transform = TextureRef::IDENTITY;
    if let Some(t) = info.texture_transform() {
        let [ox, oy] = t.offset();
        let [sx, sy] = t.scale();
        let (sin, cos) = t.rotation().sin_cos();
        transform = [[cos * sx, -sin * sy, ox], [sin * sx, cos * sy, oy]];
    }
    let tex_coord = Some(texture_set(info)).filter(|&set| set <= MAX_TEXTURE_SET)?;
    Some(TextureRef { image: texture_image(json, &info.texture()).ok()?, tex_coord, transform, wrap })
}

/// The highest TEXCOORD_n a material texture can sample in the bake: the
/// scene keeps sets 0 and 1 only. A texture on a later set is baked as
/// absent (with a notice), not through another set's coordinates.
const MAX_TEXTURE_SET: u32 = 1;

/// The TEXCOORD set a texture samples: its `texCoord`, or
/// KHR_texture_transform's override of it.
fn texture_set(info: &gltf::texture::Info) -> u32 {
    info.texture_transform().and_then(|t| t.tex_coord()).unwrap_or(info.tex_coord())
}

/// Decodes every image a baked primitive's material samples, into linear
/// RGB (from sRGB, as glTF stores colour textures) and linear alpha.
fn decode_images(
    source: &SourceAsset,
    scene_materials: &[Material],
    used: &[usize],
) -> (Vec<Option<Arc<LinearImage>>>, Vec<String>) {
    let mut notices = Vec::new();
    let mut wanted = vec![false; source.document.images().len()];
    for &m in used {
        let material = &scene_materials[m];
        for texture in [&material.base_color_texture, &material.emissive_texture].into_iter().flatten() {
            if let Some(w) = wanted.get_mut(texture.image) {
                *w = true;
            }
        }
    }
    let images = wanted
        .iter()
        .enumerate()
        .map(|(i, &wanted)| {
            if !wanted {
                return None;
            }
            let decoded = source.image_bytes(i).and_then(|(bytes, _)| decode_image(&bytes));
            match decoded {
                Ok(image) => Some(Arc::new(linear_image(&image))),
                Err(e) => {
                    notices.push(format!(
                        "image {i} could not be decoded ({e:#}): its material is baked with its colour factors alone"
                    ));
                    None
                }
            }
        })
        .collect();
    (images, notices)
}

/// One material image as RGBA8, refused before decoding when its header
/// declares more texels than [`limits::MAX_IMAGE_SQUARE`]².
fn decode_image(bytes: &[u8]) -> Result<image::RgbaImage> {
    let ktx2 = ktx2::is_ktx2(bytes);
    let (width, height) = match ktx2 {
        true => ktx2::dimensions(bytes)?,
        false => image::ImageReader::new(std::io::Cursor::new(bytes)).with_guessed_format()?.into_dimensions()?,
    };
    let side = limits::MAX_IMAGE_SQUARE;
    if u64::from(width) * u64::from(height) > side * side {
        bail!("it is {width}×{height} texels, more than a {side}×{side} image, the most bake decodes");
    }
    match ktx2 {
        true => ktx2::decode(bytes),
        false => Ok(image::load_from_memory(bytes).map_err(|e| anyhow!("{e}"))?.to_rgba8()),
    }
}

fn linear_image(rgba: &image::RgbaImage) -> LinearImage {
    let lut: Vec<f32> = (0..256)
        .map(|v| {
            let c = v as f32 / 255.0;
            if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
        })
        .collect();
    LinearImage {
        width: rgba.width(),
        height: rgba.height(),
        pixels: rgba
            .pixels()
            .map(|p| [lut[p[0] as usize], lut[p[1] as usize], lut[p[2] as usize], p[3] as f32 / 255.0])
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strips_alternate_winding() {
        assert_eq!(triangle_list(Mode::TriangleStrip, &[0, 1, 2, 3]), vec![0, 1, 2, 1, 3, 2]);
    }

    #[test]
    fn fans_share_the_first_vertex() {
        // glTF spec: fan triangle i is (i+1, i+2, 0).
        assert_eq!(triangle_list(Mode::TriangleFan, &[0, 1, 2, 3]), vec![1, 2, 0, 2, 3, 0]);
    }
}
