//! Rewrites every baked primitive of the output document: its attributes
//! gathered through the unwrap's vertex map, new indices (a triangle list),
//! and the lightmap UVs as TEXCOORD_1. Materials are assigned afterwards
//! (`materials.rs`).
//!
//! What is not baked is not touched: a mesh that a non-baked node also draws
//! (a skinned node, a node of another scene) keeps its primitives and
//! accessors, and each baked node that draws it gets a copy. A mesh drawn by
//! several baked nodes is copied too, so that each node gets its own
//! lightmap region, and so is the mesh of each GPU instance, which becomes
//! a child node of its own (EXT_mesh_gpu_instancing shares one set of UVs).
//! An input TEXCOORD_1 that the lightmap UVs replace moves to the first
//! free TEXCOORD_n, so no vertex data is lost. Morph targets are gathered
//! like the attributes they displace.

use std::collections::{BTreeMap, BTreeSet};

use anyhow::{Context, Result, anyhow, bail};
use serde_json::{Value, json};

use super::document::Document;
use crate::asset::instancing::{self, Instances};
use crate::asset::{self, SourceAsset, accessor};
use crate::scene::Scene;
use crate::unwrap::{Atlas, UnwrappedMesh};

const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const FLOAT: u32 = 5126;
const UNSIGNED_SHORT: u32 = 5123;
const UNSIGNED_INT: u32 = 5125;

/// One rewritten primitive of the output document.
#[derive(Clone, Debug, PartialEq)]
pub struct Rewritten {
    /// The output node that draws it: the baked node, or the child node of its GPU instance.
    pub node: usize,
    /// Output mesh index (the input's, or a copy's) and primitive index within it.
    pub mesh: usize,
    pub primitive: usize,
    /// The input primitive's material; `None` is glTF's default material.
    pub material: Option<usize>,
    /// The set the input's TEXCOORD_1 moved to (`n` of TEXCOORD_n), if it moved.
    pub moved_uv1_to: Option<u32>,
}

/// Rewrites every primitive of `scene` in `document` with the UVs of `atlas`.
/// With `uv1_reused`, the atlas' UVs are the input's own TEXCOORD_1 and
/// nothing is moved aside. Returns the rewritten primitives (in scene order)
/// and notices.
pub fn rewrite(
    document: &mut Document,
    scene: &Scene,
    atlas: &Atlas,
    uv1_reused: bool,
) -> Result<(Vec<Rewritten>, Vec<String>)> {
    if atlas.meshes.len() != scene.primitives.len() {
        bail!("the atlas has {} meshes for {} primitives", atlas.meshes.len(), scene.primitives.len());
    }
    let mesh_of = output_meshes(document, scene)?;
    let source = &scene.source;
    let mut notices = BTreeSet::new();
    let mut rewritten = Vec::new();
    for (primitive, unwrapped) in scene.primitives.iter().zip(&atlas.meshes) {
        let what = format!("mesh {} primitive {}", primitive.mesh, primitive.primitive);
        let input = &source.json["meshes"][primitive.mesh]["primitives"][primitive.primitive];
        let Some(input_attributes) = input.get("attributes").and_then(Value::as_object) else {
            bail!("{what}: not found in the input document");
        };
        let mut attributes = serde_json::Map::new();
        let mut moved_uv1_to = None;
        for (name, index) in input_attributes {
            let source_accessor = index
                .as_u64()
                .and_then(|i| source.document.accessors().nth(i as usize))
                .ok_or_else(|| anyhow!("{what}: attribute {name} names no accessor"))?;
            let mut target = name.clone();
            if name == "TEXCOORD_1" {
                if uv1_reused {
                    continue; // written below from the atlas, which holds exactly these UVs
                }
                let free = (2u32..).find(|n| !input_attributes.contains_key(&format!("TEXCOORD_{n}"))).unwrap();
                moved_uv1_to = Some(free);
                target = format!("TEXCOORD_{free}");
                notices.insert(format!(
                    "{what}: its TEXCOORD_1 moved to {target} (the lightmap UVs take TEXCOORD_1); \
                     its material's texture references follow it"
                ));
            }
            let needs_bounds = name == "POSITION";
            let index = gather_attribute(document, source, &source_accessor, unwrapped, needs_bounds)
                .with_context(|| format!("{what}, attribute {name}"))?;
            attributes.insert(target, json!(index));
        }
        let uv: Vec<[f32; 2]> = unwrapped.vertices.iter().map(|v| v.uv).collect();
        let view = document.push_view(bytemuck::cast_slice(&uv), Some(ARRAY_BUFFER));
        let uv_accessor = document.push(
            "accessors",
            json!({
                "bufferView": view, "componentType": FLOAT, "count": uv.len(), "type": "VEC2",
            }),
        );
        attributes.insert("TEXCOORD_1".into(), json!(uv_accessor));
        if !attributes.contains_key("TEXCOORD_0") {
            // glTF numbers texture coordinate sets from 0 without gaps.
            attributes.insert("TEXCOORD_0".into(), json!(uv_accessor));
            notices.insert(format!("{what}: had no TEXCOORD_0; the lightmap UVs serve as TEXCOORD_0 too"));
        }
        let indices = push_indices(document, unwrapped);
        let targets = match input.get("targets").and_then(Value::as_array) {
            Some(targets) => {
                let moved = moved_uv1_to.map(|n| format!("TEXCOORD_{n}"));
                let targets = gather_targets(document, source, targets, unwrapped, uv1_reused, moved.as_deref());
                Some(targets.with_context(|| what.clone())?)
            }
            None => None,
        };

        let (mesh, node) = mesh_of[&(primitive.node, primitive.instance)];
        let out = &mut document.json["meshes"][mesh]["primitives"][primitive.primitive];
        if !out.is_object() {
            bail!("{what}: not found in the output document");
        }
        out["attributes"] = Value::Object(attributes);
        out["indices"] = json!(indices);
        out["mode"] = json!(4);
        if let Some(targets) = targets {
            out["targets"] = targets;
        }
        rewritten.push(Rewritten {
            node,
            mesh,
            primitive: primitive.primitive,
            material: primitive.material,
            moved_uv1_to,
        });
    }
    Ok((rewritten, notices.into_iter().collect()))
}

