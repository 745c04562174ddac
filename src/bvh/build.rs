//! Binned SAH construction, parallel from the root.
//!
//! Each node costs two passes over its primitives: one bins them (which also yields
//! both children's exact boxes), one partitions them (which also yields both
//! children's centroid bounds). Above [`BvhParams::parallel_threshold`] primitives
//! both passes are split into fixed blocks over threads and the two subtrees are
//! built with `rayon::join`, so both cores work from the root on; fixed blocks keep
//! the tree the same for any number of threads.
//!
//! Nodes go straight into one array: a subtree over `m` primitives has at most
//! `2m - 1` nodes, so each subtree gets a slot range of that size at a position known
//! before any of it is built, and one pass at the end closes the gaps the ranges
//! leave (leaves hold more than one primitive, so most ranges are not filled).

use std::mem::MaybeUninit;

use glam::{BVec4A, Vec3A, Vec4};
use rayon::prelude::*;

use super::{Bvh, BvhNode, MEDIAN_SPLIT_DEPTH};
use crate::math::{Aabb, Float};
use crate::memory;

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
    /// Nodes with more primitives than this are binned and partitioned on all
    /// threads, in blocks of this many primitives, and their subtrees are built in
    /// parallel.
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
const _: () = assert!(MAX_BINS.is_power_of_two());
/// Fewest bins used for a node: small nodes use one bin per primitive (at least
/// this many), which saves clearing and sweeping bins that would stay empty.
const MIN_BINS: usize = 4;
/// Primitives per block when the references are made on all threads. Fixed, so that
/// the blocks (and with them the tree) do not depend on the number of threads.
const REF_BLOCK: usize = 16 * 1024;

/// A primitive's box with its original index in the spare lane of `min`: 32 bytes,
/// moved around during the build instead of indexing the caller's arrays.
#[derive(Clone, Copy, Debug)]
#[repr(C)]
struct PrimRef {
    min_and_index: Vec4,
    max: Vec4,
}

// SAFETY: `PrimRef` is plain `f32` lanes, for which all-zero bits are 0.0.
unsafe impl bytemuck::Zeroable for PrimRef {}

/// Keeps x, y, z and clears w. The index bits in `min_and_index.w` read as a
/// denormal float, and arithmetic on denormals takes a microcode assist on x86 (over
/// a hundred cycles): the spare lane must be zero before any SIMD arithmetic.
const XYZ: BVec4A = BVec4A::from_array([true, true, true, false]);

impl PrimRef {
    fn new(bounds: Aabb, index: usize) -> PrimRef {
        PrimRef {
            min_and_index: bounds.min.extend(f32::from_bits(index as u32)),
            max: bounds.max.extend(0.0),
        }
    }
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
    /// One coordinate of [`PrimRef::centroid2`], read from memory at an offset
    /// rather than picked out of a register by a jump on `axis`.
    #[inline(always)]
    fn centroid2_on(&self, axis: usize) -> Float {
        let min: &[f32; 4] = self.min_and_index.as_ref();
        let max: &[f32; 4] = self.max.as_ref();
        min[axis] + max[axis]
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
        // `e.x * e.y + e.y * e.z + e.z * e.x`, the products in one instruction.
        let e = (self.max - self.min).max(Vec3A::ZERO);
        (e * Vec3A::new(e.y, e.z, e.x)).element_sum()
    }
    fn to_aabb(self) -> Aabb {
        Aabb {
            min: self.min.into(),
            max: self.max.into(),
        }
    }
}

/// The boxes and centroid bounds of some primitives.
fn measure(refs: &[PrimRef]) -> (Bounds, Bounds) {
    refs.iter()
        .fold((Bounds::EMPTY, Bounds::EMPTY), |(mut b, mut c), r| {
            b.grow(r.min(), r.max());
            c.grow(r.centroid2(), r.centroid2());
            (b, c)
        })
}

/// The bins of one axis.
#[derive(Clone, Copy)]
struct AxisBins {
    bounds: [Bounds; MAX_BINS],
    counts: [u32; MAX_BINS],
}

impl AxisBins {
    const EMPTY: AxisBins = AxisBins {
        bounds: [Bounds::EMPTY; MAX_BINS],
        counts: [0; MAX_BINS],
    };

