//! Pass 1: a quick survey of a chunk. It counts the chunk's lines, elements and
//! triangles without reading a number, so that every chunk knows where its elements
//! go in the final arrays, and reads in full the rare statements (`usemtl`,
//! `mtllib`, `S`, `P`) that pass 2 skips.
//!
//! The counts are those the general parser arrives at when the chunk has no error:
//! an element per `v`, `vt` or `vn` line (by keyword, as [`Counts::of`] counts them)
//! and `corners - 2` triangles per `f` line, its corners being its tokens.

use super::{Chunk, Counts, lex};

/// What pass 1 finds in a chunk; line numbers are local to the chunk.
#[derive(Default)]
pub(super) struct Survey {
    /// Lines, elements and triangles.
    pub(super) counts: Counts,
    /// Whether the chunk holds a NUL byte.
    pub(super) has_nul: bool,
    /// The chunk's statements other than `v`, `vt`, `vn` and `f` (its events, spheres
    /// and lights), the line of its first shape before any `usemtl`, and the first
    /// error among those statements, after which no statement is recorded.
    pub(super) statements: Chunk,
}

/// Surveys one chunk.
pub(super) fn survey(text: &[u8]) -> Survey {
    let mut survey = Survey {
        has_nul: memchr::memchr(0, text).is_some(),
        ..Survey::default()
    };
    let mut slot = 0u32;
    let mut rest = text;
    // The number of the current line, local to the chunk.
    let mut line_number = 1;
    loop {
        let counts = &mut survey.counts;
        // Where the line ends, within `rest`.
        let end = match rest {
            [] => break,
            [b'f', b' ', corners @ ..] => match face_corners(corners) {
                Some((count, length)) => {
                    counts.triangles += count.saturating_sub(2);
                    survey.statements.note_face(count, line_number, slot);
                    2 + length
                }
                None => survey.other_line(rest, line_number, &mut slot),
            },
            [b'v', b' ', ..] => {
                counts.positions += 1;
                line_length(rest)
            }
            [b'v', b'n', b' ', ..] => {
                counts.normals += 1;
                line_length(rest)
            }
            [b'v', b't', b' ', ..] => {
                counts.texcoords += 1;
                line_length(rest)
            }
            _ => survey.other_line(rest, line_number, &mut slot),
        };
        match rest.get(end + 1..) {
            Some(next) => {
                rest = next;
                line_number += 1;
            }
            None => break,
        }
    }
    survey.counts.lines = line_number - 1;
    survey
}

/// The length of the line starting `text`, up to its `\n` or the end: eight
/// bytes at a time, cheaper than a call to `memchr` for lines this short.
#[inline(always)]
fn line_length(text: &[u8]) -> usize {
    let mut at = 0;
    while let Some(bytes) = text.get(at..).and_then(<[u8]>::first_chunk::<8>) {
        let newlines = first_equal_byte(u64::from_le_bytes(*bytes), b'\n');
        if newlines != 0 {
            return at + (newlines.trailing_zeros() / 8) as usize;
        }
        at += 8;
    }
    at + memchr::memchr(b'\n', &text[at..]).unwrap_or(text.len() - at)
}

/// High bit set in the first byte of `word` equal to `byte` (and maybe in later
/// bytes, equal or not), or no bit if none is.
#[inline(always)]
fn first_equal_byte(word: u64, byte: u8) -> u64 {
    const ONES: u64 = 0x0101_0101_0101_0101;
    let x = word ^ (ONES * u64::from(byte));
    // The subtraction borrows only from a zero byte, so below the first one every
    // byte's high bit stays clear.
    x.wrapping_sub(ONES) & !x & (ONES << 7)
}

impl Survey {
    /// A line not in one of the common forms, at the start of `text`: counted by
    /// its keyword, or read in full. Returns its length.
    fn other_line(&mut self, text: &[u8], line_number: usize, slot: &mut u32) -> usize {
        let length = line_length(text);
        self.other_statement(&text[..length], line_number, slot);
        length
    }

