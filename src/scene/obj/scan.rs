//! Pass 1's fast path: parses a chunk in one walk over its bytes, without splitting
//! lines or tokens first. `v`, `vn`, `vt` and `f` lines are read in place (most of
//! a mesh file); every other line goes through the general statement parser.
//!
//! The scanner never reports a problem: on a malformed line, a negative or zero
//! index, or an index with more than [`MAX_INDEX_DIGITS`] digits, it gives up and
//! the general parser reads the whole chunk again in pass 2 with the global counts.
//! So what it returns is always what the general parser returns for the chunk, for
//! any base that satisfies [`Chunk::required`]; it only has to be fast on the
//! common forms.

use super::super::decimal;
use super::{Chunk, Corner, TriangleDesc, lex};
use crate::material::MaterialId;
use crate::math::{Float, Vec2, Vec3};

/// Longest index read here: nine digits always fit a `u32`.
const MAX_INDEX_DIGITS: usize = 9;

/// Parses a chunk on its own (line numbers local), or `None` if it needs the
/// general parser.
pub(super) fn parse_chunk(text: &[u8]) -> Option<Chunk> {
    let mut scanner = Scanner {
        rest: text,
        lines: 0,
        slot: 0,
        chunk: Chunk::default(),
    };
    // Room for the elements of a typical mesh chunk (about 30 bytes per `v` line
    // and per triangle's `f` line, twice as many triangles as vertices): growing
    // from nothing would copy them several times.
    scanner.chunk.positions.reserve(text.len() / 64);
    scanner.chunk.triangles.reserve(text.len() / 32);
    scanner.run()?;
    scanner.chunk.lines = scanner.lines;
    Some(scanner.chunk)
}

/// The separators of [`lex::is_space`], as a set of bytes below 64.
const SPACES: u64 = 1 << b' ' | 1 << b'\t' | 1 << b'\r' | 1 << 0x0b | 1 << 0x0c;

/// The bytes that end a token: separators, the end of the line and a comment.
const TOKEN_ENDS: u64 = SPACES | 1 << b'\n' | 1 << b'#';

/// Whether `b` is in `set` (bytes below 64): one shift instead of a chain of
/// comparisons.
#[inline(always)]
fn in_set(set: u64, b: u8) -> bool {
    b < 64 && (set >> b) & 1 != 0
}

/// Whether `b` ends a token: a separator, the end of the line, a comment or the end
/// of the chunk (`None`).
#[inline(always)]
fn ends_token(b: Option<&u8>) -> bool {
    b.is_none_or(|&b| in_set(TOKEN_ENDS, b))
}

struct Scanner<'a> {
    /// The text not read yet.
    rest: &'a [u8],
    /// `\n` bytes passed so far: the current line's local number is `lines + 1`.
    lines: usize,
    /// The material slot in force (see [`Chunk`]).
    slot: u32,
    chunk: Chunk,
}