    /// Empties the first `bin_count` bins, the only ones a node uses: cheaper than
    /// writing a whole fresh `AxisBins` (which compiles to a copy of the constant).
    #[inline(always)]
    fn reset(&mut self, bin_count: usize) {
        self.bounds[..bin_count].fill(Bounds::EMPTY);
        // All of them: a fixed size is a few vector stores, a variable one a call.
        self.counts = [0; MAX_BINS];
    }

    #[inline(always)]
    fn add(&mut self, bin: u32, min: Vec3A, max: Vec3A) {
        // `bin` is below `MAX_BINS` already; the mask lets the compiler see it.
        let bin = bin as usize & (MAX_BINS - 1);
        self.bounds[bin].grow(min, max);
        self.counts[bin] += 1;
    }

    /// Adds the first `bin_count` bins of `other`.
    fn merge_from(&mut self, other: &AxisBins, bin_count: usize) {
        for b in 0..bin_count {
            self.bounds[b] = self.bounds[b].union(other.bounds[b]);
            self.counts[b] += other.counts[b];
        }
    }

    fn merge(mut self, other: &AxisBins) -> AxisBins {
        for b in 0..MAX_BINS {
            self.bounds[b] = self.bounds[b].union(other.bounds[b]);
            self.counts[b] += other.counts[b];
        }
        self
    }

    /// The cheapest plane between bins of the first `bin_count`, by sweeping from
    /// the right, then from the left: `(first bin on the right, A_l N_l + A_r N_r)`.
    /// `None` if every plane leaves a side empty.
    fn best_plane(&self, bin_count: usize) -> Option<(usize, Float)> {
        let mut right_cost = [0.0 as Float; MAX_BINS];
        let mut acc = Bounds::EMPTY;
        let mut count = 0u32;
        for b in (1..bin_count).rev() {
            acc = acc.union(self.bounds[b]);
            count += self.counts[b];
            right_cost[b] = acc.half_area() * count as Float;
        }
        let total = count + self.counts[0];
        // The first plane of least cost; `found` rather than an infinite start so
        // that infinite or NaN costs still pick a plane, as for finite ones.
        let (mut found, mut best_bin, mut best_cost) = (false, 0, Float::INFINITY);
        let mut acc = Bounds::EMPTY;
        let mut count = 0u32;
        for (b, right) in right_cost.iter().enumerate().take(bin_count).skip(1) {
            acc = acc.union(self.bounds[b - 1]);
            count += self.counts[b - 1];
            let cost = acc.half_area() * count as Float + right;
            if count != 0 && count != total && (!found || cost < best_cost) {
                (found, best_bin, best_cost) = (true, b, cost);
            }
        }
        found.then_some((best_bin, best_cost))
    }

