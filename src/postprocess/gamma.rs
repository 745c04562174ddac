//! Full mode's last step, `V^(1 / 2.2)` scaled to 0..255 and rounded, for a tone-mapped
//! value `V` in `[0, 1]`: by table, bit for bit what `powf` then rounding give.
//!
//! The byte only changes at 255 thresholds. The table splits the floats of `[0, 1]`
//! by their bits into buckets of 2^16 neighbours, each holding the byte at its start
//! and the one threshold inside it, if any (neighbouring thresholds lie at least
//! 72,000 floats apart: `dT / ulp(T) ~ 2.2 * 2^23 / k`). The thresholds are found once,
//! by bisection over the bits with `powf` itself. `powf` is not exactly rounded, so
//! near a threshold its rounded byte may step back and forth over a few floats;
//! within [`MARGIN`] floats of a threshold or of a bucket's edge, and outside `[0, 1]`,
//! the value goes through `powf` as before. Elsewhere a faithful `powf` (error under
//! one unit in the last place, as glibc's and musl's) cannot change the byte: the
//! curve moves by more than an output unit every three input floats.
//!
//! `powf` on every channel was two thirds of the dragon's post-processing time (the
//! stage went from 9.2 to 6.7 ms). With the test's stride set to 1, all 1,065,353,217
//! floats of `[0, 1]` agreed with glibc 2.36's `powf` (45 s, once, by hand).

use std::sync::OnceLock;

use crate::math::Float;

/// `log2` of the floats per bucket.
const BUCKET_BITS: u32 = 16;

/// Floats around a threshold or a bucket edge that go through `powf`.
const MARGIN: u32 = 256;

/// The bits of 1.0, the largest value the table covers.
const ONE: u32 = 0x3F80_0000;

/// No threshold in the bucket.
const NONE: u32 = u32::MAX;

/// The reference: the gamma curve, scaled, rounded and clamped to a byte.
#[inline]
pub(super) fn gamma_byte_exact(v: Float) -> u8 {
    (v.powf(1.0 / 2.2) * 255.0).round().clamp(0.0, 255.0) as u8
}

struct Table {
    /// Floats (as bits) below this give byte 0, [`MARGIN`] floats short of the
    /// first that gives 1: black, a render's commonest value (the dragon's
    /// background is a quarter of its channels), would otherwise sit at a bucket's
    /// edge and go through `powf`.
    zero_below: u32,
    /// The byte at each bucket's first float.
    first_byte: Vec<u8>,
    /// The first float (as bits) of the bucket whose byte is one more, or [`NONE`].
    threshold: Vec<u32>,
}

impl Table {
    fn new() -> Option<Table> {
        let byte_at = |bits: u32| gamma_byte_exact(Float::from_bits(bits));
        let buckets = (ONE >> BUCKET_BITS) as usize + 1;
        let mut first_byte = vec![0u8; buckets];
        let mut threshold = vec![NONE; buckets];
        let mut zero_below = 0;
        for (bucket, first) in first_byte.iter_mut().enumerate() {
            *first = byte_at((bucket as u32) << BUCKET_BITS);
        }
        for byte in 1..=255u8 {
            // The least bits whose byte is at least `byte`: bisection over [0, ONE].
            let (mut low, mut high) = (0u32, ONE);
            while low < high {
                let middle = low + (high - low) / 2;
                if byte_at(middle) >= byte {
                    high = middle;
                } else {
                    low = middle + 1;
                }
            }
            if byte == 1 {
                zero_below = low.saturating_sub(MARGIN);
            }
            let bucket = (low >> BUCKET_BITS) as usize;
            if low & ((1 << BUCKET_BITS) - 1) == 0 {
                continue; // at a bucket's start: its first byte says it
            }
            if threshold[bucket] != NONE {
                return None; // two thresholds in one bucket: not this `powf`
            }
            threshold[bucket] = low;
        }
        // Each bucket's byte rises by at most one inside it, or the table would be
        // wrong: checked rather than assumed.
        for bucket in 0..buckets - 1 {
            let step = first_byte[bucket + 1] - first_byte[bucket];
            if step != u8::from(threshold[bucket] != NONE) {
                return None;
            }
        }
        Some(Table {
            zero_below,
            first_byte,
            threshold,
        })
    }
}

/// [`gamma_byte_exact`], by table where that is certainly the same.
#[inline]
pub(super) fn gamma_byte(v: Float) -> u8 {
    static TABLE: OnceLock<Option<Table>> = OnceLock::new();
    let Some(table) = TABLE.get_or_init(Table::new) else {
        return gamma_byte_exact(v);
    };
    let bits = v.to_bits();
    if bits < table.zero_below {
        return 0;
    }
    let offset = bits & ((1 << BUCKET_BITS) - 1);
    if bits > ONE || !(MARGIN..(1 << BUCKET_BITS) - MARGIN).contains(&offset) {
        return gamma_byte_exact(v);
    }
    let bucket = (bits >> BUCKET_BITS) as usize;
    let threshold = table.threshold[bucket];
    if threshold != NONE && bits.abs_diff(threshold) < MARGIN {
        return gamma_byte_exact(v);
    }
    table.first_byte[bucket] + u8::from(bits >= threshold)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The table is built (this `powf` keeps thresholds apart) and agrees with the
    /// reference on every 61st float of `[0, 1]`, on every float within 2,000 of each
    /// threshold and of each bucket edge, and on what lies outside `[0, 1]`.
    #[test]
    fn gamma_byte_is_powf_and_rounding_bit_for_bit() {
        let table = Table::new().expect("thresholds one per bucket at most");
        let check = |bits: u32| {
            let v = Float::from_bits(bits);
            assert_eq!(gamma_byte(v), gamma_byte_exact(v), "{v:e} (bits {bits:#x})");
        };
        for bits in (0..=ONE).step_by(61) {
            check(bits);
        }
        let edges = (0..=ONE >> BUCKET_BITS).map(|bucket| bucket << BUCKET_BITS);
        let thresholds = table.threshold.iter().copied().filter(|&t| t != NONE);
        let mut checked_thresholds = 0;
        for centre in edges.chain(thresholds.inspect(|_| checked_thresholds += 1)) {
            for bits in centre.saturating_sub(2000)..=(centre + 2000).min(ONE) {
                check(bits);
            }
        }
        // Most thresholds lie inside buckets, so most were checked around.
        assert!(checked_thresholds > 200, "{checked_thresholds} thresholds");
        // Below the first threshold, where the table answers 0 at once: zero and
        // the denormals, then a stride up to the margin before the threshold.
        assert!(table.zero_below > 1 << 29, "{:#x}", table.zero_below);
        for bits in (0..1 << 16).chain((0..table.zero_below).step_by(997)) {
            check(bits);
        }
        check(table.zero_below - 1);
        for v in [
            -0.0,
            -1.0,
            1.0,
            1.5,
            Float::INFINITY,
            Float::NAN,
            1e-30,
            0.5,
        ] {
            check(Float::to_bits(v));
        }
    }
}
