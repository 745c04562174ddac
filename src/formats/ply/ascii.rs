//! Ascii bodies, read one element per line, as every PLY writer lays them out, so
//! that an error can name the line as well as the element. Elements with many
//! instances are parsed on all threads in runs of whole lines.

use rayon::prelude::*;

use super::header::{Element, Role, Scalar};
use super::{Body, ElementError, MeshReader, integral};
use crate::formats::error::ParseErrorKind;
use crate::formats::polygon::FanPolygon;
use crate::formats::{SceneDescription, lex};
use crate::math::Float;

/// An ascii body, one element per non-blank line.
pub(super) struct AsciiBody<'a> {
    bytes: &'a [u8],
    /// Start of the next line.
    next_line: usize,
    /// Number of the next line.
    next_line_number: usize,
    /// The current line and the position in it.
    line: &'a [u8],
    pos: usize,
    line_number: usize,
}

impl<'a> AsciiBody<'a> {
    pub(super) fn new(bytes: &'a [u8], first_line: usize) -> Self {
        AsciiBody {
            bytes,
            next_line: 0,
            next_line_number: first_line,
            line: &[],
            pos: 0,
            line_number: first_line,
        }
    }

    /// The next whitespace-separated token on the current line.
    #[inline]
    fn token(&mut self) -> Option<&'a [u8]> {
        // Any control character counts as a separator: one comparison per byte
        // instead of a set lookup, in the loop that sees every byte of the body.
        let line = self.line;
        let mut start = self.pos;
        while start < line.len() && line[start] <= b' ' {
            start += 1;
        }
        let mut end = start;
        while end < line.len() && line[end] > b' ' {
            end += 1;
        }
        self.pos = end;
        (end > start).then(|| &line[start..end])
    }

    #[inline]
    fn value(&mut self, name: &str) -> Result<&'a [u8], ParseErrorKind> {
        self.token()
            .ok_or_else(|| ParseErrorKind::MissingValue(name.to_owned()))
    }
}

impl Body for AsciiBody<'_> {
    fn begin(&mut self) -> Result<(), ParseErrorKind> {
        loop {
            // At the end of the file this names the line where the element was due.
            self.line_number = self.next_line_number;
            if self.next_line >= self.bytes.len() {
                return Err(ParseErrorKind::Truncated);
            }
            let rest = &self.bytes[self.next_line..];
            let length = memchr::memchr(b'\n', rest).unwrap_or(rest.len());
            self.line = &rest[..length];
            self.pos = 0;
            self.next_line += length + 1;
            self.next_line_number += 1;
            if !self.line.trim_ascii().is_empty() {
                return Ok(());
            }
        }
    }

    fn end(&mut self) -> Result<(), ParseErrorKind> {
        match self.token() {
            Some(extra) => Err(ParseErrorKind::ExtraValue(lex::show(extra))),
            None => Ok(()),
        }
    }

    #[inline]
    fn float(&mut self, ty: Scalar, name: &str) -> Result<Float, ParseErrorKind> {
        let token = self.value(name)?;
        if ty.is_integer() {
            return parse_int(token).map(|v| v as Float);
        }
        // A non-finite value is a warning (see `formats::finite`).
        lex::any_float(token)
    }

    #[inline]
    fn int(&mut self, ty: Scalar, name: &str) -> Result<i64, ParseErrorKind> {
        let token = self.value(name)?;
        if ty.is_integer() {
            return parse_int(token);
        }
        let value = lex::float(token)?;
        integral(value as f64).ok_or_else(|| ParseErrorKind::BadNumber(lex::show(token)))
    }

    #[inline]
    fn skip(&mut self, _ty: Scalar, name: &str) -> Result<(), ParseErrorKind> {
        self.value(name).map(|_| ())
    }

    fn line(&self) -> Option<usize> {
        Some(self.line_number)
    }

    fn remaining(&self) -> usize {
        let rest = self.bytes.get(self.next_line..).unwrap_or_default();
        rest.trim_ascii().len()
    }

    fn ascii_rest(&self) -> Option<(&[u8], usize, usize)> {
        Some((self.bytes, self.next_line, self.next_line_number))
    }

    fn ascii_seek(&mut self, offset: usize, line: usize) {
        self.next_line = offset;
        self.next_line_number = line;
        self.line = &[];
        self.pos = 0;
    }
}

