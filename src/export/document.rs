//! Rewrites the input's glTF JSON into the baked output: one GLB buffer
//! holding everything (input buffers, formerly external images, new data),
//! TEXCOORD_1 and the baked material on every baked primitive. Every field of
//! the input that bake does not change is carried through untouched.

use std::collections::HashMap;

use anyhow::{Context, Result, anyhow, bail};
use serde_json::{Value, json};

use crate::asset::{SourceAsset, accessor};
use crate::scene::Scene;
use crate::unwrap::{Atlas, UnwrappedMesh};

const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const FLOAT: u32 = 5126;
const UNSIGNED_SHORT: u32 = 5123;
const UNSIGNED_INT: u32 = 5125;
const LINEAR: u32 = 9729;
const CLAMP_TO_EDGE: u32 = 33071;

/// The output document under construction, with its binary buffer.
pub struct Document {
    pub json: Value,
    pub bin: Vec<u8>,
}

impl Document {
    /// The input's document with all its buffers merged into one GLB buffer
    /// and external or data-URI images moved into buffer views.
    pub fn from_source(source: &SourceAsset) -> Result<Document> {
        let mut json = source.json.clone();
        let mut bin = Vec::new();
        let mut starts = Vec::new();
        for (i, data) in source.buffers.iter().enumerate() {
            align(&mut bin, 8);
            starts.push(bin.len());
            let declared = source.document.buffers().nth(i).map_or(data.len(), |b| b.length());
            bin.extend_from_slice(&data[..declared.min(data.len())]);
        }
        if let Some(views) = json.get_mut("bufferViews").and_then(Value::as_array_mut) {
            for view in views {
                let buffer = view["buffer"].as_u64().unwrap_or(0) as usize;
                let offset = view.get("byteOffset").and_then(Value::as_u64).unwrap_or(0) as usize;
                view["buffer"] = json!(0);
                view["byteOffset"] = json!(starts.get(buffer).copied().unwrap_or(0) + offset);
            }
        }
        let mut document = Document { json, bin };
        let image_count = source.document.images().len();
        for i in 0..image_count {
            if document.json["images"][i].get("uri").is_none() {
                continue;
            }
            let (bytes, mime) = source.image_bytes(i)?;
            let mime = mime.or_else(|| sniff_image_mime(&bytes).map(str::to_string)).ok_or_else(|| {
                anyhow!("image {i}: unknown format (neither PNG, JPEG, WebP nor KTX2), cannot embed it")
            })?;
            let view = document.push_view(&bytes, None);
            let image = document.json["images"][i].as_object_mut().unwrap();
            image.remove("uri");
            image.insert("bufferView".into(), json!(view));
            image.insert("mimeType".into(), json!(mime));
        }
        Ok(document)
    }

    fn array(&mut self, key: &str) -> &mut Vec<Value> {
        if !self.json.get(key).is_some_and(Value::is_array) {
            self.json[key] = json!([]);
        }
        self.json[key].as_array_mut().unwrap()
    }

    fn push(&mut self, key: &str, value: Value) -> usize {
        let array = self.array(key);
        array.push(value);
        array.len() - 1
    }

    /// Appends `bytes` as a new buffer view (4-byte aligned) and returns its index.
    pub fn push_view(&mut self, bytes: &[u8], target: Option<u32>) -> usize {
        align(&mut self.bin, 4);
        let mut view = json!({ "buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len() });
        if let Some(target) = target {
            view["target"] = json!(target);
        }
        self.bin.extend_from_slice(bytes);
        self.push("bufferViews", view)
    }

    fn push_accessor(&mut self, accessor: Value) -> usize {
        self.push("accessors", accessor)
    }

    /// Adds a PNG image with a linear, clamped sampler; returns the texture index.
    pub fn push_png_texture(&mut self, name: &str, png: &[u8]) -> usize {
        let view = self.push_view(png, None);
        let image = self.push("images", json!({ "name": name, "bufferView": view, "mimeType": "image/png" }));
        // No mipmaps: minification between charts would bleed across them.
        let sampler = self.push(
            "samplers",
            json!({ "magFilter": LINEAR, "minFilter": LINEAR, "wrapS": CLAMP_TO_EDGE, "wrapT": CLAMP_TO_EDGE }),
        );
        self.push("textures", json!({ "name": name, "source": image, "sampler": sampler }))
    }

    pub fn use_extension(&mut self, name: &str) {
        let used = self.array("extensionsUsed");
        if !used.iter().any(|v| v == name) {
            used.push(json!(name));
        }
    }

    /// The finished `.glb`.
    pub fn to_glb(mut self) -> Result<Vec<u8>> {
        align(&mut self.bin, 4);
        self.json["buffers"] = json!([{ "byteLength": self.bin.len() }]);
        let json = serde_json::to_vec(&self.json).context("serializing the glTF JSON")?;
        Ok(super::glb::encode(&json, &self.bin))
    }
}

fn align(bytes: &mut Vec<u8>, to: usize) {
    while !bytes.len().is_multiple_of(to) {
        bytes.push(0);
    }
}

fn sniff_image_mime(bytes: &[u8]) -> Option<&'static str> {
    if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
        Some("image/png")
    } else if bytes.starts_with(&[0xFF, 0xD8, 0xFF]) {
        Some("image/jpeg")
    } else if bytes.len() >= 12 && &bytes[0..4] == b"RIFF" && &bytes[8..12] == b"WEBP" {
        Some("image/webp")
    } else if bytes.starts_with(b"\xABKTX 20\xBB\r\n\x1a\n") {
        Some("image/ktx2")
    } else {
        None
    }
}