    /// Box of bins `range`.
    fn side(&self, range: std::ops::Range<usize>) -> Bounds {
        range.fold(Bounds::EMPTY, |acc, b| acc.union(self.bounds[b]))
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
    /// Bin numbers on all three axes: `(c - origin) * scale`, truncated and clamped
    /// to `0..=last_bin` (NaN to 0).
    #[inline(always)]
    fn bins_of(&self, centroid2: Vec3A) -> [u32; 3] {
        // Clamped as floats, which also maps NaN to 0 (`max` returns its second
        // operand when the first is NaN): one instruction for all lanes.
        let scaled = ((centroid2 - self.origin) * self.scale)
            .max(Vec3A::ZERO)
            .min(Vec3A::splat(self.last_bin as Float));
        truncate(scaled)
    }

    /// Bins `refs` on all three axes into `bins`.
    fn bin(&self, refs: &[PrimRef], bins: &mut [AxisBins; 3]) {
        let bin_count = self.last_bin as usize + 1;
        // Neighbouring primitives mostly fall into the same bins, and each update
        // must wait for the previous one's store: two sets of bins, taking every
        // other primitive, halve that chain.
        let mut odd = [AxisBins::EMPTY; 3];
        for axis_bins in bins.iter_mut().chain(odd.iter_mut()) {
            axis_bins.reset(bin_count);
        }
        let mut pairs = refs.chunks_exact(2);
        for pair in &mut pairs {
            self.add(&pair[0], bins);
            self.add(&pair[1], &mut odd);
        }
        if let [r] = pairs.remainder() {
            self.add(r, bins);
        }
        for (axis_bins, odd) in bins.iter_mut().zip(&odd) {
            axis_bins.merge_from(odd, bin_count);
        }
    }

    #[inline(always)]
    fn add(&self, r: &PrimRef, bins: &mut [AxisBins; 3]) {
        let (min, max) = (r.min(), r.max());
        let [x, y, z] = self.bins_of(min + max);
        bins[0].add(x, min, max);
        bins[1].add(y, min, max);
        bins[2].add(z, min, max);
    }

    /// Bins `refs` along `axis` only, into `bins`. All three lanes cost the same as
    /// one, and picking a lane from memory avoids a jump on `axis` per primitive.
    fn bin_axis(&self, refs: &[PrimRef], axis: usize, bins: &mut AxisBins) {
        bins.reset(self.last_bin as usize + 1);
        for r in refs {
            let (min, max) = (r.min(), r.max());
            let b = self.bins_of(min + max)[axis];
            bins.add(b, min, max);
        }
    }

    /// Whether a doubled centroid falls in a bin before `split_bin` along `axis`:
    /// the same test as comparing [`Binning::bins_of`], without converting to
    /// integers (truncation of `x >= 0` is below an integer `k` exactly when `x` is;
    /// negative and NaN values are bin 0).
    #[inline(always)]
    // `!(x >= split)` rather than `x < split`: NaN goes left, as it is binned to 0.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    fn goes_left(&self, axis: usize, split_bin: u32) -> impl Fn(&PrimRef) -> bool + Sync + use<> {
        let origin = self.origin.to_array()[axis];
        let scale = self.scale.to_array()[axis];
        let split = split_bin as Float;
        move |r: &PrimRef| !((r.centroid2_on(axis) - origin) * scale >= split)
    }
}

/// `x` truncated towards zero, lane by lane, for lanes in `0..2^31`. `as u32` on
/// each lane would saturate in half a dozen scalar instructions per lane.
#[inline(always)]
fn truncate(x: Vec3A) -> [u32; 3] {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::_mm_cvttps_epi32;
        // SAFETY: SSE2 is part of the x86_64 baseline.
        let lanes: [u32; 4] = bytemuck::cast(unsafe { _mm_cvttps_epi32(x.into()) });
        [lanes[0], lanes[1], lanes[2]]
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        x.as_uvec3().to_array()
    }
}

/// Partitions `refs` so that those `goes_left` come first and measures the
/// centroids of both sides: `(number going left, [left, right] centroid bounds)`.
#[inline(always)]
fn partition(refs: &mut [PrimRef], goes_left: impl Fn(&PrimRef) -> bool) -> (usize, [Bounds; 2]) {
    // Branch-free: the side is data-dependent and mispredicts half the time. Every
    // element of `refs[mid..i]` goes right, so swapping a right element with
    // `refs[mid]` changes nothing that matters.
    let mut mid = 0;
    for i in 0..refs.len() {
        let left = goes_left(&refs[i]);
        refs.swap(i, mid);
        mid += usize::from(left);
    }
    // A separate pass keeps the accumulators in registers.
    let centroids_of = |part: &[PrimRef]| {
        part.iter().fold(Bounds::EMPTY, |mut acc, r| {
            let c = r.centroid2();
            acc.grow(c, c);
            acc
        })
    };
    let (left, right) = refs.split_at(mid);
    (mid, [centroids_of(left), centroids_of(right)])
}

/// [`partition`] on all threads: each block of `block` primitives is partitioned on
/// its own, then the right-goers left of the final split change places with the
/// left-goers right of it.
fn partition_parallel(
    refs: &mut [PrimRef],
    block: usize,
    goes_left: impl Fn(&PrimRef) -> bool + Sync,
) -> (usize, [Bounds; 2]) {
    let parts: Vec<(usize, [Bounds; 2])> = refs
        .par_chunks_mut(block)
        .map(|chunk| partition(chunk, &goes_left))
        .collect();
    let left_counts: Vec<usize> = parts.iter().map(|p| p.0).collect();
    let mid = gather_block_heads(refs, block, &left_counts);
    let centroids = parts.iter().fold([Bounds::EMPTY; 2], |acc, p| {
        [acc[0].union(p.1[0]), acc[1].union(p.1[1])]
    });
    (mid, centroids)
}