/// Output (mesh, node) by (baked node, GPU instance): `output_meshes`.
type MeshOf = BTreeMap<(usize, Option<usize>), (usize, usize)>;

/// Which output mesh each baked node (or GPU instance) draws, and the output
/// node that draws it (the node, or its instance's child). A mesh keeps
/// its index for the first baked node that draws it, unless a node that is
/// not baked draws it too; every other baked node gets a copy (appended to
/// `meshes`, the node pointed at it). Each instance of an instanced node
/// becomes a child node drawing a mesh of its own; the node keeps its
/// transform and children but draws nothing itself.
fn output_meshes(document: &mut Document, scene: &Scene) -> Result<MeshOf> {
    let baked_nodes: BTreeSet<usize> = scene.primitives.iter().map(|p| p.node).collect();
    let nodes = document.json.get("nodes").and_then(Value::as_array).cloned().unwrap_or_default();
    let drawn_by_others: BTreeSet<usize> = nodes
        .iter()
        .enumerate()
        .filter(|(i, _)| !baked_nodes.contains(i))
        .filter_map(|(_, node)| node.get("mesh").and_then(Value::as_u64).map(|m| m as usize))
        .collect();
    let name_of = |node: usize| nodes[node].get("name").and_then(Value::as_str);
    let mut instanced = BTreeMap::new();
    for node in scene.primitives.iter().filter(|p| p.instance.is_some()).map(|p| p.node) {
        if let std::collections::btree_map::Entry::Vacant(entry) = instanced.entry(node) {
            let instances = instancing::read(&scene.source, node)?;
            entry.insert(instances.ok_or_else(|| anyhow!("node {node}: its instances are gone"))?);
        }
    }
    let mut mesh_of = BTreeMap::new();
    let mut claimed = BTreeSet::new();
    for primitive in &scene.primitives {
        let key = (primitive.node, primitive.instance);
        if mesh_of.contains_key(&key) {
            continue;
        }
        let mesh = primitive.mesh;
        let target = if !drawn_by_others.contains(&mesh) && claimed.insert(mesh) {
            mesh
        } else {
            let mut copy = scene.source.json["meshes"][mesh].clone();
            let name = copy.get("name").and_then(Value::as_str).map_or_else(|| format!("mesh {mesh}"), str::to_string);
            let instance = primitive.instance.map(|k| format!(", instance {k}")).unwrap_or_default();
            let node = primitive.node;
            let node = name_of(node).map_or_else(|| format!("node {node}"), |n| format!("node '{n}'"));
            copy["name"] = json!(format!("{name} ({node}{instance})"));
            document.push("meshes", copy)
        };
        let drawer = match primitive.instance {
            None => primitive.node,
            Some(k) => {
                let parent = primitive.node;
                let name = name_of(parent).map_or_else(|| format!("node {parent}"), str::to_string);
                instance_node(document, parent, &name, &instanced[&parent], k)?
            }
        };
        document.json["nodes"][drawer]["mesh"] = json!(target);
        mesh_of.insert(key, (target, drawer));
    }
    for &node in instanced.keys() {
        let node = &mut document.json["nodes"][node];
        asset::remove_extension(node, instancing::EXTENSION);
        node.as_object_mut().map(|n| n.remove("mesh"));
    }
    let still_instanced = document.json["nodes"].as_array().is_some_and(|nodes| {
        nodes.iter().any(|n| n.pointer(&format!("/extensions/{}", instancing::EXTENSION)).is_some())
    });
    if !instanced.is_empty() && !still_instanced {
        asset::drop_extensions(&mut document.json, &[instancing::EXTENSION]);
    }
    Ok(mesh_of)
}

