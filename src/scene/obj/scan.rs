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
        text,
        at: 0,
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

/// Whether `b` ends a token: a separator, the end of the line, a comment or the end
/// of the chunk (`None`).
#[inline(always)]
fn ends_token(b: Option<&u8>) -> bool {
    match b {
        None | Some(b'\n' | b'#') => true,
        Some(&b) => lex::is_space(b),
    }
}

struct Scanner<'a> {
    text: &'a [u8],
    /// Position of the next byte to read.
    at: usize,
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
            let Some(&first) = self.text.get(self.at) else {
                return Some(());
            };
            let second = self.text.get(self.at + 1).copied();
            let third = self.text.get(self.at + 2).copied();
            match (first, second, third) {
                (b'\n', _, _) => {
                    self.at += 1;
                    self.lines += 1;
                    continue;
                }
                (b'v', Some(b' '), _) => {
                    self.at += 2;
                    let position = self.vec3()?;
                    self.chunk.positions.push(position);
                }
                (b'f', Some(b' '), _) => {
                    self.at += 2;
                    self.face()?;
                }
                (b'v', Some(b'n'), Some(b' ')) => {
                    self.at += 3;
                    let normal = self.vec3()?;
                    self.chunk.normals.push(normal);
                }
                (b'v', Some(b't'), Some(b' ')) => {
                    self.at += 3;
                    let u = self.number()?;
                    self.skip_spaces();
                    let v = if ends_token(self.text.get(self.at)) {
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
        let rest = &self.text[self.at..];
        let end = memchr::memchr(b'\n', rest).unwrap_or(rest.len());
        let line = &rest[..end];
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
        self.at += end;
        Some(())
    }

    #[inline(always)]
    fn skip_spaces(&mut self) {
        while let Some(&b) = self.text.get(self.at)
            && lex::is_space(b)
        {
            self.at += 1;
        }
    }

    /// Skips what is left of the line (values beyond those a statement reads are
    /// ignored, as the general parser does) and its `\n`.
    #[inline(always)]
    fn skip_line(&mut self) {
        if self.text.get(self.at) != Some(&b'\n') {
            match memchr::memchr(b'\n', &self.text[self.at..]) {
                Some(offset) => self.at += offset,
                None => {
                    self.at = self.text.len();
                    return;
                }
            }
        }
        self.at += 1;
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
        let rest = &self.text[self.at..];
        if let Some((value, len)) = decimal::parse_short(rest)
            && ends_token(rest.get(len))
        {
            self.at += len;
            return Some(value);
        }
        self.general_number()
    }

    #[cold]
    fn general_number(&mut self) -> Option<Float> {
        let rest = &self.text[self.at..];
        let len = rest
            .iter()
            .position(|b| ends_token(Some(b)))
            .unwrap_or(rest.len());
        if len == 0 {
            return None;
        }
        let value = lex::float(&rest[..len]).ok()?;
        self.at += len;
        Some(value)
    }

    /// A face: triangles fanned from its first corner, as the general parser does.
    #[inline(always)]
    fn face(&mut self) -> Option<()> {
        let slot = self.slot;
        let mut first: Option<Corner> = None;
        let mut previous: Option<Corner> = None;
        let mut count = 0usize;
        loop {
            self.skip_spaces();
            if ends_token(self.text.get(self.at)) {
                break;
            }
            let corner = self.corner()?;
            count += 1;
            if let (Some(a), Some(b), 3..) = (first, previous, count) {
                let normals = match (a.normal, b.normal, corner.normal) {
                    (Some(na), Some(nb), Some(nc)) => Some([na, nb, nc]),
                    _ => None,
                };
                self.chunk.triangles.push(TriangleDesc {
                    positions: [a.position, b.position, corner.position],
                    normals,
                    material: MaterialId(slot),
                });
            }
            first.get_or_insert(corner);
            previous = Some(corner);
        }
        if count < 3 {
            return None;
        }
        self.chunk.note_shape(self.lines + 1, slot);
        Some(())
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
        if self.text.get(self.at) == Some(&b'/') {
            self.at += 1;
            let mut slash = true;
            if self.text.get(self.at) != Some(&b'/') {
                let texcoord = self.index()?;
                let chunk = &mut self.chunk;
                chunk.required.texcoords =
                    (chunk.required.texcoords).max(texcoord.saturating_sub(chunk.texcoords.len()));
                slash = self.text.get(self.at) == Some(&b'/');
            }
            if slash {
                self.at += 1;
                let index = self.index()?;
                let chunk = &mut self.chunk;
                chunk.required.normals =
                    (chunk.required.normals).max(index.saturating_sub(chunk.normals.len()));
                normal = Some(index as u32 - 1);
            }
        }
        if !ends_token(self.text.get(self.at)) {
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
        let (value, digits) = decimal::leading_digits(&self.text[self.at..]);
        if digits == 0 || digits > MAX_INDEX_DIGITS || value == 0 {
            return None;
        }
        self.at += digits;
        Some(value as usize)
    }
}
