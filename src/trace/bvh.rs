//! A bounding volume hierarchy over boxes: a compact binned-SAH tree (Wald,
//! "On fast Construction of SAH-based Bounding Volume Hierarchies", 2007)
//! built sequentially, so the tree is the same on every run and thread
//! count. The CPU tracer walks it with a stack (`trace::rays`); the GPU
//! walks its depth-first flattening (`flatten`), stacklessly.

use glam::DVec3;

/// Leaves of the CPU tracer's tree: at most `MAX_LEAF` items, or twice as
/// many where splitting them costs more than it saves.
pub(crate) const MAX_LEAF: usize = 4;
/// SAH bins per axis.
const BINS: usize = 16;

/// One node: a box over its items, and where they are.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Node {
    pub lo: DVec3,
    pub hi: DVec3,
    /// Leaf: first item in `Tree::order`; interior: index of the left child
    /// (the right one follows it).
    pub start: u32,
    /// Items in the leaf; 0 for an interior node.
    pub count: u32,
}

/// The hierarchy: nodes (the root first) and the order of the items its
/// leaves list.
pub(crate) struct Tree {
    pub nodes: Vec<Node>,
    /// Item indices as the leaves list them (leaf `start..start + count`).
    pub order: Vec<u32>,
}

/// A node in depth-first order for a stackless walk: after a node come its
/// descendants; `escape` is where the walk goes when it skips the node's
/// subtree (the next node that is not a descendant).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct FlatNode {
    pub lo: DVec3,
    pub hi: DVec3,
    pub escape: u32,
    /// The node's range in `Tree::order` (first, count): the whole subtree's,
    /// so a leaf's are its own items.
    pub first: u32,
    pub count: u32,
    pub leaf: bool,
}

struct Item {
    lo: DVec3,
    hi: DVec3,
    centroid: DVec3,
    index: u32,
}

fn area(lo: DVec3, hi: DVec3) -> f64 {
    let d = (hi - lo).max(DVec3::ZERO);
    d.x * d.y + d.y * d.z + d.z * d.x
}

impl Tree {
    /// Builds the tree over the boxes `(lo, hi)` of the items, with leaves of
    /// at most `max_leaf` items (up to twice that where a split costs more).
    pub(crate) fn build(boxes: &[(DVec3, DVec3)], max_leaf: usize) -> Tree {
        let mut items: Vec<Item> = boxes
            .iter()
            .enumerate()
            .map(|(i, &(lo, hi))| Item { lo, hi, centroid: (lo + hi) * 0.5, index: i as u32 })
            .collect();
        let mut nodes = Vec::with_capacity(2 * items.len().max(1));
        nodes.push(Node { lo: DVec3::ZERO, hi: DVec3::ZERO, start: 0, count: 0 });
        if !items.is_empty() {
            build(&mut nodes, 0, &mut items, 0, max_leaf.max(1));
        }
        Tree { nodes, order: items.iter().map(|it| it.index).collect() }
    }

    /// The nodes in depth-first order with escape links (empty for an
    /// empty tree).
    pub(crate) fn flatten(&self) -> Vec<FlatNode> {
        let mut flat = Vec::with_capacity(self.nodes.len());
        if !self.order.is_empty() {
            self.flatten_from(0, &mut flat);
        }
        flat
    }

    /// Appends node `index`'s subtree; returns its range in `order`.
    fn flatten_from(&self, index: usize, flat: &mut Vec<FlatNode>) -> (u32, u32) {
        let node = self.nodes[index];
        let at = flat.len();
        flat.push(FlatNode {
            lo: node.lo,
            hi: node.hi,
            escape: 0,
            first: node.start,
            count: node.count,
            leaf: node.count > 0,
        });
        if node.count == 0 {
            let (first, left) = self.flatten_from(node.start as usize, flat);
            let (_, right) = self.flatten_from(node.start as usize + 1, flat);
            flat[at].first = first;
            flat[at].count = left + right;
        }
        flat[at].escape = flat.len() as u32;
        (flat[at].first, flat[at].count)
    }
}

/// Builds node `index` over `items` (which start at `offset` in the final order).
fn build(nodes: &mut Vec<Node>, index: usize, items: &mut [Item], offset: usize, max_leaf: usize) {
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    let (mut clo, mut chi) = (lo, hi);
    for it in items.iter() {
        lo = lo.min(it.lo);
        hi = hi.max(it.hi);
        clo = clo.min(it.centroid);
        chi = chi.max(it.centroid);
    }
    nodes[index] = Node { lo, hi, start: offset as u32, count: items.len() as u32 };
    if items.len() <= max_leaf {
        return;
    }
    let extent = chi - clo;
    let leaf_cost = items.len() as f64 * area(lo, hi);
    let mid = match best_split(items, clo, extent) {
        Some((cost, axis, split)) => {
            if cost >= leaf_cost && items.len() <= 2 * max_leaf {
                return;
            }
            let scale = BINS as f64 / extent[axis];
            let bin_of = |c: f64| (((c - clo[axis]) * scale) as usize).min(BINS - 1);
            partition(items, |it| bin_of(it.centroid[axis]) < split)
        }
        // All centroids coincide: split the list in half.
        None => items.len() / 2,
    };
    let left = nodes.len();
    let dummy = Node { lo: DVec3::ZERO, hi: DVec3::ZERO, start: 0, count: 0 };
    nodes.push(dummy);
    nodes.push(dummy);
    nodes[index] = Node { lo, hi, start: left as u32, count: 0 };
    let (a, b) = items.split_at_mut(mid);
    build(nodes, left, a, offset, max_leaf);
    build(nodes, left + 1, b, offset + mid, max_leaf);
}