    fn other_statement(&mut self, line: &[u8], line_number: usize, slot: &mut u32) {
        let line = match memchr::memchr(b'#', line) {
            Some(hash) => &line[..hash],
            None => line,
        };
        let mut tokens = lex::tokens(line);
        let Some(keyword) = tokens.next() else {
            return;
        };
        let counts = &mut self.counts;
        match keyword {
            b"v" => counts.positions += 1,
            b"vt" => counts.texcoords += 1,
            b"vn" => counts.normals += 1,
            b"f" => {
                let count = tokens.count();
                counts.triangles += count.saturating_sub(2);
                self.statements.note_face(count, line_number, *slot);
            }
            _ if self.statements.error.is_some() => {}
            _ => {
                let statements = &mut self.statements;
                if let Err(kind) =
                    statements.parse_statement(keyword, tokens, line, line_number, slot)
                {
                    statements.error = Some((line_number, kind));
                }
            }
        }
    }
}

/// The corners of the face whose text after `f ` starts `text`, and the length of
/// that text up to the line's `\n`; `None` for a line that holds a control
/// character or a comment, or that ends less than eight bytes before the chunk
/// (left to the tokenizer). Eight bytes at a time: the only separator is the space.
#[inline(always)]
fn face_corners(text: &[u8]) -> Option<(usize, usize)> {
    const ONES: u64 = 0x0101_0101_0101_0101;
    const HIGH: u64 = 0x8080_8080_8080_8080;
    let mut corners = 0;
    // Whether the byte before the current word is a space (the one before the
    // first corner is).
    let mut after_space = true;
    let mut at = 0;
    loop {
        let word = u64::from_le_bytes(*text.get(at..)?.first_chunk::<8>()?);
        let newlines = first_equal_byte(word, b'\n');
        // The high bits of the bytes before the first `\n` (all if there is none).
        let line = newlines.wrapping_sub(1) & !newlines & HIGH;
        // Bytes below 0x20, exact for "is there any" before the `\n` (a borrow only
        // marks bytes after one that is), and `#`.
        let control = word.wrapping_sub(ONES * 0x20) & !word;
        if (control | first_equal_byte(word, b'#')) & line != 0 {
            return None;
        }
        let spaces = equal_bytes(word, b' ');
        // A token starts at a non-space byte that follows a space.
        let follows_space = (spaces << 8) | u64::from(after_space) << 7;
        corners += (!spaces & follows_space & line).count_ones() as usize;
        if newlines != 0 {
            return Some((corners, at + (newlines.trailing_zeros() / 8) as usize));
        }
        after_space = spaces >> 63 != 0;
        at += 8;
    }
}

/// High bit set in each byte of `word` equal to `byte`, exactly.
#[inline(always)]
fn equal_bytes(word: u64, byte: u8) -> u64 {
    const LOW7: u64 = 0x7f7f_7f7f_7f7f_7f7f;
    let x = word ^ (0x0101_0101_0101_0101 * u64::from(byte));
    // A byte of `x` is zero exactly when adding 0x7f to its low seven bits leaves
    // its high bit clear and its own high bit is clear.
    !(((x & LOW7) + LOW7) | x) & !LOW7
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corners_are_the_tokens_of_the_line() {
        let cases: [&[u8]; 12] = [
            b"1 2 3",
            b"1/1/1 2/2/2 3/3/3 4/4/4",
            b"  1   2 3  ",
            b"1\t2\r3",
            b"1 2 3 # 4 5",
            b"1 2#3 4",
            b"",
            b" ",
            b"123456789 123456789 123456789",
            b"1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17",
            b"1\x012 3",
            b"\xff\xfe 3",
        ];
        for line in cases {
            let tokens = lex::tokens(line.split(|&b| b == b'#').next().unwrap()).count();
            // As a chunk's last line and followed by others.
            for text in [
                [b"f ", line].concat(),
                [b"f ", line, b"\nv 1 2 3\n"].concat(),
            ] {
                let survey = survey(&text);
                assert_eq!(
                    survey.counts.triangles,
                    tokens.saturating_sub(2),
                    "{:?}",
                    String::from_utf8_lossy(&text)
                );
            }
            let text = [b"f ", line, b"\n"].concat();
            if let Some((corners, length)) = face_corners(&text[2..]) {
                assert_eq!((corners, length), (tokens, line.len()));
            }
        }
    }

    #[test]
    fn equal_bytes_marks_exactly_the_equal_bytes() {
        for byte in [0u8, b' ', b'#', 0x80, 0xff] {
            let bytes = [0u8, b' ', b'#', 0x80, 0xff, 0x7f, 0x01, b' '];
            let mask = equal_bytes(u64::from_le_bytes(bytes), byte);
            for (i, &b) in bytes.iter().enumerate() {
                assert_eq!(mask >> (8 * i + 7) & 1 == 1, b == byte, "{byte:#x} at {i}");
            }
        }
    }
}
