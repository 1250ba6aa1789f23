//! Procedural scenes with known answers, for tests, examples and
//! benchmarks. Everything in `fixtures/` is written by
//! `cargo run --example make_fixtures` from these functions, so no fixture is
//! a blob that cannot be regenerated.

use glam::{Quat, Vec3};
use image::ExtendedColorType::Rgba8;
use serde_json::{Value, json};

/// An indexed triangle mesh with normals and TEXCOORD_0.
#[derive(Clone, Debug, Default)]
pub struct MeshData {
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    pub uv0: Vec<[f32; 2]>,
    pub indices: Vec<u32>,
}

impl MeshData {
    /// A UV sphere of `radius` around the origin, counter-clockwise seen from outside.
    pub fn sphere(radius: f32, segments: u32, rings: u32) -> MeshData {
        let mut mesh = MeshData::default();
        for r in 0..=rings {
            let theta = r as f32 / rings as f32 * std::f32::consts::PI;
            for s in 0..=segments {
                let phi = s as f32 / segments as f32 * std::f32::consts::TAU;
                let n = Vec3::new(theta.sin() * phi.cos(), theta.cos(), -theta.sin() * phi.sin());
                mesh.positions.push((n * radius).to_array());
                mesh.normals.push(n.to_array());
                mesh.uv0.push([s as f32 / segments as f32, r as f32 / rings as f32]);
            }
        }
        let row = segments + 1;
        for r in 0..rings {
            for s in 0..segments {
                let a = r * row + s;
                let b = a + row;
                if r != 0 {
                    mesh.indices.extend_from_slice(&[a, b, a + 1]);
                }
                if r != rings - 1 {
                    mesh.indices.extend_from_slice(&[a + 1, b, b + 1]);
                }
            }
        }
        mesh
    }

    /// A torus around the Y axis (ring radius `major`, tube radius `minor`),
    /// counter-clockwise seen from outside; its UV0 seams duplicate vertices.
    pub fn torus(major: f32, minor: f32, segments: u32, sides: u32) -> MeshData {
        let mut mesh = MeshData::default();
        for i in 0..=segments {
            let phi = i as f32 / segments as f32 * std::f32::consts::TAU;
            let ring = Vec3::new(phi.cos(), 0.0, -phi.sin());
            for j in 0..=sides {
                let theta = j as f32 / sides as f32 * std::f32::consts::TAU;
                let n = ring * theta.cos() + Vec3::Y * theta.sin();
                mesh.positions.push((ring * major + n * minor).to_array());
                mesh.normals.push(n.to_array());
                mesh.uv0.push([i as f32 / segments as f32, j as f32 / sides as f32]);
            }
        }
        let row = sides + 1;
        for i in 0..segments {
            for j in 0..sides {
                let a = i * row + j;
                let b = a + row;
                mesh.indices.extend_from_slice(&[a, b, a + 1, a + 1, b, b + 1]);
            }
        }
        mesh
    }

    /// A flat `width`×`depth` rectangle in the XZ plane facing +Y, centred on
    /// the origin, split into `cells`×`cells` quads.
    pub fn plane(width: f32, depth: f32, cells: u32) -> MeshData {
        let mut mesh = MeshData::default();
        let cells = cells.max(1);
        for j in 0..=cells {
            for i in 0..=cells {
                let (u, v) = (i as f32 / cells as f32, j as f32 / cells as f32);
                mesh.positions.push([(u - 0.5) * width, 0.0, (v - 0.5) * depth]);
                mesh.normals.push([0.0, 1.0, 0.0]);
                mesh.uv0.push([u, v]);
            }
        }
        let row = cells + 1;
        for j in 0..cells {
            for i in 0..cells {
                let a = j * row + i;
                mesh.indices.extend_from_slice(&[a, a + row, a + 1, a + 1, a + row, a + row + 1]);
            }
        }
        mesh
    }

    /// An axis-aligned box of the given size centred on the origin, with
    /// outward normals (24 vertices; each face its own quad).
    pub fn cuboid(size: [f32; 3]) -> MeshData {
        Self::cuboid_facing(size, false)
    }

    /// The inside of a box: faces point inwards (a closed room).
    pub fn room(size: [f32; 3]) -> MeshData {
        Self::cuboid_facing(size, true)
    }

