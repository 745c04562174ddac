//! Centroid binning and the surface area heuristic: primitives are counted into
//! bins by centroid along each axis, each bin keeping the box of what it holds, and
//! one sweep each way over the bins prices every plane between them.

use glam::Vec3A;
use wide::f32x8;

use super::refs::{Bounds, PrimRef};
use crate::math::Float;

/// Most bins any [`BvhParams`](super::BvhParams) may ask for; bins live in fixed arrays on the stack,
/// cleared for every node, so more would cost more than they gain.
pub(super) const MAX_BINS: usize = 16;
const _: () = assert!(MAX_BINS.is_power_of_two());
/// Fewest bins used for a node: small nodes use one bin per primitive (at least
/// this many), which saves clearing and sweeping bins that would stay empty.
pub(super) const MIN_BINS: usize = 4;

/// The bins of one axis. Each bin's box is eight lanes: its lower corner, then its
/// upper corner negated ([`PrimRef::lanes`]), so that growing it is one `min` over
/// all eight lanes, which halves the loads and stores of binning, the build's
/// busiest loop.
#[derive(Clone, Copy)]
pub(super) struct AxisBins {
    boxes: [f32x8; MAX_BINS],
    counts: [u32; MAX_BINS],
}

/// The empty box in the lanes of [`AxisBins`]: every lane `+inf`.
pub(super) const EMPTY_LANES: f32x8 = f32x8::new([Float::INFINITY; 8]);

/// The box of eight lanes `lanes` (see [`AxisBins`]).
#[inline(always)]
pub(super) fn bounds_of(lanes: f32x8) -> Bounds {
    let [x, y, z, _, nx, ny, nz, _] = lanes.to_array();
    Bounds {
        min: Vec3A::new(x, y, z),
        max: Vec3A::new(-nx, -ny, -nz),
    }
}

impl AxisBins {
    pub(super) const EMPTY: AxisBins = AxisBins {
        boxes: [EMPTY_LANES; MAX_BINS],
        counts: [0; MAX_BINS],
    };

    /// Empties the first `bin_count` bins, the only ones a node uses: cheaper than
    /// writing a whole fresh `AxisBins` (which compiles to a copy of the constant).
    #[inline(always)]
    fn reset(&mut self, bin_count: usize) {
        self.boxes[..bin_count].fill(EMPTY_LANES);
        // All of them: a fixed size is a few vector stores, a variable one a call.
        self.counts = [0; MAX_BINS];
    }

    /// Adds a primitive whose box is `lanes` ([`PrimRef::lanes`]) to bin `bin`.
    #[inline(always)]
    fn add(&mut self, bin: u32, lanes: f32x8) {
        // `bin` is below `MAX_BINS` already; the mask lets the compiler see it.
        let bin = bin as usize & (MAX_BINS - 1);
        // The bin first, as `Vec3A::min` and `max` take the old box first: a NaN
        // lane takes the primitive's value either way.
        self.boxes[bin] = self.boxes[bin].fast_min(lanes);
        self.counts[bin] += 1;
    }

    /// Adds the first `bin_count` bins of `other`.
    fn merge_from(&mut self, other: &AxisBins, bin_count: usize) {
        for b in 0..bin_count {
            self.boxes[b] = self.boxes[b].fast_min(other.boxes[b]);
            self.counts[b] += other.counts[b];
        }
    }

    pub(super) fn merge(mut self, other: &AxisBins) -> AxisBins {
        self.merge_from(other, MAX_BINS);
        self
    }

    /// The cheapest plane between bins of the first `bin_count`, by sweeping from
    /// the right, then from the left: `(first bin on the right, A_l B_l + A_r B_r)`,
    /// where a side of `N` primitives costs `B = ceil(N / 2^block_shift)` leaf tests
    /// (see [`BvhParams::block_size`](super::BvhParams::block_size)). `None` if every
    /// plane leaves a side empty.
    pub(super) fn best_plane(&self, bin_count: usize, block_shift: u32) -> Option<(usize, Float)> {
        // `BvhParams::leaf_tests` with a shift for the division: two per plane.
        let mask = (1u32 << block_shift) - 1;
        let blocks = |count: u32| ((count >> block_shift) + u32::from(count & mask != 0)) as Float;
        let mut right_cost = [0.0 as Float; MAX_BINS];
        let mut acc = EMPTY_LANES;
        let mut count = 0u32;
        for b in (1..bin_count).rev() {
            acc = acc.fast_min(self.boxes[b]);
            count += self.counts[b];
            right_cost[b] = bounds_of(acc).half_area() * blocks(count);
        }
        let total = count + self.counts[0];
        // Every plane's cost first, then the choice: the costs do not wait for each
        // other, and the choice waits only for comparisons.
        let mut cost = [0.0 as Float; MAX_BINS];
        let mut valid = 0u32;
        let mut acc = EMPTY_LANES;
        let mut count = 0u32;
        for b in 1..bin_count {
            acc = acc.fast_min(self.boxes[b - 1]);
            count += self.counts[b - 1];
            cost[b] = bounds_of(acc).half_area() * blocks(count) + right_cost[b];
            valid |= u32::from(count != 0 && count != total) << b;
        }
        // The first plane of least cost; `found` rather than an infinite start so
        // that infinite or NaN costs still pick a plane, as for finite ones.
        let (mut found, mut best_bin, mut best_cost) = (false, 0, Float::INFINITY);
        while valid != 0 {
            let b = valid.trailing_zeros() as usize;
            valid &= valid - 1;
            if !found || cost[b] < best_cost {
                (found, best_bin, best_cost) = (true, b, cost[b]);
            }
        }
        found.then_some((best_bin, best_cost))
    }

