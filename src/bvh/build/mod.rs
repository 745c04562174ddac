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
//!
//! This module makes the primitive references and drives the build from the root
//! down; the rest is split by concept:
//! - [`refs`]: the primitive references the build moves around, and SIMD boxes;
//! - [`bins`]: centroid binning and the SAH sweep for the cheapest plane;
//! - [`split`]: the decision for one node (leaf, SAH plane, or halving by count);
//! - [`partition`]: reordering a node's references around its plane, in fixed
//!   blocks on all threads for big nodes;
//! - [`layout`]: node slots while building, and closing their gaps at the end.

mod bins;
mod layout;
mod partition;
mod refs;
mod split;

use rayon::prelude::*;

use super::{Bvh, BvhNode};
use crate::math::{Aabb, Float};
use crate::memory;
use bins::{AxisBins, MAX_BINS, MIN_BINS};
use layout::{Segment, Slot, close_gaps, node};
use partition::gather_block_heads;
use refs::{Bounds, PrimRef, measure};
use split::{Split, split_node};

/// Tuning numbers of the builder.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BvhParams {
    /// Number of SAH bins per axis, in `4..=16`.
    pub bins: usize,
    /// Cost of visiting an interior node, relative to `intersection_cost`.
    pub traversal_cost: Float,
    /// Cost of one leaf test, which takes up to `block_size` primitives.
    pub intersection_cost: Float,
    /// Primitives one leaf test takes at once, a power of two: the scene's packets
    /// hold four triangles, and a leaf of five costs two packet tests, as much as one
    /// of eight. So the SAH prices a leaf of `n` primitives as `ceil(n / block_size)`
    /// tests (Embree's SAH block size), and prefers planes that fill whole packets;
    /// 1 prices every primitive on its own.
    pub block_size: usize,
    /// Nodes of at most this many primitives become leaves without a plane search.
    /// The wide BVH makes one leaf of every binary subtree of up to eight
    /// primitives (`Scene::build`), so splitting such nodes would only cost build
    /// time.
    pub min_leaf_size: usize,
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

impl BvhParams {
    /// Leaf tests a leaf of `n` primitives costs: `ceil(n / block_size)`.
    pub fn leaf_tests(&self, n: usize) -> Float {
        n.div_ceil(self.block_size.max(1)) as Float
    }
}

impl Default for BvhParams {
    fn default() -> Self {
        BvhParams {
            bins: 16,
            traversal_cost: 1.0,
            intersection_cost: 1.0,
            block_size: 4,
            min_leaf_size: 8,
            max_leaf_size: 8,
            parallel_threshold: 16 * 1024,
            all_axes_threshold: 64,
        }
    }
}

/// Primitives per block when the references are made on all threads. Fixed, so that
/// the blocks (and with them the tree) do not depend on the number of threads.
const REF_BLOCK: usize = 16 * 1024;

/// One node's primitives with their box and centroid bounds.
struct Task<'a> {
    refs: &'a mut [PrimRef],
    /// Leaf-order index of `refs[0]`.
    offset: u32,
    bounds: Bounds,
    /// Bounds of the doubled centroids.
    centroids: Bounds,
    depth: usize,
    /// Whether an ancestor's centroids already coincided (see [`Bvh::coincident`]).
    coincident: bool,
}

/// Whether a node of `n` primitives with these centroid bounds starts a range of
/// [`Bvh::coincident`] (`inside`: an ancestor already did).
fn starts_coincident(centroids: &Bounds, n: usize, inside: bool, params: &BvhParams) -> bool {
    !inside && n > params.max_leaf_size && (centroids.max - centroids.min).max_element() <= 0.0
}