/// Component-wise min and max of packed accessor elements, as JSON numbers
/// of the accessor's component type (the validator checks them exactly).
fn bounds(accessor: &gltf::Accessor, packed: &[u8]) -> (Vec<Value>, Vec<Value>) {
    use gltf::accessor::DataType;
    let width = accessor.dimensions().multiplicity();
    let size = accessor.data_type().size();
    let read = |bytes: &[u8]| -> f64 {
        match accessor.data_type() {
            DataType::F32 => f32::from_le_bytes(bytes.try_into().unwrap()) as f64,
            DataType::U8 => bytes[0] as f64,
            DataType::I8 => bytes[0] as i8 as f64,
            DataType::U16 => u16::from_le_bytes(bytes.try_into().unwrap()) as f64,
            DataType::I16 => i16::from_le_bytes(bytes.try_into().unwrap()) as f64,
            DataType::U32 => u32::from_le_bytes(bytes.try_into().unwrap()) as f64,
        }
    };
    let mut lo = vec![f64::INFINITY; width];
    let mut hi = vec![f64::NEG_INFINITY; width];
    for element in packed.chunks_exact(width * size) {
        for c in 0..width {
            let v = read(&element[c * size..(c + 1) * size]);
            lo[c] = lo[c].min(v);
            hi[c] = hi[c].max(v);
        }
    }
    let number = |v: f64| {
        if accessor.data_type() == DataType::F32 { json!(v as f32) } else { json!(v as i64) }
    };
    (lo.into_iter().map(number).collect(), hi.into_iter().map(number).collect())
}

