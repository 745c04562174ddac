//! Line and token splitting shared by the OBJ and MTL readers. Works on bytes and
//! borrows from the file buffer: no allocation per line.

use std::cell::Cell;

use super::decimal;
use super::error::ParseErrorKind;
use crate::math::{Float, Vec3};

/// The lines of `text` with their 1-based numbers, comments (`#` to end of line)
/// removed. Both `\n` and `\r\n` endings work; blank lines are kept (they are skipped
/// by having no tokens).
pub(crate) fn lines(text: &[u8]) -> impl Iterator<Item = (usize, &[u8])> {
    let mut start = 0;
    let ends = memchr::memchr_iter(b'\n', text).chain(std::iter::once(text.len()));
    ends.enumerate().filter_map(move |(i, end)| {
        if start > text.len() {
            return None;
        }
        let line = &text[start..end];
        start = end + 1;
        let line = match memchr::memchr(b'#', line) {
            Some(hash) => &line[..hash],
            None => line,
        };
        Some((i + 1, line))
    })
}

/// Whether `b` separates tokens: space, tab, `\r`, vertical tab or form feed.
#[inline(always)]
pub(crate) fn is_space(b: u8) -> bool {
    matches!(b, b' ' | b'\t' | b'\r' | 0x0b | 0x0c)
}

/// The whitespace-separated tokens of a line.
pub(crate) fn tokens(line: &[u8]) -> Tokens<'_> {
    Tokens { rest: line }
}

/// Iterator over the tokens of a line; cheap to clone for look-ahead.
#[derive(Clone, Debug)]
pub(crate) struct Tokens<'a> {
    rest: &'a [u8],
}

impl<'a> Iterator for Tokens<'a> {
    type Item = &'a [u8];

    #[inline]
    fn next(&mut self) -> Option<&'a [u8]> {
        let start = self.rest.iter().position(|&b| !is_space(b))?;
        let rest = &self.rest[start..];
        let end = rest.iter().position(|&b| is_space(b)).unwrap_or(rest.len());
        self.rest = &rest[end..];
        Some(&rest[..end])
    }
}

/// Checks that `text` is text: a NUL byte never occurs in an OBJ or MTL file, but
/// does in binary data and in UTF-16 text. Returns the 1-based line of the first one.
pub(crate) fn check_text(text: &[u8]) -> Result<(), (usize, ParseErrorKind)> {
    match memchr::memchr(0, text) {
        None => Ok(()),
        Some(at) => {
            let line = 1 + memchr::memchr_iter(b'\n', &text[..at]).count();
            Err((line, ParseErrorKind::NotText))
        }
    }
}

/// A token as text for error messages, cut to a readable length.
pub(crate) fn show(token: &[u8]) -> String {
    const MAX_SHOWN: usize = 40;
    let shown = &token[..token.len().min(MAX_SHOWN)];
    let mut s = String::from_utf8_lossy(shown).into_owned();
    if token.len() > MAX_SHOWN {
        s.push_str("...");
    }
    s
}

/// Parses one finite number. Short decimals take [`decimal::parse_short`]; the
/// rest `fast-float2`, which reads bytes directly with the Eisel-Lemire algorithm:
/// no UTF-8 check and about twice as fast as `str::parse`.
#[inline]
pub(crate) fn float(token: &[u8]) -> Result<Float, ParseErrorKind> {
    let value = any_float(token)?;
    if value.is_finite() {
        Ok(value)
    } else {
        Err(ParseErrorKind::NonFinite(show(token)))
    }
}

/// Parses one number, `nan`, `inf` and numbers too large for a `Float` included:
/// vertex positions, where a non-finite one is a warning (`formats::finite`) rather
/// than an error. Text that is not a number is still an error.
#[inline]
pub(crate) fn any_float(token: &[u8]) -> Result<Float, ParseErrorKind> {
    if let Some((value, rest)) = decimal::parse_short(token)
        && rest.is_empty()
    {
        return Ok(value);
    }
    fast_float2::parse(token).map_err(|_| ParseErrorKind::BadNumber(show(token)))
}

/// Parses one vertex value as [`any_float`] does, or, where the token is a number
/// followed by other characters (`3.1+e2`, a misspelt exponent; `1,5`), by that
/// leading number, as assimp, tinyobjloader and Blender's importer read it; `lenient`
/// is then set, for the caller's warning. A token that does not start with a number
/// is still an error.
#[inline]
pub(crate) fn leading_float(token: &[u8], lenient: &Cell<bool>) -> Result<Float, ParseErrorKind> {
    any_float(token).or_else(
        |error| match fast_float2::parse_partial::<Float, _>(token) {
            Ok((value, used)) if used > 0 => {
                lenient.set(true);
                Ok(value)
            }
            _ => Err(error),
        },
    )
}

