//! Pass 2's fast path: reads a chunk's `v`, `vn`, `vt` and `f` lines in one walk
//! over its bytes, without splitting lines or tokens first, and writes the
//! elements straight into the chunk's parts of the final arrays. Pass 1 has read
//! every other line; this one only counts `usemtl` lines, to know each face's
//! material.
//!
//! The scanner never reports a problem: on a malformed line, an index of 0 or out
//! of range, an index with more than [`MAX_INDEX_DIGITS`] digits or an uncommon
//! spelling, it gives up and the general parser reads the chunk. So what it writes
//! is always what the general parser reads; it only has to be fast on the common
//! forms.

use std::mem::MaybeUninit;

use super::super::decimal;
use super::faces::{INHERITED_GROUP, Shaping};
use super::{Counts, TriangleDesc, lex, smoothing_group};
use crate::material::MaterialId;
use crate::math::{Float, Vec2, Vec3};

/// Longest index read here: nine digits always fit a `u32`.
const MAX_INDEX_DIGITS: usize = 9;

/// A chunk's parts of the final arrays, each exactly as long as the chunk's
/// elements of that kind.
pub(super) struct Parts<'a> {
    pub(super) positions: &'a mut [MaybeUninit<Vec3>],
    pub(super) texcoords: &'a mut [MaybeUninit<Vec2>],
    pub(super) normals: &'a mut [MaybeUninit<Vec3>],
    pub(super) triangles: &'a mut [MaybeUninit<TriangleDesc>],
    /// Each triangle's texture coordinate indices, when the description keeps them.
    pub(super) triangle_texcoords: Option<&'a mut [MaybeUninit<Option<[u32; 3]>>]>,
    /// Each triangle's normal indices, when the description keeps them.
    pub(super) triangle_normals: Option<&'a mut [MaybeUninit<Option<[u32; 3]>>]>,
}