/// Rewrites every baked primitive: attributes gathered through the unwrap's
/// vertex map, new indices, TEXCOORD_1 and `material_for(original material)`.
/// A mesh drawn by several nodes is copied so each node gets its own
/// lightmap region. Returns notices.
pub fn rewrite_primitives(
    document: &mut Document,
    scene: &Scene,
    atlas: &Atlas,
    material_for: &mut dyn FnMut(&mut Document, Option<usize>) -> usize,
) -> Result<Vec<String>> {
    let mut notices = Vec::new();
    // Which output mesh each (node) writes into; the first node keeps the original mesh.
    let mut mesh_of_node: HashMap<usize, usize> = HashMap::new();
    let mut claimed: HashMap<usize, usize> = HashMap::new();
    for primitive in &scene.primitives {
        if mesh_of_node.contains_key(&primitive.node) {
            continue;
        }
        let target = match claimed.get(&primitive.mesh) {
            None => {
                claimed.insert(primitive.mesh, primitive.node);
                primitive.mesh
            }
            Some(_) => {
                let mut copy = document.json["meshes"][primitive.mesh].clone();
                let name = copy.get("name").and_then(Value::as_str).unwrap_or("mesh").to_string();
                copy["name"] = json!(format!("{name} (node {})", primitive.node));
                let index = document.push("meshes", copy);
                document.json["nodes"][primitive.node]["mesh"] = json!(index);
                index
            }
        };
        mesh_of_node.insert(primitive.node, target);
    }

    let source = &scene.source;
    for (primitive, unwrapped) in scene.primitives.iter().zip(&atlas.meshes) {
        let mesh_index = mesh_of_node[&primitive.node];
        let gltf_primitive = source
            .document
            .meshes()
            .nth(primitive.mesh)
            .and_then(|m| m.primitives().nth(primitive.primitive))
            .ok_or_else(|| anyhow!("mesh {} primitive {} vanished", primitive.mesh, primitive.primitive))?;
        let what = format!("mesh {} primitive {}", primitive.mesh, primitive.primitive);
        let mut attributes = serde_json::Map::new();
        for (semantic, source_accessor) in gltf_primitive.attributes() {
            let name = semantic.to_string();
            if name == "TEXCOORD_1" {
                notices.push(format!("{what}: its TEXCOORD_1 is replaced by the lightmap UVs"));
                continue;
            }
            let needs_bounds = semantic == gltf::Semantic::Positions;
            let index = gather_attribute(document, source, &source_accessor, unwrapped, needs_bounds)
                .with_context(|| format!("{what}, attribute {name}"))?;
            attributes.insert(name, json!(index));
        }
        let uv: Vec<[f32; 2]> = unwrapped.vertices.iter().map(|v| v.uv).collect();
        let view = document.push_view(bytemuck::cast_slice(&uv), Some(ARRAY_BUFFER));
        let uv_accessor = document.push_accessor(json!({
            "bufferView": view, "componentType": FLOAT, "count": uv.len(), "type": "VEC2",
        }));
        attributes.insert("TEXCOORD_1".into(), json!(uv_accessor));

        let vertex_count = unwrapped.vertices.len();
        let indices = if vertex_count < u16::MAX as usize {
            let short: Vec<u16> = unwrapped.indices.iter().map(|&i| i as u16).collect();
            let view = document.push_view(bytemuck::cast_slice(&short), Some(ELEMENT_ARRAY_BUFFER));
            document.push_accessor(json!({
                "bufferView": view, "componentType": UNSIGNED_SHORT, "count": short.len(), "type": "SCALAR",
            }))
        } else {
            let view = document.push_view(bytemuck::cast_slice(&unwrapped.indices), Some(ELEMENT_ARRAY_BUFFER));
            document.push_accessor(json!({
                "bufferView": view, "componentType": UNSIGNED_INT, "count": unwrapped.indices.len(), "type": "SCALAR",
            }))
        };
        let material = material_for(document, primitive.material);
        let out = &mut document.json["meshes"][mesh_index]["primitives"][primitive.primitive];
        if !out.is_object() {
            bail!("{what}: not found in the output document");
        }
        out["attributes"] = Value::Object(attributes);
        out["indices"] = json!(indices);
        out["mode"] = json!(4);
        out["material"] = json!(material);
    }
    Ok(notices)
}

/// Copies `source_accessor`'s elements in the unwrap's vertex order into a new accessor.
fn gather_attribute(
    document: &mut Document,
    source: &SourceAsset,
    source_accessor: &gltf::Accessor,
    unwrapped: &UnwrappedMesh,
    needs_bounds: bool,
) -> Result<usize> {
    let packed = accessor::packed_bytes(source, source_accessor)?;
    let size = accessor::element_size(source_accessor);
    let mut gathered = Vec::with_capacity(unwrapped.vertices.len() * size);
    for v in &unwrapped.vertices {
        let at = v.xref as usize * size;
        let element = packed.get(at..at + size).ok_or_else(|| anyhow!("vertex {} is out of range", v.xref))?;
        gathered.extend_from_slice(element);
    }
    // Vertex attributes need 4-byte aligned strides; pad elements that are not.
    let stride = size.div_ceil(4) * 4;
    let bytes = if stride == size {
        gathered
    } else {
        gathered
            .chunks_exact(size)
            .flat_map(|e| e.iter().copied().chain(std::iter::repeat_n(0, stride - size)))
            .collect()
    };
    let view = document.push_view(&bytes, Some(ARRAY_BUFFER));
    if stride != size {
        document.json["bufferViews"][view]["byteStride"] = json!(stride);
    }
    let source_json = &source.json["accessors"][source_accessor.index()];
    let mut out = json!({
        "bufferView": view,
        "componentType": source_json["componentType"],
        "count": unwrapped.vertices.len(),
        "type": source_json["type"],
    });
    for key in ["normalized", "name", "extras", "extensions"] {
        if let Some(value) = source_json.get(key) {
            out[key] = value.clone();
        }
    }
    // The validator checks declared bounds exactly, so recompute them for the gathered set.
    if needs_bounds || source_json.get("min").is_some() || source_json.get("max").is_some() {
        let packed_out: Vec<u8> = if stride == size {
            bytes.clone()
        } else {
            bytes.chunks_exact(stride).flat_map(|e| e[..size].to_vec()).collect()
        };
        let (lo, hi) = bounds(source_accessor, &packed_out);
        out["min"] = json!(lo);
        out["max"] = json!(hi);
    }
    Ok(document.push_accessor(out))
}