/// An optionally signed decimal integer of at most 18 digits.
#[inline]
fn parse_int(token: &[u8]) -> Result<i64, ParseErrorKind> {
    let bad = || ParseErrorKind::BadNumber(lex::show(token));
    let (negative, digits) = match token {
        [b'-', rest @ ..] => (true, rest),
        [b'+', rest @ ..] => (false, rest),
        _ => (false, token),
    };
    if digits.is_empty() || digits.len() > 18 {
        return Err(bad());
    }
    let mut value: i64 = 0;
    for &d in digits {
        if !d.is_ascii_digit() {
            return Err(bad());
        }
        value = value * 10 + (d - b'0') as i64;
    }
    Ok(if negative { -value } else { value })
}

/// Ascii elements with at least this many instances are parsed on all threads, in
/// runs of whole lines; for fewer, splitting costs more than it saves.
pub(super) const PARALLEL_ASCII_ELEMENTS: usize = 1 << 15;
/// Fewest elements one parallel task parses.
const MIN_ASCII_RUN: usize = 1 << 13;

/// Where a run of ascii lines starts: byte offset, line number, and the index of
/// its first element.
#[derive(Clone, Copy, Debug)]
struct LineRun {
    offset: usize,
    line: usize,
    first_index: usize,
}

impl MeshReader {
    /// Parses the `element.count` elements of an ascii body that start at byte
    /// `offset` (line `line`) on all threads: one serial pass finds line runs of about
    /// equal element counts, each run is parsed into a reader of its own, and the
    /// results are appended in file order, so errors and output are exactly those of
    /// the serial loop. Returns where the element ends, or `None` when the file ends
    /// first (the serial loop then reports where).
    pub(super) fn read_ascii_parallel(
        &mut self,
        element_index: usize,
        element: &Element,
        roles: &[Role],
        bytes: &[u8],
        offset: usize,
        line: usize,
    ) -> Result<Option<(usize, usize)>, ElementError> {
        // Split into runs: the serial part, a newline search and a blank-line test.
        let run_count = (rayon::current_num_threads() * 4)
            .min(element.count / MIN_ASCII_RUN)
            .max(1);
        let per_run = element.count.div_ceil(run_count);
        let mut runs = Vec::with_capacity(run_count + 1);
        let (mut start, mut line_number, mut index) = (offset, line, 0);
        let ends = memchr::memchr_iter(b'\n', &bytes[offset.min(bytes.len())..])
            .map(|i| offset + i)
            .chain(std::iter::once(bytes.len()));
        for end in ends {
            if index == element.count {
                break;
            }
            if !bytes[start..end].trim_ascii().is_empty() {
                if index % per_run == 0 {
                    runs.push(LineRun {
                        offset: start,
                        line: line_number,
                        first_index: index,
                    });
                }
                index += 1;
            }
            start = end + 1;
            line_number += 1;
        }
        if index < element.count {
            return Ok(None);
        }
        let end = LineRun {
            offset: start.min(bytes.len()),
            line: line_number,
            first_index: element.count,
        };
        runs.push(end);

        let (vertex_count, has_normals, has_texcoords, has_colours) = (
            self.vertex_count,
            self.has_normals,
            self.has_texcoords,
            self.has_colours,
        );
        let parts: Vec<Result<MeshReader, ElementError>> = runs
            .par_windows(2)
            .map(|run| {
                let (first, next) = (run[0], run[1]);
                let mut part = MeshReader {
                    scene: SceneDescription::default(),
                    vertex_count,
                    has_normals,
                    has_texcoords,
                    has_colours,
                    polygons: Vec::new(),
                };
                let elements = next.first_index - first.first_index;
                match element.name.as_str() {
                    "vertex" => part.scene.positions.reserve(elements),
                    "face" => part.scene.triangles.reserve(elements),
                    _ => {}
                }
                let mut body = AsciiBody::new(&bytes[first.offset..next.offset], first.line);
                for index in first.first_index..next.first_index {
                    part.read_element(element, roles, &mut body)
                        .map_err(|kind| ElementError {
                            element: element_index,
                            index,
                            line: body.line(),
                            kind,
                        })?;
                }
                Ok(part)
            })
            .collect();
        for part in parts {
            let part = part?;
            // The part's polygons count their triangles from its first.
            let base = self.scene.triangles.len() as u32;
            self.polygons
                .extend(part.polygons.iter().map(|p| FanPolygon {
                    first: base.wrapping_add(p.first),
                    ..*p
                }));
            let part = part.scene;
            self.scene.positions.extend_from_slice(&part.positions);
            self.scene.normals.extend_from_slice(&part.normals);
            self.scene.texcoords.extend_from_slice(&part.texcoords);
            self.scene.colours.extend_from_slice(&part.colours);
            self.scene.triangles.extend_from_slice(&part.triangles);
        }
        if self.scene.triangles.len() > u32::MAX as usize {
            return Err(ElementError {
                element: element_index,
                index: element.count - 1,
                line: Some(end.line - 1),
                kind: ParseErrorKind::TooMany("triangles"),
            });
        }
        Ok(Some((end.offset, end.line)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formats::ply::testing::{FACES, Mesh, VERTS, ascii, error, parse, triangles};
    use crate::math::{Vec2, Vec3};

    #[test]
    fn ascii_takes_crlf_blank_lines_and_u_v() {
        let text = "ply\r\nformat ascii 1.0\r\nelement vertex 3\r\nproperty double x\r\nproperty double y\r\nproperty double z\r\nproperty float u\r\nproperty float v\r\nelement face 1\r\nproperty list uchar int vertex_indices\r\nend_header\r\n0 0 0 0 0\r\n\r\n1 0 0 1 0\r\n 0\t1 0 0 1 \r\n3 0 1 2\r\n";
        let scene = parse(text.as_bytes()).unwrap();
        assert_eq!(scene.positions[2], Vec3::Y);
        assert_eq!(scene.texcoords[1], Vec2::X);
        assert_eq!(triangles(&scene), [[0, 1, 2]]);
    }

    #[test]
    fn ascii_element_errors_name_line_element_and_index() {
        let file = |body: &str| error(&ascii(&format!("{VERTS}{FACES}"), body));
        let verts = "0 0 0\n1 0 0\n0 1 0\n";
        assert_eq!(
            file("0 0 0\n1 0\n"),
            "t.ply:11: vertex 1: the line ends before property 'z'"
        );
        assert_eq!(
            file("0 0 0\n1 0 0 4\n"),
            "t.ply:11: vertex 1: unexpected value '4' after the element's last property"
        );
        assert_eq!(
            file("0 0 0\n1 x 0\n"),
            "t.ply:11: vertex 1: invalid number 'x'"
        );
        assert_eq!(
            file(verts),
            "t.ply:13: face 0: file ends inside the element"
        );
        assert_eq!(
            file("0 0 0\n1 0 0\n"),
            "t.ply:12: vertex 2: file ends inside the element"
        );
        assert_eq!(
            file(&format!("{verts}3 0 1 3\n")),
            "t.ply:13: face 0: face index 3 out of range (3 vertices defined)"
        );
        assert_eq!(
            file(&format!("{verts}3 0 -1 2\n")),
            "t.ply:13: face 0: face index -1 out of range (3 vertices defined)"
        );
        assert_eq!(
            file(&format!("{verts}2 0 1\n")),
            "t.ply:13: face 0: face has 2 vertices, needs at least 3"
        );
        assert_eq!(
            file(&format!("{verts}3 0 1\n")),
            "t.ply:13: face 0: the line ends before property 'vertex_indices'"
        );
        assert_eq!(
            file(&format!("{verts}3 0 1.5 2\n")),
            "t.ply:13: face 0: invalid number '1.5'"
        );
        let negative = error(&ascii(
            &format!("{VERTS}element face 1\nproperty list int int vertex_indices\n"),
            &format!("{verts}-3 0 1 2\n"),
        ));
        assert_eq!(negative, "t.ply:13: face 0: negative list length -3");
    }

    #[test]
    fn large_ascii_files_parse_in_parallel_exactly_like_small_ones() {
        // A strip of quads with normals: enough elements for the parallel path.
        let n = 3 * PARALLEL_ASCII_ELEMENTS / 2;
        let (f, u, i) = (Scalar::F32, Scalar::U8, Scalar::I32);
        let mut rows: Vec<Vec<(Scalar, f64)>> = (0..2 * n)
            .map(|k| {
                vec![
                    (f, (k / 2) as f64),
                    (f, (k % 2) as f64),
                    (f, 0.0),
                    (f, 0.0),
                    (f, 0.0),
                    (f, 1.0),
                ]
            })
            .collect();
        rows.extend((0..n - 1).map(|q| {
            let k = 2.0 * q as f64;
            vec![(u, 4.0), (i, k), (i, k + 2.0), (i, k + 3.0), (i, k + 1.0)]
        }));
        // One late quad made concave (an arrow head whose fan from its first corner
        // would cover the notch): it is cut again, in the part that read it.
        let concave = n - 20;
        let k = 2 * concave;
        rows[k + 1][0].1 = (k / 2) as f64 + 0.6;
        rows[k + 1][1].1 = 0.4;
        let header = format!(
            "element vertex {}\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nelement face {}\nproperty list uchar int vertex_indices\n",
            2 * n,
            n - 1
        );
        let mesh = Mesh { header, rows };
        let mut ascii = mesh.ascii();
        // Blank lines inside must not shift element indices or line numbers.
        let at = ascii.len() / 3;
        let newline = at + ascii[at..].iter().position(|&b| b == b'\n').unwrap();
        ascii.splice(newline..newline, *b"\n\n");
        let parallel = parse(&ascii).unwrap();
        let serial = parse(&mesh.binary(false)).unwrap();
        assert_eq!(parallel.positions, serial.positions);
        assert_eq!(parallel.normals, serial.normals);
        assert_eq!(parallel.triangles, serial.triangles);
        assert_eq!(parallel.triangles.len(), 2 * (n - 1));
        // Cut along the diagonal from the notch (vertex k + 1) to the opposite corner
        // (k + 2), where the fan cuts along the other.
        let k = k as u32;
        for t in &triangles(&parallel)[2 * concave..2 * concave + 2] {
            assert!(t.contains(&(k + 1)) && t.contains(&(k + 2)), "{t:?}");
        }
        assert_eq!(
            parallel.triangles[2 * (n - 1) - 1].positions,
            [2 * n as u32 - 4, 2 * n as u32 - 1, 2 * n as u32 - 3]
        );

        // An error late in the file names the same line and index as a serial read:
        // 13 header lines, the blank lines before it, one line per element.
        let text = String::from_utf8(ascii).unwrap();
        let face = n - 10;
        let bad_index = 2 * n + face;
        let bad = text
            .lines()
            .enumerate()
            .map(|(k, l)| if k == 14 + bad_index { "4 0 1 2" } else { l })
            .collect::<Vec<_>>()
            .join("\n");
        assert_eq!(
            parse(bad.as_bytes()).unwrap_err().to_string(),
            format!(
                "t.ply:{}: face {face}: the line ends before property 'vertex_indices'",
                15 + bad_index
            )
        );
        // A file cut short falls back to the serial read, which says where.
        let cut: String = text
            .lines()
            .take(14 + 2 * n + 5)
            .collect::<Vec<_>>()
            .join("\n");
        assert_eq!(
            parse(cut.as_bytes()).unwrap_err().to_string(),
            format!(
                "t.ply:{}: face 5: file ends inside the element",
                15 + 2 * n + 5
            )
        );
    }
}
