//! KHR_draco_mesh_compression: a primitive whose attributes and indices are
//! one Draco-compressed mesh in a buffer view, its accessors describing the
//! decoded data but holding none. Decoded on load (draco-core, a pure-Rust
//! Draco decoder) into a buffer appended for the purpose, each accessor
//! pointed at its data and the extension removed, so import and export see
//! a plain asset. A primitive whose accessors carry uncompressed fallback
//! data keeps that data instead.

use anyhow::{Context, Result, anyhow, bail, ensure};
use draco_core::draco_types::DataType;
use draco_core::geometry_attribute::PointAttribute;
use draco_core::geometry_indices::PointIndex;
use draco_core::{DecoderBuffer, Mesh, MeshDecoder};
use serde_json::{Value, json};

use super::{drop_extensions, remove_extension};

pub const EXTENSION: &str = "KHR_draco_mesh_compression";

const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;

/// Decodes every Draco-compressed primitive of `json` into a new buffer
/// appended to `buffers` (and to the document), and removes the extension.
/// Returns how many primitives were compressed.
pub fn decode(json: &mut Value, buffers: &mut Vec<Vec<u8>>) -> Result<usize> {
    let mut decoded = Vec::new();
    let mut compressed = 0;
    let meshes = json.get("meshes").and_then(Value::as_array).map_or(0, Vec::len);
    for m in 0..meshes {
        let primitives = json["meshes"][m].get("primitives").and_then(Value::as_array).map_or(0, Vec::len);
        for p in 0..primitives {
            let Some(extension) = json["meshes"][m]["primitives"][p].pointer(&format!("/extensions/{EXTENSION}"))
            else {
                continue;
            };
            let extension = extension.clone();
            compressed += 1;
            decode_primitive(json, buffers, &mut decoded, m, p, &extension)
                .with_context(|| format!("mesh {m} primitive {p} ({EXTENSION})"))?;
            remove_extension(&mut json["meshes"][m]["primitives"][p], EXTENSION);
        }
    }
    if compressed > 0 {
        if !decoded.is_empty() {
            let buffer = json["buffers"].as_array().map_or(0, Vec::len);
            json["buffers"].as_array_mut().ok_or_else(|| anyhow!("the file has no buffers"))?.push(json!({
                "byteLength": decoded.len(),
                "name": "decoded Draco geometry",
            }));
            // The views pushed while decoding name this buffer's index.
            ensure!(buffer == buffers.len(), "buffers and their declarations disagree");
            buffers.push(decoded);
        }
        drop_extensions(json, &[EXTENSION]);
    }
    Ok(compressed)
}

/// Decodes one primitive's mesh into `decoded`, pointing its accessors at it,
/// unless every accessor already has (fallback) data.
fn decode_primitive(
    json: &mut Value,
    buffers: &[Vec<u8>],
    decoded: &mut Vec<u8>,
    m: usize,
    p: usize,
    extension: &Value,
) -> Result<()> {
    let primitive = json["meshes"][m]["primitives"][p].clone();
    let accessor_of = |name: &str| -> Result<usize> {
        let index = primitive["attributes"].get(name).and_then(Value::as_u64);
        let index = index.ok_or_else(|| anyhow!("compresses {name}, which the primitive does not have"))? as usize;
        ensure!(json["accessors"].get(index).is_some(), "{name} names accessor {index}, which does not exist");
        Ok(index)
    };
    let attributes = extension.get("attributes").and_then(Value::as_object).ok_or_else(|| anyhow!("no attributes"))?;
    let mut targets = Vec::new();
    for (name, id) in attributes {
        let id = id.as_u64().ok_or_else(|| anyhow!("{name}: its Draco id is not a number"))? as u32;
        targets.push((name.clone(), accessor_of(name)?, id));
    }
    let indices = primitive.get("indices").and_then(Value::as_u64).map(|i| i as usize);
    let has_data = |a: usize| json["accessors"][a].get("bufferView").is_some();
    if targets.iter().all(|(_, a, _)| has_data(*a)) && indices.is_none_or(has_data) {
        return Ok(()); // uncompressed fallback data
    }

    let mesh = decode_mesh(json, buffers, extension)?;
    let points = mesh.num_points();
    let mut attributes = Vec::new();
    for (name, accessor, id) in targets {
        let attribute =
            mesh.attribute_by_unique_id(id).ok_or_else(|| anyhow!("{name}: the Draco mesh has no attribute {id}"))?;
        let layout =
            Layout::of(&json["accessors"][accessor]).with_context(|| format!("{name}, accessor {accessor}"))?;
        ensure!(
            layout.count == points,
            "{name}: accessor {accessor} has count {} but the Draco mesh decodes {points} points",
            layout.count
        );
        let bytes = attribute_bytes(attribute, &layout, points).with_context(|| name.clone())?;
        attributes.push((name, accessor, layout, bytes));
    }
    renormalize_float_weights(&mut attributes, points);
    for (_, accessor, layout, bytes) in attributes {
        let view = push_view(json, decoded, buffers.len(), &bytes, layout.element, Some(ARRAY_BUFFER));
        point_accessor(&mut json["accessors"][accessor], view);
        if layout.component == 5126 {
            declare_float_bounds(&mut json["accessors"][accessor], &bytes, layout.components);
        }
    }
    if let Some(accessor) = indices {
        let layout =
            Layout::of(&json["accessors"][accessor]).with_context(|| format!("indices, accessor {accessor}"))?;
        let corners = mesh.num_faces() * 3;
        ensure!(
            layout.count == corners,
            "indices: accessor {accessor} has count {} but the Draco mesh decodes {} triangles",
            layout.count,
            mesh.num_faces()
        );
        let flat = mesh.faces().iter().flat_map(|face| face.map(|point| point.0));
        let bytes: Vec<u8> = match layout.component {
            5121 => flat.map(u8::try_from).collect::<Result<Vec<u8>, _>>().map_err(|_| anyhow!("index past 255"))?,
            5123 => flat
                .map(|i| u16::try_from(i).map(u16::to_le_bytes))
                .collect::<Result<Vec<_>, _>>()
                .map_err(|_| anyhow!("index past 65535"))?
                .concat(),
            5125 => flat.flat_map(u32::to_le_bytes).collect(),
            other => bail!("indices: component type {other} is not an index type"),
        };
        let view = push_view(json, decoded, buffers.len(), &bytes, layout.element, Some(ELEMENT_ARRAY_BUFFER));
        point_accessor(&mut json["accessors"][accessor], view);
    } else {
        bail!("the primitive has no indices accessor for its Draco triangles");
    }
    Ok(())
}

