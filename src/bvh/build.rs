//! Binned SAH construction, parallel near the root.
//!
//! Each node costs two passes over its primitives: one bins them on all three axes
//! (which also yields both children's exact boxes), one partitions them (which also
//! yields both children's centroid bounds). Above [`BvhParams::parallel_threshold`]
//! primitives the binning pass is split over threads and the two subtrees are built
//! with `rayon::join`.

use glam::{BVec4A, Vec3A, Vec4};
use rayon::prelude::*;

use super::{Bvh, BvhNode, MEDIAN_SPLIT_DEPTH};
use crate::math::{Aabb, Float};

/// Tuning numbers of the builder.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BvhParams {
    /// Number of SAH bins per axis, in `4..=16`.
    pub bins: usize,
    /// Cost of visiting an interior node, relative to `intersection_cost`.
    pub traversal_cost: Float,
    /// Cost of intersecting one primitive.
    pub intersection_cost: Float,
    /// Nodes with more primitives than this are always split.
    pub max_leaf_size: usize,
    /// Subtrees with more primitives than this are built on two threads.
    pub parallel_threshold: usize,
    /// Nodes with more primitives than this are binned on all three axes; smaller
    /// ones only along their widest centroid extent, as pbrt does everywhere. The few
    /// big nodes near the root decide most of the tree's quality; the many small
    /// ones decide most of the build time.
    pub all_axes_threshold: usize,
}

impl Default for BvhParams {
    fn default() -> Self {
        BvhParams {
            bins: 16,
            traversal_cost: 1.0,
            intersection_cost: 1.0,
            max_leaf_size: 8,
            parallel_threshold: 16 * 1024,
            all_axes_threshold: 64,
        }
    }
}

/// Most bins any [`BvhParams`] may ask for; bins live in fixed arrays on the stack,
/// cleared for every node, so more would cost more than they gain.
const MAX_BINS: usize = 16;
/// Fewest bins used for a node: small nodes use one bin per primitive (at least
/// this many), which saves clearing and sweeping bins that would stay empty.
const MIN_BINS: usize = 4;

/// A primitive's box with its original index in the spare lane of `min`: 32 bytes,
/// moved around during the build instead of indexing the caller's arrays.
#[derive(Clone, Copy, Debug)]
#[repr(C)]
struct PrimRef {
    min_and_index: Vec4,
    max: Vec4,
}

/// Keeps x, y, z and clears w. The index bits in `min_and_index.w` read as a
/// denormal float, and arithmetic on denormals takes a microcode assist on x86 (over
/// a hundred cycles): the spare lane must be zero before any SIMD arithmetic.
const XYZ: BVec4A = BVec4A::from_array([true, true, true, false]);

impl PrimRef {
    #[inline(always)]
    fn min(&self) -> Vec3A {
        Vec3A::from_vec4(Vec4::select(XYZ, self.min_and_index, Vec4::ZERO))
    }
    #[inline(always)]
    fn max(&self) -> Vec3A {
        Vec3A::from_vec4(self.max)
    }
    #[inline(always)]
    fn index(&self) -> u32 {
        self.min_and_index.w.to_bits()
    }
    /// Twice the centroid: the factor 1/2 cancels in every comparison.
    #[inline(always)]
    fn centroid2(&self) -> Vec3A {
        self.min() + self.max()
    }
}

/// A box in SIMD registers, for the build's inner loops.
#[derive(Clone, Copy, Debug)]
struct Bounds {
    min: Vec3A,
    max: Vec3A,
}