    fn cuboid_facing(size: [f32; 3], inward: bool) -> MeshData {
        let half = Vec3::from(size) * 0.5;
        let mut mesh = MeshData::default();
        let faces = [Vec3::X, Vec3::NEG_X, Vec3::Y, Vec3::NEG_Y, Vec3::Z, Vec3::NEG_Z];
        for n in faces {
            let (u, v) = if n.y.abs() > 0.5 { (Vec3::X, Vec3::Z) } else { (n.cross(Vec3::Y).normalize(), Vec3::Y) };
            let base = mesh.positions.len() as u32;
            for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                let p = (n + u * a + v * b) * half;
                mesh.positions.push(p.to_array());
                mesh.normals.push(if inward { (-n).to_array() } else { n.to_array() });
                mesh.uv0.push([(a + 1.0) * 0.5, (b + 1.0) * 0.5]);
            }
            // Counter-clockwise seen from the side the normal points to.
            let outward = (u * 2.0).cross(v * 2.0).dot(n) > 0.0;
            let quad = if outward != inward { [0, 1, 2, 0, 2, 3] } else { [0, 2, 1, 0, 3, 2] };
            mesh.indices.extend(quad.iter().map(|i| base + i));
        }
        mesh
    }
    /// A closed, statue-like blob about 1 m tall standing on y = 0: a geodesic sphere of
    /// `frequency` (each icosahedron edge cut into that many segments: 10·f² + 2 vertices,
    /// 20·f² triangles) pushed out into a lumpy, bunny-ish body with two ear-like bulges, its
    /// lowest 2 % cut flat as a base. `variant` shifts the bumps and the ears, so several
    /// statues differ. The surface stays star-shaped about its centre, so it never intersects
    /// itself. A procedural stand-in for the seed paper's scanned bunnies (benchmarks).
    pub fn statue(frequency: u32, variant: u32) -> MeshData {
        let mut mesh = MeshData::geodesic_sphere(frequency);
        let v = variant as f32;
        let (phase, ear_x, ear_y) = (1.7 * v, 0.30 + 0.08 * v, 0.80 - 0.05 * v);
        for p in &mut mesh.positions {
            let [x, y, z] = *p;
            let bumps = 0.06 * (7.0 * x + 1.3 + phase).sin() * (5.0 * y).cos() * (6.0 * z + 0.7).sin()
                + 0.03 * (13.0 * x + 17.0 * y + phase).sin() * (11.0 * z).cos()
                + 0.012 * (31.0 * y + 29.0 * z).sin() * (23.0 * x + phase).cos();
            let ear = |dx: f32| {
                let d = (x - dx) * (x - dx) + (y - ear_y) * (y - ear_y) + z * z;
                0.55 * (-d * 9.0).exp()
            };
            let r = 1.0 + bumps + ear(ear_x) + ear(-ear_x);
            *p = [0.42 * r * x, 0.45 * r * y, 0.35 * r * z];
        }
        let (lo, hi) =
            mesh.positions.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), p| (lo.min(p[1]), hi.max(p[1])));
        let base = lo + 0.02 * (hi - lo);
        for p in &mut mesh.positions {
            p[1] = p[1].max(base) - base;
        }
        mesh.normals = vertex_normals(&mesh.positions, &mesh.indices);
        mesh
    }

    /// Adds `other`, placed by `placement`, to this mesh: one mesh of
    /// several parts, as exporters often merge them.
    pub fn append(&mut self, other: &MeshData, placement: Placement) {
        let base = self.positions.len() as u32;
        let Placement { translation, rotation, scale } = placement;
        for p in &other.positions {
            self.positions.push((rotation * (Vec3::from(*p) * scale) + translation).to_array());
        }
        for n in &other.normals {
            self.normals.push((rotation * (Vec3::from(*n) / scale)).normalize_or_zero().to_array());
        }
        self.uv0.extend_from_slice(&other.uv0);
        self.indices.extend(other.indices.iter().map(|i| i + base));
    }

    /// A unit geodesic sphere: the icosahedron with each edge cut into `frequency` segments
    /// (10·f² + 2 vertices, 20·f² triangles), projected onto the sphere, shared vertices welded,
    /// counter-clockwise seen from outside. TEXCOORD_0 is each vertex's (longitude, latitude).
    pub fn geodesic_sphere(frequency: u32) -> MeshData {
        use std::collections::HashMap;
        let t = (1.0 + 5.0f32.sqrt()) / 2.0;
        let mut corners = Vec::new();
        for (a, b) in [(1.0, t), (-1.0, t), (1.0, -t), (-1.0, -t)] {
            corners.extend([Vec3::new(a, b, 0.0), Vec3::new(0.0, a, b), Vec3::new(b, 0.0, a)]);
        }
        // The 20 faces: triples of corners at mutual distance 2 (the edge length), outward.
        let edge = |a: usize, b: usize| ((corners[a] - corners[b]).length() - 2.0).abs() < 1e-3;
        let mut faces = Vec::new();
        for i in 0..12 {
            for j in i + 1..12 {
                for k in j + 1..12 {
                    if edge(i, j) && edge(j, k) && edge(i, k) {
                        let (a, b, c) = (corners[i], corners[j], corners[k]);
                        let outward = (b - a).cross(c - a).dot(a + b + c) > 0.0;
                        faces.push(if outward { [i, j, k] } else { [i, k, j] });
                    }
                }
            }
        }
        let n = frequency.max(1);
        // A point is keyed by its corners and integer weights (summing to n), so the points
        // that faces share on edges and corners become one vertex.
        let mut welded: HashMap<Vec<(usize, u32)>, u32> = HashMap::new();
        let mut points: Vec<Vec3> = Vec::new();
        let mut indices = Vec::new();
        for face in &faces {
            let mut id = |i: u32, j: u32| -> u32 {
                let mut key: Vec<(usize, u32)> =
                    [(face[0], n - i - j), (face[1], i), (face[2], j)].into_iter().filter(|&(_, w)| w > 0).collect();
                key.sort_unstable();
                *welded.entry(key).or_insert_with_key(|key| {
                    points.push(key.iter().map(|&(c, w)| corners[c] * w as f32).sum::<Vec3>().normalize());
                    points.len() as u32 - 1
                })
            };
            for i in 0..n {
                for j in 0..n - i {
                    indices.extend([id(i, j), id(i + 1, j), id(i, j + 1)]);
                    if i + j + 1 < n {
                        indices.extend([id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]);
                    }
                }
            }
        }
        let uv = |d: &Vec3| {
            let u = 0.5 + d.z.atan2(d.x) / std::f32::consts::TAU;
            [u, d.y.clamp(-1.0, 1.0).acos() / std::f32::consts::PI]
        };
        MeshData {
            positions: points.iter().map(|d| d.to_array()).collect(),
            normals: points.iter().map(|d| d.to_array()).collect(),
            uv0: points.iter().map(uv).collect(),
            indices,
        }
    }
}

/// Area-weighted vertex normals of an indexed triangle mesh (counter-clockwise
/// triangles face the way their normals point).
pub fn vertex_normals(positions: &[[f32; 3]], indices: &[u32]) -> Vec<[f32; 3]> {
    let mut normals = vec![Vec3::ZERO; positions.len()];
    for tri in indices.chunks_exact(3) {
        let [a, b, c] = [0, 1, 2].map(|k| Vec3::from(positions[tri[k] as usize]));
        let n = (b - a).cross(c - a);
        for &v in tri {
            normals[v as usize] += n;
        }
    }
    normals.iter().map(|n| n.normalize_or(Vec3::Y).to_array()).collect()
}

/// A node's placement: translation, rotation, uniform or per-axis scale.
#[derive(Clone, Copy, Debug)]
pub struct Placement {
    pub translation: Vec3,
    pub rotation: Quat,
    pub scale: Vec3,
}

impl Default for Placement {
    fn default() -> Self {
        Placement { translation: Vec3::ZERO, rotation: Quat::IDENTITY, scale: Vec3::ONE }
    }
}

impl Placement {
    pub fn at(translation: Vec3) -> Placement {
        Placement { translation, ..Default::default() }
    }
    pub fn rotated(mut self, rotation: Quat) -> Placement {
        self.rotation = rotation;
        self
    }
    pub fn scaled(mut self, scale: Vec3) -> Placement {
        self.scale = scale;
        self
    }
}

/// Builds a small glTF asset in memory: meshes, materials and nodes of one scene.
#[derive(Default)]
pub struct SceneBuilder {
    binary: Vec<u8>,
    buffer_views: Vec<Value>,
    accessors: Vec<Value>,
    meshes: Vec<Value>,
    materials: Vec<Value>,
    nodes: Vec<Value>,
    images: Vec<Value>,
    textures: Vec<Value>,
    samplers: Vec<Value>,
    animations: Vec<Value>,
    lights: Vec<Value>,
}

impl SceneBuilder {
    pub fn new() -> SceneBuilder {
        SceneBuilder::default()
    }