/// Moves the heads of all blocks to the front: block `k` of `refs` (`block`
/// elements each, the last one shorter) starts with `heads[k]` elements that belong
/// in front, followed by elements that belong at the back. Swaps, on all threads,
/// the back elements before the final split with the front elements after it, and
/// returns the split (the sum of `heads`). Fixed blocks make the result independent
/// of the thread count.
fn gather_block_heads(refs: &mut [PrimRef], block: usize, heads: &[usize]) -> usize {
    let mid: usize = heads.iter().sum();
    // Back elements before `mid` and front elements after it, as ranges in order;
    // there are as many of one as of the other.
    let mut back_early = Vec::new();
    let mut front_late = Vec::new();
    for (k, &head) in heads.iter().enumerate() {
        let start = k * block;
        let end = (start + block).min(refs.len());
        let split = start + head;
        if split < mid && split < end {
            back_early.push(split..end.min(mid));
        }
        if split > mid {
            front_late.push(start.max(mid)..split);
        }
    }
    // Pair them up into equal pieces.
    let mut pieces = Vec::new();
    let mut late = front_late.into_iter();
    let mut current = late.next();
    for mut early in back_early {
        while early.start < early.end {
            let Some(l) = current.as_mut() else {
                unreachable!("as many back elements before the split as front ones after")
            };
            let len = early.len().min(l.len());
            pieces.push((early.start, l.start, len));
            early.start += len;
            l.start += len;
            if l.start == l.end {
                current = late.next();
            }
        }
    }
    // Cut both sides into the pieces' disjoint slices, then swap them in parallel.
    let (mut front, mut back) = refs.split_at_mut(mid);
    let (mut front_at, mut back_at) = (0, mid);
    let mut swaps = Vec::with_capacity(pieces.len());
    for (a, b, len) in pieces {
        let (_, rest) = std::mem::take(&mut front).split_at_mut(a - front_at);
        let (piece_a, rest) = rest.split_at_mut(len);
        front = rest;
        front_at = a + len;
        let (_, rest) = std::mem::take(&mut back).split_at_mut(b - back_at);
        let (piece_b, rest) = rest.split_at_mut(len);
        back = rest;
        back_at = b + len;
        swaps.push((piece_a, piece_b));
    }
    swaps
        .into_par_iter()
        .for_each(|(a, b)| a.swap_with_slice(b));
    mid
}

/// What became of one node's primitives.
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

/// A run of filled slots in the node array, in the order the build left them.
#[derive(Clone, Copy, Debug)]
struct Segment {
    start: u32,
    len: u32,
    /// A pair of children built on their own: its interior nodes point at the start
    /// of another segment. Otherwise a subtree built sequentially, whose interior
    /// nodes point inside the segment.
    joined: bool,
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
        Bvh::build_filtered(prim_count, |i| Some(bounds_of(i)), params)
    }

    /// [`Bvh::build_with`] over the primitives for which `bounds_of(i)` gives a box;
    /// the others are left out of the tree and of the returned order, which lists
    /// original indices. Lets the caller drop primitives in the same pass that
    /// measures them.
    ///
    /// # Panics
    /// As [`Bvh::build`].
    pub fn build_filtered<F>(prim_count: usize, bounds_of: F, params: &BvhParams) -> (Bvh, Vec<u32>)
    where
        F: Fn(usize) -> Option<Aabb> + Sync,
    {
        assert!(u32::try_from(prim_count).is_ok(), "too many primitives");
        assert!(
            (MIN_BINS..=MAX_BINS).contains(&params.bins),
            "bins out of range"
        );
        let (mut refs, bounds, centroids) = make_refs(prim_count, bounds_of);
        let n = refs.len();
        if n == 0 {
            return (Bvh::default(), Vec::new());
        }

        // A tree over n primitives has at most 2n - 1 nodes: one slot each, the root
        // first, none written before the builder fills it. The slots a subtree leaves
        // unused are squeezed out afterwards, in place.
        let mut nodes: Vec<BvhNode> = Vec::with_capacity(2 * n - 1);
        memory::advise_huge_pages(&nodes);
        let (root, rest) = nodes.spare_capacity_mut()[..2 * n - 1]
            .split_first_mut()
            .expect("n > 0");
        let task = Task {
            refs: &mut refs,
            offset: 0,
            bounds,
            centroids,
            depth: 0,
        };
        let (segments, max_depth) = build_subtree(task, root, rest, 1, params);
        let mut order = Vec::with_capacity(n);
        refs.par_iter()
            .map(PrimRef::index)
            .collect_into_vec(&mut order);
        drop(refs);
        close_gaps(&mut nodes, &segments);
        (Bvh { nodes, max_depth }, order)
    }
}

