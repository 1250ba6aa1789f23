//! Morph targets: a primitive whose attributes are its base values plus the
//! weighted sum of its targets' displacements. Import bakes a morphing mesh
//! at its node's weights (the node's `weights`, else the mesh's, else 0),
//! which is the shape a viewer draws until an animation moves them; export
//! keeps the targets, remapped to the unwrapped vertices.
//!
//! Also which nodes an animation moves, so import can say that a lightmap
//! holds only in the rest pose.

use std::collections::{BTreeMap, BTreeSet};

use anyhow::{Context, Result, anyhow, bail, ensure};
use serde_json::Value;

use super::{SourceAsset, accessor};

/// The morph weights `node` draws `mesh` with: the node's own, else the
/// mesh's default, else all 0. Errors when a list does not match the
/// number of targets.
pub fn weights(node: &gltf::Node, mesh: &gltf::Mesh) -> Result<Vec<f32>> {
    let targets = mesh.primitives().map(|p| p.morph_targets().len()).max().unwrap_or(0);
    let (weights, whose) = match (node.weights(), mesh.weights()) {
        (Some(w), _) => (w, format!("node {}", node.index())),
        (None, Some(w)) => (w, format!("mesh {}", mesh.index())),
        (None, None) => return Ok(vec![0.0; targets]),
    };
    ensure!(
        weights.len() == targets,
        "{whose} lists {} morph weights for the {targets} morph targets of mesh {}",
        weights.len(),
        mesh.index()
    );
    if let Some(i) = weights.iter().position(|w| !w.is_finite()) {
        bail!("{whose}: morph weight {i} is not finite ({})", weights[i]);
    }
    Ok(weights.to_vec())
}

/// Adds to `values` (the base attribute `attribute`, `width` floats per
/// vertex) each target's displacement of that attribute times its weight.
/// Targets that do not displace `attribute`, or have weight 0, are skipped.
pub fn displace(
    source: &SourceAsset,
    mesh: usize,
    primitive: usize,
    weights: &[f32],
    attribute: &str,
    width: usize,
    values: &mut [f32],
) -> Result<()> {
    let targets = source.json.pointer(&format!("/meshes/{mesh}/primitives/{primitive}/targets"));
    let Some(targets) = targets.and_then(Value::as_array) else { return Ok(()) };
    for (t, target) in targets.iter().enumerate() {
        let weight = weights.get(t).copied().unwrap_or(0.0);
        let Some(index) = target.get(attribute) else { continue };
        if weight == 0.0 {
            continue;
        }
        let read = || -> Result<Vec<f32>> {
            let accessor = index
                .as_u64()
                .and_then(|i| source.document.accessors().nth(i as usize))
                .ok_or_else(|| anyhow!("names no accessor"))?;
            let found = accessor.dimensions().multiplicity();
            ensure!(found == width, "has {found} components, its base attribute {width}");
            let displacement = accessor::read_floats(source, &accessor)?;
            ensure!(
                displacement.len() == values.len(),
                "has {} entries for {} vertices",
                displacement.len() / width,
                values.len() / width
            );
            Ok(displacement)
        };
        let displacement = read().with_context(|| format!("morph target {t}, {attribute}"))?;
        for (value, d) in values.iter_mut().zip(displacement) {
            *value += weight * d;
        }
    }
    Ok(())
}

/// Every node an animation moves, with the properties it animates
/// (`translation`, `rotation`, `scale`, `weights`): from animation channels
/// and from KHR_animation_pointer pointers into `/nodes/n/...`.
pub fn animated_nodes(json: &Value) -> BTreeMap<usize, BTreeSet<String>> {
    let mut animated: BTreeMap<usize, BTreeSet<String>> = BTreeMap::new();
    let channels = json.get("animations").and_then(Value::as_array).into_iter().flatten();
    for channel in channels.filter_map(|a| a.get("channels").and_then(Value::as_array)).flatten() {
        let target = &channel["target"];
        let path = target.get("path").and_then(Value::as_str).unwrap_or_default();
        let moved = match (target.get("node").and_then(Value::as_u64), path) {
            (Some(node), _) => Some((node as usize, path.to_string())),
            (None, "pointer") => {
                let pointer = target.pointer("/extensions/KHR_animation_pointer/pointer").and_then(Value::as_str);
                let mut parts = pointer.unwrap_or_default().split('/').skip(1);
                match (parts.next(), parts.next().and_then(|n| n.parse().ok()), parts.next()) {
                    (Some("nodes"), Some(node), Some(property)) => Some((node, property.to_string())),
                    _ => None,
                }
            }
            _ => None,
        };
        if let Some((node, property)) = moved {
            animated.entry(node).or_default().insert(property);
        }
    }
    animated
}
