//! The decision for one node: a leaf, the cheapest SAH plane (binned, then
//! partitioned), or halving by count where no plane can separate the centroids or
//! the tree has grown too deep.

use glam::Vec3A;
use rayon::prelude::*;

use super::BvhParams;
use super::bins::{AxisBins, Binning, MIN_BINS};
use super::partition::{partition, partition_parallel};
use super::refs::{Bounds, PrimRef, measure};
use crate::bvh::MEDIAN_SPLIT_DEPTH;
use crate::math::Float;

/// What became of one node's primitives.
pub(super) enum Split {
    Leaf,
    /// Children get `refs[..mid]` and `refs[mid..]` (already partitioned), with
    /// these boxes and centroid bounds.
    At {
        mid: usize,
        bounds: [Bounds; 2],
        centroids: [Bounds; 2],
    },
}

/// Decides how to split a node and partitions `refs` accordingly, on all threads if
/// the node is above the parallel threshold.
pub(super) fn split_node(
    refs: &mut [PrimRef],
    bounds: Bounds,
    centroids: Bounds,
    depth: usize,
    params: &BvhParams,
    bins: &mut [AxisBins; 3],
) -> Split {
    let n = refs.len();
    if n == 1 || n <= params.min_leaf_size.min(params.max_leaf_size) {
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
        if let Some((bin, cost)) =
            axis_bins.best_plane(bin_count, params.block_size.trailing_zeros())
            && best.is_none_or(|(_, _, c)| cost < c)
        {
            best = Some((axis, bin, cost));
        }
    }

    // Step 3: compare the cheapest split, `c_trav + c_int (A_l B_l + A_r B_r) / A`,
    // with making a leaf, `c_int B` (`B`: leaf tests, see `BvhParams::block_size`).
    let Some((axis, split_bin, cost)) = best else {
        return Split::Leaf;
    };
    let area = bounds.half_area().max(Float::MIN_POSITIVE);
    let split_cost = params.traversal_cost + params.intersection_cost * cost / area;
    let leaf_cost = params.intersection_cost * params.leaf_tests(n);
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
    if split_cost >= params.intersection_cost * params.leaf_tests(2) && 2 <= params.max_leaf_size {
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