impl Bounds {
    const EMPTY: Bounds = Bounds {
        min: Vec3A::splat(Float::INFINITY),
        max: Vec3A::splat(Float::NEG_INFINITY),
    };
    #[inline(always)]
    fn grow(&mut self, min: Vec3A, max: Vec3A) {
        self.min = self.min.min(min);
        self.max = self.max.max(max);
    }
    #[inline(always)]
    fn union(self, other: Bounds) -> Bounds {
        Bounds {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }
    #[inline(always)]
    fn half_area(&self) -> Float {
        let e = (self.max - self.min).max(Vec3A::ZERO);
        e.x * e.y + e.y * e.z + e.z * e.x
    }
    fn to_aabb(self) -> Aabb {
        Aabb {
            min: self.min.into(),
            max: self.max.into(),
        }
    }
}

/// Per-axis bins of one node.
#[derive(Clone, Copy)]
struct Bins {
    bounds: [[Bounds; MAX_BINS]; 3],
    counts: [[u32; MAX_BINS]; 3],
}

impl Bins {
    fn new() -> Bins {
        Bins {
            bounds: [[Bounds::EMPTY; MAX_BINS]; 3],
            counts: [[0; MAX_BINS]; 3],
        }
    }
    fn merge(mut self, other: &Bins) -> Bins {
        for a in 0..3 {
            for b in 0..MAX_BINS {
                self.bounds[a][b] = self.bounds[a][b].union(other.bounds[a][b]);
                self.counts[a][b] += other.counts[a][b];
            }
        }
        self
    }
}

/// Maps doubled centroids to bin numbers along each axis.
#[derive(Clone, Copy)]
struct Binning {
    origin: Vec3A,
    scale: Vec3A,
    last_bin: u32,
}

impl Binning {
    #[inline(always)]
    fn bins_of(&self, centroid2: Vec3A) -> [u32; 3] {
        let b = ((centroid2 - self.origin) * self.scale).as_uvec3();
        b.min(glam::UVec3::splat(self.last_bin)).to_array()
    }

    /// Bins `refs` on all three axes.
    fn bin(&self, refs: &[PrimRef]) -> Bins {
        let mut bins = Bins::new();
        for r in refs {
            let (min, max) = (r.min(), r.max());
            for (axis, b) in self.bins_of(min + max).into_iter().enumerate() {
                bins.bounds[axis][b as usize].grow(min, max);
                bins.counts[axis][b as usize] += 1;
            }
        }
        bins
    }

    /// Bins `refs` along `axis` only (the other axes' bins stay empty).
    fn bin_axis(&self, refs: &[PrimRef], axis: usize) -> Bins {
        let mut bins = Bins::new();
        let (origin, scale) = (self.origin[axis], self.scale[axis]);
        for r in refs {
            let (min, max) = (r.min(), r.max());
            let b = (((min[axis] + max[axis] - origin) * scale) as u32).min(self.last_bin) as usize;
            bins.bounds[axis][b].grow(min, max);
            bins.counts[axis][b] += 1;
        }
        bins
    }
}

/// One node's primitives with their box and centroid bounds.
struct Task<'a> {
    refs: &'a mut [PrimRef],
    /// Leaf-order index of `refs[0]`.
    offset: u32,
    bounds: Bounds,
    /// Bounds of the doubled centroids.
    centroids: Bounds,
    depth: usize,
}

/// What to do with one node's primitives.
enum Split {
    Leaf,
    /// Children get `refs[..mid]` and `refs[mid..]` (already partitioned), with
    /// these boxes and centroid bounds.
    At {
        mid: usize,
        bounds: [Bounds; 2],
        centroids: [Bounds; 2],
    },
}

/// A subtree built on its own, before the parallel pieces are laid out in one array.
enum Subtree {
    /// Nodes with child indices relative to this vector, root first.
    Flat(Vec<BvhNode>),
    /// An interior node whose two subtrees were built in parallel.
    Joined(BvhNode, Box<(Subtree, Subtree)>),
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
    /// `4..=16`.
    pub fn build(prim_bounds: &[Aabb], params: &BvhParams) -> (Bvh, Vec<u32>) {
        Bvh::build_with(prim_bounds.len(), |i| prim_bounds[i], params)
    }

