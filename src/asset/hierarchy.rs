//! The node hierarchy as glTF requires it: disjoint strict trees, each
//! scene listing its roots once. A node with two parents, or a root that is
//! also another node's child, would be drawn twice from one node, whose one
//! set of lightmap UVs can hold only one of its two placements; such a file
//! is refused, naming the nodes.

use anyhow::{Result, bail};

/// Checks that `scene`'s nodes form trees (nothing is walked yet).
pub fn check_trees(document: &gltf::Document, scene: &gltf::Scene) -> Result<()> {
    let names: Vec<String> = document.nodes().map(|n| named("node", n.index(), n.name())).collect();
    let mut parents: Vec<Option<usize>> = vec![None; names.len()];
    for node in document.nodes() {
        for child in node.children().map(|c| c.index()) {
            if child == node.index() {
                bail!("{} is its own child: glTF nodes form trees", names[child]);
            }
            if let Some(first) = parents[child].replace(node.index()) {
                bail!(
                    "{} is a child of both {} and {}: a glTF node has one parent at most (nodes form trees)",
                    names[child],
                    names[first],
                    names[node.index()]
                );
            }
        }
    }
    let scene_name = named("scene", scene.index(), scene.name());
    let mut listed = vec![false; names.len()];
    for root in scene.nodes().map(|n| n.index()) {
        if std::mem::replace(&mut listed[root], true) {
            bail!("{scene_name} lists {} twice among its root nodes", names[root]);
        }
        if let Some(parent) = parents[root] {
            bail!("{scene_name} lists {} as a root node, but it is a child of {}", names[root], names[parent]);
        }
    }
    Ok(())
}

/// "node 3 'door'", or "node 3" without a name.
fn named(kind: &str, index: usize, name: Option<&str>) -> String {
    match name {
        Some(name) => format!("{kind} {index} '{name}'"),
        None => format!("{kind} {index}"),
    }
}