/// The cheapest binned split of `items` (centroids from `clo` over
/// `extent`): (SAH cost, axis, first bin of the right side).
fn best_split(items: &[Item], clo: DVec3, extent: DVec3) -> Option<(f64, usize, usize)> {
    let mut best: Option<(f64, usize, usize)> = None;
    for axis in 0..3 {
        if extent[axis] <= 0.0 {
            continue;
        }
        let scale = BINS as f64 / extent[axis];
        let bin_of = |c: f64| (((c - clo[axis]) * scale) as usize).min(BINS - 1);
        let mut counts = [0usize; BINS];
        let mut blo = [DVec3::splat(f64::INFINITY); BINS];
        let mut bhi = [DVec3::splat(f64::NEG_INFINITY); BINS];
        for it in items.iter() {
            let b = bin_of(it.centroid[axis]);
            counts[b] += 1;
            blo[b] = blo[b].min(it.lo);
            bhi[b] = bhi[b].max(it.hi);
        }
        // Sweep from the right, then from the left.
        let mut right_area = [0.0; BINS];
        let mut right_count = [0usize; BINS];
        let (mut rlo, mut rhi, mut rc) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY), 0);
        for b in (1..BINS).rev() {
            rlo = rlo.min(blo[b]);
            rhi = rhi.max(bhi[b]);
            rc += counts[b];
            right_area[b] = area(rlo, rhi);
            right_count[b] = rc;
        }
        let (mut llo, mut lhi, mut lc) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY), 0);
        for b in 0..BINS - 1 {
            llo = llo.min(blo[b]);
            lhi = lhi.max(bhi[b]);
            lc += counts[b];
            let rc = right_count[b + 1];
            if lc == 0 || rc == 0 {
                continue;
            }
            let cost = lc as f64 * area(llo, lhi) + rc as f64 * right_area[b + 1];
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, b + 1));
            }
        }
    }
    best
}

/// Stable in-place partition; returns the number of items for which `left` holds.
fn partition(items: &mut [Item], left: impl Fn(&Item) -> bool) -> usize {
    let mut i = 0;
    for j in 0..items.len() {
        if left(&items[j]) {
            items.swap(i, j);
            i += 1;
        }
    }
    i
}

#[cfg(test)]
mod tests {
    use super::*;

    fn boxes(n: usize) -> Vec<(DVec3, DVec3)> {
        // A fixed scatter of small boxes (no RNG needed for a structural test).
        (0..n)
            .map(|i| {
                let f = i as f64;
                let c = DVec3::new((f * 0.618).fract(), (f * 0.382).fract(), (f * 0.137).fract()) * 10.0;
                (c - 0.1, c + 0.1)
            })
            .collect()
    }

    #[test]
    fn every_item_is_listed_once() {
        let tree = Tree::build(&boxes(1000), MAX_LEAF);
        let mut seen = tree.order.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..1000).collect::<Vec<_>>());
    }

    #[test]
    fn the_flattening_keeps_subtrees_contiguous_with_their_escapes() {
        let input = boxes(777);
        let tree = Tree::build(&input, MAX_LEAF);
        let flat = tree.flatten();
        assert_eq!(flat.len(), tree.nodes.len());
        assert_eq!(flat[0].escape as usize, flat.len());
        assert_eq!((flat[0].first, flat[0].count), (0, 777));
        for (i, n) in flat.iter().enumerate() {
            assert!(n.escape as usize > i && n.escape as usize <= flat.len());
            // Every node inside the subtree lies inside the box and the item range.
            for inner in &flat[i + 1..n.escape as usize] {
                assert!(inner.lo.cmpge(n.lo).all() && inner.hi.cmple(n.hi).all());
                assert!(inner.first >= n.first && inner.first + inner.count <= n.first + n.count);
                assert!(inner.escape <= n.escape);
            }
            if n.leaf {
                assert!(n.count as usize <= 2 * MAX_LEAF && n.escape as usize == i + 1);
                for &item in &tree.order[n.first as usize..(n.first + n.count) as usize] {
                    let (lo, hi) = input[item as usize];
                    assert!(lo.cmpge(n.lo).all() && hi.cmple(n.hi).all());
                }
            }
        }
    }

    #[test]
    fn an_empty_tree_flattens_to_nothing() {
        assert!(Tree::build(&[], MAX_LEAF).flatten().is_empty());
    }
}