/// Fills `parts` from the chunk `text`, preceded in the file by `base`; `materials`
/// are the chunk's material slots (see `Chunk`). `Some` only if every element of
/// every part was written.
pub(super) fn fill(
    text: &[u8],
    base: &Counts,
    materials: &[MaterialId],
    parts: &mut Parts<'_>,
    shaping: &mut Shaping,
) -> Option<()> {
    let mut scanner = Scanner {
        rest: text,
        base,
        materials,
        slot: 0,
        group: INHERITED_GROUP,
        written: Counts::default(),
        parts,
        shaping,
    };
    scanner.run()?;
    let parts = &scanner.parts;
    let written = &scanner.written;
    (written.positions == parts.positions.len()
        && written.texcoords == parts.texcoords.len()
        && written.normals == parts.normals.len()
        && written.triangles == parts.triangles.len())
    .then_some(())
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

/// One corner of a face, resolved to 0-based indices.
#[derive(Clone, Copy)]
struct Corner {
    position: u32,
    texcoord: Option<u32>,
    normal: Option<u32>,
}

struct Scanner<'s, 'p> {
    /// The text not read yet.
    rest: &'s [u8],
    /// The elements before the chunk.
    base: &'s Counts,
    /// The material of each slot.
    materials: &'s [MaterialId],
    /// The slot in force: how many `usemtl` lines were passed.
    slot: usize,
    /// The smoothing group in force.
    group: u32,
    /// Elements written so far.
    written: Counts,
    parts: &'s mut Parts<'p>,
    /// What pass 4 needs of the faces.
    shaping: &'s mut Shaping,
}

impl Scanner<'_, '_> {
    fn run(&mut self) -> Option<()> {
        loop {
            self.skip_spaces();
            match self.rest {
                [] => return Some(()),
                [b'\n', rest @ ..] => {
                    self.rest = rest;
                    continue;
                }
                [b'v', b' ', rest @ ..] => {
                    self.rest = rest;
                    let position = self.vec3()?;
                    // A `w` is read past; more values (a vertex colour: `v x y z r g
                    // b`) are the general parser's.
                    if !self.at_line_end() {
                        self.number()?;
                        if !self.at_line_end() {
                            return None;
                        }
                    }
                    let written = &mut self.written.positions;
                    self.parts.positions.get_mut(*written)?.write(position);
                    *written += 1;
                }
                [b'f', b' ', rest @ ..] => {
                    self.rest = rest;
                    self.face()?;
                }
                [b'v', b'n', b' ', rest @ ..] => {
                    self.rest = rest;
                    let normal = self.vec3()?;
                    let written = &mut self.written.normals;
                    self.parts.normals.get_mut(*written)?.write(normal);
                    *written += 1;
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
                    let written = &mut self.written.texcoords;
                    self.parts
                        .texcoords
                        .get_mut(*written)?
                        .write(Vec2::new(u, v));
                    *written += 1;
                }
                _ => {
                    self.other_line()?;
                    continue;
                }
            }
            self.skip_line();
        }
    }

    /// Any other line, by the tokenizer: elements not spelt as above, and the
    /// statements pass 1 read, of which only `usemtl` matters here. Faces not spelt
    /// as above give up.
    fn other_line(&mut self) -> Option<()> {
        let end = memchr::memchr(b'\n', self.rest).unwrap_or(self.rest.len());
        let (line, rest) = self.rest.split_at(end);
        self.rest = rest;
        let line = match memchr::memchr(b'#', line) {
            Some(hash) => &line[..hash],
            None => line,
        };
        let mut tokens = lex::tokens(line);
        let parts = &mut self.parts;
        let written = &mut self.written;
        match tokens.next() {
            Some(b"f") => return None,
            Some(b"v") => {
                let position = lex::any_vec3("v", &mut tokens).ok()?;
                // A `w` is read past; a vertex colour is the general parser's.
                if tokens.nth(1).is_some() {
                    return None;
                }
                parts.positions.get_mut(written.positions)?.write(position);
                written.positions += 1;
            }
            Some(b"vn") => {
                let normal = lex::any_vec3("vn", &mut tokens).ok()?;
                parts.normals.get_mut(written.normals)?.write(normal);
                written.normals += 1;
            }
            Some(b"vt") => {
                let u = lex::any_float(tokens.next()?).ok()?;
                let v = match tokens.next() {
                    Some(token) => lex::any_float(token).ok()?,
                    None => 0.0,
                };
                parts
                    .texcoords
                    .get_mut(written.texcoords)?
                    .write(Vec2::new(u, v));
                written.texcoords += 1;
            }
            Some(b"usemtl") => self.slot += 1,
            // A malformed group is an error that pass 1 found.
            Some(b"s") => self.group = smoothing_group(tokens.next()).ok()?,
            _ => {}
        }
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

    /// Whether only spaces, perhaps a comment, are left on the line.
    #[inline(always)]
    fn at_line_end(&mut self) -> bool {
        self.skip_spaces();
        matches!(self.rest, [] | [b'\n' | b'#', ..])
    }

    /// Skips what is left of the line (values beyond those a statement reads are
    /// ignored, as the general parser does) and its `\n`.
    #[inline(always)]
    fn skip_line(&mut self) {
        self.rest = match self.rest {
            [b'\n', rest @ ..] => rest,
            _ => match memchr::memchr(b'\n', self.rest) {
                Some(end) => &self.rest[end + 1..],
                None => &[],
            },
        };
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

    /// A face: triangles fanned from its first corner, as the general parser does (pass
    /// 4 cuts concave polygons again).
    #[inline(always)]
    fn face(&mut self) -> Option<()> {
        let material = *self.materials.get(self.slot)?;
        // A face of fewer than three corners is skipped (pass 1 noted it for the
        // warning); its corners are checked all the same.
        let Some(first) = self.next_corner()? else {
            return Some(());
        };
        let Some(mut previous) = self.next_corner()? else {
            return Some(());
        };
        let Some(mut corner) = self.next_corner()? else {
            return Some(());
        };
        let start = self.written.triangles;
        let mut all_normals = first.normal.is_some() && previous.normal.is_some();
        loop {
            let normals = match (first.normal, previous.normal, corner.normal) {
                (Some(na), Some(nb), Some(nc)) => Some([na, nb, nc]),
                _ => None,
            };
            all_normals &= normals.is_some();
            let written = &mut self.written.triangles;
            if let Some(part) = &mut self.parts.triangle_texcoords {
                let texcoords = match (first.texcoord, previous.texcoord, corner.texcoord) {
                    (Some(ta), Some(tb), Some(tc)) => Some([ta, tb, tc]),
                    _ => None,
                };
                part.get_mut(*written)?.write(texcoords);
            }
            if let Some(part) = &mut self.parts.triangle_normals {
                part.get_mut(*written)?.write(normals);
            } else if normals.is_some() {
                // Pass 1 counted no normals, which a corner cannot then name.
                return None;
            }
            self.parts.triangles.get_mut(*written)?.write(TriangleDesc {
                positions: [first.position, previous.position, corner.position],
                material,
            });
            *written += 1;
            previous = corner;
            match self.next_corner()? {
                Some(next) => corner = next,
                None => break,
            }
        }
        let count = self.written.triangles - start;
        self.shaping.face(start, count, all_normals, self.group);
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

    /// `v`, `v/vt`, `v//vn` or `v/vt/vn`, resolved against the elements defined so
    /// far.
    #[inline(always)]
    fn corner(&mut self) -> Option<Corner> {
        let defined = self.base.positions + self.written.positions;
        let position = self.index(defined)?;
        let mut normal = None;
        let mut texcoord = None;
        if let [b'/', rest @ ..] = self.rest {
            self.rest = rest;
            let mut slash = true;
            if self.rest.first() != Some(&b'/') {
                texcoord = Some(self.index(self.base.texcoords + self.written.texcoords)?);
                slash = self.rest.first() == Some(&b'/');
            }
            if slash {
                self.rest = &self.rest[1..];
                normal = Some(self.index(self.base.normals + self.written.normals)?);
            }
        }
        if !ends_token(self.rest.first()) {
            return None;
        }
        Some(Corner {
            position,
            texcoord,
            normal,
        })
    }

    /// A 1-based index of one to [`MAX_INDEX_DIGITS`] digits, or a negative one
    /// counting back from the end, resolved to 0-based among `defined` elements.
    #[inline(always)]
    fn index(&mut self, defined: usize) -> Option<u32> {
        let (negative, digits) = match self.rest {
            [b'-', rest @ ..] => (true, rest),
            _ => (false, self.rest),
        };
        let (value, count) = decimal::leading_digits(digits);
        if count == 0 || count > MAX_INDEX_DIGITS || value == 0 {
            return None;
        }
        self.rest = &digits[count..];
        let value = value as usize;
        let resolved = if negative {
            defined.checked_sub(value)?
        } else {
            (value <= defined).then(|| value - 1)?
        };
        u32::try_from(resolved).ok()
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
