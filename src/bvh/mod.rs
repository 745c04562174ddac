//! Bounding volume hierarchies over boxes and indices.
//!
//! The BVHs know nothing of triangles, spheres or materials. The binary [`Bvh`] is
//! built from one [`Aabb`] per primitive; [`Bvh::build`] returns the order in which
//! the caller must store its primitives, so leaves index primitive arrays directly.
//! It is then collapsed into the 8-wide [`WideBvh`], which rays traverse with a
//! closure that intersects a leaf's items (as obvhs and the `bvh` crate do).

mod build;
mod collapse;
mod node;
mod packet;
mod stream;
mod wide;

pub use build::BvhParams;
pub use node::BvhNode;
pub use packet::{CLOSEST_CULL_MARGIN, PACKET_SIZE, RayPacket, lanes_of};
pub(crate) use packet::{lane_mask, reduce_min};
pub use stream::STREAM_RAYS;
pub(crate) use wide::{PREFETCH_LINES, STACK_SIZE, WIDTH};
pub use wide::{RayQuery, WideBvh, WideNode};

use crate::math::Aabb;

/// A flat BVH: node 0 is the root; an interior node's children are adjacent.
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    /// All nodes; see [`BvhNode`] for the invariants.
    pub nodes: Vec<BvhNode>,
    /// Greatest depth of the tree, the root being depth 0.
    pub max_depth: usize,
    /// Ranges of the leaf order holding more than `max_leaf_size` primitives whose
    /// centroids all coincide (the largest such subtrees): no plane separates them,
    /// so every ray that reaches one tests them all. Copies of one primitive pile up
    /// here, and only here, so a caller can look for duplicates in these ranges
    /// alone. Empty for almost every scene.
    pub coincident: Vec<std::ops::Range<u32>>,
}

/// Deepest tree the traversal stack can hold. The builder switches to median splits
/// below `MEDIAN_SPLIT_DEPTH`, so depth stays under this bound for any input size
/// a `u32` index can address (64 + 32 levels).
pub const MAX_DEPTH: usize = 128;
/// Depth from which the builder stops trusting SAH and halves nodes by count.
pub(crate) const MEDIAN_SPLIT_DEPTH: usize = 64;

/// A broken invariant found by [`Bvh::validate`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("invalid BVH: {0}")]
pub struct BvhInvariantError(pub String);

impl Bvh {
    /// Number of primitives referenced by the leaves.
    pub fn prim_count(&self) -> usize {
        self.nodes
            .iter()
            .filter(|n| n.is_leaf())
            .map(|n| n.prim_count as usize)
            .sum()
    }

    /// The surface area heuristic cost of the tree, relative to the root's area:
    /// `sum(interior) A/A_root * c_trav + sum(leaves) A/A_root * tests * c_int`, a
    /// leaf's tests as [`BvhParams::leaf_tests`] counts them.
    /// Lower is better; a quality number to compare builders with.
    pub fn sah_cost(&self, params: &BvhParams) -> f64 {
        let Some(root) = self.nodes.first() else {
            return 0.0;
        };
        let root_area = root.bounds().half_area() as f64;
        if root_area <= 0.0 {
            return 0.0;
        }
        self.nodes
            .iter()
            .map(|n| {
                let rel = n.bounds().half_area() as f64 / root_area;
                if n.is_leaf() {
                    rel * params.leaf_tests(n.prim_count as usize) as f64
                        * params.intersection_cost as f64
                } else {
                    rel * params.traversal_cost as f64
                }
            })
            .sum()
    }

    /// Checks every invariant: each node is reached exactly once from the root, each
    /// primitive `0..prim_bounds.len()` is in exactly one leaf, children lie inside
    /// their parent, leaves contain their primitives' boxes, and depth fits the stack.
    /// `prim_bounds` must be in leaf order (the order [`Bvh::build`] returned).
    ///
    /// # Errors
    /// The first broken invariant found.
    pub fn validate(&self, prim_bounds: &[Aabb]) -> Result<(), BvhInvariantError> {
        let fail = |msg: String| Err(BvhInvariantError(msg));
        if self.nodes.is_empty() {
            return if prim_bounds.is_empty() {
                Ok(())
            } else {
                fail(format!("no nodes for {} primitives", prim_bounds.len()))
            };
        }
        let mut node_seen = vec![false; self.nodes.len()];
        let mut prim_seen = vec![false; prim_bounds.len()];
        let mut stack = vec![(0usize, 0usize)];
        let mut max_depth = 0;
        while let Some((index, depth)) = stack.pop() {
            max_depth = max_depth.max(depth);
            if node_seen[index] {
                return fail(format!("node {index} reached twice"));
            }
            node_seen[index] = true;
            let node = &self.nodes[index];
            let bounds = node.bounds();
            if node.is_leaf() {
                let range =
                    node.first_index as usize..(node.first_index + node.prim_count) as usize;
                if range.end > prim_bounds.len() {
                    return fail(format!("leaf {index} refers past the primitive array"));
                }
                for p in range {
                    if std::mem::replace(&mut prim_seen[p], true) {
                        return fail(format!("primitive {p} in two leaves"));
                    }
                    if !bounds.contains(&prim_bounds[p]) {
                        return fail(format!("leaf {index} does not contain primitive {p}"));
                    }
                }
            } else {
                let first = node.first_index as usize;
                if first == 0 || first + 1 >= self.nodes.len() {
                    return fail(format!("node {index} has children out of range"));
                }
                for child in [first, first + 1] {
                    if !bounds.contains(&self.nodes[child].bounds()) {
                        return fail(format!("child {child} sticks out of node {index}"));
                    }
                    stack.push((child, depth + 1));
                }
            }
        }
        if let Some(unseen) = node_seen.iter().position(|&s| !s) {
            return fail(format!("node {unseen} unreachable"));
        }
        if let Some(missing) = prim_seen.iter().position(|&s| !s) {
            return fail(format!("primitive {missing} in no leaf"));
        }
        if max_depth != self.max_depth || max_depth >= MAX_DEPTH {
            return fail(format!(
                "depth {max_depth} (recorded {}, limit {MAX_DEPTH})",
                self.max_depth
            ));
        }
        Ok(())
    }
}
