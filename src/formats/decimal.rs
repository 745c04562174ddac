//! A fast path for the short decimals of mesh files (`-0.0503644`, `1.5e-3`), exact
//! by construction: when the digits form an integer `m <= 2^24` and the decimal
//! exponent `e` is within `-10..=10`, both `m` and `10^|e|` are exact `f32` values
//! (`5^10 < 2^24`), so one IEEE multiplication or division rounds `m * 10^e`
//! correctly. This is Clinger's fast path, the one `fast-float2` itself takes first;
//! inlined into the scanners without its generic framing, it halves the time per
//! number. Anything else (more digits, a large exponent, `+`, `.5`, `inf`) returns
//! `None`, and the caller uses `fast-float2`, so every result has the same bits.

use crate::math::Float;

/// `10^k` for `k` in `0..=10`, each exact in `f32`.
const POWERS_OF_TEN: [Float; 11] = [1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10];

/// The largest mantissa the fast path takes: every integer up to it is exact in `f32`.
const MAX_EXACT_MANTISSA: u64 = 1 << 24;

/// More digits than this may overflow the `u64` mantissa; such numbers take the
/// general parser.
const MAX_DIGITS: usize = 19;

/// Parses `-?digits(.digits)?([eE][+-]?digits)?` at the start of `text` when the
/// fast path applies. Returns the value and the text after it, which is the
/// caller's to check.
#[inline(always)]
pub(crate) fn parse_short(text: &[u8]) -> Option<(Float, &[u8])> {
    let (negative, unsigned) = match text {
        [b'-', rest @ ..] => (true, rest),
        _ => (false, text),
    };
    // Mesh coordinates mostly have one digit before the point: no need to gather
    // eight bytes for it.
    let (mut mantissa, mut digits) = match unsigned {
        [d @ b'0'..=b'9', b'.', ..] => (u64::from(d - b'0'), 1),
        _ => leading_digits(unsigned),
    };
    if digits == 0 {
        return None;
    }
    let mut rest = &unsigned[digits..];
    let mut exponent: i32 = 0;
    if let [b'.', fraction @ ..] = rest {
        let (fraction_value, fraction_digits) = leading_digits(fraction);
        if fraction_digits == 0 {
            return None;
        }
        digits += fraction_digits;
        if digits > MAX_DIGITS {
            return None;
        }
        mantissa = mantissa * POWERS_OF_TEN_U64[fraction_digits] + fraction_value;
        exponent = -(fraction_digits as i32);
        rest = &fraction[fraction_digits..];
    }
    if digits > MAX_DIGITS {
        return None;
    }
    if let [b'e' | b'E', after @ ..] = rest {
        let (negative_exponent, unsigned_exponent) = match after {
            [b'-', tail @ ..] => (true, tail),
            [b'+', tail @ ..] => (false, tail),
            _ => (false, after),
        };
        let (written, written_digits) = leading_digits(unsigned_exponent);
        // Four digits already put the value out of the fast path's range.
        if written_digits == 0 || written_digits > 3 {
            return None;
        }
        let written = written as i32;
        exponent += if negative_exponent { -written } else { written };
        rest = &unsigned_exponent[written_digits..];
    }
    let magnitude = if mantissa == 0 {
        0.0
    } else if mantissa > MAX_EXACT_MANTISSA {
        return None;
    } else {
        let power = *POWERS_OF_TEN.get(exponent.unsigned_abs() as usize)?;
        if exponent < 0 {
            mantissa as Float / power
        } else {
            mantissa as Float * power
        }
    };
    Some((if negative { -magnitude } else { magnitude }, rest))
}

/// `10^k` for `k` in `0..=19`.
const POWERS_OF_TEN_U64: [u64; 20] = {
    let mut powers = [1u64; 20];
    let mut k = 1;
    while k < 20 {
        powers[k] = powers[k - 1] * 10;
        k += 1;
    }
    powers
};

/// The ASCII digits at the start of `text`: their value and how many there are.
/// The value is exact up to [`MAX_DIGITS`] digits (wrapped beyond: the caller
/// checks the count). Reads eight bytes at a time where the text has them.
#[inline(always)]
pub(crate) fn leading_digits(text: &[u8]) -> (u64, usize) {
    let (value, count) = eight_digits(text);
    if count < 8 {
        return (value, count);
    }
    more_digits(text, value)
}