    /// A PBR material with the given base colour (linear RGBA) and emission.
    pub fn material(&mut self, name: &str, base_color: [f32; 4], emission: [f32; 3]) -> usize {
        let mut material = json!({
            "name": name,
            "pbrMetallicRoughness": { "baseColorFactor": base_color, "metallicFactor": 0.0, "roughnessFactor": 1.0 },
        });
        let peak = emission.iter().cloned().fold(0.0f32, f32::max);
        if peak > 0.0 {
            // emissiveFactor is limited to [0, 1]; the rest goes into KHR_materials_emissive_strength.
            let strength = peak.max(1.0);
            material["emissiveFactor"] = json!(emission.map(|e| e / strength));
            if strength > 1.0 {
                material["extensions"] = json!({ "KHR_materials_emissive_strength": { "emissiveStrength": strength } });
            }
        }
        self.materials.push(material);
        self.materials.len() - 1
    }

    fn push_view(&mut self, bytes: &[u8], target: Option<u32>) -> usize {
        while !self.binary.len().is_multiple_of(4) {
            self.binary.push(0);
        }
        let mut view = json!({ "buffer": 0, "byteOffset": self.binary.len(), "byteLength": bytes.len() });
        if let Some(target) = target {
            view["target"] = json!(target);
        }
        self.binary.extend_from_slice(bytes);
        self.buffer_views.push(view);
        self.buffer_views.len() - 1
    }