impl Bvh {
    /// Builds a BVH over `prim_bounds` (one box per primitive).
    ///
    /// Returns the tree and the leaf order: `order[i]` is the original index of the
    /// primitive that must be stored at position `i`, because leaves address
    /// primitives as ranges of that order.
    ///
    /// # Panics
    /// If there are more than `u32::MAX` primitives, `params.bins` is not in
    /// `4..=16` or `params.block_size` is not a power of two.
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
        Bvh::build_with_slots(prim_count, bounds_of, params, usual_slots)
    }

    /// [`Bvh::build_filtered`], giving a subtree of `m` primitives built beside
    /// another `slots_for(m)` slots (the tests compare [`usual_slots`] with the
    /// `2m - 2` that never overflow).
    fn build_with_slots<F>(
        prim_count: usize,
        bounds_of: F,
        params: &BvhParams,
        slots_for: fn(usize, &BvhParams) -> usize,
    ) -> (Bvh, Vec<u32>)
    where
        F: Fn(usize) -> Option<Aabb> + Sync,
    {
        assert!(u32::try_from(prim_count).is_ok(), "too many primitives");
        assert!(
            (MIN_BINS..=MAX_BINS).contains(&params.bins),
            "bins out of range"
        );
        assert!(
            params.block_size.is_power_of_two(),
            "block size not a power of two"
        );
        let (mut refs, bounds, centroids) = make_refs(prim_count, bounds_of);
        let n = refs.len();
        if n == 0 {
            return (Bvh::default(), Vec::new());
        }

        // A tree over n primitives has at most 2n - 1 nodes: room for each, the root
        // first, none written before the builder fills it (subtrees built beside
        // another get fewer slots, see `usual_slots`). The slots a subtree leaves
        // unused are squeezed out afterwards.
        // Small pages: most of the array is never touched.
        let mut nodes: Vec<BvhNode> = Vec::with_capacity(2 * n - 1);
        let (root, rest) = nodes.spare_capacity_mut()[..2 * n - 1]
            .split_first_mut()
            .expect("n > 0");
        let task = Task {
            refs: &mut refs,
            offset: 0,
            bounds,
            centroids,
            depth: 0,
            coincident: false,
        };
        let (segments, max_depth, mut coincident) =
            build_subtree(task, root, rest, 1, params, slots_for);
        coincident.sort_by_key(|r| r.start);
        // Closing the gaps is one sequential pass over the nodes; the leaf order is
        // read out of the references meanwhile, on the other threads.
        let mut order = Vec::with_capacity(n);
        memory::advise_huge_pages(&order);
        rayon::join(
            || close_gaps(&mut nodes, &segments),
            || {
                refs.par_iter()
                    .map(PrimRef::index)
                    .collect_into_vec(&mut order);
                drop(refs);
            },
        );
        (
            Bvh {
                nodes,
                max_depth,
                coincident,
            },
            order,
        )
    }
}

/// References to the primitives `bounds_of` keeps, with their box and centroid
/// bounds, made on all threads in fixed blocks.
fn make_refs<F>(prim_count: usize, bounds_of: F) -> (Vec<PrimRef>, Bounds, Bounds)
where
    F: Fn(usize) -> Option<Aabb> + Sync,
{
    // Written block by block on all threads, not zeroed first: a zeroed buffer took
    // a 28 MB `memset` on one thread on the dragon (2 ms while the other waited).
    let mut refs: Vec<PrimRef> = Vec::with_capacity(prim_count);
    memory::advise_huge_pages(&refs);
    // Each block keeps its primitives at its head; dropped ones leave its tail
    // unused (zeroed, so that every element is initialized).
    let blocks: Vec<(usize, Bounds, Bounds)> = refs.spare_capacity_mut()[..prim_count]
        .par_chunks_mut(REF_BLOCK)
        .enumerate()
        .map(|(k, block)| {
            let first = k * REF_BLOCK;
            let mut kept = 0;
            for i in first..first + block.len() {
                if let Some(b) = bounds_of(i) {
                    block[kept].write(PrimRef::new(b, i));
                    kept += 1;
                }
            }
            for unused in &mut block[kept..] {
                unused.write(bytemuck::Zeroable::zeroed());
            }
            // SAFETY: the first `kept` elements were written just above.
            let kept_refs = unsafe { &*(std::ptr::from_ref(&block[..kept]) as *const [PrimRef]) };
            let (bounds, centroids) = measure(kept_refs);
            (kept, bounds, centroids)
        })
        .collect();
    // SAFETY: every block wrote each of its elements, kept or zeroed.
    unsafe { refs.set_len(prim_count) };
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
/// node array. Returns the filled runs of slots in order, the subtree's depth, and
/// its ranges of [`Bvh::coincident`].
fn build_subtree(
    task: Task<'_>,
    root: &mut Slot,
    slots: &mut [Slot],
    base: u32,
    params: &BvhParams,
    slots_for: fn(usize, &BvhParams) -> usize,
) -> (Vec<Segment>, usize, Vec<std::ops::Range<u32>>) {
    let n = task.refs.len();
    if n <= params.parallel_threshold {
        let (used, depth, coincident, overflow) = build_sequential(task, root, slots, base, params);
        let segment = Segment {
            start: base,
            len: used as u32,
            joined: false,
            overflow,
        };
        return (
            Vec::from_iter((used > 0).then_some(segment)),
            depth,
            coincident,
        );
    }
    let depth = task.depth;
    let starts = starts_coincident(&task.centroids, n, task.coincident, params);
    let mut coincident = Vec::from_iter(starts.then(|| task.offset..task.offset + n as u32));
    let inside = task.coincident || starts;
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
            (Vec::new(), depth, coincident)
        }
        Split::At {
            mid,
            bounds,
            centroids,
        } => {
            // The children as a pair, then each one's own slots: the left child's
            // as many as such a subtree usually needs, the right child's the rest.
            root.write(node(task.bounds, base, 0));
            let (pair, rest) = slots.split_at_mut(2);
            let left_len = slots_for(mid, params).min(rest.len());
            let (left_slots, right_slots) = rest.split_at_mut(left_len);
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
                coincident: inside,
            };
            let right = Task {
                refs: right_refs,
                offset: task.offset + mid as u32,
                bounds: bounds[1],
                centroids: centroids[1],
                depth: depth + 1,
                coincident: inside,
            };
            let right_base = base + 2 + left_len as u32;
            let (
                (left_segments, left_depth, left_coincident),
                (right_segments, right_depth, right_coincident),
            ) = rayon::join(
                || build_subtree(left, left_root, left_slots, base + 2, params, slots_for),
                || {
                    build_subtree(
                        right,
                        right_root,
                        right_slots,
                        right_base,
                        params,
                        slots_for,
                    )
                },
            );
            let mut segments = vec![Segment {
                start: base,
                len: 2,
                joined: true,
                overflow: Vec::new(),
            }];
            segments.extend(left_segments);
            segments.extend(right_segments);
            coincident.extend(left_coincident);
            coincident.extend(right_coincident);
            (segments, left_depth.max(right_depth), coincident)
        }
    }
}

