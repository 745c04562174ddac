//! Binned SAH construction, parallel near the root.

use super::{Bvh, BvhNode, MEDIAN_SPLIT_DEPTH};
use crate::math::{Aabb, Float, Vec3};

/// Tuning numbers of the builder.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BvhParams {
    /// Number of SAH bins per axis.
    pub bins: usize,
    /// Cost of visiting an interior node, relative to `intersection_cost`.
    pub traversal_cost: Float,
    /// Cost of intersecting one primitive.
    pub intersection_cost: Float,
    /// Nodes with more primitives than this are always split.
    pub max_leaf_size: usize,
    /// Subtrees with more primitives than this are built on two threads.
    pub parallel_threshold: usize,
}

impl Default for BvhParams {
    fn default() -> Self {
        BvhParams {
            bins: 16,
            traversal_cost: 1.0,
            intersection_cost: 1.0,
            max_leaf_size: 8,
            parallel_threshold: 32 * 1024,
        }
    }
}

/// Most bins any [`BvhParams`] may ask for; bins live in fixed arrays on the stack.
const MAX_BINS: usize = 32;

/// A primitive's box and original index, moved around during the build instead of
/// indexing into the caller's arrays (sequential memory, no indirection).
#[derive(Clone, Copy, Debug)]
struct PrimRef {
    min: Vec3,
    index: u32,
    max: Vec3,
}

impl PrimRef {
    #[inline]
    fn centroid(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }
    #[inline]
    fn bounds(&self) -> Aabb {
        Aabb {
            min: self.min,
            max: self.max,
        }
    }
}

impl Bvh {
    /// Builds a BVH over `prim_bounds` (one box per primitive).
    ///
    /// Returns the tree and the leaf order: `order[i]` is the original index of the
    /// primitive that must be stored at position `i`, because leaves address
    /// primitives as ranges of that order.
    ///
    /// # Panics
    /// If there are more than `u32::MAX` primitives or `params.bins` is not in
    /// `2..=32`.
    pub fn build(prim_bounds: &[Aabb], params: &BvhParams) -> (Bvh, Vec<u32>) {
        assert!(
            u32::try_from(prim_bounds.len()).is_ok(),
            "too many primitives"
        );
        assert!((2..=MAX_BINS).contains(&params.bins), "bins out of range");
        let mut refs: Vec<PrimRef> = prim_bounds
            .iter()
            .enumerate()
            .map(|(i, b)| PrimRef {
                min: b.min,
                index: i as u32,
                max: b.max,
            })
            .collect();
        if refs.is_empty() {
            return (Bvh::default(), Vec::new());
        }
        let (nodes, max_depth) = build_subtree(&mut refs, 0, 0, params);
        let order = refs.iter().map(|r| r.index).collect();
        (Bvh { nodes, max_depth }, order)
    }
}

/// What to do with one node's primitives.
enum Split {
    Leaf,
    /// Children are `refs[..mid]` and `refs[mid..]` (already partitioned).
    At(usize),
}

/// Builds the subtree over `refs` (whose first element has leaf-order index
/// `offset`) and returns its nodes, root first, with child indices relative to the
/// returned vector, and the greatest depth reached (the subtree root is at `depth`).
fn build_subtree(
    refs: &mut [PrimRef],
    offset: u32,
    depth: usize,
    params: &BvhParams,
) -> (Vec<BvhNode>, usize) {
    if refs.len() <= params.parallel_threshold {
        return build_sequential(refs, offset, depth, params);
    }
    let (bounds, split) = split_node(refs, depth, params);
    let mut root = BvhNode::default();
    root.set_bounds(bounds);
    let Split::At(mid) = split else {
        root.first_index = offset;
        root.prim_count = refs.len() as u32;
        return (vec![root], depth);
    };
    let (left_refs, right_refs) = refs.split_at_mut(mid);
    let ((left, left_depth), (right, right_depth)) = rayon::join(
        || build_subtree(left_refs, offset, depth + 1, params),
        || build_subtree(right_refs, offset + mid as u32, depth + 1, params),
    );
    // Layout: root, left root, right root, rest of left, rest of right.
    let mut nodes = Vec::with_capacity(1 + left.len() + right.len());
    root.first_index = 1;
    nodes.push(root);
    let left_shift = 2;
    let right_shift = left.len() as u32 + 1;
    let relocate = |mut node: BvhNode, shift: u32| {
        if !node.is_leaf() {
            node.first_index += shift;
        }
        node
    };
    nodes.push(relocate(left[0], left_shift));
    nodes.push(relocate(right[0], right_shift));
    nodes.extend(left[1..].iter().map(|&n| relocate(n, left_shift)));
    nodes.extend(right[1..].iter().map(|&n| relocate(n, right_shift)));
    (nodes, left_depth.max(right_depth))
}

