//! Line and token splitting shared by the OBJ and MTL readers. Works on bytes and
//! borrows from the file buffer: no allocation per line.

use super::error::ParseErrorKind;
use crate::math::{Float, Vec3};

/// The lines of `text` with their 1-based numbers, comments (`#` to end of line)
/// removed. Both `\n` and `\r\n` endings work; blank lines are kept (they are skipped
/// by having no tokens).
pub(crate) fn lines(text: &[u8]) -> impl Iterator<Item = (usize, &[u8])> {
    text.split(|&b| b == b'\n').enumerate().map(|(i, line)| {
        let line = match line.iter().position(|&b| b == b'#') {
            Some(hash) => &line[..hash],
            None => line,
        };
        (i + 1, line)
    })
}

/// Checks that `text` is text: a NUL byte never occurs in an OBJ or MTL file, but
/// does in binary data and in UTF-16 text. Returns the 1-based line of the first one.
pub(crate) fn check_text(text: &[u8]) -> Result<(), (usize, ParseErrorKind)> {
    match text.iter().position(|&b| b == 0) {
        None => Ok(()),
        Some(at) => {
            let line = 1 + text[..at].iter().filter(|&&b| b == b'\n').count();
            Err((line, ParseErrorKind::NotText))
        }
    }
}

/// The whitespace-separated tokens of a line (spaces, tabs, `\r`, form feeds).
pub(crate) fn tokens(line: &[u8]) -> impl Iterator<Item = &[u8]> + Clone {
    line.split(|b| b.is_ascii_whitespace())
        .filter(|t| !t.is_empty())
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

/// Parses one finite number.
pub(crate) fn float(token: &[u8]) -> Result<Float, ParseErrorKind> {
    let value: Float = std::str::from_utf8(token)
        .ok()
        .and_then(|s| s.parse().ok())
        .ok_or_else(|| ParseErrorKind::BadNumber(show(token)))?;
    if value.is_finite() {
        Ok(value)
    } else {
        Err(ParseErrorKind::NonFinite(show(token)))
    }
}

/// Parses the next `N` tokens as numbers; `statement` names the line in errors.
pub(crate) fn floats<'a, const N: usize>(
    statement: &'static str,
    tokens: &mut impl Iterator<Item = &'a [u8]>,
) -> Result<[Float; N], ParseErrorKind> {
    let mut values = [0.0; N];
    for (found, slot) in values.iter_mut().enumerate() {
        let token = tokens.next().ok_or(ParseErrorKind::TooFewValues {
            statement,
            expected: N,
            found,
        })?;
        *slot = float(token)?;
    }
    Ok(values)
}

/// Parses the next three tokens as a vector.
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