/// Slots a subtree of `m` primitives is given besides its root's when it is built
/// beside another, where it can need up to `2m - 2`: about 1.25 times what such a
/// subtree usually needs, which is set by its leaves' size. With leaves of one or two
/// primitives (`min_leaf_size` 1) that is `5m/4 - 2` (the dragon's subtrees needed at
/// most `1.15m`); with `min_leaf_size` 8, `5m/12 - 2` (the dragon's leaves hold six
/// primitives on average: `0.335m` nodes). A subtree that needs more goes on in an
/// overflow array (see [`build_sequential`]). Each slot range is written from its
/// start, so the node array's pages touched (and zeroed by the kernel first) are
/// about as many as the nodes: with `2m - 2` slots the dragon touched 56 MB for 31
/// MB of nodes, as the unused end of each range was smaller than a 2 MiB page; with
/// `5m/4 - 2` and leaves of up to eight, 56 MB for 9 MB.
fn usual_slots(m: usize, params: &BvhParams) -> usize {
    let smallest_leaf = params.min_leaf_size.min(params.max_leaf_size).max(1);
    // Leaves average three quarters of the smallest size split no further.
    let expected = (8 * m).div_ceil(3 * smallest_leaf).min(m);
    (expected + expected / 4).saturating_sub(2)
}

