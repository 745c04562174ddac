//! Centroid binning and the surface area heuristic: primitives are counted into
//! bins by centroid along each axis, each bin keeping the box of what it holds, and
//! one sweep each way over the bins prices every plane between them.

use glam::Vec3A;

use super::refs::{Bounds, PrimRef};
use crate::math::Float;

/// Most bins any [`BvhParams`](super::BvhParams) may ask for; bins live in fixed arrays on the stack,
/// cleared for every node, so more would cost more than they gain.
pub(super) const MAX_BINS: usize = 16;
const _: () = assert!(MAX_BINS.is_power_of_two());
/// Fewest bins used for a node: small nodes use one bin per primitive (at least
/// this many), which saves clearing and sweeping bins that would stay empty.
pub(super) const MIN_BINS: usize = 4;

/// The bins of one axis.
#[derive(Clone, Copy)]
pub(super) struct AxisBins {
    bounds: [Bounds; MAX_BINS],
    counts: [u32; MAX_BINS],
}

impl AxisBins {
    pub(super) const EMPTY: AxisBins = AxisBins {
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

    pub(super) fn merge(mut self, other: &AxisBins) -> AxisBins {
        for b in 0..MAX_BINS {
            self.bounds[b] = self.bounds[b].union(other.bounds[b]);
            self.counts[b] += other.counts[b];
        }
        self
    }

    /// The cheapest plane between bins of the first `bin_count`, by sweeping from
    /// the right, then from the left: `(first bin on the right, A_l N_l + A_r N_r)`.
    /// `None` if every plane leaves a side empty.
    pub(super) fn best_plane(&self, bin_count: usize) -> Option<(usize, Float)> {
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
    pub(super) fn side(&self, range: std::ops::Range<usize>) -> Bounds {
        range.fold(Bounds::EMPTY, |acc, b| acc.union(self.bounds[b]))
    }
}

/// Maps doubled centroids to bin numbers along each axis.
#[derive(Clone, Copy)]
pub(super) struct Binning {
    pub(super) origin: Vec3A,
    pub(super) scale: Vec3A,
    pub(super) last_bin: u32,
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
    pub(super) fn bin(&self, refs: &[PrimRef], bins: &mut [AxisBins; 3]) {
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
    pub(super) fn bin_axis(&self, refs: &[PrimRef], axis: usize, bins: &mut AxisBins) {
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
    pub(super) fn goes_left(
        &self,
        axis: usize,
        split_bin: u32,
    ) -> impl Fn(&PrimRef) -> bool + Sync + use<> {
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