/// References to the primitives `bounds_of` keeps, with their box and centroid
/// bounds, made on all threads in fixed blocks.
fn make_refs<F>(prim_count: usize, bounds_of: F) -> (Vec<PrimRef>, Bounds, Bounds)
where
    F: Fn(usize) -> Option<Aabb> + Sync,
{
    let mut refs: Vec<PrimRef> = memory::zeroed_vec(prim_count);
    // Each block keeps its primitives at its head; dropped ones leave its tail unused.
    let blocks: Vec<(usize, Bounds, Bounds)> = refs
        .par_chunks_mut(REF_BLOCK)
        .enumerate()
        .map(|(k, block)| {
            let first = k * REF_BLOCK;
            let mut kept = 0;
            for i in first..first + block.len() {
                if let Some(b) = bounds_of(i) {
                    block[kept] = PrimRef::new(b, i);
                    kept += 1;
                }
            }
            let (bounds, centroids) = measure(&block[..kept]);
            (kept, bounds, centroids)
        })
        .collect();
    let heads: Vec<usize> = blocks.iter().map(|b| b.0).collect();
    let kept = gather_block_heads(&mut refs, REF_BLOCK, &heads);
    refs.truncate(kept);
    let (bounds, centroids) = blocks
        .iter()
        .fold((Bounds::EMPTY, Bounds::EMPTY), |acc, b| {
            (acc.0.union(b.1), acc.1.union(b.2))
        });
    (refs, bounds, centroids)
}

/// Builds the subtree of `task`: its root into `root`, the rest into `slots` (at
/// least `2m - 2` of them for `m` primitives), which start at index `base` of the
/// node array. Returns the filled runs of slots in order, and the subtree's depth.
fn build_subtree(
    task: Task<'_>,
    root: &mut Slot,
    slots: &mut [Slot],
    base: u32,
    params: &BvhParams,
) -> (Vec<Segment>, usize) {
    let n = task.refs.len();
    if n <= params.parallel_threshold {
        let (used, depth) = build_sequential(task, root, slots, base, params);
        let segment = Segment {
            start: base,
            len: used as u32,
            joined: false,
        };
        return (Vec::from_iter((used > 0).then_some(segment)), depth);
    }
    let depth = task.depth;
    let mut bins = [AxisBins::EMPTY; 3];
    match split_node(
        task.refs,
        task.bounds,
        task.centroids,
        depth,
        params,
        &mut bins,
    ) {
        Split::Leaf => {
            root.write(node(task.bounds, task.offset, n));
            (Vec::new(), depth)
        }
        Split::At {
            mid,
            bounds,
            centroids,
        } => {
            // The children as a pair, then each one's own slots.
            root.write(node(task.bounds, base, 0));
            let (pair, rest) = slots.split_at_mut(2);
            let (left_slots, right_slots) = rest.split_at_mut(2 * mid - 2);
            let [left_root, right_root] = pair else {
                unreachable!("split_at_mut(2)")
            };
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
            let right_base = base + 2 * mid as u32;
            let ((left_segments, left_depth), (right_segments, right_depth)) = rayon::join(
                || build_subtree(left, left_root, left_slots, base + 2, params),
                || build_subtree(right, right_root, right_slots, right_base, params),
            );
            let mut segments = vec![Segment {
                start: base,
                len: 2,
                joined: true,
            }];
            segments.extend(left_segments);
            segments.extend(right_segments);
            (segments, left_depth.max(right_depth))
        }
    }
}