fn decode_mesh(json: &Value, buffers: &[Vec<u8>], extension: &Value) -> Result<Mesh> {
    let v = extension.get("bufferView").and_then(Value::as_u64).ok_or_else(|| anyhow!("no bufferView"))? as usize;
    let view = json["bufferViews"].get(v).ok_or_else(|| anyhow!("buffer view {v} does not exist"))?;
    let field = |key: &str| view.get(key).and_then(Value::as_u64).map(|n| n as usize);
    let (buffer, offset, length) =
        (field("buffer").unwrap_or(0), field("byteOffset").unwrap_or(0), field("byteLength"));
    let bytes = length
        .and_then(|length| buffers.get(buffer)?.get(offset..offset.checked_add(length)?))
        .ok_or_else(|| anyhow!("buffer view {v} lies past the end of buffer {buffer}"))?;
    let mut mesh = Mesh::new();
    MeshDecoder::new()
        .decode(&mut DecoderBuffer::new(bytes), &mut mesh)
        .map_err(|e| anyhow!("buffer view {v} is not a Draco mesh that decodes: {e:?}"))?;
    Ok(mesh)
}

/// What an accessor says its data is.
struct Layout {
    count: usize,
    component: u64,
    components: usize,
    /// Bytes one element takes.
    element: usize,
}

impl Layout {
    fn of(accessor: &Value) -> Result<Layout> {
        let count = accessor.get("count").and_then(Value::as_u64).ok_or_else(|| anyhow!("no count"))? as usize;
        let component = accessor.get("componentType").and_then(Value::as_u64).unwrap_or(0);
        let components = match accessor.get("type").and_then(Value::as_str) {
            Some("SCALAR") => 1,
            Some("VEC2") => 2,
            Some("VEC3") => 3,
            Some("VEC4") => 4,
            other => bail!("type {other:?} is not a vertex attribute type"),
        };
        let size = match component {
            5120 | 5121 => 1,
            5122 | 5123 => 2,
            5125 | 5126 => 4,
            other => bail!("component type {other} is not a glTF component type"),
        };
        Ok(Layout { count, component, components, element: size * components })
    }
}