    /// [`Bvh::build`] for `prim_count` primitives whose boxes `bounds_of(i)` gives,
    /// so that callers need not hold a second array of boxes.
    ///
    /// # Panics
    /// As [`Bvh::build`].
    pub fn build_with<F>(prim_count: usize, bounds_of: F, params: &BvhParams) -> (Bvh, Vec<u32>)
    where
        F: Fn(usize) -> Aabb + Sync,
    {
        assert!(u32::try_from(prim_count).is_ok(), "too many primitives");
        assert!(
            (MIN_BINS..=MAX_BINS).contains(&params.bins),
            "bins out of range"
        );
        if prim_count == 0 {
            return (Bvh::default(), Vec::new());
        }
        let mut refs: Vec<PrimRef> = (0..prim_count)
            .into_par_iter()
            .map(|i| {
                let b = bounds_of(i);
                PrimRef {
                    min_and_index: b.min.extend(f32::from_bits(i as u32)),
                    max: b.max.extend(0.0),
                }
            })
            .collect();
        let (bounds, centroids) = refs
            .par_chunks(params.parallel_threshold)
            .map(|chunk| {
                let mut bounds = Bounds::EMPTY;
                let mut centroids = Bounds::EMPTY;
                for r in chunk {
                    bounds.grow(r.min(), r.max());
                    centroids.grow(r.centroid2(), r.centroid2());
                }
                (bounds, centroids)
            })
            .reduce(
                || (Bounds::EMPTY, Bounds::EMPTY),
                |a, b| (a.0.union(b.0), a.1.union(b.1)),
            );
        let task = Task {
            refs: &mut refs,
            offset: 0,
            bounds,
            centroids,
            depth: 0,
        };
        let mut max_depth = 0;
        let tree = build_subtree(task, params, &mut max_depth);
        let mut nodes = Vec::with_capacity(count_nodes(&tree));
        nodes.push(BvhNode::default());
        lay_out(tree, 0, &mut nodes);
        let order = refs.iter().map(PrimRef::index).collect();
        (Bvh { nodes, max_depth }, order)
    }
}

fn count_nodes(tree: &Subtree) -> usize {
    match tree {
        Subtree::Flat(nodes) => nodes.len(),
        Subtree::Joined(_, children) => 1 + count_nodes(&children.0) + count_nodes(&children.1),
    }
}

/// Writes `tree` with its root at `nodes[at]` (already allocated), appending the
/// rest; children stay adjacent.
fn lay_out(tree: Subtree, at: usize, nodes: &mut Vec<BvhNode>) {
    match tree {
        Subtree::Flat(flat) => {
            let shift = nodes.len() as u32 - 1;
            let relocate = |mut node: BvhNode| {
                if !node.is_leaf() {
                    node.first_index += shift;
                }
                node
            };
            nodes[at] = relocate(flat[0]);
            nodes.extend(flat[1..].iter().map(|&n| relocate(n)));
        }
        Subtree::Joined(mut root, children) => {
            let first = nodes.len();
            root.first_index = first as u32;
            nodes[at] = root;
            nodes.push(BvhNode::default());
            nodes.push(BvhNode::default());
            let (left, right) = *children;
            lay_out(left, first, nodes);
            lay_out(right, first + 1, nodes);
        }
    }
}

fn build_subtree(task: Task<'_>, params: &BvhParams, max_depth: &mut usize) -> Subtree {
    if task.refs.len() <= params.parallel_threshold {
        return Subtree::Flat(build_sequential(task, params, max_depth));
    }
    let mut root = BvhNode::default();
    root.set_bounds(task.bounds.to_aabb());
    let depth = task.depth;
    match split_node(task.refs, task.bounds, task.centroids, depth, params) {
        Split::Leaf => {
            root.first_index = task.offset;
            root.prim_count = task.refs.len() as u32;
            *max_depth = (*max_depth).max(depth);
            Subtree::Flat(vec![root])
        }
        Split::At {
            mid,
            bounds,
            centroids,
        } => {
            let (left_refs, right_refs) = task.refs.split_at_mut(mid);
            let left = Task {
                refs: left_refs,
                offset: task.offset,
                bounds: bounds[0],
                centroids: centroids[0],
                depth: depth + 1,
            };
            let right = Task {
                refs: right_refs,
                offset: task.offset + mid as u32,
                bounds: bounds[1],
                centroids: centroids[1],
                depth: depth + 1,
            };
            let (mut left_depth, mut right_depth) = (0, 0);
            let children = rayon::join(
                || build_subtree(left, params, &mut left_depth),
                || build_subtree(right, params, &mut right_depth),
            );
            *max_depth = (*max_depth).max(left_depth).max(right_depth);
            Subtree::Joined(root, Box::new(children))
        }
    }
}