/// The single-threaded builder: an explicit work stack, children allocated as
/// adjacent pairs from the start of `slots`. Returns the slots used and the depth.
fn build_sequential(
    task: Task<'_>,
    root: &mut Slot,
    slots: &mut [Slot],
    base: u32,
    params: &BvhParams,
) -> (usize, usize) {
    const ROOT: usize = usize::MAX;
    let refs = task.refs;
    let mut used = 0;
    let mut max_depth = 0;
    // (slot, start, end relative to `refs`, bounds, centroid bounds, depth)
    let mut work = Vec::with_capacity(64);
    let mut bins = [AxisBins::EMPTY; 3];
    work.push((ROOT, 0, refs.len(), task.bounds, task.centroids, task.depth));
    while let Some((slot, start, end, bounds, centroids, depth)) = work.pop() {
        max_depth = max_depth.max(depth);
        let split = split_node(
            &mut refs[start..end],
            bounds,
            centroids,
            depth,
            params,
            &mut bins,
        );
        let written = match split {
            Split::Leaf => node(bounds, task.offset + start as u32, end - start),
            Split::At {
                mid,
                bounds: child_bounds,
                centroids,
            } => {
                let left = used;
                used += 2;
                let split = start + mid;
                work.push((
                    left + 1,
                    split,
                    end,
                    child_bounds[1],
                    centroids[1],
                    depth + 1,
                ));
                work.push((left, start, split, child_bounds[0], centroids[0], depth + 1));
                node(bounds, base + left as u32, 0)
            }
        };
        if slot == ROOT {
            root.write(written);
        } else {
            slots[slot].write(written);
        }
    }
    (used, max_depth)
}

/// A node's place in the array while the tree is built: written once, by the
/// builder, before anything reads it.
type Slot = MaybeUninit<BvhNode>;

/// A node with box `bounds`; a leaf of `prim_count` primitives from `first_index`,
/// or, if `prim_count` is 0, an interior node with children from `first_index`.
fn node(bounds: Bounds, first_index: u32, prim_count: usize) -> BvhNode {
    let mut node = BvhNode {
        first_index,
        prim_count: prim_count as u32,
        ..BvhNode::default()
    };
    node.set_bounds(bounds.to_aabb());
    node
}

/// Turns the slots written by the build into the node array: slot 0 (the root),
/// then the filled `segments` moved together in order, child indices renumbered.
/// In place, one pass: a copy to a fresh array would take as many page faults and
/// hold both arrays at once (the peak memory of a whole render). The unused tail is
/// given back to the system.
fn close_gaps(nodes: &mut Vec<BvhNode>, segments: &[Segment]) {
    let mut new_starts = Vec::with_capacity(segments.len());
    let mut count = 1;
    for s in segments {
        new_starts.push(count as u32);
        count += s.len as usize;
    }
    // Children of a joined pair (or of the root) start a segment.
    let moved = |old_start: u32| -> u32 {
        let at = segments.partition_point(|s| s.start < old_start);
        debug_assert_eq!(segments[at].start, old_start);
        new_starts[at]
    };
    let slots = nodes.spare_capacity_mut();
    // SAFETY (for every `assume_init_read` below): the builder wrote the root and
    // every slot of every segment, and segments only move towards the front, in
    // order, so each slot is read before anything overwrites it.
    let read = |slot: &Slot| unsafe { slot.assume_init_read() };
    let mut root = read(&slots[0]);
    if !root.is_leaf() {
        root.first_index = moved(root.first_index);
    }
    slots[0].write(root);
    for (s, &new_start) in segments.iter().zip(&new_starts) {
        let shift = s.start - new_start;
        let (start, new_start) = (s.start as usize, new_start as usize);
        for i in 0..s.len as usize {
            let mut node = read(&slots[start + i]);
            if !node.is_leaf() {
                node.first_index = if s.joined {
                    moved(node.first_index)
                } else {
                    node.first_index - shift
                };
            }
            slots[new_start + i].write(node);
        }
    }
    // SAFETY: slot 0 and the segments, whose lengths add up to `count`, now fill
    // `0..count`.
    unsafe { nodes.set_len(count) };
    memory::release_spare_capacity(nodes);
}