/// The single-threaded builder: an explicit work stack, children allocated as
/// adjacent pairs from the start of `slots`, then (if `slots` runs out) in an
/// overflow array that continues its numbering. Returns the slots used, the depth,
/// the ranges of [`Bvh::coincident`] and the overflow nodes.
fn build_sequential(
    task: Task<'_>,
    root: &mut Slot,
    slots: &mut [Slot],
    base: u32,
    params: &BvhParams,
) -> (usize, usize, Vec<std::ops::Range<u32>>, Vec<BvhNode>) {
    const ROOT: usize = usize::MAX;
    let refs = task.refs;
    let mut used = 0;
    let mut max_depth = 0;
    let mut coincident = Vec::new();
    let mut overflow = Vec::new();
    // (slot, start, end relative to `refs`, bounds, centroid bounds, depth, inside a
    // coincident range)
    let mut work = Vec::with_capacity(64);
    let mut bins = [AxisBins::EMPTY; 3];
    work.push((
        ROOT,
        0,
        refs.len(),
        task.bounds,
        task.centroids,
        task.depth,
        task.coincident,
    ));
    while let Some((slot, start, end, bounds, centroids, depth, inside)) = work.pop() {
        max_depth = max_depth.max(depth);
        let starts = starts_coincident(&centroids, end - start, inside, params);
        if starts {
            coincident.push(task.offset + start as u32..task.offset + end as u32);
        }
        let inside = inside || starts;
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
                if used > slots.len() {
                    overflow.resize(used - slots.len(), BvhNode::default());
                }
                let split = start + mid;
                work.push((
                    left + 1,
                    split,
                    end,
                    child_bounds[1],
                    centroids[1],
                    depth + 1,
                    inside,
                ));
                work.push((
                    left,
                    start,
                    split,
                    child_bounds[0],
                    centroids[0],
                    depth + 1,
                    inside,
                ));
                node(bounds, base + left as u32, 0)
            }
        };
        if slot == ROOT {
            root.write(written);
        } else if let Some(slot) = slots.get_mut(slot) {
            slot.write(written);
        } else {
            overflow[slot - slots.len()] = written;
        }
    }
    (used, max_depth, coincident, overflow)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;

    /// Subtrees that need more than their usual slots (here every leaf holds one
    /// primitive, so a subtree of `m` needs `2m - 2`) go on in their overflow, and
    /// the tree comes out exactly as with slots enough for any subtree.
    #[test]
    fn subtrees_beyond_their_slots_make_the_same_tree() {
        let boxes: Vec<Aabb> = (0..3000)
            .map(|i| {
                let min = Vec3::new((i * 37 % 101) as f32, (i * 11 % 53) as f32, (i % 7) as f32);
                Aabb {
                    min,
                    max: min + Vec3::splat(0.5),
                }
            })
            .collect();
        let params = BvhParams {
            max_leaf_size: 1,
            parallel_threshold: 100,
            ..BvhParams::default()
        };
        let tight = same_tree_as_with_room_for_any_subtree(&boxes, &params);
        assert_eq!(
            tight.nodes.len(),
            2 * boxes.len() - 1,
            "one primitive per leaf"
        );
    }

    /// Builds over `boxes` with the usual slots and with `2m - 2` for every subtree,
    /// checks that both make the same valid tree, and returns it.
    fn same_tree_as_with_room_for_any_subtree(boxes: &[Aabb], params: &BvhParams) -> Bvh {
        let bounds_of = |i: usize| Some(boxes[i]);
        let (tight, tight_order) =
            Bvh::build_with_slots(boxes.len(), bounds_of, params, usual_slots);
        let (roomy, roomy_order) =
            Bvh::build_with_slots(boxes.len(), bounds_of, params, |m, _| 2 * m - 2);
        assert_eq!(tight.nodes, roomy.nodes);
        assert_eq!(tight_order, roomy_order);
        let leaf_order: Vec<Aabb> = tight_order.iter().map(|&i| boxes[i as usize]).collect();
        tight.validate(&leaf_order).unwrap();
        tight
    }

    /// With leaves of up to eight primitives a subtree gets well under half as many
    /// slots as primitives (a third is what a surface usually needs), and the tree of
    /// a surface comes out exactly as with slots enough for any subtree.
    #[test]
    fn subtrees_of_big_leaves_get_fewer_slots_and_the_same_tree() {
        let params = BvhParams {
            parallel_threshold: 500,
            ..BvhParams::default()
        };
        assert!(usual_slots(10_000, &params) <= 10_000 / 2);
        let one_per_leaf = BvhParams {
            max_leaf_size: 1,
            ..params
        };
        assert!(usual_slots(10_000, &one_per_leaf) > 10_000);
        // Two triangles' boxes per cell of a bumpy 100x100 grid.
        let boxes: Vec<Aabb> = (0..20_000)
            .map(|i| {
                let (x, z) = ((i / 2 % 100) as f32, (i / 200) as f32);
                let y = (x * 0.3).sin() * (z * 0.2).cos();
                let min = Vec3::new(x, y, z);
                Aabb {
                    min,
                    max: min + Vec3::new(1.0, 0.2 + 0.1 * (i % 2) as f32, 1.0),
                }
            })
            .collect();
        let tight = same_tree_as_with_room_for_any_subtree(&boxes, &params);
        assert!(
            tight.nodes.len() < boxes.len() / 2,
            "{} nodes",
            tight.nodes.len()
        );
    }
}
