//! Reordering references in place: a node's around its split plane (branch-free,
//! and in fixed blocks on all threads for big nodes), and the blocks' kept heads
//! gathered to the front, which also compacts the references made in parallel.

use glam::{BVec3A, Vec3A};
use rayon::prelude::*;

use super::refs::{Bounds, PrimRef};

/// Partitions `refs` so that those `goes_left` come first and measures the
/// centroids of both sides: `(number going left, [left, right] centroid bounds)`.
#[inline(always)]
pub(super) fn partition(
    refs: &mut [PrimRef],
    goes_left: impl Fn(&PrimRef) -> bool,
) -> (usize, [Bounds; 2]) {
    // Branch-free: the side is data-dependent and mispredicts half the time. Every
    // element of `refs[mid..i]` goes right, so swapping a right element with
    // `refs[mid]` changes nothing that matters. The centroid bounds of both sides
    // grow in the same pass rather than in a second one reading the node again:
    // each side's by a select of its grown and its old bounds, which leaves the
    // side not taken exactly as it was (the same bounds as measuring each side).
    let mut mid = 0;
    let mut sides = [Bounds::EMPTY; 2];
    for i in 0..refs.len() {
        let r = refs[i];
        let left = goes_left(&r);
        let c = r.centroid2();
        let mask = BVec3A::splat(left);
        let [l, rt] = &mut sides;
        l.min = Vec3A::select(mask, l.min.min(c), l.min);
        l.max = Vec3A::select(mask, l.max.max(c), l.max);
        rt.min = Vec3A::select(mask, rt.min, rt.min.min(c));
        rt.max = Vec3A::select(mask, rt.max, rt.max.max(c));
        refs.swap(i, mid);
        mid += usize::from(left);
    }
    (mid, sides)
}

/// [`partition`] on all threads: each block of `block` primitives is partitioned on
/// its own, then the right-goers left of the final split change places with the
/// left-goers right of it.
pub(super) fn partition_parallel(
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
pub(super) fn gather_block_heads(refs: &mut [PrimRef], block: usize, heads: &[usize]) -> usize {
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