/// Decides how to split a node and partitions `refs` accordingly, on all threads if
/// the node is above the parallel threshold.
fn split_node(
    refs: &mut [PrimRef],
    bounds: Bounds,
    centroids: Bounds,
    depth: usize,
    params: &BvhParams,
    bins: &mut [AxisBins; 3],
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
            a.centroid2_on(widest).total_cmp(&b.centroid2_on(widest))
        });
        return split_by_count(refs, n / 2);
    }
    if n == 2 {
        return split_pair(refs, bounds, widest, params);
    }
    let parallel = n > params.parallel_threshold;
    let block = params.parallel_threshold.max(1);

    // Step 1: bin centroids, on all three axes for big nodes.
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
    if parallel {
        *bins = refs
            .par_chunks(block)
            .map(|chunk| {
                let mut bins = [AxisBins::EMPTY; 3];
                binning.bin(chunk, &mut bins);
                bins
            })
            .reduce(
                || [AxisBins::EMPTY; 3],
                |a, b| [a[0].merge(&b[0]), a[1].merge(&b[1]), a[2].merge(&b[2])],
            );
    } else if all_axes {
        binning.bin(refs, bins);
    } else {
        binning.bin_axis(refs, widest, &mut bins[widest]);
    }

    // Step 2: the plane of lowest cost `A_l N_l + A_r N_r` over the binned axes.
    let mut best: Option<(usize, usize, Float)> = None;
    for (axis, axis_bins) in bins.iter().enumerate() {
        if extent[axis] <= 0.0 || !(all_axes || axis == widest) {
            continue;
        }
        if let Some((bin, cost)) = axis_bins.best_plane(bin_count)
            && best.is_none_or(|(_, _, c)| cost < c)
        {
            best = Some((axis, bin, cost));
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

    // Step 4: partition around the chosen plane, measuring both sides' centroids;
    // their boxes come from the bins.
    let goes_left = binning.goes_left(axis, split_bin as u32);
    let (mid, centroid_sides) = if parallel {
        partition_parallel(refs, block, goes_left)
    } else {
        partition(refs, goes_left)
    };
    if mid == 0 || mid == n {
        // The bins promised both sides primitives; only non-finite coordinates can
        // break that promise.
        return split_by_count(refs, n / 2);
    }
    let axis_bins = &bins[axis];
    Split::At {
        mid,
        bounds: [
            axis_bins.side(0..split_bin),
            axis_bins.side(split_bin..bin_count),
        ],
        centroids: centroid_sides,
    }
}

/// [`split_node`] for two primitives whose centroids differ along `widest`, where
/// it is most of the calls: the same decision and order as binning them (they land
/// in the first and the last bin, so every plane between costs `A_l + A_r`),
/// without the bins.
fn split_pair(refs: &mut [PrimRef], bounds: Bounds, widest: usize, params: &BvhParams) -> Split {
    if refs[1].centroid2_on(widest) < refs[0].centroid2_on(widest) {
        refs.swap(0, 1);
    }
    let box_of = |r: &PrimRef| Bounds {
        min: r.min(),
        max: r.max(),
    };
    let point_of = |r: &PrimRef| Bounds {
        min: r.centroid2(),
        max: r.centroid2(),
    };
    let (left, right) = (box_of(&refs[0]), box_of(&refs[1]));
    let cost = left.half_area() + right.half_area();
    let area = bounds.half_area().max(Float::MIN_POSITIVE);
    let split_cost = params.traversal_cost + params.intersection_cost * cost / area;
    if split_cost >= params.intersection_cost * 2.0 && 2 <= params.max_leaf_size {
        return Split::Leaf;
    }
    Split::At {
        mid: 1,
        bounds: [left, right],
        centroids: [point_of(&refs[0]), point_of(&refs[1])],
    }
}

/// Splits at `mid` as the primitives lie, measuring both sides.
fn split_by_count(refs: &[PrimRef], mid: usize) -> Split {
    let (left_bounds, left_centroids) = measure(&refs[..mid]);
    let (right_bounds, right_centroids) = measure(&refs[mid..]);
    Split::At {
        mid,
        bounds: [left_bounds, right_bounds],
        centroids: [left_centroids, right_centroids],
    }
}
