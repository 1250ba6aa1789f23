//! EXT_mesh_gpu_instancing: a node that draws its mesh once per instance,
//! each placed by a TRANSLATION / ROTATION / SCALE triple relative to the
//! node (world = node's world · instance's TRS). Import bakes every instance
//! as a mesh of its own; export writes each as a child node, since instances
//! share one set of UVs and a lightmap needs a region per instance.

use anyhow::{Context, Result, anyhow, bail, ensure};
use glam::{DMat4, DQuat, DVec3};
use serde_json::{Value, json};

use super::{SourceAsset, accessor};

pub const EXTENSION: &str = "EXT_mesh_gpu_instancing";

/// One instance's placement relative to its node, as the extension stores it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Instance {
    pub translation: [f32; 3],
    /// Unit quaternion (x, y, z, w).
    pub rotation: [f32; 4],
    pub scale: [f32; 3],
}

impl Instance {
    pub fn matrix(&self) -> DMat4 {
        let [x, y, z, w] = self.rotation.map(f64::from);
        DMat4::from_scale_rotation_translation(
            DVec3::from(self.scale.map(f64::from)),
            DQuat::from_xyzw(x, y, z, w),
            DVec3::from(self.translation.map(f64::from)),
        )
    }

    /// The instance as a glTF node's TRS properties (defaults left out).
    pub fn node_properties(&self) -> serde_json::Map<String, Value> {
        let mut node = serde_json::Map::new();
        if self.translation != [0.0; 3] {
            node.insert("translation".into(), json!(self.translation));
        }
        if self.rotation != [0.0, 0.0, 0.0, 1.0] {
            node.insert("rotation".into(), json!(self.rotation));
        }
        if self.scale != [1.0; 3] {
            node.insert("scale".into(), json!(self.scale));
        }
        node
    }
}

/// A node's instances, with its custom per-instance attributes (`_ID`,
/// `_COLOR`, ...) as JSON values, one per instance.
#[derive(Clone, Debug, PartialEq)]
pub struct Instances {
    pub placements: Vec<Instance>,
    pub custom: Vec<(String, Vec<Value>)>,
}

/// The instances of node `node`, or `None` where it does not use the
/// extension. Errors say which attribute is wrong.
pub fn read(source: &SourceAsset, node: usize) -> Result<Option<Instances>> {
    let Some(extension) = source.json.pointer(&format!("/nodes/{node}/extensions/{EXTENSION}")) else {
        return Ok(None);
    };
    let read = || -> Result<Instances> {
        let attributes = extension
            .get("attributes")
            .and_then(Value::as_object)
            .ok_or_else(|| anyhow!("has no attributes object"))?;
        let mut count = None;
        let mut accessor_of = |name: &str| -> Result<Option<gltf::Accessor>> {
            let Some(index) = attributes.get(name) else { return Ok(None) };
            let accessor = index
                .as_u64()
                .and_then(|i| source.document.accessors().nth(i as usize))
                .ok_or_else(|| anyhow!("{name} names no accessor ({index})"))?;
            match count {
                None => count = Some(accessor.count()),
                Some(n) => ensure!(
                    accessor.count() == n,
                    "{name} has {} entries where another attribute has {n}",
                    accessor.count()
                ),
            }
            Ok(Some(accessor))
        };
        let vectors = |name: &str, accessor: Option<gltf::Accessor>| -> Result<Option<Vec<[f32; 3]>>> {
            let Some(a) = accessor else { return Ok(None) };
            let values = accessor::read_vectors::<3>(source, &a).with_context(|| name.to_string())?;
            if let Some(i) = values.iter().position(|v| v.iter().any(|c| !c.is_finite())) {
                bail!("{name} {i} is not finite ({:?})", values[i]);
            }
            Ok(Some(values))
        };
        let translation = vectors("TRANSLATION", accessor_of("TRANSLATION")?)?;
        let scale = vectors("SCALE", accessor_of("SCALE")?)?;
        let rotation = match accessor_of("ROTATION")? {
            None => None,
            Some(a) => {
                let values = accessor::read_vectors::<4>(source, &a).context("ROTATION")?;
                let unit = values.iter().enumerate().map(|(i, q)| {
                    let length = q.iter().map(|c| c * c).sum::<f32>().sqrt();
                    ensure!(length.is_finite() && length > 0.0, "ROTATION {i} is not a rotation ({q:?})");
                    Ok(q.map(|c| c / length))
                });
                Some(unit.collect::<Result<Vec<_>>>()?)
            }
        };
        let mut custom = Vec::new();
        for (name, _) in attributes.iter().filter(|(name, _)| name.starts_with('_')) {
            let accessor = accessor_of(name)?.expect("listed");
            let width = accessor.dimensions().multiplicity();
            let values = accessor::read_floats(source, &accessor).with_context(|| name.clone())?;
            let per_instance = values
                .chunks_exact(width)
                .map(|c| if width == 1 { number(c[0]) } else { Value::Array(c.iter().map(|&v| number(v)).collect()) })
                .collect();
            custom.push((name.clone(), per_instance));
        }
        let count = count.ok_or_else(|| anyhow!("lists no per-instance attribute"))?;
        let placements = (0..count)
            .map(|i| Instance {
                translation: translation.as_ref().map_or([0.0; 3], |t| t[i]),
                rotation: rotation.as_ref().map_or([0.0, 0.0, 0.0, 1.0], |r| r[i]),
                scale: scale.as_ref().map_or([1.0; 3], |s| s[i]),
            })
            .collect();
        Ok(Instances { placements, custom })
    };
    let name = super::quoted_name(source.json.pointer(&format!("/nodes/{node}/name")).and_then(Value::as_str));
    read().map(Some).with_context(|| format!("node {node}{name}: {EXTENSION}"))
}

/// A JSON number, integral where the value is (an `_ID` stays an integer).
fn number(v: f32) -> Value {
    if v.fract() == 0.0 && v.abs() < 1e15 { json!(v as i64) } else { json!(v) }
}