/// The single-threaded builder: an explicit work stack writing straight into one
/// array, children allocated as adjacent pairs.
fn build_sequential(task: Task<'_>, params: &BvhParams, max_depth: &mut usize) -> Vec<BvhNode> {
    let refs = task.refs;
    // A binary tree over n leaves-worth of primitives has at most 2n - 1 nodes.
    // Reserving that bound never reallocates; the unused tail is never touched, so
    // it costs address space, not memory.
    let mut nodes = Vec::with_capacity(2 * refs.len());
    nodes.push(BvhNode::default());
    // (node index, start, end relative to `refs`, bounds, centroid bounds, depth)
    let mut work = vec![(
        0usize,
        0usize,
        refs.len(),
        task.bounds,
        task.centroids,
        task.depth,
    )];
    while let Some((node_index, start, end, bounds, centroids, depth)) = work.pop() {
        *max_depth = (*max_depth).max(depth);
        nodes[node_index].set_bounds(bounds.to_aabb());
        match split_node(&mut refs[start..end], bounds, centroids, depth, params) {
            Split::Leaf => {
                nodes[node_index].first_index = task.offset + start as u32;
                nodes[node_index].prim_count = (end - start) as u32;
            }
            Split::At {
                mid,
                bounds,
                centroids,
            } => {
                let left = nodes.len();
                nodes.push(BvhNode::default());
                nodes.push(BvhNode::default());
                nodes[node_index].first_index = left as u32;
                let split = start + mid;
                work.push((left + 1, split, end, bounds[1], centroids[1], depth + 1));
                work.push((left, start, split, bounds[0], centroids[0], depth + 1));
            }
        }
    }
    nodes
}