    /// Box of bins `range`.
    pub(super) fn side(&self, range: std::ops::Range<usize>) -> Bounds {
        bounds_of(range.fold(EMPTY_LANES, |acc, b| acc.fast_min(self.boxes[b])))
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
        let [x, y, z] = self.bins_of(r.centroid2());
        let lanes = r.lanes();
        bins[0].add(x, lanes);
        bins[1].add(y, lanes);
        bins[2].add(z, lanes);
    }

    /// Bins `refs` along `axis` only, into `bins`. All three lanes cost the same as
    /// one, and picking a lane from memory avoids a jump on `axis` per primitive.
    pub(super) fn bin_axis(&self, refs: &[PrimRef], axis: usize, bins: &mut AxisBins) {
        bins.reset(self.last_bin as usize + 1);
        for r in refs {
            let b = self.bins_of(r.centroid2())[axis];
            bins.add(b, r.lanes());
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

#[cfg(test)]
mod tests {
    use rand::{Rng, SeedableRng};

    use super::*;
    use crate::bvh::build::refs::random_refs;

    /// The eight-lane bins hold exactly the boxes and counts that growing plain
    /// boxes gives, and price planes exactly as a sweep over plain boxes does.
    #[test]
    fn bins_match_plain_boxes() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        for case in 0..200 {
            let count = rng.random_range(1..300);
            let refs = random_refs(&mut rng, count, 20.0);
            let centroids = refs.iter().fold(Bounds::EMPTY, |mut acc, r| {
                acc.grow(r.centroid2(), r.centroid2());
                acc
            });
            let bin_count = MIN_BINS + case % (MAX_BINS - MIN_BINS + 1);
            let extent = centroids.max - centroids.min;
            let binning = Binning {
                origin: centroids.min,
                scale: Vec3A::splat(bin_count as Float) / extent,
                last_bin: bin_count as u32 - 1,
            };
            let mut bins = [AxisBins::EMPTY; 3];
            binning.bin(&refs, &mut bins);
            let mut one_axis = AxisBins::EMPTY;
            binning.bin_axis(&refs, case % 3, &mut one_axis);
            for (axis, axis_bins) in bins.iter().enumerate() {
                // Plain boxes and counts per bin.
                let mut plain = [(Bounds::EMPTY, 0u32); MAX_BINS];
                for r in &refs {
                    let bin = binning.bins_of(r.centroid2())[axis] as usize;
                    plain[bin].0.grow(r.min(), r.max());
                    plain[bin].1 += 1;
                }
                let same = |a: Bounds, b: Bounds| {
                    a.min.to_array() == b.min.to_array() && a.max.to_array() == b.max.to_array()
                };
                for start in 0..bin_count {
                    for end in start..=bin_count {
                        let expected = plain[start..end]
                            .iter()
                            .fold(Bounds::EMPTY, |acc, p| acc.union(p.0));
                        assert!(same(axis_bins.side(start..end), expected), "case {case}");
                        if axis == case % 3 {
                            assert!(same(one_axis.side(start..end), expected), "case {case}");
                        }
                    }
                }
                // The plane sweep over plain boxes, pricing single primitives and
                // blocks of two and four.
                let total: u32 = plain.iter().map(|p| p.1).sum();
                for block_shift in [0, 1, 2] {
                    let tests = |n: u32| n.div_ceil(1 << block_shift) as Float;
                    let mut best: Option<(usize, Float)> = None;
                    for split in 1..bin_count {
                        let (left, right) = plain[..bin_count].split_at(split);
                        let side = |part: &[(Bounds, u32)]| {
                            part.iter()
                                .fold((Bounds::EMPTY, 0), |acc, p| (acc.0.union(p.0), acc.1 + p.1))
                        };
                        let ((lb, ln), (rb, rn)) = (side(left), side(right));
                        let cost = lb.half_area() * tests(ln) + rb.half_area() * tests(rn);
                        if ln != 0 && ln != total && best.is_none_or(|(_, c)| cost < c) {
                            best = Some((split, cost));
                        }
                    }
                    assert_eq!(
                        axis_bins.best_plane(bin_count, block_shift),
                        best,
                        "case {case}, block shift {block_shift}"
                    );
                }
            }
        }
    }
}