/// [`leading_digits`] past the first eight.
#[cold]
fn more_digits(text: &[u8], mut value: u64) -> (u64, usize) {
    let mut count = 8;
    loop {
        let (more, more_count) = eight_digits(&text[count..]);
        value = value
            .wrapping_mul(POWERS_OF_TEN_U64[more_count])
            .wrapping_add(more);
        count += more_count;
        if more_count < 8 {
            return (value, count);
        }
    }
}

/// Up to eight leading digits of `text`, as value and count.
#[inline(always)]
fn eight_digits(text: &[u8]) -> (u64, usize) {
    let Some(bytes) = text.first_chunk::<8>() else {
        // The end of the text: byte by byte.
        let mut value = 0;
        let mut count = 0;
        while let Some(&d) = text.get(count)
            && d.is_ascii_digit()
        {
            value = value * 10 + u64::from(d - b'0');
            count += 1;
        }
        return (value, count);
    };
    // SWAR ("SIMD within a register"), after simdjson's
    // `parse_eight_digits_unrolled`: the first byte read is the lowest.
    let word = u64::from_le_bytes(*bytes);
    let values = word.wrapping_sub(0x3030_3030_3030_3030);
    // A byte's high bit is set here if it is below `'0'` (the subtraction borrows)
    // or above `'9'` (adding 0x46 reaches 0x80). A borrow only disturbs the bytes
    // after the first non-digit, which are not used.
    let non_digits = (values | word.wrapping_add(0x4646_4646_4646_4646)) & 0x8080_8080_8080_8080;
    let count = (non_digits.trailing_zeros() / 8) as usize;
    if count == 0 {
        return (0, 0);
    }
    // The digits moved to the top bytes; the zero bytes below act as leading zeros.
    let digits = values << (8 * (8 - count));
    // Pairs, then fours, then all eight digits combined by multiplications.
    let pairs = (digits.wrapping_mul(10) + (digits >> 8)) & 0x00ff_00ff_00ff_00ff;
    let fours = (pairs.wrapping_mul(100) + (pairs >> 16)) & 0x0000_ffff_0000_ffff;
    let eight = fours.wrapping_mul(10_000) + (fours >> 32);
    (eight & 0xffff_ffff, count)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The fast path must give `fast-float2`'s bits wherever it answers.
    fn check(text: &str) -> bool {
        let expected: Result<Float, _> = fast_float2::parse(text);
        match parse_short(text.as_bytes()) {
            Some((value, [])) => {
                let expected = expected.unwrap_or_else(|_| panic!("{text} is not a number"));
                assert_eq!(value.to_bits(), expected.to_bits(), "{text}");
                true
            }
            _ => false,
        }
    }

    #[test]
    fn short_decimals_round_exactly_as_fast_float2() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let mut fast = 0;
        let cases = 2_000_000;
        for _ in 0..cases {
            let digits = rng.random_range(1..=9);
            let mantissa: u64 = rng.random_range(0..10u64.pow(digits));
            let mut text = format!("{mantissa:0width$}", width = digits as usize);
            let point = rng.random_range(0..=digits as usize);
            if point < digits as usize {
                text.insert(point.max(1), '.');
            }
            if rng.random_bool(0.5) {
                text.insert(0, '-');
            }
            if rng.random_bool(0.2) {
                let sign = ["", "+", "-"][rng.random_range(0..3)];
                let e = rng.random_range(0..14);
                text.push_str(&format!("{}{sign}{e}", ["e", "E"][rng.random_range(0..2)]));
            }
            fast += usize::from(check(&text));
        }
        // Most of these take the fast path; the rest are checked by falling back.
        assert!(fast > cases / 2, "{fast} of {cases}");
    }

    #[test]
    fn edges_of_the_fast_path_and_what_it_leaves_to_fast_float2() {
        for text in [
            "0",
            "-0",
            "-0.0",
            "0e99",
            "16777216",
            "1.6777216",
            "-0.0503644",
            "1e10",
            "1e-10",
            "7E+3",
            "3.4028235e38",
        ] {
            check(text);
        }
        assert_eq!(
            parse_short(b"-0").map(|(v, _)| v.to_bits()),
            Some((-0.0f32).to_bits())
        );
        for text in [
            "16777217",
            "1e11",
            "1e-11",
            "+1",
            ".5",
            "5.",
            "1e",
            "1e+",
            "-",
            "inf",
            "nan",
            "12345678901234567890",
            "1e00001",
        ] {
            assert!(!check(text), "{text} should take the general parser");
        }
        // Stops before what is not part of the number.
        assert_eq!(parse_short(b"1.5/2"), Some((1.5, &b"/2"[..])));
        assert_eq!(parse_short(b"2e"), None);
    }
}