    fn push_floats<const N: usize>(&mut self, values: &[[f32; N]], kind: &str, bounds: bool) -> usize {
        let view = self.push_view(bytemuck::cast_slice(values), Some(34962));
        let mut accessor = json!({ "bufferView": view, "componentType": 5126, "count": values.len(), "type": kind });
        if bounds {
            let mut lo = [f32::INFINITY; N];
            let mut hi = [f32::NEG_INFINITY; N];
            for v in values {
                for c in 0..N {
                    lo[c] = lo[c].min(v[c]);
                    hi[c] = hi[c].max(v[c]);
                }
            }
            accessor["min"] = json!(lo.to_vec());
            accessor["max"] = json!(hi.to_vec());
        }
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    /// Adds a mesh with one primitive and returns its index.
    pub fn mesh(&mut self, name: &str, data: &MeshData, material: Option<usize>) -> usize {
        let position = self.push_floats(&data.positions, "VEC3", true);
        let mut attributes = json!({ "POSITION": position });
        if !data.normals.is_empty() {
            attributes["NORMAL"] = json!(self.push_floats(&data.normals, "VEC3", false));
        }
        if !data.uv0.is_empty() {
            attributes["TEXCOORD_0"] = json!(self.push_floats(&data.uv0, "VEC2", false));
        }
        let view = self.push_view(bytemuck::cast_slice(&data.indices), Some(34963));
        self.accessors
            .push(json!({ "bufferView": view, "componentType": 5125, "count": data.indices.len(), "type": "SCALAR" }));
        let mut primitive = json!({ "attributes": attributes, "indices": self.accessors.len() - 1 });
        if let Some(material) = material {
            primitive["material"] = json!(material);
        }
        self.meshes.push(json!({ "name": name, "primitives": [primitive] }));
        self.meshes.len() - 1
    }

    /// Gives every primitive of `mesh` the vertex colours `colors` (COLOR_0,
    /// float RGB, one per vertex).
    pub fn vertex_colors(&mut self, mesh: usize, colors: &[[f32; 3]]) {
        let accessor = self.push_floats(colors, "VEC3", false);
        for primitive in self.meshes[mesh]["primitives"].as_array_mut().expect("primitives") {
            primitive["attributes"]["COLOR_0"] = json!(accessor);
        }
    }

    /// Appends a morph target to every primitive of `mesh` that displaces
    /// `attribute` (`POSITION`, `NORMAL`, `TEXCOORD_0`, `COLOR_0`, ...) by
    /// `displacements`, one per vertex; returns the target's index.
    pub fn morph_target<const N: usize>(&mut self, mesh: usize, attribute: &str, displacements: &[[f32; N]]) -> usize {
        let kind = ["SCALAR", "VEC2", "VEC3", "VEC4"][N - 1];
        // The spec asks for bounds on POSITION displacements.
        let accessor = self.push_floats(displacements, kind, attribute == "POSITION");
        let mut index = 0;
        for primitive in self.meshes[mesh]["primitives"].as_array_mut().expect("primitives") {
            let targets = primitive.as_object_mut().unwrap().entry("targets").or_insert_with(|| json!([]));
            let targets = targets.as_array_mut().unwrap();
            targets.push(json!({ attribute: accessor }));
            index = targets.len() - 1;
        }
        index
    }

    /// Sets the default morph weights of `mesh`.
    pub fn mesh_weights(&mut self, mesh: usize, weights: &[f32]) {
        self.meshes[mesh]["weights"] = json!(weights);
    }

    /// Sets the morph weights `node` draws its mesh with.
    pub fn node_weights(&mut self, node: usize, weights: &[f32]) {
        self.nodes[node]["weights"] = json!(weights);
    }

    /// Adds an animation that moves `node`'s morph weights linearly through
    /// `keys` (time in seconds, then one weight per target).
    pub fn animate_weights(&mut self, node: usize, keys: &[(f32, Vec<f32>)]) {
        let times: Vec<[f32; 1]> = keys.iter().map(|(t, _)| [*t]).collect();
        let values: Vec<[f32; 1]> = keys.iter().flat_map(|(_, w)| w.iter().map(|&w| [w])).collect();
        let (input, output) = (self.push_floats(&times, "SCALAR", true), self.push_floats(&values, "SCALAR", false));
        for accessor in [input, output] {
            // Animation data must not sit in vertex buffer views.
            let view = self.accessors[accessor]["bufferView"].as_u64().unwrap() as usize;
            self.buffer_views[view].as_object_mut().unwrap().remove("target");
        }
        self.animations.push(json!({
            "channels": [{ "sampler": 0, "target": { "node": node, "path": "weights" } }],
            "samplers": [{ "input": input, "output": output }],
        }));
    }

    /// Adds a root node drawing `mesh` at `placement`.
    pub fn node(&mut self, name: &str, mesh: usize, placement: Placement) -> usize {
        self.placed(json!({ "name": name, "mesh": mesh }), placement)
    }

    /// Adds a KHR_lights_punctual light (`light`: its object, such as
    /// `{"type": "point", "intensity": 10.0}`) on a root node at `placement`,
    /// which it shines from along the node's −Z; returns the node's index.
    pub fn light(&mut self, name: &str, light: Value, placement: Placement) -> usize {
        self.lights.push(light);
        let node = json!({ "name": name, "extensions": { "KHR_lights_punctual": { "light": self.lights.len() - 1 } } });
        self.placed(node, placement)
    }

    /// Adds `node` as a root node with `placement`'s transform; returns its index.
    fn placed(&mut self, mut node: Value, placement: Placement) -> usize {
        if placement.translation != Vec3::ZERO {
            node["translation"] = json!(placement.translation.to_array());
        }
        if placement.rotation != Quat::IDENTITY {
            node["rotation"] = json!(placement.rotation.to_array());
        }
        if placement.scale != Vec3::ONE {
            node["scale"] = json!(placement.scale.to_array());
        }
        self.nodes.push(node);
        self.nodes.len() - 1
    }

    /// Adds a root node at `placement` drawing `mesh` once per instance
    /// (EXT_mesh_gpu_instancing), each instance placed relative to the node;
    /// each instance's index is its `_ID` attribute.
    pub fn instanced_node(&mut self, name: &str, mesh: usize, placement: Placement, instances: &[Placement]) -> usize {
        let node = self.node(name, mesh, placement);
        let mut attribute = |values: Vec<f32>, component_type: u32, kind: &str| {
            // Instance attributes are no vertex data: their views have no target.
            let view = self.push_view(bytemuck::cast_slice(&values), None);
            let accessor =
                json!({ "bufferView": view, "componentType": component_type, "count": instances.len(), "type": kind });
            self.accessors.push(accessor);
            self.accessors.len() - 1
        };
        let translation = attribute(instances.iter().flat_map(|i| i.translation.to_array()).collect(), 5126, "VEC3");
        let rotation = attribute(instances.iter().flat_map(|i| i.rotation.to_array()).collect(), 5126, "VEC4");
        let scale = attribute(instances.iter().flat_map(|i| i.scale.to_array()).collect(), 5126, "VEC3");
        let id = attribute((0..instances.len()).map(|i| i as f32).collect(), 5126, "SCALAR");
        self.nodes[node]["extensions"] = json!({ "EXT_mesh_gpu_instancing": { "attributes": {
            "TRANSLATION": translation, "ROTATION": rotation, "SCALE": scale, "_ID": id,
        } } });
        node
    }

    /// Convenience: a mesh with a material, drawn by one node.
    pub fn object(
        &mut self,
        name: &str,
        data: &MeshData,
        base_color: [f32; 4],
        emission: [f32; 3],
        placement: Placement,
    ) -> usize {
        let material = self.material(name, base_color, emission);
        let mesh = self.mesh(name, data, Some(material));
        self.node(name, mesh, placement)
    }

    /// Adds an sRGB RGBA image as an embedded PNG texture with the given
    /// wrap mode (glTF code) for both axes; returns the texture index.
    pub fn png_texture(&mut self, image: &image::RgbaImage, wrap: u32) -> usize {
        let mut png = Vec::new();
        let encoder = image::codecs::png::PngEncoder::new(&mut png);
        image::ImageEncoder::write_image(encoder, image.as_raw(), image.width(), image.height(), Rgba8)
            .expect("PNG encodes");
        let image = self.embedded_image(&png, "image/png");
        self.texture(json!({ "source": image }), wrap)
    }

    /// Adds an sRGB RGBA image as an embedded lossless WebP that only
    /// EXT_texture_webp names (no PNG fallback), as glTF-Transform's `webp`
    /// command writes it; returns the texture index.
    pub fn webp_texture(&mut self, image: &image::RgbaImage, wrap: u32) -> usize {
        let mut webp = Vec::new();
        let encoder = image::codecs::webp::WebPEncoder::new_lossless(&mut webp);
        image::ImageEncoder::write_image(encoder, image.as_raw(), image.width(), image.height(), Rgba8)
            .expect("WebP encodes");
        let image = self.embedded_image(&webp, "image/webp");
        self.texture(json!({ "extensions": { "EXT_texture_webp": { "source": image } } }), wrap)
    }

    /// Adds a KTX2 file (Basis Universal, encoded elsewhere: bake has no
    /// encoder) as an embedded image that only KHR_texture_basisu names (no
    /// PNG fallback), as gltfpack `-tc` writes it; returns the texture index.
    pub fn ktx2_texture(&mut self, ktx2: &[u8], wrap: u32) -> usize {
        let image = self.embedded_image(ktx2, "image/ktx2");
        self.texture(json!({ "extensions": { "KHR_texture_basisu": { "source": image } } }), wrap)
    }

    fn embedded_image(&mut self, bytes: &[u8], mime: &str) -> usize {
        let view = self.push_view(bytes, None);
        self.images.push(json!({ "bufferView": view, "mimeType": mime }));
        self.images.len() - 1
    }

    /// Adds `texture` (its image source set) with a sampler of wrap mode
    /// `wrap` for both axes and linear filtering; returns its index.
    fn texture(&mut self, mut texture: Value, wrap: u32) -> usize {
        self.samplers.push(json!({ "magFilter": 9729, "minFilter": 9987, "wrapS": wrap, "wrapT": wrap }));
        texture["sampler"] = json!(self.samplers.len() - 1);
        self.textures.push(texture);
        self.textures.len() - 1
    }

    /// Multiplies `material`'s base colour by `texture` through TEXCOORD_0,
    /// optionally with a KHR_texture_transform object.
    pub fn base_color_texture(&mut self, material: usize, texture: usize, transform: Option<Value>) {
        let mut info = json!({ "index": texture });
        if let Some(transform) = transform {
            info["extensions"] = json!({ "KHR_texture_transform": transform });
        }
        self.materials[material]["pbrMetallicRoughness"]["baseColorTexture"] = info;
    }

    /// Makes `material` a specular-glossiness one
    /// (KHR_materials_pbrSpecularGlossiness) whose diffuse colour is
    /// `diffuse`, times `texture` when given, and leaves its metal-rough
    /// fallback white, as some exporters did.
    pub fn specular_glossiness(&mut self, material: usize, diffuse: [f32; 4], texture: Option<usize>) {
        let mut extension = json!({ "diffuseFactor": diffuse, "specularFactor": [0.04, 0.04, 0.04] });
        if let Some(texture) = texture {
            extension["diffuseTexture"] = json!({ "index": texture });
        }
        let material = &mut self.materials[material];
        material["pbrMetallicRoughness"] = json!({ "baseColorFactor": [1.0, 1.0, 1.0, 1.0] });
        let extensions = material.as_object_mut().unwrap().entry("extensions").or_insert_with(|| json!({}));
        extensions["KHR_materials_pbrSpecularGlossiness"] = extension;
    }

    /// Sets `material`'s emitted radiance (linear RGB, any magnitude).
    pub fn set_emission(&mut self, material: usize, emission: [f32; 3]) {
        let strength = emission.iter().cloned().fold(1.0f32, f32::max);
        self.materials[material]["emissiveFactor"] = json!(emission.map(|e| e / strength));
        if strength > 1.0 {
            self.materials[material]["extensions"] =
                json!({ "KHR_materials_emissive_strength": { "emissiveStrength": strength } });
        }
    }

    /// Multiplies `material`'s emission by `texture` through TEXCOORD_0.
    pub fn emissive_texture(&mut self, material: usize, texture: usize) {
        self.materials[material]["emissiveTexture"] = json!({ "index": texture });
    }

    /// Makes `material` an alpha cut-out (alphaMode MASK) at `cutoff`.
    pub fn alpha_mask(&mut self, material: usize, cutoff: f32) {
        self.materials[material]["alphaMode"] = json!("MASK");
        self.materials[material]["alphaCutoff"] = json!(cutoff);
    }

    /// Makes `material` transmit `factor` of the light through it, as
    /// clear glass does (KHR_materials_transmission).
    pub fn transmission(&mut self, material: usize, factor: f32) {
        let material = &mut self.materials[material];
        let extensions = material.as_object_mut().unwrap().entry("extensions").or_insert_with(|| json!({}));
        extensions["KHR_materials_transmission"] = json!({ "transmissionFactor": factor });
    }

    /// Makes `material` alpha-blended (alphaMode BLEND), at the alpha of
    /// its base colour.
    pub fn alpha_blend(&mut self, material: usize) {
        self.materials[material]["alphaMode"] = json!("BLEND");
    }

    /// Takes `material`'s base colour texture away.
    pub fn clear_base_color_texture(&mut self, material: usize) {
        if let Some(pbr) = self.materials[material]["pbrMetallicRoughness"].as_object_mut() {
            pbr.remove("baseColorTexture");
        }
    }

    /// Sets the alpha of `material`'s base colour factor.
    pub fn set_base_color_alpha(&mut self, material: usize, alpha: f32) {
        self.materials[material]["pbrMetallicRoughness"]["baseColorFactor"][3] = json!(alpha);
    }

    fn document(&self) -> Value {
        let mut extensions_used = Vec::new();
        for extension in
            ["KHR_materials_emissive_strength", "KHR_materials_pbrSpecularGlossiness", "KHR_materials_transmission"]
        {
            if self.materials.iter().any(|m| m.pointer(&format!("/extensions/{extension}")).is_some()) {
                extensions_used.push(extension);
            }
        }
        if self.materials.iter().any(|m| m.pointer("/pbrMetallicRoughness/baseColorTexture/extensions").is_some()) {
            extensions_used.push("KHR_texture_transform");
        }
        if self.nodes.iter().any(|n| n.pointer("/extensions/EXT_mesh_gpu_instancing").is_some()) {
            extensions_used.push("EXT_mesh_gpu_instancing");
        }
        if !self.lights.is_empty() {
            extensions_used.push("KHR_lights_punctual");
        }
        let mut extensions_required = Vec::new();
        for extension in ["EXT_texture_webp", "KHR_texture_basisu"] {
            if self.textures.iter().any(|t| t.pointer(&format!("/extensions/{extension}")).is_some()) {
                extensions_used.push(extension);
                extensions_required.push(extension);
            }
        }
        let mut doc = json!({
            "asset": { "version": "2.0", "generator": "bake fixtures" },
            "scene": 0,
            "scenes": [{ "nodes": (0..self.nodes.len()).collect::<Vec<_>>() }],
            "nodes": self.nodes,
            "meshes": self.meshes,
            "materials": self.materials,
            "accessors": self.accessors,
            "bufferViews": self.buffer_views,
            "buffers": [{ "byteLength": self.binary.len() }],
        });
        if !extensions_used.is_empty() {
            doc["extensionsUsed"] = json!(extensions_used);
        }
        if !extensions_required.is_empty() {
            doc["extensionsRequired"] = json!(extensions_required);
        }
        if !self.animations.is_empty() {
            doc["animations"] = json!(self.animations);
        }
        if !self.lights.is_empty() {
            doc["extensions"] = json!({ "KHR_lights_punctual": { "lights": self.lights } });
        }
        if !self.images.is_empty() {
            doc["images"] = json!(self.images);
            doc["textures"] = json!(self.textures);
            doc["samplers"] = json!(self.samplers);
        }
        doc
    }

    /// The asset as a `.glb` file.
    pub fn to_glb(&self) -> Vec<u8> {
        let json = serde_json::to_vec(&self.document()).expect("fixture JSON serializes");
        crate::export::glb::encode(&json, &self.binary)
    }
}

/// A closed 2×2×2 m room whose six walls are separate quads facing inwards,
/// with (albedo, emission) per wall: floor, ceiling, −X, +X, −Z, +Z.
pub fn six_wall_room(walls: [(f32, f32); 6]) -> SceneBuilder {
    let mut builder = SceneBuilder::new();
    let placements = [
        (Quat::IDENTITY, Vec3::new(0.0, -1.0, 0.0)),
        (Quat::from_rotation_x(180f32.to_radians()), Vec3::new(0.0, 1.0, 0.0)),
        (Quat::from_rotation_z(-90f32.to_radians()), Vec3::new(-1.0, 0.0, 0.0)),
        (Quat::from_rotation_z(90f32.to_radians()), Vec3::new(1.0, 0.0, 0.0)),
        (Quat::from_rotation_x(90f32.to_radians()), Vec3::new(0.0, 0.0, -1.0)),
        (Quat::from_rotation_x(-90f32.to_radians()), Vec3::new(0.0, 0.0, 1.0)),
    ];
    for (k, ((rotation, at), (albedo, emission))) in placements.into_iter().zip(walls).enumerate() {
        builder.object(
            &format!("wall{k}"),
            &MeshData::plane(2.0, 2.0, 4),
            [albedo, albedo, albedo, 1.0],
            [emission; 3],
            Placement::at(at).rotated(rotation),
        );
    }
    builder
}

/// A closed room (inward-facing box of `size`) of one grey material of
/// base colour `base` and emission `emission`, every vertex coloured `tint`
/// (COLOR_0): its albedo is `base × tint`.
pub fn vertex_coloured_room(size: [f32; 3], base: f32, emission: f32, tint: [f32; 3]) -> SceneBuilder {
    let room = MeshData::room(size);
    let mut builder = SceneBuilder::new();
    let material = builder.material("room", [base, base, base, 1.0], [emission; 3]);
    let mesh = builder.mesh("room", &room, Some(material));
    builder.vertex_colors(mesh, &vec![tint; room.positions.len()]);
    builder.node("room", mesh, Placement::default());
    builder
}

/// Every file in `fixtures/`: (file name, bytes). Scenes as `.glb`;
/// environments with known answers as Radiance `.hdr` and OpenEXR.
pub fn files() -> anyhow::Result<Vec<(String, Vec<u8>)>> {
    use crate::environment::{EnvironmentMap, ExrPrecision, write_exr, write_hdr};
    let mut files = vec![
        ("sphere_on_ground.glb".to_string(), sphere_on_ground().to_glb()),
        ("sphere.glb".to_string(), lone_sphere().to_glb()),
        ("everything.glb".to_string(), everything()),
        ("corner.glb".to_string(), corner().to_glb()),
    ];
    let maps = [
        ("sky_constant", EnvironmentMap::constant([1.0; 3])),
        ("sky_horizon", EnvironmentMap::horizon([1.0; 3])),
        ("sky_sun", EnvironmentMap::sun_and_sky([0.3, 0.45, 0.8], [0.4, 0.6, 0.3], 1e4, 0.5f32.to_radians())),
    ];
    let dir = std::env::temp_dir().join(format!("bake-fixtures-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    for (name, map) in maps {
        let hdr = dir.join(format!("{name}.hdr"));
        write_hdr(&map, &hdr)?;
        files.push((format!("{name}.hdr"), std::fs::read(&hdr)?));
        let exr = dir.join(format!("{name}.exr"));
        write_exr(&map, &exr, ExrPrecision::Float, false)?;
        files.push((format!("{name}.exr"), std::fs::read(&exr)?));
    }
    std::fs::remove_dir_all(&dir)?;
    Ok(files)
}

/// A white-ish sphere of radius 1 floating 0.5 m above a 10×10 m ground.
/// A floor in the corner of a red and a green wall, with a white sphere, a
/// box and a torus: colour bleeding, contact shadows, seams on curved
/// charts. The README's picture.
pub fn corner() -> SceneBuilder {
    use std::f32::consts::FRAC_PI_2;
    let mut scene = SceneBuilder::new();
    let grey = [0.75, 0.75, 0.75, 1.0];
    scene.object("floor", &MeshData::plane(6.0, 6.0, 6), grey, [0.0; 3], Placement::default());
    scene.object(
        "red wall",
        &MeshData::plane(6.0, 3.0, 6),
        [0.8, 0.15, 0.1, 1.0],
        [0.0; 3],
        Placement::at(Vec3::new(-3.0, 1.5, 0.0))
            .rotated(Quat::from_rotation_z(-FRAC_PI_2) * Quat::from_rotation_y(FRAC_PI_2)),
    );
    scene.object(
        "green wall",
        &MeshData::plane(6.0, 3.0, 6),
        [0.15, 0.7, 0.15, 1.0],
        [0.0; 3],
        Placement::at(Vec3::new(0.0, 1.5, -3.0)).rotated(Quat::from_rotation_x(FRAC_PI_2)),
    );
    scene.object("sphere", &MeshData::sphere(0.7, 48, 24), grey, [0.0; 3], Placement::at(Vec3::new(-1.6, 0.7, -1.4)));
    scene.object(
        "box",
        &MeshData::cuboid([1.0, 1.4, 1.0]),
        [0.9, 0.9, 0.9, 1.0],
        [0.0; 3],
        Placement::at(Vec3::new(0.6, 0.7, -1.8)).rotated(Quat::from_rotation_y(0.4)),
    );
    scene.object(
        "torus",
        &MeshData::torus(0.6, 0.22, 48, 24),
        [0.9, 0.75, 0.3, 1.0],
        [0.0; 3],
        Placement::at(Vec3::new(0.4, 0.22, 0.9)),
    );
    scene
}

pub fn sphere_on_ground() -> SceneBuilder {
    let mut scene = SceneBuilder::new();
    scene.object("ground", &MeshData::plane(10.0, 10.0, 4), [0.8, 0.8, 0.8, 1.0], [0.0; 3], Placement::default());
    scene.object(
        "sphere",
        &MeshData::sphere(1.0, 48, 24),
        [0.8, 0.8, 0.8, 1.0],
        [0.0; 3],
        Placement::at(Vec3::new(0.0, 1.5, 0.0)),
    );
    scene
}

/// A sphere of radius 1 alone at the origin (the white furnace).
pub fn lone_sphere() -> SceneBuilder {
    let mut scene = SceneBuilder::new();
    scene.object("sphere", &MeshData::sphere(1.0, 48, 24), [0.8, 0.8, 0.8, 1.0], [0.0; 3], Placement::default());
    scene
}

/// Statue frequency of [`three_statues`] that matches the seed paper's Table 4 scene.
pub const TABLE4_STATUE_FREQUENCY: u32 = 17;

/// The benchmark scene of the seed paper's Table 4 (three scanned bunny statues, 9,225
/// vertices in all), procedurally: three [`MeshData::statue`]s of `frequency` (10·f² + 2
/// vertices and 20·f² triangles each; 2,892 and 5,780 at f = 17) side by side, a hand's
/// width apart, on a 6 × 6 m ground of 23 × 23 cells (576 vertices): 9,252 vertices and
/// 18,398 triangles at f = 17. White, red and green statues on grey ground, so light
/// bounces between them and bleeds colour.
pub fn three_statues(frequency: u32) -> SceneBuilder {
    let mut scene = SceneBuilder::new();
    scene.object("ground", &MeshData::plane(6.0, 6.0, 23), [0.5, 0.5, 0.5, 1.0], [0.0; 3], Placement::default());
    let statues = [
        ("statue white", [0.8, 0.78, 0.72, 1.0], Vec3::new(-1.0, 0.0, 0.25), 20.0f32),
        ("statue red", [0.8, 0.25, 0.2, 1.0], Vec3::new(0.0, 0.0, -0.25), -15.0),
        ("statue green", [0.3, 0.7, 0.35, 1.0], Vec3::new(1.0, 0.0, 0.25), 35.0),
    ];
    for (variant, (name, colour, at, turn)) in statues.into_iter().enumerate() {
        let placement = Placement::at(at).rotated(Quat::from_rotation_y(turn.to_radians()));
        scene.object(name, &MeshData::statue(frequency, variant as u32), colour, [0.0; 3], placement);
    }
    scene
}

/// A scene that uses everything export must carry through (`fixtures/everything.glb`):
///
/// - node 0 `ground`: mesh 0 — primitive 0 baked, with TANGENT, COLOR_0 (normalized bytes), a
///   second UV set (TEXCOORD_1) and material 0 (`ground`: base-colour texture with
///   KHR_texture_transform); primitive 1 draws POINTS (material 3, not baked). Node extras and an
///   unknown extension (`ACME_marker`, in `extensionsUsed`).
/// - nodes 1 and 2 `crate A`/`crate B`: the same mesh 1 (`crate`), whose material 1 samples its
///   occlusion map through TEXCOORD_1.
/// - nodes 3 `flag (static)` and 4 `flag (skinned)`: the same mesh 2 (`flag`, with JOINTS_0,
///   WEIGHTS_0, TEXCOORD_1, material 1) drawn static and skinned (skin 0, joints: nodes 5 and 6).
/// - node 7 `spinner` (mesh 3 `orb`, material 2) turned by animation 0; animation 1 bends joint 6.
/// - node 8 `camera` with camera 0; extras on the root, scene, mesh, material, accessor, camera,
///   animation and skin; two images, one in a buffer view and one as a data URI.
pub fn everything() -> Vec<u8> {
    let mut scene = SceneBuilder::new();
    let checker = checker_png([200, 160, 90], [90, 60, 40]);
    let dots = checker_png([255, 255, 255], [170, 170, 170]);
    let checker_view = scene.push_view(&checker, None);
    // The steps below append to the binary buffer in turn; their order fixes the file's bytes.
    let materials = EverythingMaterials::add(&mut scene);
    let ground = everything_ground(&mut scene, &materials);
    let crate_mesh = everything_crate(&mut scene, &materials);
    let flag = everything_flag(&mut scene, &materials);
    let orb = scene.mesh("orb", &MeshData::sphere(0.4, 12, 6), Some(materials.orb));
    let spinner = everything_nodes(&mut scene, ground, crate_mesh, flag, orb);
    let motion = EverythingMotion::add(&mut scene);
    let doc = everything_document(&scene, checker_view, &dots, spinner, &motion);
    let json = serde_json::to_vec(&doc).expect("fixture JSON serializes");
    crate::export::glb::encode(&json, &scene.binary)
}

/// glTF component types the [`everything`] fixture writes raw.
const FLOAT: u32 = 5126;
const UNSIGNED_BYTE: u32 = 5121;

/// The [`everything`] fixture's materials, by index.
struct EverythingMaterials {
    ground: usize,
    crate_: usize,
    orb: usize,
    markers: usize,
}

impl EverythingMaterials {
    /// Adds the four materials: a transformed base-colour texture, an occlusion map read
    /// through TEXCOORD_1, a double-sided one, and one for the points primitive.
    fn add(scene: &mut SceneBuilder) -> Self {
        let ground = scene.material("ground", [0.8, 0.8, 0.8, 1.0], [0.0; 3]);
        let crate_ = scene.material("crate", [0.7, 0.5, 0.3, 1.0], [0.0; 3]);
        let orb = scene.material("orb", [0.9, 0.2, 0.2, 1.0], [0.0; 3]);
        let markers = scene.material("markers", [1.0, 1.0, 0.0, 1.0], [0.0; 3]);
        scene.materials[ground]["pbrMetallicRoughness"]["baseColorTexture"] = json!({
            "index": 0, "extensions": { "KHR_texture_transform": { "offset": [0.0, 0.0], "scale": [4.0, 4.0] } },
        });
        scene.materials[ground]["extras"] = json!({ "surface": "concrete" });
        scene.materials[crate_]["pbrMetallicRoughness"]["baseColorTexture"] = json!({ "index": 0 });
        scene.materials[crate_]["occlusionTexture"] = json!({ "index": 1, "texCoord": 1, "strength": 0.8 });
        scene.materials[crate_]["extensions"] = json!({ "ACME_marker": { "kind": "material" } });
        scene.materials[orb]["doubleSided"] = json!(true);
        Self { ground, crate_, orb, markers }
    }
}

/// Mesh 0: the ground, with extra attributes, and a points primitive.
fn everything_ground(scene: &mut SceneBuilder, materials: &EverythingMaterials) -> usize {
    let plane = MeshData::plane(6.0, 6.0, 2);
    let ground = scene.mesh("ground", &plane, Some(materials.ground));
    let tangents = vec![[1.0f32, 0.0, 0.0, 1.0]; plane.positions.len()];
    let colours: Vec<u8> = (0..plane.positions.len()).flat_map(|i| [255, (i * 20) as u8, 128, 255]).collect();
    let uv1 = plane.uv0.clone();
    let attributes = [
        ("TANGENT", scene.push_floats(&tangents, "VEC4", false)),
        ("COLOR_0", scene.push_raw(&colours, UNSIGNED_BYTE, plane.positions.len(), "VEC4", true)),
        ("TEXCOORD_1", scene.push_floats(&uv1, "VEC2", false)),
    ];
    for (name, accessor) in attributes {
        scene.meshes[ground]["primitives"][0]["attributes"][name] = json!(accessor);
    }
    let position = scene.meshes[ground]["primitives"][0]["attributes"]["POSITION"].as_u64().unwrap() as usize;
    scene.accessors[position]["extras"] = json!({ "unit": "metre" });
    let marks = [[-2.0f32, 0.05, -2.0], [2.0, 0.05, -2.0], [2.0, 0.05, 2.0], [-2.0, 0.05, 2.0]];
    let mark_colours: Vec<u8> = (0..4).flat_map(|i| [255, 255, (i * 60) as u8, 255]).collect();
    let points = json!({
        "attributes": {
            "POSITION": scene.push_floats(&marks, "VEC3", true),
            "COLOR_0": scene.push_raw(&mark_colours, UNSIGNED_BYTE, 4, "VEC4", true),
        },
        "mode": 0,
        "material": materials.markers,
    });
    scene.meshes[ground]["primitives"].as_array_mut().unwrap().push(points);
    ground
}

/// Mesh 1: a crate with a second UV set its occlusion map reads.
fn everything_crate(scene: &mut SceneBuilder, materials: &EverythingMaterials) -> usize {
    let cuboid = MeshData::cuboid([0.6, 0.6, 0.6]);
    let crate_mesh = scene.mesh("crate", &cuboid, Some(materials.crate_));
    let uv1: Vec<[f32; 2]> = cuboid.uv0.iter().map(|uv| [0.25 + 0.5 * uv[0], 0.25 + 0.5 * uv[1]]).collect();
    scene.meshes[crate_mesh]["primitives"][0]["attributes"]["TEXCOORD_1"] =
        json!(scene.push_floats(&uv1, "VEC2", false));
    scene.meshes[crate_mesh]["extras"] = json!({ "stackable": true });
    crate_mesh
}

/// Mesh 2: a flag, skinned to two joints, with the crate's material.
fn everything_flag(scene: &mut SceneBuilder, materials: &EverythingMaterials) -> usize {
    let cloth = MeshData::plane(1.0, 1.0, 2);
    let flag = scene.mesh("flag", &cloth, Some(materials.crate_));
    let joints: Vec<u8> = cloth.positions.iter().flat_map(|_| [0, 1, 0, 0]).collect();
    let weights: Vec<[f32; 4]> =
        cloth.uv0.iter().map(|uv| [0.25 + 0.5 * uv[1], 0.75 - 0.5 * uv[1], 0.0, 0.0]).collect();
    let attributes = [
        ("TEXCOORD_1", scene.push_floats(&cloth.uv0, "VEC2", false)),
        ("JOINTS_0", scene.push_raw(&joints, UNSIGNED_BYTE, cloth.positions.len(), "VEC4", false)),
        ("WEIGHTS_0", scene.push_floats(&weights, "VEC4", false)),
    ];
    for (name, accessor) in attributes {
        scene.meshes[flag]["primitives"][0]["attributes"][name] = json!(accessor);
    }
    flag
}

/// Nodes, in the order the output must keep; gives the spinner's index.
fn everything_nodes(scene: &mut SceneBuilder, ground: usize, crate_mesh: usize, flag: usize, orb: usize) -> usize {
    let ground_node = scene.node("ground", ground, Placement::default());
    scene.nodes[ground_node]["extras"] = json!({ "layer": "static" });
    scene.nodes[ground_node]["extensions"] = json!({ "ACME_marker": { "kind": "node" } });
    scene.node("crate A", crate_mesh, Placement::at(Vec3::new(-1.5, 0.3, 1.0)));
    let turned = Quat::from_xyzw(0.0, std::f32::consts::FRAC_1_SQRT_2, 0.0, std::f32::consts::FRAC_1_SQRT_2);
    scene.node("crate B", crate_mesh, Placement::at(Vec3::new(1.5, 0.3, 1.0)).rotated(turned));
    scene.node("flag (static)", flag, Placement::at(Vec3::new(0.0, 0.8, -1.5)));
    let skinned = scene.node("flag (skinned)", flag, Placement::default());
    scene.nodes[skinned]["skin"] = json!(0);
    scene.nodes.push(json!({ "name": "flag root joint", "translation": [-2.0, 0.0, 0.0], "children": [6] }));
    scene.nodes.push(json!({ "name": "flag tip joint", "translation": [0.0, 1.0, 0.0] }));
    let spinner = scene.node("spinner", orb, Placement::at(Vec3::new(0.0, 1.0, 1.5)));
    scene.nodes.push(json!({ "name": "camera", "camera": 0, "translation": [0.0, 2.0, 8.0] }));
    spinner
}

/// The [`everything`] fixture's skin and animation accessors.
struct EverythingMotion {
    inverse_bind: usize,
    times: usize,
    spin: usize,
    bend: usize,
}

impl EverythingMotion {
    fn add(scene: &mut SceneBuilder) -> Self {
        // Skin: inverse bind matrices (column-major) undo each joint's world translation.
        let inverse_bind: Vec<[f32; 16]> = [[2.0f32, 0.0, 0.0], [2.0, -1.0, 0.0]]
            .iter()
            .map(|t| [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, t[0], t[1], t[2], 1.0])
            .collect();
        let inverse_bind = scene.push_raw(bytemuck::cast_slice(&inverse_bind), FLOAT, 2, "MAT4", false);

        // Animations: the orb turns about +Y; the flag's tip joint bends about +X.
        let times = scene.push_floats(&[[0.0f32], [1.0], [2.0]], "SCALAR", true);
        let h = std::f32::consts::FRAC_1_SQRT_2;
        let spin = scene.push_floats(&[[0.0f32, 0.0, 0.0, 1.0], [0.0, h, 0.0, h], [0.0, 1.0, 0.0, 0.0]], "VEC4", false);
        let bend = scene.push_floats(&[[0.0f32, 0.0, 0.0, 1.0], [h, 0.0, 0.0, h], [0.0, 0.0, 0.0, 1.0]], "VEC4", false);
        for accessor in [times, spin, bend, inverse_bind] {
            // Animation and skin data must not sit in vertex buffer views.
            let view = scene.accessors[accessor]["bufferView"].as_u64().unwrap() as usize;
            scene.buffer_views[view].as_object_mut().unwrap().remove("target");
        }
        Self { inverse_bind, times, spin, bend }
    }
}

/// The glTF document around the [`everything`] fixture's meshes and nodes: its scene, skin,
/// animations, camera, images, extensions and extras.
fn everything_document(
    scene: &SceneBuilder,
    checker_view: usize,
    dots: &[u8],
    spinner: usize,
    motion: &EverythingMotion,
) -> Value {
    use base64::Engine as _;
    let EverythingMotion { inverse_bind, times, spin, bend } = *motion;
    let mut doc = scene.document();
    doc["scenes"] =
        json!([{ "name": "everything", "nodes": [0, 1, 2, 3, 4, 5, spinner, 8], "extras": { "lit": "sky" } }]);
    doc["skins"] = json!([{ "name": "flag rig", "joints": [5, 6], "skeleton": 5, "inverseBindMatrices": inverse_bind,
        "extras": { "bones": 2 } }]);
    doc["animations"] = json!([
        { "name": "spin", "channels": [{ "sampler": 0, "target": { "node": spinner, "path": "rotation" } }],
          "samplers": [{ "input": times, "output": spin, "interpolation": "LINEAR" }], "extras": { "loop": true } },
        { "name": "wave", "channels": [{ "sampler": 0, "target": { "node": 6, "path": "rotation" } }],
          "samplers": [{ "input": times, "output": bend }] },
    ]);
    doc["cameras"] = json!([{ "name": "overview", "type": "perspective",
        "perspective": { "yfov": 0.8, "znear": 0.1, "zfar": 100.0, "aspectRatio": 1.5 }, "extras": { "rig": "tripod" } }]);
    doc["images"] = json!([
        { "name": "checker", "bufferView": checker_view, "mimeType": "image/png" },
        { "name": "dots", "uri": format!("data:image/png;base64,{}", base64::engine::general_purpose::STANDARD.encode(dots)) },
    ]);
    doc["samplers"] = json!([{ "magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497 }]);
    doc["textures"] =
        json!([{ "name": "checker", "source": 0, "sampler": 0 }, { "name": "dots", "source": 1, "sampler": 0 }]);
    doc["extensionsUsed"] = json!(["KHR_texture_transform", "ACME_marker"]);
    doc["extensions"] = json!({ "ACME_marker": { "kind": "root", "version": 1 } });
    doc["extras"] = json!({ "project": "bake fixtures", "revision": 3 });
    doc["asset"]["copyright"] = json!("CC0");
    doc
}

impl SceneBuilder {
    /// Appends raw accessor data (`count` elements of `kind`) in a buffer view of its own.
    fn push_raw(&mut self, bytes: &[u8], component_type: u32, count: usize, kind: &str, normalized: bool) -> usize {
        let view = self.push_view(bytes, Some(34962));
        let mut accessor = json!({ "bufferView": view, "componentType": component_type, "count": count, "type": kind });
        if normalized {
            accessor["normalized"] = json!(true);
        }
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }
}

/// A 4×4 two-colour checkerboard as an RGB PNG.
fn checker_png(a: [u8; 3], b: [u8; 3]) -> Vec<u8> {
    let rgb: Vec<u8> = (0..16).flat_map(|i| if (i % 4 + i / 4) % 2 == 0 { a } else { b }).collect();
    let mut png = Vec::new();
    let encoder = image::codecs::png::PngEncoder::new(&mut png);
    image::ImageEncoder::write_image(encoder, &rgb, 4, 4, image::ExtendedColorType::Rgb8).expect("PNG encodes");
    png
}