/// Parses the next three tokens as a vertex position, normal or texture coordinate,
/// whose values may be non-finite (see [`any_float`]); `statement` names the line in
/// errors.
#[inline]
pub(crate) fn any_vec3<'a>(
    statement: &'static str,
    tokens: &mut impl Iterator<Item = &'a [u8]>,
) -> Result<Vec3, ParseErrorKind> {
    numbers::<3>(statement, tokens, any_float).map(Vec3::from)
}

/// Parses the next `N` tokens as numbers; `statement` names the line in errors.
#[inline]
pub(crate) fn floats<'a, const N: usize>(
    statement: &'static str,
    tokens: &mut impl Iterator<Item = &'a [u8]>,
) -> Result<[Float; N], ParseErrorKind> {
    numbers(statement, tokens, float)
}

/// Parses the next `N` tokens with `parse`; `statement` names the line in errors.
#[inline]
pub(crate) fn numbers<'a, const N: usize>(
    statement: &'static str,
    tokens: &mut impl Iterator<Item = &'a [u8]>,
    parse: impl Fn(&[u8]) -> Result<Float, ParseErrorKind>,
) -> Result<[Float; N], ParseErrorKind> {
    let mut values = [0.0; N];
    for (found, slot) in values.iter_mut().enumerate() {
        let token = tokens.next().ok_or(ParseErrorKind::TooFewValues {
            statement,
            expected: N,
            found,
        })?;
        *slot = parse(token)?;
    }
    Ok(values)
}

/// Parses the next three tokens as a vector.
#[inline]
pub(crate) fn vec3<'a>(
    statement: &'static str,
    tokens: &mut impl Iterator<Item = &'a [u8]>,
) -> Result<Vec3, ParseErrorKind> {
    floats::<3>(statement, tokens).map(Vec3::from)
}

/// The rest of the line after the keyword, trimmed: names may contain spaces.
pub(crate) fn rest_of_line<'a>(line: &'a [u8], keyword: &[u8]) -> &'a [u8] {
    let start = line
        .windows(keyword.len())
        .position(|w| w == keyword)
        .map_or(line.len(), |p| p + keyword.len());
    line[start..].trim_ascii()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_strip_comments_and_carriage_returns_split_tokens() {
        let text = b"v 1\t2  3\r\n# comment\nf 1 2 3 # trailing\n";
        let got: Vec<(usize, Vec<&[u8]>)> =
            lines(text).map(|(n, l)| (n, tokens(l).collect())).collect();
        assert_eq!(got[0], (1, vec![&b"v"[..], b"1", b"2", b"3"]));
        assert_eq!(got[1], (2, vec![]));
        assert_eq!(got[2], (3, vec![&b"f"[..], b"1", b"2", b"3"]));
    }

    #[test]
    fn a_number_followed_by_other_characters_reads_as_the_number_leniently() {
        let lenient = Cell::new(false);
        assert_eq!(leading_float(b"-3.25", &lenient), Ok(-3.25));
        assert!(!lenient.get());
        assert_eq!(leading_float(b"3.1+e2", &lenient), Ok(3.1));
        assert!(lenient.get());
        for token in [&b"x"[..], b"+e2", b"-", b"."] {
            assert_eq!(
                leading_float(token, &lenient),
                Err(ParseErrorKind::BadNumber(show(token)))
            );
        }
    }

    #[test]
    fn a_nul_byte_is_not_text_and_names_its_line() {
        assert_eq!(check_text(b"v 1 2 3\n# caf\xe9\n"), Ok(()));
        assert_eq!(
            check_text(b"v 1 2 3\nv 1\x002 3\n"),
            Err((2, ParseErrorKind::NotText))
        );
    }

    #[test]
    fn float_rejects_garbage_and_non_finite() {
        assert_eq!(float(b"-1.5e2"), Ok(-150.0));
        assert!(matches!(float(b"1.2.3"), Err(ParseErrorKind::BadNumber(_))));
        assert!(matches!(float(b"inf"), Err(ParseErrorKind::NonFinite(_))));
        assert!(matches!(float(b"NaN"), Err(ParseErrorKind::NonFinite(_))));
    }
}