/// Appends instance `k` of `parent` as a child node placed by the instance's
/// transform, its custom per-instance attributes in its extras; returns it.
fn instance_node(
    document: &mut Document,
    parent: usize,
    parent_name: &str,
    instances: &Instances,
    k: usize,
) -> Result<usize> {
    let placement = instances.placements.get(k).ok_or_else(|| anyhow!("{parent_name} has no instance {k}"))?;
    let mut node = placement.node_properties();
    node.insert("name".into(), json!(format!("{parent_name} instance {k}")));
    if !instances.custom.is_empty() {
        let values: serde_json::Map<String, Value> =
            instances.custom.iter().map(|(name, values)| (name.clone(), values[k].clone())).collect();
        node.insert("extras".into(), json!({ instancing::EXTENSION: values }));
    }
    let index = document.push("nodes", Value::Object(node));
    let children = &mut document.json["nodes"][parent]["children"];
    if !children.is_array() {
        *children = json!([]);
    }
    children.as_array_mut().unwrap().push(json!(index));
    Ok(index)
}

/// The primitive's morph targets gathered in the unwrap's vertex order, as
/// its attributes are. A TEXCOORD_1 displacement follows TEXCOORD_1 to
/// `moved_uv1`, or goes when the lightmap UVs are that TEXCOORD_1.
fn gather_targets(
    document: &mut Document,
    source: &SourceAsset,
    targets: &[Value],
    unwrapped: &UnwrappedMesh,
    uv1_reused: bool,
    moved_uv1: Option<&str>,
) -> Result<Value> {
    let mut gathered = Vec::with_capacity(targets.len());
    for (t, target) in targets.iter().enumerate() {
        let mut out = serde_json::Map::new();
        for (name, index) in target.as_object().into_iter().flatten() {
            let name = match (name.as_str(), moved_uv1) {
                ("TEXCOORD_1", _) if uv1_reused => continue,
                ("TEXCOORD_1", Some(moved)) => moved,
                (name, _) => name,
            };
            let source_accessor = index
                .as_u64()
                .and_then(|i| source.document.accessors().nth(i as usize))
                .ok_or_else(|| anyhow!("morph target {t}: {name} names no accessor"))?;
            // The spec asks for the bounds of a target's POSITION displacements.
            let needs_bounds = name == "POSITION";
            let index = gather_attribute(document, source, &source_accessor, unwrapped, needs_bounds)
                .with_context(|| format!("morph target {t}, attribute {name}"))?;
            out.insert(name.to_string(), json!(index));
        }
        gathered.push(Value::Object(out));
    }
    Ok(Value::Array(gathered))
}

/// The unwrapped triangle list as 16-bit indices where they fit, else 32-bit.
fn push_indices(document: &mut Document, unwrapped: &UnwrappedMesh) -> usize {
    // 65535 is the primitive-restart value for 16-bit indices: keep it out.
    if unwrapped.vertices.len() < u16::MAX as usize {
        let short: Vec<u16> = unwrapped.indices.iter().map(|&i| i as u16).collect();
        let view = document.push_view(bytemuck::cast_slice(&short), Some(ELEMENT_ARRAY_BUFFER));
        document.push(
            "accessors",
            json!({
                "bufferView": view, "componentType": UNSIGNED_SHORT, "count": short.len(), "type": "SCALAR",
            }),
        )
    } else {
        let view = document.push_view(bytemuck::cast_slice(&unwrapped.indices), Some(ELEMENT_ARRAY_BUFFER));
        document.push(
            "accessors",
            json!({
                "bufferView": view, "componentType": UNSIGNED_INT, "count": unwrapped.indices.len(), "type": "SCALAR",
            }),
        )
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
    Ok(document.push("accessors", out))
}
