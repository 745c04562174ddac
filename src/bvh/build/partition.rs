//! Reordering references in place: a node's around its split plane (branch-free,
//! and in fixed blocks on all threads for big nodes), and the blocks' kept heads
//! gathered to the front, which also compacts the references made in parallel.

use rayon::prelude::*;
use wide::f32x8;

use super::bins::{EMPTY_LANES, bounds_of};
use super::refs::{Bounds, PrimRef};
#[cfg(test)]
use super::refs::{measure, random_refs};

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
    // grow in the same pass rather than in a second one reading the node again, as
    // eight lanes each (the bins' form, `[min, -max]`: one `min` a side): each
    // side's by the centroid or by `+inf`, which leaves it exactly as it was, so
    // the same bounds as measuring each side.
    let mut mid = 0;
    let mut sides = [EMPTY_LANES; 2];
    for i in 0..refs.len() {
        let r = refs[i];
        let left = goes_left(&r);
        let c = r.centroid_lanes();
        let mask = f32x8::splat(f32::from_bits(0u32.wrapping_sub(u32::from(left))));
        let [l, rt] = &mut sides;
        *l = l.fast_min(mask.select(c, EMPTY_LANES));
        *rt = rt.fast_min(mask.select(EMPTY_LANES, c));
        refs.swap(i, mid);
        mid += usize::from(left);
    }
    (mid, sides.map(bounds_of))
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

#[cfg(test)]
mod tests {
    use rand::{Rng, SeedableRng};

    use super::*;

    /// The same bits, lane by lane, of both boxes.
    fn same(a: Bounds, b: Bounds) -> bool {
        let bits = |v: glam::Vec3A| v.to_array().map(f32::to_bits);
        bits(a.min) == bits(b.min) && bits(a.max) == bits(b.max)
    }

    /// The partition puts those going left first, and the centroid bounds it grows
    /// in its pass (as eight lanes) are bit for bit those of measuring each side
    /// afterwards, and so are those of the blocks on all threads.
    #[test]
    fn partition_measures_each_side_exactly() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        for case in 0..100 {
            let count = rng.random_range(0..2000);
            let mut refs = random_refs(&mut rng, count, 8.0);
            let plane = rng.random_range(-4.0..4.0);
            let axis = case % 3;
            let goes_left = |r: &PrimRef| r.centroid2_on(axis) < plane;
            let mut blocked = refs.clone();
            let (mid, sides) = partition(&mut refs, goes_left);
            assert!(refs[..mid].iter().all(goes_left), "case {case}");
            assert!(!refs[mid..].iter().any(goes_left), "case {case}");
            let measured = [measure(&refs[..mid]).1, measure(&refs[mid..]).1];
            for side in 0..2 {
                assert!(
                    same(sides[side], measured[side]),
                    "case {case}, side {side}"
                );
            }
            let (blocked_mid, blocked_sides) = partition_parallel(&mut blocked, 100, goes_left);
            assert_eq!(blocked_mid, mid, "case {case}");
            for side in 0..2 {
                assert!(same(blocked_sides[side], measured[side]), "case {case}");
            }
        }
    }
}