impl Scanner<'_> {
    fn run(&mut self) -> Option<()> {
        loop {
            self.skip_spaces();
            match self.rest {
                [] => return Some(()),
                [b'\n', rest @ ..] => {
                    self.rest = rest;
                    self.lines += 1;
                    continue;
                }
                [b'v', b' ', rest @ ..] => {
                    self.rest = rest;
                    let position = self.vec3()?;
                    self.chunk.positions.push(position);
                }
                [b'f', b' ', rest @ ..] => {
                    self.rest = rest;
                    self.face()?;
                }
                [b'v', b'n', b' ', rest @ ..] => {
                    self.rest = rest;
                    let normal = self.vec3()?;
                    self.chunk.normals.push(normal);
                }
                [b'v', b't', b' ', rest @ ..] => {
                    self.rest = rest;
                    let u = self.number()?;
                    self.skip_spaces();
                    let v = if ends_token(self.rest.first()) {
                        0.0
                    } else {
                        self.number()?
                    };
                    self.chunk.texcoords.push(Vec2::new(u, v));
                }
                _ => {
                    self.other_line()?;
                    continue;
                }
            }
            self.skip_line();
        }
    }

    /// Any other line, by the general parser; `f` lines not written `f ` give up.
    fn other_line(&mut self) -> Option<()> {
        let end = memchr::memchr(b'\n', self.rest).unwrap_or(self.rest.len());
        let (line, rest) = self.rest.split_at(end);
        let line = match memchr::memchr(b'#', line) {
            Some(hash) => &line[..hash],
            None => line,
        };
        let mut tokens = lex::tokens(line);
        if let Some(keyword) = tokens.next() {
            if keyword == b"f" {
                return None;
            }
            let line_number = self.lines + 1;
            self.chunk
                .parse_statement(keyword, tokens, line, line_number, &mut self.slot)
                .ok()?;
        }
        self.rest = rest;
        Some(())
    }

    #[inline(always)]
    fn skip_spaces(&mut self) {
        while let [b, rest @ ..] = self.rest
            && in_set(SPACES, *b)
        {
            self.rest = rest;
        }
    }

    /// Skips what is left of the line (values beyond those a statement reads are
    /// ignored, as the general parser does) and its `\n`.
    #[inline(always)]
    fn skip_line(&mut self) {
        let rest = match self.rest {
            [b'\n', rest @ ..] => rest,
            _ => match memchr::memchr(b'\n', self.rest) {
                Some(end) => &self.rest[end + 1..],
                None => {
                    self.rest = &[];
                    return;
                }
            },
        };
        self.rest = rest;
        self.lines += 1;
    }

    /// Three numbers.
    #[inline(always)]
    fn vec3(&mut self) -> Option<Vec3> {
        let x = self.number()?;
        let y = self.number()?;
        let z = self.number()?;
        Some(Vec3::new(x, y, z))
    }

    /// The next token as a number, exactly as [`lex::float`] reads it.
    #[inline(always)]
    fn number(&mut self) -> Option<Float> {
        self.skip_spaces();
        if let Some((value, rest)) = decimal::parse_short(self.rest)
            && ends_token(rest.first())
        {
            self.rest = rest;
            return Some(value);
        }
        self.general_number()
    }

    #[cold]
    fn general_number(&mut self) -> Option<Float> {
        let len = self
            .rest
            .iter()
            .position(|b| ends_token(Some(b)))
            .unwrap_or(self.rest.len());
        if len == 0 {
            return None;
        }
        let (token, rest) = self.rest.split_at(len);
        let value = lex::float(token).ok()?;
        self.rest = rest;
        Some(value)
    }

    /// A face: triangles fanned from its first corner, as the general parser does.
    #[inline(always)]
    fn face(&mut self) -> Option<()> {
        let slot = self.slot;
        // Fewer than three corners is an error, left to the general parser.
        let first = self.next_corner()??;
        let mut previous = self.next_corner()??;
        let mut corner = self.next_corner()??;
        loop {
            let normals = match (first.normal, previous.normal, corner.normal) {
                (Some(na), Some(nb), Some(nc)) => Some([na, nb, nc]),
                _ => None,
            };
            self.chunk.triangles.push(TriangleDesc {
                positions: [first.position, previous.position, corner.position],
                normals,
                material: MaterialId(slot),
            });
            previous = corner;
            match self.next_corner()? {
                Some(next) => corner = next,
                None => break,
            }
        }
        self.chunk.note_shape(self.lines + 1, slot);
        Some(())
    }

    /// The next corner of a face, `Some(None)` at the end of the line, `None` if
    /// the scanner gives up.
    #[inline(always)]
    fn next_corner(&mut self) -> Option<Option<Corner>> {
        self.skip_spaces();
        if ends_token(self.rest.first()) {
            return Some(None);
        }
        self.corner().map(Some)
    }

    /// `v`, `v/vt`, `v//vn` or `v/vt/vn` with positive indices, as 0-based indices;
    /// records how many elements must precede the chunk for them to be in range.
    #[inline(always)]
    fn corner(&mut self) -> Option<Corner> {
        let position = self.index()?;
        let chunk = &mut self.chunk;
        chunk.required.positions =
            (chunk.required.positions).max(position.saturating_sub(chunk.positions.len()));
        let mut normal = None;
        if let [b'/', rest @ ..] = self.rest {
            self.rest = rest;
            let mut slash = true;
            if self.rest.first() != Some(&b'/') {
                let texcoord = self.index()?;
                let chunk = &mut self.chunk;
                chunk.required.texcoords =
                    (chunk.required.texcoords).max(texcoord.saturating_sub(chunk.texcoords.len()));
                slash = self.rest.first() == Some(&b'/');
            }
            if slash {
                self.rest = &self.rest[1..];
                let index = self.index()?;
                let chunk = &mut self.chunk;
                chunk.required.normals =
                    (chunk.required.normals).max(index.saturating_sub(chunk.normals.len()));
                normal = Some(index as u32 - 1);
            }
        }
        if !ends_token(self.rest.first()) {
            return None;
        }
        Some(Corner {
            position: position as u32 - 1,
            normal,
        })
    }

    /// A 1-based index of one to [`MAX_INDEX_DIGITS`] digits, not 0.
    #[inline(always)]
    fn index(&mut self) -> Option<usize> {
        let (value, digits) = decimal::leading_digits(self.rest);
        if digits == 0 || digits > MAX_INDEX_DIGITS || value == 0 {
            return None;
        }
        self.rest = &self.rest[digits..];
        Some(value as usize)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn byte_sets_match_the_tokenizer() {
        for b in 0..=u8::MAX {
            assert_eq!(in_set(SPACES, b), lex::is_space(b), "{b:#x}");
            let ends = lex::is_space(b) || b == b'\n' || b == b'#';
            assert_eq!(ends_token(Some(&b)), ends, "{b:#x}");
        }
        assert!(ends_token(None));
    }
}