/// The single-threaded builder: an explicit work stack writing straight into the
/// final array, children allocated as adjacent pairs.
fn build_sequential(
    refs: &mut [PrimRef],
    offset: u32,
    depth: usize,
    params: &BvhParams,
) -> (Vec<BvhNode>, usize) {
    let mut nodes = Vec::with_capacity(2 * refs.len().div_ceil(2));
    nodes.push(BvhNode::default());
    let mut max_depth = depth;
    // (node index, start, end, depth) with start/end relative to `refs`.
    let mut work = vec![(0usize, 0usize, refs.len(), depth)];
    while let Some((node_index, start, end, node_depth)) = work.pop() {
        max_depth = max_depth.max(node_depth);
        let (bounds, split) = split_node(&mut refs[start..end], node_depth, params);
        nodes[node_index].set_bounds(bounds);
        match split {
            Split::Leaf => {
                nodes[node_index].first_index = offset + start as u32;
                nodes[node_index].prim_count = (end - start) as u32;
            }
            Split::At(mid) => {
                let left = nodes.len();
                nodes.push(BvhNode::default());
                nodes.push(BvhNode::default());
                nodes[node_index].first_index = left as u32;
                work.push((left, start, start + mid, node_depth + 1));
                work.push((left + 1, start + mid, end, node_depth + 1));
            }
        }
    }
    (nodes, max_depth)
}

/// Computes the node's box and decides how to split it, partitioning `refs` in place.
fn split_node(refs: &mut [PrimRef], depth: usize, params: &BvhParams) -> (Aabb, Split) {
    // Step 1: bounds of the boxes and of the centroids.
    let mut bounds = Aabb::EMPTY;
    let mut centroid_bounds = Aabb::EMPTY;
    for r in refs.iter() {
        bounds = bounds.union(r.bounds());
        centroid_bounds = centroid_bounds.grow(r.centroid());
    }
    let n = refs.len();
    if n == 1 {
        return (bounds, Split::Leaf);
    }
    let extent = centroid_bounds.max - centroid_bounds.min;
    let axis = extent.max_position();
    if extent[axis] <= 0.0 || !extent[axis].is_finite() {
        // All centroids coincide: no plane separates them. Halve by count so that
        // leaves stay small even for piles of identical primitives.
        return if n <= params.max_leaf_size {
            (bounds, Split::Leaf)
        } else {
            (bounds, Split::At(n / 2))
        };
    }
    if depth >= MEDIAN_SPLIT_DEPTH {
        let mid = n / 2;
        refs.select_nth_unstable_by(mid, |a, b| {
            a.centroid()[axis].total_cmp(&b.centroid()[axis])
        });
        return (bounds, Split::At(mid));
    }

    // Step 2: bin centroids on all three axes.
    let bins = params.bins;
    let mut bin_bounds = [[Aabb::EMPTY; MAX_BINS]; 3];
    let mut bin_counts = [[0u32; MAX_BINS]; 3];
    let scale = Vec3::select(
        extent.cmpgt(Vec3::ZERO),
        Vec3::splat(bins as Float) / extent,
        Vec3::ZERO,
    );
    let bin_of = |c: Vec3, a: usize| -> usize {
        (((c[a] - centroid_bounds.min[a]) * scale[a]) as usize).min(bins - 1)
    };
    for r in refs.iter() {
        let c = r.centroid();
        for a in 0..3 {
            let b = bin_of(c, a);
            bin_bounds[a][b] = bin_bounds[a][b].union(r.bounds());
            bin_counts[a][b] += 1;
        }
    }

    // Step 3: sweep each axis from the right, then from the left, to find the plane
    // of lowest cost `c_trav + (A_l N_l + A_r N_r) / A * c_int`.
    let mut best: Option<(usize, usize, Float)> = None;
    for a in 0..3 {
        if extent[a] <= 0.0 {
            continue;
        }
        let mut right_cost = [0.0 as Float; MAX_BINS];
        let mut acc = Aabb::EMPTY;
        let mut count = 0u32;
        for b in (1..bins).rev() {
            acc = acc.union(bin_bounds[a][b]);
            count += bin_counts[a][b];
            right_cost[b] = acc.half_area() * count as Float;
        }
        let mut acc = Aabb::EMPTY;
        let mut count = 0u32;
        for b in 1..bins {
            acc = acc.union(bin_bounds[a][b - 1]);
            count += bin_counts[a][b - 1];
            if count == 0 || count as usize == n {
                continue;
            }
            let cost = acc.half_area() * count as Float + right_cost[b];
            if best.is_none_or(|(_, _, c)| cost < c) {
                best = Some((a, b, cost));
            }
        }
    }

    // Step 4: compare the cheapest split with making a leaf.
    let area = bounds.half_area();
    let Some((axis, split_bin, cost)) = best else {
        return (bounds, Split::Leaf);
    };
    let split_cost =
        params.traversal_cost + params.intersection_cost * cost / area.max(Float::MIN_POSITIVE);
    let leaf_cost = params.intersection_cost * n as Float;
    if split_cost >= leaf_cost && n <= params.max_leaf_size {
        return (bounds, Split::Leaf);
    }

    // Step 5: partition in place around the chosen plane.
    let mut mid = 0;
    for i in 0..n {
        if bin_of(refs[i].centroid(), axis) < split_bin {
            refs.swap(i, mid);
            mid += 1;
        }
    }
    debug_assert!(mid > 0 && mid < n, "SAH split leaves a side empty");
    (bounds, Split::At(mid))
}