/// Decides how to split a node and partitions `refs` accordingly.
fn split_node(
    refs: &mut [PrimRef],
    bounds: Bounds,
    centroids: Bounds,
    depth: usize,
    params: &BvhParams,
) -> Split {
    let n = refs.len();
    if n == 1 {
        return Split::Leaf;
    }
    let extent = centroids.max - centroids.min;
    let widest = extent.max_position();
    if extent[widest] <= 0.0 || !extent[widest].is_finite() {
        // All centroids coincide: no plane separates them. Halve by count so that
        // leaves stay small even for piles of identical primitives.
        return if n <= params.max_leaf_size {
            Split::Leaf
        } else {
            split_by_count(refs, n / 2)
        };
    }
    if depth >= MEDIAN_SPLIT_DEPTH {
        refs.select_nth_unstable_by(n / 2, |a, b| {
            a.centroid2()[widest].total_cmp(&b.centroid2()[widest])
        });
        return split_by_count(refs, n / 2);
    }

    // Step 1: bin centroids on all three axes.
    let bin_count = n.clamp(MIN_BINS, params.bins);
    let binning = Binning {
        origin: centroids.min,
        scale: Vec3A::select(
            extent.cmpgt(Vec3A::ZERO),
            Vec3A::splat(bin_count as Float) / extent,
            Vec3A::ZERO,
        ),
        last_bin: bin_count as u32 - 1,
    };
    let all_axes = n > params.all_axes_threshold;
    let bins = if n > params.parallel_threshold {
        refs.par_chunks(params.parallel_threshold)
            .map(|chunk| binning.bin(chunk))
            .reduce(Bins::new, |a, b| a.merge(&b))
    } else if all_axes {
        binning.bin(refs)
    } else {
        binning.bin_axis(refs, widest)
    };

    // Step 2: sweep each binned axis from the right, then from the left, to find the
    // plane of lowest cost `A_l N_l + A_r N_r`.
    let mut best: Option<(usize, usize, Float)> = None;
    for axis in 0..3 {
        if extent[axis] <= 0.0 || !(all_axes || axis == widest) {
            continue;
        }
        let mut right_cost = [0.0 as Float; MAX_BINS];
        let mut acc = Bounds::EMPTY;
        let mut count = 0u32;
        for b in (1..bin_count).rev() {
            acc = acc.union(bins.bounds[axis][b]);
            count += bins.counts[axis][b];
            right_cost[b] = acc.half_area() * count as Float;
        }
        let mut acc = Bounds::EMPTY;
        let mut count = 0u32;
        for (b, right) in right_cost.iter().enumerate().take(bin_count).skip(1) {
            acc = acc.union(bins.bounds[axis][b - 1]);
            count += bins.counts[axis][b - 1];
            if count == 0 || count as usize == n {
                continue;
            }
            let cost = acc.half_area() * count as Float + right;
            if best.is_none_or(|(_, _, c)| cost < c) {
                best = Some((axis, b, cost));
            }
        }
    }

    // Step 3: compare the cheapest split, `c_trav + c_int (A_l N_l + A_r N_r) / A`,
    // with making a leaf, `c_int N`.
    let Some((axis, split_bin, cost)) = best else {
        return Split::Leaf;
    };
    let area = bounds.half_area().max(Float::MIN_POSITIVE);
    let split_cost = params.traversal_cost + params.intersection_cost * cost / area;
    let leaf_cost = params.intersection_cost * n as Float;
    if split_cost >= leaf_cost && n <= params.max_leaf_size {
        return Split::Leaf;
    }

    // Step 4: partition in place around the chosen plane, then measure both sides'
    // centroids (a separate pass keeps the accumulators in registers); their boxes
    // come from the bins.
    let (origin, scale) = (binning.origin[axis], binning.scale[axis]);
    let goes_left = |r: &PrimRef| {
        let c = r.min_and_index[axis] + r.max[axis];
        (((c - origin) * scale) as u32).min(binning.last_bin) < split_bin as u32
    };
    // Branch-free: the side is data-dependent and mispredicts half the time. Every
    // element of `refs[mid..i]` goes right, so swapping a right element with
    // `refs[mid]` changes nothing that matters.
    let mut mid = 0;
    for i in 0..n {
        let left = goes_left(&refs[i]);
        refs.swap(i, mid);
        mid += usize::from(left);
    }
    let centroids_of = |part: &[PrimRef]| {
        part.iter().fold(Bounds::EMPTY, |mut acc, r| {
            let c = r.centroid2();
            acc.grow(c, c);
            acc
        })
    };
    let centroid_sides = [centroids_of(&refs[..mid]), centroids_of(&refs[mid..])];
    debug_assert!(mid > 0 && mid < n, "SAH split leaves a side empty");
    let side = |range: std::ops::Range<usize>| {
        range.fold(Bounds::EMPTY, |acc, b| acc.union(bins.bounds[axis][b]))
    };
    Split::At {
        mid,
        bounds: [side(0..split_bin), side(split_bin..bin_count)],
        centroids: centroid_sides,
    }
}

/// Splits at `mid` as the primitives lie, measuring both sides.
fn split_by_count(refs: &[PrimRef], mid: usize) -> Split {
    let measure = |part: &[PrimRef]| {
        part.iter()
            .fold((Bounds::EMPTY, Bounds::EMPTY), |(mut b, mut c), r| {
                b.grow(r.min(), r.max());
                c.grow(r.centroid2(), r.centroid2());
                (b, c)
            })
    };
    let (left_bounds, left_centroids) = measure(&refs[..mid]);
    let (right_bounds, right_centroids) = measure(&refs[mid..]);
    Split::At {
        mid,
        bounds: [left_bounds, right_bounds],
        centroids: [left_centroids, right_centroids],
    }
}