/// The attribute's values in point order, in the accessor's component type:
/// widened to f32 for a FLOAT accessor (quantized positions come back
/// dequantized), copied as they are for an integer accessor of the same type.
fn attribute_bytes(attribute: &PointAttribute, layout: &Layout, points: usize) -> Result<Vec<u8>> {
    ensure!(
        attribute.num_components() as usize == layout.components,
        "the Draco attribute has {} components, its accessor {}",
        attribute.num_components(),
        layout.components
    );
    if layout.component == 5126 {
        // Normalized integers map to [0, 1] or [-1, 1] as glTF defines them;
        // the signed ones' lowest value is clamped to -1.
        let scale = match attribute.data_type() {
            DataType::Uint8 if attribute.normalized() => Some(255.0),
            DataType::Int8 if attribute.normalized() => Some(127.0),
            DataType::Uint16 if attribute.normalized() => Some(65535.0),
            DataType::Int16 if attribute.normalized() => Some(32767.0),
            _ => None,
        };
        let values = attribute.read_f32s(points, layout.components);
        let to_float = |v: f32| scale.map_or(v, |scale| (v / scale).max(-1.0));
        return Ok(values.iter().flat_map(|&v| to_float(v).to_le_bytes()).collect());
    }
    let same = matches!(
        (layout.component, attribute.data_type()),
        (5120, DataType::Int8)
            | (5121, DataType::Uint8)
            | (5122, DataType::Int16)
            | (5123, DataType::Uint16)
            | (5125, DataType::Uint32)
    );
    ensure!(
        same,
        "Draco stores {:?} where its accessor has component type {}",
        attribute.data_type(),
        layout.component
    );
    let stride = attribute.byte_stride() as usize;
    let mut bytes = vec![0u8; points * layout.element];
    for (point, out) in bytes.chunks_exact_mut(layout.element).enumerate() {
        let value = attribute.mapped_index(PointIndex(point as u32)).0 as usize;
        ensure!(
            attribute.buffer().try_read(value * stride, out),
            "point {point} maps to value {value}, past the attribute's data"
        );
    }
    Ok(bytes)
}

/// Scales each point's FLOAT skin weights (over all its `WEIGHTS_n` sets) to
/// sum to 1, as glTF asks: quantized by the encoder, they come back off by
/// a step. Points whose weights sum to 0 are left alone.
fn renormalize_float_weights(attributes: &mut [(String, usize, Layout, Vec<u8>)], points: usize) {
    let is_float_weights = |(name, _, layout, _): &(String, usize, Layout, Vec<u8>)| {
        name.starts_with("WEIGHTS_") && layout.component == 5126
    };
    let mut sums = vec![0f64; points];
    for (_, _, layout, bytes) in attributes.iter().filter(|a| is_float_weights(a)) {
        for (point, weights) in bytes.chunks_exact(layout.element).enumerate() {
            sums[point] +=
                weights.chunks_exact(4).map(|w| f32::from_le_bytes(w.try_into().unwrap()) as f64).sum::<f64>();
        }
    }
    for (_, _, layout, bytes) in attributes.iter_mut().filter(|a| is_float_weights(a)) {
        for (point, weights) in bytes.chunks_exact_mut(layout.element).enumerate() {
            if sums[point] > 0.0 {
                for w in weights.chunks_exact_mut(4) {
                    let value = f32::from_le_bytes((&*w).try_into().unwrap()) as f64 / sums[point];
                    w.copy_from_slice(&(value as f32).to_le_bytes());
                }
            }
        }
    }
}

/// Appends `bytes` as a buffer view of the decoded buffer (`buffer`),
/// elements padded to a 4-byte stride as vertex attributes need; returns it.
fn push_view(
    json: &mut Value,
    decoded: &mut Vec<u8>,
    buffer: usize,
    bytes: &[u8],
    element: usize,
    target: Option<u32>,
) -> usize {
    while !decoded.len().is_multiple_of(4) {
        decoded.push(0);
    }
    let offset = decoded.len();
    let stride = element.div_ceil(4) * 4;
    let padded = target == Some(ARRAY_BUFFER) && stride != element;
    if padded {
        for e in bytes.chunks_exact(element) {
            decoded.extend_from_slice(e);
            decoded.extend(std::iter::repeat_n(0, stride - element));
        }
    } else {
        decoded.extend_from_slice(bytes);
    }
    let mut view = json!({ "buffer": buffer, "byteOffset": offset, "byteLength": decoded.len() - offset });
    if padded {
        view["byteStride"] = json!(stride);
    }
    if let Some(target) = target {
        view["target"] = json!(target);
    }
    let views = json.as_object_mut().unwrap().entry("bufferViews").or_insert_with(|| json!([]));
    let views = views.as_array_mut().unwrap();
    views.push(view);
    views.len() - 1
}

fn point_accessor(accessor: &mut Value, view: usize) {
    accessor["bufferView"] = json!(view);
    accessor.as_object_mut().map(|a| a.remove("byteOffset"));
}

/// Replaces a FLOAT accessor's declared `min` / `max` (where it has them) by
/// the decoded values' bounds: encoders declare the bounds of the data they
/// quantized, which the dequantized values overshoot by a step, and glTF
/// asks the bounds to be exact.
fn declare_float_bounds(accessor: &mut Value, bytes: &[u8], components: usize) {
    if accessor.get("min").is_none() && accessor.get("max").is_none() {
        return;
    }
    let mut min = vec![f32::INFINITY; components];
    let mut max = vec![f32::NEG_INFINITY; components];
    for (i, value) in bytes.chunks_exact(4).map(|b| f32::from_le_bytes(b.try_into().unwrap())).enumerate() {
        min[i % components] = min[i % components].min(value);
        max[i % components] = max[i % components].max(value);
    }
    if min.iter().all(|m| m.is_finite()) {
        accessor["min"] = json!(min);
        accessor["max"] = json!(max);
    }
}
