//! Procedural scenes with known answers, for tests, examples and
//! benchmarks. Everything in `fixtures/` is written by
//! `cargo run --example make_fixtures` from these functions, so no fixture is
//! a blob that cannot be regenerated.

use glam::{Quat, Vec3};
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

    /// Adds a root node drawing `mesh` at `placement`.
    pub fn node(&mut self, name: &str, mesh: usize, placement: Placement) -> usize {
        let mut node = json!({ "name": name, "mesh": mesh });
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
        image::ImageEncoder::write_image(
            image::codecs::png::PngEncoder::new(&mut png),
            image.as_raw(),
            image.width(),
            image.height(),
            image::ExtendedColorType::Rgba8,
        )
        .expect("PNG encodes");
        let view = self.push_view(&png, None);
        self.images.push(json!({ "bufferView": view, "mimeType": "image/png" }));
        self.samplers.push(json!({ "magFilter": 9729, "minFilter": 9987, "wrapS": wrap, "wrapT": wrap }));
        self.textures.push(json!({ "source": self.images.len() - 1, "sampler": self.samplers.len() - 1 }));
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

    fn document(&self) -> Value {
        let mut extensions_used = Vec::new();
        if self.materials.iter().any(|m| m.get("extensions").is_some()) {
            extensions_used.push("KHR_materials_emissive_strength");
        }
        if self.materials.iter().any(|m| m.pointer("/pbrMetallicRoughness/baseColorTexture/extensions").is_some()) {
            extensions_used.push("KHR_texture_transform");
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

/// Every file in `fixtures/`: (file name, bytes). Scenes as `.glb`;
/// environments with known answers as Radiance `.hdr` and OpenEXR.
pub fn files() -> anyhow::Result<Vec<(String, Vec<u8>)>> {
    use crate::environment::{EnvironmentMap, ExrPrecision, write_exr, write_hdr};
    let mut files = vec![
        ("sphere_on_ground.glb".to_string(), sphere_on_ground().to_glb()),
        ("sphere.glb".to_string(), lone_sphere().to_glb()),
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
