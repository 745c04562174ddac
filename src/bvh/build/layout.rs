//! The node array while the tree is built and after: each subtree writes its nodes
//! into a slot range reserved for it, and [`close_gaps`] squeezes out the slots the
//! ranges left unused, in place.

use std::mem::MaybeUninit;

use super::refs::Bounds;
use crate::bvh::BvhNode;
use crate::memory;

/// A run of filled slots in the node array, in the order the build left them.
#[derive(Clone, Debug)]
pub(super) struct Segment {
    pub(super) start: u32,
    /// Nodes, the overflow's included.
    pub(super) len: u32,
    /// A pair of children built on their own: its interior nodes point at the start
    /// of another segment. Otherwise a subtree built sequentially, whose interior
    /// nodes point inside the segment.
    pub(super) joined: bool,
    /// The segment's last nodes when its slots ran out: they follow the slots in
    /// its numbering.
    pub(super) overflow: Vec<BvhNode>,
}

/// A node's place in the array while the tree is built: written once, by the
/// builder, before anything reads it.
pub(super) type Slot = MaybeUninit<BvhNode>;

/// A node with box `bounds`; a leaf of `prim_count` primitives from `first_index`,
/// or, if `prim_count` is 0, an interior node with children from `first_index`.
pub(super) fn node(bounds: Bounds, first_index: u32, prim_count: usize) -> BvhNode {
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
/// given back to the system. If a segment overflowed, the segments after it may
/// have to move back, not forward: then they are copied to a fresh array instead.
pub(super) fn close_gaps(nodes: &mut Vec<BvhNode>, segments: &[Segment]) {
    if segments.iter().any(|s| !s.overflow.is_empty()) {
        let total = 1 + segments.iter().map(|s| s.len as usize).sum::<usize>();
        let mut copy = Vec::with_capacity(total);
        gather_segments(nodes.spare_capacity_mut(), segments, |node| copy.push(node));
        *nodes = copy;
        return;
    }
    let (new_starts, count) = closed_starts(segments);
    let moved = |old_start| moved(segments, &new_starts, old_start);
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

/// Where each segment starts once the gaps are closed (after the root), and the
/// number of nodes then.
fn closed_starts(segments: &[Segment]) -> (Vec<u32>, usize) {
    let mut new_starts = Vec::with_capacity(segments.len());
    let mut count = 1;
    for s in segments {
        new_starts.push(count as u32);
        count += s.len as usize;
    }
    (new_starts, count)
}

/// The new index of the child pair that started at slot `old_start`: children of a
/// joined pair (or of the root) start a segment.
fn moved(segments: &[Segment], new_starts: &[u32], old_start: u32) -> u32 {
    let at = segments.partition_point(|s| s.start < old_start);
    debug_assert_eq!(segments[at].start, old_start);
    new_starts[at]
}

/// [`close_gaps`] into `out` (called with each node in order) rather than in place.
fn gather_segments(slots: &[Slot], segments: &[Segment], mut out: impl FnMut(BvhNode)) {
    let (new_starts, _) = closed_starts(segments);
    let moved = |old_start| moved(segments, &new_starts, old_start);
    // SAFETY: the builder wrote the root and every slot of every segment's
    // in-array part.
    let read = |slot: &Slot| unsafe { slot.assume_init_read() };
    let mut root = read(&slots[0]);
    if !root.is_leaf() {
        root.first_index = moved(root.first_index);
    }
    out(root);
    for (s, &new_start) in segments.iter().zip(&new_starts) {
        let in_array = s.len as usize - s.overflow.len();
        let start = s.start as usize;
        let nodes = slots[start..start + in_array]
            .iter()
            .map(read)
            .chain(s.overflow.iter().copied());
        for mut node in nodes {
            if !node.is_leaf() {
                node.first_index = if s.joined {
                    moved(node.first_index)
                } else {
                    node.first_index - s.start + new_start
                };
            }
            out(node);
        }
    }
}
