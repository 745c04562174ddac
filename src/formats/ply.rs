//! The PLY reader (Greg Turk's polygon file format): `ascii`, `binary_little_endian`
//! and `binary_big_endian` bodies, every scalar type under both its names.
//!
//! From the `vertex` element it takes `x y z`, and when present `nx ny nz` (as vertex
//! normals) and texture coordinates `u v` (or `s t`, `texture_u texture_v`,
//! `texture_s texture_t`); from `face` the list `vertex_indices` (or `vertex_index`),
//! split into triangle fans. Every other element and property is read past and
//! ignored. PLY has no materials: every triangle gets [`Material::fallback`].
//!
//! Ascii bodies are read one element per line, as every PLY writer lays them out, so
//! that an error can name the line as well as the element.

use std::path::Path;

use rayon::prelude::*;

use super::error::{IndexKind, ParseErrorKind, SceneError};
use super::{SceneDescription, TriangleDesc, lex, read_file};
use crate::material::{Material, MaterialId};
use crate::math::{Float, Vec2, Vec3};

/// Reads a PLY file (gzip-compressed or not).
///
/// # Errors
/// An unreadable file, a malformed header (naming file and line), or a malformed or
/// truncated element (naming file, element and its 0-based index, and for ascii files
/// the line).
pub fn load_ply(path: &Path) -> Result<SceneDescription, SceneError> {
    let bytes = read_file(path)?;
    parse_ply(&bytes, path)
}

/// Parses a PLY file's bytes; `path` names it in messages.
///
/// # Errors
/// As [`load_ply`].
pub fn parse_ply(bytes: &[u8], path: &Path) -> Result<SceneDescription, SceneError> {
    let header_error = |(line, kind)| SceneError::Parse {
        path: path.to_path_buf(),
        line,
        kind,
    };
    let header = parse_header(bytes).map_err(header_error)?;
    let roles = header
        .elements
        .iter()
        .map(roles)
        .collect::<Result<Vec<_>, _>>()
        .map_err(header_error)?;
    let body = &bytes[header.body_offset..];
    let mut reader = MeshReader::new(&header, &roles, body.len());
    match header.format {
        Format::Ascii => reader.read(&header, &roles, &mut AsciiBody::new(body, header.body_line)),
        Format::BinaryLittleEndian => {
            reader.read(&header, &roles, &mut BinaryBody::<false>::new(body))
        }
        Format::BinaryBigEndian => reader.read(&header, &roles, &mut BinaryBody::<true>::new(body)),
    }
    .map_err(|e| SceneError::Element {
        path: path.to_path_buf(),
        line: e.line,
        element: header.elements[e.element].name.clone(),
        index: e.index,
        kind: Box::new(e.kind),
    })?;
    Ok(reader.finish())
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Format {
    Ascii,
    BinaryLittleEndian,
    BinaryBigEndian,
}

/// A PLY scalar type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    /// The type of a header name: the original names and the sized aliases.
    fn from_name(name: &[u8]) -> Option<Scalar> {
        Some(match name {
            b"char" | b"int8" => Scalar::I8,
            b"uchar" | b"uint8" => Scalar::U8,
            b"short" | b"int16" => Scalar::I16,
            b"ushort" | b"uint16" => Scalar::U16,
            b"int" | b"int32" => Scalar::I32,
            b"uint" | b"uint32" => Scalar::U32,
            b"float" | b"float32" => Scalar::F32,
            b"double" | b"float64" => Scalar::F64,
            _ => return None,
        })
    }

    /// Bytes in a binary body.
    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum PropertyType {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Clone, Debug)]
struct Property {
    name: String,
    ty: PropertyType,
    /// Header line, for errors about the property's type.
    line: usize,
}

#[derive(Clone, Debug)]
struct Element {
    name: String,
    count: usize,
    properties: Vec<Property>,
    /// Header line, for errors about missing properties.
    line: usize,
}

impl Element {
    /// Bytes of one element in a binary body, counting lists as empty: a lower bound
    /// used to cap allocations by what the file can hold.
    fn min_binary_size(&self) -> usize {
        self.properties
            .iter()
            .map(|p| match p.ty {
                PropertyType::Scalar(s) => s.size(),
                PropertyType::List { count, .. } => count.size(),
            })
            .sum::<usize>()
            .max(1)
    }
}

#[derive(Clone, Debug)]
struct Header {
    format: Format,
    elements: Vec<Element>,
    /// Byte offset of the body: just past the `end_header` line's newline.
    body_offset: usize,
    /// 1-based line number of the body's first line.
    body_line: usize,
}

type HeaderError = (usize, ParseErrorKind);

fn parse_header(bytes: &[u8]) -> Result<Header, HeaderError> {
    let header_error = |line: usize, message: String| (line, ParseErrorKind::PlyHeader(message));
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut offset = 0;
    let mut line_number = 0;
    loop {
        line_number += 1;
        let Some(length) = bytes[offset..].iter().position(|&b| b == b'\n') else {
            return Err(if line_number == 1 {
                (1, ParseErrorKind::NotPly)
            } else {
                header_error(line_number, "the header has no 'end_header' line".into())
            });
        };
        let line = &bytes[offset..offset + length];
        offset += length + 1;
        let line = line.strip_suffix(b"\r").unwrap_or(line);
        if line_number == 1 {
            if line != b"ply" {
                return Err((1, ParseErrorKind::NotPly));
            }
            continue;
        }
        let mut tokens = lex::tokens(line);
        let Some(keyword) = tokens.next() else {
            continue;
        };
        let words: Vec<&[u8]> = tokens.collect();
        match keyword {
            b"comment" | b"obj_info" => {}
            b"format" => {
                format = Some(match words.first().copied() {
                    Some(b"ascii") => Format::Ascii,
                    Some(b"binary_little_endian") => Format::BinaryLittleEndian,
                    Some(b"binary_big_endian") => Format::BinaryBigEndian,
                    other => {
                        return Err(header_error(
                            line_number,
                            format!(
                                "unknown format '{}' (expected ascii, binary_little_endian or binary_big_endian)",
                                lex::show(other.unwrap_or(b""))
                            ),
                        ));
                    }
                });
            }
            b"element" => {
                let [name, count] = words[..] else {
                    return Err(header_error(
                        line_number,
                        "'element' needs a name and a count".into(),
                    ));
                };
                let count = std::str::from_utf8(count)
                    .ok()
                    .and_then(|c| c.parse::<usize>().ok())
                    .ok_or_else(|| {
                        header_error(
                            line_number,
                            format!("invalid element count '{}'", lex::show(count)),
                        )
                    })?;
                let name = String::from_utf8_lossy(name).into_owned();
                if elements.iter().any(|e| e.name == name) {
                    return Err(header_error(
                        line_number,
                        format!("element '{name}' declared twice"),
                    ));
                }
                elements.push(Element {
                    name,
                    count,
                    properties: Vec::new(),
                    line: line_number,
                });
            }
            b"property" => {
                let element = elements.last_mut().ok_or_else(|| {
                    header_error(line_number, "'property' before any 'element'".into())
                })?;
                let scalar = |name: &[u8]| {
                    Scalar::from_name(name).ok_or_else(|| {
                        header_error(
                            line_number,
                            format!("unknown property type '{}'", lex::show(name)),
                        )
                    })
                };
                let (ty, name) = match words[..] {
                    [b"list", count, item, name] => (
                        PropertyType::List {
                            count: scalar(count)?,
                            item: scalar(item)?,
                        },
                        name,
                    ),
                    [b"list", ..] => {
                        return Err(header_error(
                            line_number,
                            "'property list' needs a count type, an item type and a name".into(),
                        ));
                    }
                    [ty, name] => (PropertyType::Scalar(scalar(ty)?), name),
                    _ => {
                        return Err(header_error(
                            line_number,
                            "'property' needs a type and a name".into(),
                        ));
                    }
                };
                element.properties.push(Property {
                    name: String::from_utf8_lossy(name).into_owned(),
                    ty,
                    line: line_number,
                });
            }
            b"end_header" => break,
            other => {
                return Err(header_error(
                    line_number,
                    format!("unknown header keyword '{}'", lex::show(other)),
                ));
            }
        }
    }
    let format = format.ok_or_else(|| header_error(2, "the header has no 'format' line".into()))?;
    Ok(Header {
        format,
        elements,
        body_offset: offset,
        body_line: line_number + 1,
    })
}

/// What the reader does with one property's value.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Role {
    Skip,
    Position(usize),
    Normal(usize),
    TexCoord(usize),
    Indices,
}

/// The roles of an element's properties, checked against their types.
fn roles(element: &Element) -> Result<Vec<Role>, HeaderError> {
    let mut roles = vec![Role::Skip; element.properties.len()];
    let find = |names: &[&str]| {
        element
            .properties
            .iter()
            .position(|p| names.contains(&p.name.as_str()))
    };
    let scalar = |index: usize| {
        let p = &element.properties[index];
        match p.ty {
            PropertyType::Scalar(_) => Ok(index),
            PropertyType::List { .. } => Err((
                p.line,
                ParseErrorKind::PlyHeader(format!(
                    "property '{}' of element '{}' must be a scalar, not a list",
                    p.name, element.name
                )),
            )),
        }
    };
    match element.name.as_str() {
        "vertex" => {
            for (axis, name) in ["x", "y", "z"].into_iter().enumerate() {
                let index = find(&[name]).ok_or_else(|| {
                    (
                        element.line,
                        ParseErrorKind::PlyHeader(format!(
                            "element 'vertex' has no property '{name}'"
                        )),
                    )
                })?;
                roles[scalar(index)?] = Role::Position(axis);
            }
            // Normals and texture coordinates count only when complete.
            let normals: &[&[&str]] = &[&["nx"], &["ny"], &["nz"]];
            let texcoords: &[&[&str]] = &[
                &["u", "s", "texture_u", "texture_s"],
                &["v", "t", "texture_v", "texture_t"],
            ];
            for (names, role) in [
                (normals, Role::Normal as fn(usize) -> Role),
                (texcoords, Role::TexCoord),
            ] {
                let found: Vec<Option<usize>> = names.iter().map(|n| find(n)).collect();
                if found.iter().all(Option::is_some) {
                    for (axis, index) in found.into_iter().flatten().enumerate() {
                        roles[scalar(index)?] = role(axis);
                    }
                }
            }
        }
        "face" => {
            let index = find(&["vertex_indices", "vertex_index"]).ok_or_else(|| {
                (
                    element.line,
                    ParseErrorKind::PlyHeader(
                        "element 'face' has no property 'vertex_indices' or 'vertex_index'".into(),
                    ),
                )
            })?;
            let p = &element.properties[index];
            if !matches!(p.ty, PropertyType::List { .. }) {
                return Err((
                    p.line,
                    ParseErrorKind::PlyHeader(format!(
                        "property '{}' of element 'face' must be a list",
                        p.name
                    )),
                ));
            }
            roles[index] = Role::Indices;
        }
        _ => {}
    }
    Ok(roles)
}

/// Where in the body an element failed.
struct ElementError {
    element: usize,
    index: usize,
    line: Option<usize>,
    kind: ParseErrorKind,
}

/// The values of a body, element by element. Implemented for ascii and both binary
/// byte orders, so that one monomorphized loop reads each.
trait Body {
    /// Moves to the next element (the next non-blank line in ascii).
    fn begin(&mut self) -> Result<(), ParseErrorKind>;
    /// Checks that the element is complete (no values left on an ascii line).
    fn end(&mut self) -> Result<(), ParseErrorKind>;
    /// The next value as a float; `name` names the property in errors.
    fn float(&mut self, ty: Scalar, name: &str) -> Result<Float, ParseErrorKind>;
    /// The next value as an integer (a float value must be integral).
    fn int(&mut self, ty: Scalar, name: &str) -> Result<i64, ParseErrorKind>;
    /// Reads past the next value.
    fn skip(&mut self, ty: Scalar, name: &str) -> Result<(), ParseErrorKind>;
    /// 1-based line of the current element, for ascii bodies.
    fn line(&self) -> Option<usize>;
    /// Bytes left after the last element.
    fn remaining(&self) -> usize;
    /// For binary bodies: the unread bytes and whether they are big-endian, for
    /// [`MeshReader::read_binary_fixed`].
    fn binary_rest(&self) -> Option<(&[u8], bool)> {
        None
    }
    /// Marks `bytes` more bytes of a binary body read.
    fn advance(&mut self, bytes: usize) {
        debug_assert_eq!(bytes, 0, "only binary bodies advance");
    }
    /// For ascii bodies: all the bytes, and the byte offset and number of the next
    /// line, for [`MeshReader::read_ascii_parallel`].
    fn ascii_rest(&self) -> Option<(&[u8], usize, usize)> {
        None
    }
    /// Moves an ascii body to the line that starts at byte `offset`, numbered `line`.
    fn ascii_seek(&mut self, offset: usize, line: usize) {
        debug_assert!(offset == 0 && line == 0, "only ascii bodies seek");
    }
}

struct AsciiBody<'a> {
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
    fn new(bytes: &'a [u8], first_line: usize) -> Self {
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
        lex::float(token)
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

/// `value` as an integer, if it is one (indices and counts stored as floats).
#[inline]
fn integral(value: f64) -> Option<i64> {
    (value.fract() == 0.0 && value.abs() < 1e18).then_some(value as i64)
}

/// A binary body; `BIG_ENDIAN` picks the byte order at compile time.
struct BinaryBody<'a, const BIG_ENDIAN: bool> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a, const BIG_ENDIAN: bool> BinaryBody<'a, BIG_ENDIAN> {
    fn new(bytes: &'a [u8]) -> Self {
        BinaryBody { bytes, pos: 0 }
    }

    /// The next value, as `f64` for float types (exact) and `i64` for integers.
    #[inline(always)]
    fn number(&mut self, ty: Scalar) -> Result<Number, ParseErrorKind> {
        let bytes = self.bytes[self.pos..]
            .get(..ty.size())
            .ok_or(ParseErrorKind::Truncated)?;
        self.pos += ty.size();
        Ok(decode::<BIG_ENDIAN>(bytes, ty))
    }
}

/// A binary value, kept integral when its type is.
#[derive(Clone, Copy)]
enum Number {
    Int(i64),
    Float(f64),
}

impl Number {
    #[inline(always)]
    fn as_float(self) -> f64 {
        match self {
            Number::Int(i) => i as f64,
            Number::Float(f) => f,
        }
    }
}

/// Decodes the value of type `ty` at the start of `bytes`, which holds at least
/// `ty.size()` bytes.
#[inline(always)]
fn decode<const BIG_ENDIAN: bool>(bytes: &[u8], ty: Scalar) -> Number {
    macro_rules! read {
        ($t:ty) => {{
            let raw = *bytes.first_chunk().expect("caller checked the length");
            if BIG_ENDIAN {
                <$t>::from_be_bytes(raw)
            } else {
                <$t>::from_le_bytes(raw)
            }
        }};
    }
    match ty {
        Scalar::I8 => Number::Int(read!(i8) as i64),
        Scalar::U8 => Number::Int(read!(u8) as i64),
        Scalar::I16 => Number::Int(read!(i16) as i64),
        Scalar::U16 => Number::Int(read!(u16) as i64),
        Scalar::I32 => Number::Int(read!(i32) as i64),
        Scalar::U32 => Number::Int(read!(u32) as i64),
        Scalar::F32 => Number::Float(read!(f32) as f64),
        Scalar::F64 => Number::Float(read!(f64)),
    }
}

/// Decodes a value of integer type `ty` (floats are truncated: callers pass integer
/// types only).
#[inline(always)]
fn decode_int<const BIG_ENDIAN: bool>(bytes: &[u8], ty: Scalar) -> i64 {
    match decode::<BIG_ENDIAN>(bytes, ty) {
        Number::Int(i) => i,
        Number::Float(f) => f as i64,
    }
}

/// Item `k` of a list of integer type `item`, with the usual 32-bit index types
/// decoded without a size lookup.
#[inline(always)]
fn list_item<const BIG_ENDIAN: bool>(list: &[u8], k: usize, item: Scalar) -> i64 {
    let four = |k: usize| -> [u8; 4] {
        [
            list[4 * k],
            list[4 * k + 1],
            list[4 * k + 2],
            list[4 * k + 3],
        ]
    };
    match (item, BIG_ENDIAN) {
        (Scalar::I32, false) => i32::from_le_bytes(four(k)) as i64,
        (Scalar::I32, true) => i32::from_be_bytes(four(k)) as i64,
        (Scalar::U32, false) => u32::from_le_bytes(four(k)) as i64,
        (Scalar::U32, true) => u32::from_be_bytes(four(k)) as i64,
        _ => decode_int::<BIG_ENDIAN>(&list[k * item.size()..], item),
    }
}

/// A decoded value as an integer (a float must be integral).
#[inline(always)]
fn integer(value: Number) -> Result<i64, ParseErrorKind> {
    match value {
        Number::Int(i) => Ok(i),
        Number::Float(f) => integral(f).ok_or_else(|| ParseErrorKind::BadNumber(f.to_string())),
    }
}

/// A decoded value as a finite float.
#[inline(always)]
fn finite_float(value: Number) -> Result<Float, ParseErrorKind> {
    let v = value.as_float() as Float;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(ParseErrorKind::NonFinite(value.as_float().to_string()))
    }
}

impl<const BIG_ENDIAN: bool> Body for BinaryBody<'_, BIG_ENDIAN> {
    #[inline]
    fn begin(&mut self) -> Result<(), ParseErrorKind> {
        Ok(())
    }

    #[inline]
    fn end(&mut self) -> Result<(), ParseErrorKind> {
        Ok(())
    }

    #[inline]
    fn float(&mut self, ty: Scalar, _name: &str) -> Result<Float, ParseErrorKind> {
        finite_float(self.number(ty)?)
    }

    #[inline]
    fn int(&mut self, ty: Scalar, _name: &str) -> Result<i64, ParseErrorKind> {
        integer(self.number(ty)?)
    }

    #[inline]
    fn skip(&mut self, ty: Scalar, _name: &str) -> Result<(), ParseErrorKind> {
        let end = self.pos + ty.size();
        if end > self.bytes.len() {
            return Err(ParseErrorKind::Truncated);
        }
        self.pos = end;
        Ok(())
    }

    fn line(&self) -> Option<usize> {
        None
    }

    fn remaining(&self) -> usize {
        self.bytes.len() - self.pos
    }

    fn binary_rest(&self) -> Option<(&[u8], bool)> {
        Some((&self.bytes[self.pos..], BIG_ENDIAN))
    }

    fn advance(&mut self, bytes: usize) {
        self.pos += bytes;
    }
}

/// Binary elements with at least this many instances are decoded on all threads.
const PARALLEL_BINARY_ELEMENTS: usize = 1 << 16;

/// One output array of fixed-stride records decoded on all threads: the values of the
/// `fields` whose slots are `first_slot..first_slot + N`, turned into `T` by `make`.
fn gather<const BIG_ENDIAN: bool, const N: usize, T: Send>(
    records: &[u8],
    stride: usize,
    fields: &[(usize, usize, Scalar)],
    first_slot: usize,
    make: impl Fn([Float; N]) -> T + Sync,
) -> Vec<T> {
    let fields: Vec<(usize, usize, Scalar)> = fields
        .iter()
        .filter(|&&(slot, _, _)| (first_slot..first_slot + N).contains(&slot))
        .map(|&(slot, offset, ty)| (slot - first_slot, offset, ty))
        .collect();
    records
        .par_chunks_exact(stride)
        .map(|record| {
            let mut values = [0.0; N];
            for &(slot, offset, ty) in &fields {
                values[slot] = decode::<BIG_ENDIAN>(&record[offset..], ty).as_float() as Float;
            }
            make(values)
        })
        .collect()
}

/// `to` followed by `from`, moving `from` over whole when `to` is empty.
fn append_triangles(to: &mut Vec<TriangleDesc>, mut from: Vec<TriangleDesc>) {
    if to.is_empty() {
        *to = from;
    } else {
        to.append(&mut from);
    }
}

/// Ascii elements with at least this many instances are parsed on all threads, in
/// runs of whole lines; for fewer, splitting costs more than it saves.
const PARALLEL_ASCII_ELEMENTS: usize = 1 << 15;
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

/// Collects the mesh while the body is read.
struct MeshReader {
    scene: SceneDescription,
    /// Vertices declared by the header: the range face indices must fall in.
    vertex_count: usize,
    has_normals: bool,
    has_texcoords: bool,
}

impl MeshReader {
    fn new(header: &Header, roles: &[Vec<Role>], body_len: usize) -> MeshReader {
        let vertex = header.elements.iter().position(|e| e.name == "vertex");
        let vertex_roles = vertex.map_or(&[][..], |i| &roles[i]);
        MeshReader {
            scene: SceneDescription::default(),
            vertex_count: vertex.map_or(0, |i| header.elements[i].count),
            has_normals: vertex_roles.contains(&Role::Normal(0)),
            has_texcoords: vertex_roles.contains(&Role::TexCoord(0)),
        }
        .with_capacity(header, body_len)
    }

    /// Reserves space for the declared counts, but no more than the body can hold,
    /// so that an absurd count in a small file cannot exhaust memory.
    fn with_capacity(mut self, header: &Header, body_len: usize) -> MeshReader {
        for element in &header.elements {
            let min_size = match header.format {
                Format::Ascii => 2,
                _ => element.min_binary_size(),
            };
            let count = element.count.min(body_len / min_size);
            match element.name.as_str() {
                "vertex" => {
                    self.scene.positions.reserve(count);
                    if self.has_normals {
                        self.scene.normals.reserve(count);
                    }
                    if self.has_texcoords {
                        self.scene.texcoords.reserve(count);
                    }
                }
                "face" => self.scene.triangles.reserve(count),
                _ => {}
            }
        }
        self
    }

    fn read<B: Body>(
        &mut self,
        header: &Header,
        roles: &[Vec<Role>],
        body: &mut B,
    ) -> Result<(), ElementError> {
        for (element_index, (element, roles)) in header.elements.iter().zip(roles).enumerate() {
            let at = |index: usize, line: Option<usize>, kind| ElementError {
                element: element_index,
                index,
                line,
                kind,
            };
            if element.name == "vertex" && element.count > u32::MAX as usize {
                return Err(at(0, None, ParseErrorKind::TooMany("vertices")));
            }
            if let Some((bytes, big_endian)) = body.binary_rest() {
                let fast = if big_endian {
                    self.read_binary_fixed::<true>(element, roles, bytes)
                } else {
                    self.read_binary_fixed::<false>(element, roles, bytes)
                };
                if let Some(result) = fast {
                    body.advance(result.map_err(|(index, kind)| at(index, None, kind))?);
                    continue;
                }
            }
            if let Some((bytes, offset, line)) = body.ascii_rest()
                && element.count >= PARALLEL_ASCII_ELEMENTS
                && let Some((offset, line)) =
                    self.read_ascii_parallel(element_index, element, roles, bytes, offset, line)?
            {
                body.ascii_seek(offset, line);
                continue;
            }
            for index in 0..element.count {
                self.read_element(element, roles, body)
                    .map_err(|kind| at(index, body.line(), kind))?;
            }
        }
        let extra = body.remaining();
        if extra > 0 {
            self.scene
                .warnings
                .push(format!("{extra} bytes after the last element were ignored"));
        }
        Ok(())
    }

    /// Parses the `element.count` elements of an ascii body that start at byte
    /// `offset` (line `line`) on all threads: one serial pass finds line runs of about
    /// equal element counts, each run is parsed into a reader of its own, and the
    /// results are appended in file order, so errors and output are exactly those of
    /// the serial loop. Returns where the element ends, or `None` when the file ends
    /// first (the serial loop then reports where).
    fn read_ascii_parallel(
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

        let empty = MeshReader {
            scene: SceneDescription::default(),
            ..*self
        };
        let parts: Vec<Result<MeshReader, ElementError>> = runs
            .par_windows(2)
            .map(|run| {
                let (first, next) = (run[0], run[1]);
                let mut part = MeshReader {
                    scene: SceneDescription::default(),
                    ..empty
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
            let part = part?.scene;
            self.scene.positions.extend_from_slice(&part.positions);
            self.scene.normals.extend_from_slice(&part.normals);
            self.scene.texcoords.extend_from_slice(&part.texcoords);
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

    #[inline]
    fn read_element<B: Body>(
        &mut self,
        element: &Element,
        roles: &[Role],
        body: &mut B,
    ) -> Result<(), ParseErrorKind> {
        body.begin()?;
        let mut position = [0.0; 3];
        let mut normal = [0.0; 3];
        let mut texcoord = [0.0; 2];
        for (property, &role) in element.properties.iter().zip(roles) {
            let name = property.name.as_str();
            match (property.ty, role) {
                (PropertyType::Scalar(ty), Role::Position(axis)) => {
                    position[axis] = body.float(ty, name)?;
                }
                (PropertyType::Scalar(ty), Role::Normal(axis)) => {
                    normal[axis] = body.float(ty, name)?;
                }
                (PropertyType::Scalar(ty), Role::TexCoord(axis)) => {
                    texcoord[axis] = body.float(ty, name)?;
                }
                (PropertyType::Scalar(ty), _) => body.skip(ty, name)?,
                (PropertyType::List { count, item }, Role::Indices) => {
                    let n = body.int(count, name)?;
                    self.add_face(n, |_| body.int(item, name))?;
                }
                (PropertyType::List { count, item }, _) => {
                    let n = body.int(count, name)?;
                    if n < 0 {
                        return Err(ParseErrorKind::NegativeCount(n));
                    }
                    for _ in 0..n {
                        body.skip(item, name)?;
                    }
                }
            }
        }
        body.end()?;
        if element.name == "vertex" {
            self.scene.positions.push(Vec3::from(position));
            if self.has_normals {
                self.scene.normals.push(Vec3::from(normal));
            }
            if self.has_texcoords {
                self.scene.texcoords.push(Vec2::from(texcoord));
            }
        }
        Ok(())
    }

    /// Adds the triangle fan of a face of `n` vertices; `index(k)` reads the k-th
    /// vertex index (called for k = 0, 1, ... in turn).
    #[inline(always)]
    fn add_face(
        &mut self,
        n: i64,
        mut index: impl FnMut(usize) -> Result<i64, ParseErrorKind>,
    ) -> Result<(), ParseErrorKind> {
        if n < 0 {
            return Err(ParseErrorKind::NegativeCount(n));
        }
        if n < 3 {
            return Err(ParseErrorKind::TooFewVertices(n as usize));
        }
        if self.scene.triangles.len() + (n as usize - 2) > u32::MAX as usize {
            return Err(ParseErrorKind::TooMany("triangles"));
        }
        let defined = self.vertex_count;
        let mut vertex = |k: usize| -> Result<u32, ParseErrorKind> {
            let index = index(k)?;
            if index < 0 || index as u64 >= defined as u64 {
                return Err(ParseErrorKind::IndexOutOfRange {
                    kind: IndexKind::Vertex,
                    index,
                    defined,
                });
            }
            Ok(index as u32)
        };
        let first = vertex(0)?;
        let mut previous = vertex(1)?;
        for k in 2..n as usize {
            let next = vertex(k)?;
            let positions = [first, previous, next];
            self.scene.triangles.push(TriangleDesc {
                positions,
                normals: self.has_normals.then_some(positions),
                material: MaterialId(0),
            });
            previous = next;
        }
        Ok(())
    }

    /// Reads a binary element whose layout allows slicing the bytes directly: only
    /// scalar properties (a fixed stride), or a face element whose one property is
    /// its index list. These cover nearly every PLY file and run several times faster
    /// than [`MeshReader::read_element`]'s value-by-value walk. Returns the bytes read,
    /// or `None` for other layouts.
    fn read_binary_fixed<const BIG_ENDIAN: bool>(
        &mut self,
        element: &Element,
        roles: &[Role],
        bytes: &[u8],
    ) -> Option<Result<usize, (usize, ParseErrorKind)>> {
        let scalars: Option<Vec<Scalar>> = element
            .properties
            .iter()
            .map(|p| match p.ty {
                PropertyType::Scalar(ty) => Some(ty),
                PropertyType::List { .. } => None,
            })
            .collect();
        if let Some(types) = scalars {
            return Some(self.read_fixed_stride::<BIG_ENDIAN>(element, roles, &types, bytes));
        }
        match (&element.properties[..], roles) {
            ([property], [Role::Indices]) => match property.ty {
                PropertyType::List { count, item } if count.is_integer() && item.is_integer() => {
                    Some(self.read_index_lists::<BIG_ENDIAN>(element.count, count, item, bytes))
                }
                _ => None,
            },
            _ => None,
        }
    }

    /// Elements of scalars only: one record every `stride` bytes.
    fn read_fixed_stride<const BIG_ENDIAN: bool>(
        &mut self,
        element: &Element,
        roles: &[Role],
        types: &[Scalar],
        bytes: &[u8],
    ) -> Result<usize, (usize, ParseErrorKind)> {
        const NORMAL: usize = 3;
        const TEXCOORD: usize = 6;
        // (slot in `values`, offset in the record, type) of each value to keep.
        let mut fields = Vec::new();
        let mut offset = 0;
        for (&ty, &role) in types.iter().zip(roles) {
            let slot = match role {
                Role::Position(axis) => Some(axis),
                Role::Normal(axis) => Some(NORMAL + axis),
                Role::TexCoord(axis) => Some(TEXCOORD + axis),
                Role::Skip | Role::Indices => None,
            };
            if let Some(slot) = slot {
                fields.push((slot, offset, ty));
            }
            offset += ty.size();
        }
        let stride = offset;
        let complete = match stride {
            0 => element.count,
            _ => element.count.min(bytes.len() / stride),
        };
        if !fields.is_empty() && complete == element.count && complete >= PARALLEL_BINARY_ELEMENTS {
            let records = &bytes[..complete * stride];
            let positions = gather::<BIG_ENDIAN, 3, _>(records, stride, &fields, 0, Vec3::from);
            let normals = match self.has_normals {
                true => gather::<BIG_ENDIAN, 3, _>(records, stride, &fields, NORMAL, Vec3::from),
                false => Vec::new(),
            };
            let texcoords = match self.has_texcoords {
                true => gather::<BIG_ENDIAN, 2, _>(records, stride, &fields, TEXCOORD, Vec2::from),
                false => Vec::new(),
            };
            // Serial checks: rayon's short-circuiting `all` pays an atomic per item.
            let finite = positions.iter().all(|p| p.is_finite())
                && normals.iter().all(|n| n.is_finite())
                && texcoords.iter().all(|t| t.is_finite());
            // Otherwise the serial loop below finds and reports the bad value.
            if finite {
                self.scene.positions = positions;
                self.scene.normals = normals;
                self.scene.texcoords = texcoords;
                return Ok(complete * stride);
            }
        }
        if !fields.is_empty() {
            for (index, record) in bytes[..complete * stride].chunks_exact(stride).enumerate() {
                let mut values: [Float; 8] = [0.0; 8];
                for &(slot, offset, ty) in &fields {
                    values[slot] = finite_float(decode::<BIG_ENDIAN>(&record[offset..], ty))
                        .map_err(|kind| (index, kind))?;
                }
                self.scene
                    .positions
                    .push(Vec3::from_slice(&values[..NORMAL]));
                if self.has_normals {
                    self.scene
                        .normals
                        .push(Vec3::from_slice(&values[NORMAL..TEXCOORD]));
                }
                if self.has_texcoords {
                    self.scene
                        .texcoords
                        .push(Vec2::from_slice(&values[TEXCOORD..]));
                }
            }
        }
        if complete < element.count {
            return Err((complete, ParseErrorKind::Truncated));
        }
        Ok(complete * stride)
    }

    /// Face elements whose one property is the index list, of integer types.
    fn read_index_lists<const BIG_ENDIAN: bool>(
        &mut self,
        faces: usize,
        count: Scalar,
        item: Scalar,
        bytes: &[u8],
    ) -> Result<usize, (usize, ParseErrorKind)> {
        let defined = self.vertex_count;
        let (count_size, item_size) = (count.size(), item.size());
        if faces >= PARALLEL_BINARY_ELEMENTS
            && let Some(triangles) =
                self.read_triangle_records::<BIG_ENDIAN>(faces, count, item, bytes)
        {
            let read = triangles.len() * (count_size + 3 * item_size);
            append_triangles(&mut self.scene.triangles, triangles);
            return Ok(read);
        }
        let mut pos = 0;
        for face in 0..faces {
            let at = |kind| (face, kind);
            let Some(n) = bytes.get(pos..pos + count_size) else {
                return Err(at(ParseErrorKind::Truncated));
            };
            let n = decode_int::<BIG_ENDIAN>(n, count);
            pos += count_size;
            let list_len = (n.max(0) as usize).saturating_mul(item_size);
            let Some(list) = bytes.get(pos..pos.saturating_add(list_len)) else {
                return Err(at(ParseErrorKind::Truncated));
            };
            pos += list_len;
            // The hot loop decodes indices without `Result`s; anything wrong goes to
            // the general path, which reports it (and would add a face it accepts).
            let index = |k: usize| list_item::<BIG_ENDIAN>(list, k, item);
            let valid = |k: usize| (index(k) as u64) < defined as u64;
            let well_formed = n >= 3
                && self.scene.triangles.len() + (n as usize - 2) <= u32::MAX as usize
                && (0..n as usize).all(valid);
            if !well_formed {
                self.add_face(n, |k| Ok(index(k))).map_err(at)?;
                continue;
            }
            let first = index(0) as u32;
            let mut previous = index(1) as u32;
            for k in 2..n as usize {
                let next = index(k) as u32;
                let positions = [first, previous, next];
                self.scene.triangles.push(TriangleDesc {
                    positions,
                    normals: self.has_normals.then_some(positions),
                    material: MaterialId(0),
                });
                previous = next;
            }
        }
        Ok(pos)
    }

    /// The faces as triangles decoded on all threads, when every face is a valid
    /// triangle: then records have one size and can be cut apart without reading
    /// them in order. `None` otherwise (the serial loop then reads, or reports).
    fn read_triangle_records<const BIG_ENDIAN: bool>(
        &self,
        faces: usize,
        count: Scalar,
        item: Scalar,
        bytes: &[u8],
    ) -> Option<Vec<TriangleDesc>> {
        let record = count.size() + 3 * item.size();
        let records = bytes.get(..faces.checked_mul(record)?)?;
        // One loop per index type, so the hot loop has no type dispatch.
        let four = |b: &[u8]| [b[0], b[1], b[2], b[3]];
        let triangles = match (item, BIG_ENDIAN) {
            (Scalar::I32, false) => {
                self.decode_triangles::<BIG_ENDIAN>(records, count, item.size(), |b| {
                    i32::from_le_bytes(four(b)) as i64
                })
            }
            (Scalar::I32, true) => {
                self.decode_triangles::<BIG_ENDIAN>(records, count, item.size(), |b| {
                    i32::from_be_bytes(four(b)) as i64
                })
            }
            (Scalar::U32, false) => {
                self.decode_triangles::<BIG_ENDIAN>(records, count, item.size(), |b| {
                    u32::from_le_bytes(four(b)) as i64
                })
            }
            (Scalar::U32, true) => {
                self.decode_triangles::<BIG_ENDIAN>(records, count, item.size(), |b| {
                    u32::from_be_bytes(four(b)) as i64
                })
            }
            _ => self.decode_triangles::<BIG_ENDIAN>(records, count, item.size(), |b| {
                decode_int::<BIG_ENDIAN>(b, item)
            }),
        };
        // Serial: rayon's short-circuiting `all` pays an atomic per item.
        let valid = triangles.iter().all(|t| !t.positions.contains(&u32::MAX));
        valid.then_some(triangles)
    }

    /// Decodes records of a count of type `count` and three indices of `item_size`
    /// bytes read by `index`. A record whose count is not 3 or whose index is out of
    /// range gets index `u32::MAX`, which no valid index equals (there are at most
    /// `u32::MAX` vertices), so one check afterwards finds them.
    fn decode_triangles<const BIG_ENDIAN: bool>(
        &self,
        records: &[u8],
        count: Scalar,
        item_size: usize,
        index: impl Fn(&[u8]) -> i64 + Sync,
    ) -> Vec<TriangleDesc> {
        let count_size = count.size();
        let defined = self.vertex_count as u64;
        let has_normals = self.has_normals;
        records
            .par_chunks_exact(count_size + 3 * item_size)
            .map(|r| {
                let is_triangle = decode_int::<BIG_ENDIAN>(r, count) == 3;
                let positions = [0, 1, 2].map(|k| {
                    let i = index(&r[count_size + k * item_size..]);
                    if is_triangle && (i as u64) < defined {
                        i as u32
                    } else {
                        u32::MAX
                    }
                });
                TriangleDesc {
                    positions,
                    normals: has_normals.then_some(positions),
                    material: MaterialId(0),
                }
            })
            .collect()
    }

    fn finish(mut self) -> SceneDescription {
        if !self.scene.triangles.is_empty() {
            self.scene.materials.push(Material::fallback());
        }
        self.scene
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SCALARS: [Scalar; 8] = [
        Scalar::I8,
        Scalar::U8,
        Scalar::I16,
        Scalar::U16,
        Scalar::I32,
        Scalar::U32,
        Scalar::F32,
        Scalar::F64,
    ];

    fn parse(bytes: &[u8]) -> Result<SceneDescription, SceneError> {
        parse_ply(bytes, Path::new("t.ply"))
    }

    fn error(text: &str) -> String {
        parse(text.as_bytes()).unwrap_err().to_string()
    }

    /// Header names, alternating between the original and the sized spelling.
    fn name(ty: Scalar, sized: bool) -> &'static str {
        let (original, alias) = match ty {
            Scalar::I8 => ("char", "int8"),
            Scalar::U8 => ("uchar", "uint8"),
            Scalar::I16 => ("short", "int16"),
            Scalar::U16 => ("ushort", "uint16"),
            Scalar::I32 => ("int", "int32"),
            Scalar::U32 => ("uint", "uint32"),
            Scalar::F32 => ("float", "float32"),
            Scalar::F64 => ("double", "float64"),
        };
        if sized { alias } else { original }
    }

    fn encode(ty: Scalar, value: f64, big_endian: bool) -> Vec<u8> {
        macro_rules! bytes {
            ($t:ty) => {{
                let v = value as $t;
                if big_endian {
                    v.to_be_bytes().to_vec()
                } else {
                    v.to_le_bytes().to_vec()
                }
            }};
        }
        match ty {
            Scalar::I8 => bytes!(i8),
            Scalar::U8 => bytes!(u8),
            Scalar::I16 => bytes!(i16),
            Scalar::U16 => bytes!(u16),
            Scalar::I32 => bytes!(i32),
            Scalar::U32 => bytes!(u32),
            Scalar::F32 => bytes!(f32),
            Scalar::F64 => bytes!(f64),
        }
    }

    /// A file's elements as rows of (type, value) properties; lists are a count
    /// followed by the items.
    struct Mesh {
        header: String,
        rows: Vec<Vec<(Scalar, f64)>>,
    }

    impl Mesh {
        fn ascii(&self) -> Vec<u8> {
            let mut text = format!("ply\nformat ascii 1.0\n{}end_header\n", self.header);
            for row in &self.rows {
                let values: Vec<String> = row.iter().map(|(_, v)| v.to_string()).collect();
                text.push_str(&values.join(" "));
                text.push('\n');
            }
            text.into_bytes()
        }

        fn binary(&self, big_endian: bool) -> Vec<u8> {
            let format = if big_endian {
                "binary_big_endian"
            } else {
                "binary_little_endian"
            };
            let mut bytes =
                format!("ply\nformat {format} 1.0\n{}end_header\n", self.header).into_bytes();
            for row in &self.rows {
                for &(ty, v) in row {
                    bytes.extend(encode(ty, v, big_endian));
                }
            }
            bytes
        }

        /// The three encodings of this mesh.
        fn encodings(&self) -> [(&'static str, Vec<u8>); 3] {
            [
                ("ascii", self.ascii()),
                ("little-endian", self.binary(false)),
                ("big-endian", self.binary(true)),
            ]
        }
    }

    /// Five vertices, a quad and a triangle; coordinates fit every type.
    fn quad_and_triangle(position: Scalar, count: Scalar, item: Scalar, sized: bool) -> Mesh {
        let header = format!(
            "element vertex 5\nproperty {p} x\nproperty {p} y\nproperty {p} z\nelement face 2\nproperty list {c} {i} vertex_indices\n",
            p = name(position, sized),
            c = name(count, sized),
            i = name(item, !sized),
        );
        let points = [
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [2.0, 2.0, 0.0],
            [0.0, 2.0, 0.0],
            [1.0, 1.0, 3.0],
        ];
        let mut rows: Vec<Vec<(Scalar, f64)>> = points
            .iter()
            .map(|p| p.iter().map(|&v| (position, v)).collect())
            .collect();
        for face in [&[0.0, 1.0, 2.0, 3.0][..], &[0.0, 1.0, 4.0]] {
            let mut row = vec![(count, face.len() as f64)];
            row.extend(face.iter().map(|&i| (item, i)));
            rows.push(row);
        }
        Mesh { header, rows }
    }

    fn triangles(scene: &SceneDescription) -> Vec<[u32; 3]> {
        scene.triangles.iter().map(|t| t.positions).collect()
    }

    #[test]
    fn every_format_and_scalar_type_reads_the_same_mesh() {
        let integers = [
            Scalar::I8,
            Scalar::U8,
            Scalar::I16,
            Scalar::U16,
            Scalar::I32,
            Scalar::U32,
        ];
        let mut cases = 0;
        for (n, &position) in SCALARS.iter().enumerate() {
            for &count in &integers {
                for &item in &SCALARS {
                    let mesh = quad_and_triangle(position, count, item, n % 2 == 0);
                    for (format, bytes) in mesh.encodings() {
                        let what = format!("{format} {position:?} {count:?} {item:?}");
                        let scene = parse(&bytes).unwrap_or_else(|e| panic!("{what}: {e}"));
                        assert_eq!(scene.positions[2], Vec3::new(2.0, 2.0, 0.0), "{what}");
                        assert_eq!(scene.positions[4], Vec3::new(1.0, 1.0, 3.0), "{what}");
                        assert_eq!(
                            triangles(&scene),
                            [[0, 1, 2], [0, 2, 3], [0, 1, 4]],
                            "{what}"
                        );
                        assert!(scene.triangles.iter().all(|t| t.normals.is_none()));
                        assert_eq!(scene.materials, [Material::fallback()]);
                        assert!(scene.warnings.is_empty(), "{what}: {:?}", scene.warnings);
                        cases += 1;
                    }
                }
            }
        }
        assert_eq!(cases, 8 * 6 * 8 * 3);
    }

    #[test]
    fn normals_texture_coordinates_aliases_and_skipped_data() {
        // Extra vertex properties (a scalar and a list), an element to skip between
        // vertices and faces, `vertex_index`, and a face property after the list.
        let header = "comment scanned\nobj_info none\nelement vertex 3\nproperty float x\nproperty uchar red\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nproperty float s\nproperty float t\nproperty list uchar int neighbours\nelement edge 2\nproperty int vertex1\nproperty int vertex2\nelement face 1\nproperty list uint8 uint32 vertex_index\nproperty uchar flags\nelement empty 0\n";
        let (f, b, i, u) = (Scalar::F32, Scalar::U8, Scalar::I32, Scalar::U32);
        let vertex = |x: f64, y: f64, n: [f64; 3], st: [f64; 2]| {
            vec![
                (f, x),
                (b, 200.0),
                (f, y),
                (f, 0.5),
                (f, n[0]),
                (f, n[1]),
                (f, n[2]),
                (f, st[0]),
                (f, st[1]),
                (b, 2.0),
                (i, 7.0),
                (i, 8.0),
            ]
        };
        let mesh = Mesh {
            header: header.into(),
            rows: vec![
                vertex(0.0, 0.0, [0.0, 0.0, 1.0], [0.0, 0.0]),
                vertex(1.0, 0.0, [0.0, 1.0, 0.0], [1.0, 0.0]),
                vertex(0.0, 1.0, [1.0, 0.0, 0.0], [0.0, 1.0]),
                vec![(i, 0.0), (i, 1.0)],
                vec![(i, 1.0), (i, 2.0)],
                vec![(b, 3.0), (u, 0.0), (u, 1.0), (u, 2.0), (b, 9.0)],
            ],
        };
        for (format, bytes) in mesh.encodings() {
            let scene = parse(&bytes).unwrap_or_else(|e| panic!("{format}: {e}"));
            assert_eq!(
                scene.positions,
                [
                    Vec3::new(0.0, 0.0, 0.5),
                    Vec3::new(1.0, 0.0, 0.5),
                    Vec3::new(0.0, 1.0, 0.5)
                ],
                "{format}"
            );
            assert_eq!(scene.normals, [Vec3::Z, Vec3::Y, Vec3::X], "{format}");
            assert_eq!(scene.texcoords, [Vec2::ZERO, Vec2::X, Vec2::Y], "{format}");
            assert_eq!(scene.triangles.len(), 1);
            assert_eq!(scene.triangles[0].positions, [0, 1, 2]);
            assert_eq!(scene.triangles[0].normals, Some([0, 1, 2]), "{format}");
        }
    }

    #[test]
    fn ascii_takes_crlf_blank_lines_and_u_v() {
        let text = "ply\r\nformat ascii 1.0\r\nelement vertex 3\r\nproperty double x\r\nproperty double y\r\nproperty double z\r\nproperty float u\r\nproperty float v\r\nelement face 1\r\nproperty list uchar int vertex_indices\r\nend_header\r\n0 0 0 0 0\r\n\r\n1 0 0 1 0\r\n 0\t1 0 0 1 \r\n3 0 1 2\r\n";
        let scene = parse(text.as_bytes()).unwrap();
        assert_eq!(scene.positions[2], Vec3::Y);
        assert_eq!(scene.texcoords[1], Vec2::X);
        assert_eq!(triangles(&scene), [[0, 1, 2]]);
    }

    #[test]
    fn a_point_cloud_has_no_material() {
        let text = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n";
        let scene = parse(text.as_bytes()).unwrap();
        assert_eq!(scene.positions, [Vec3::new(1.0, 2.0, 3.0)]);
        assert!(scene.triangles.is_empty() && scene.materials.is_empty());
    }

    const VERTS: &str = "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n";
    const FACES: &str = "element face 1\nproperty list uchar int vertex_indices\n";

    fn ascii(header: &str, body: &str) -> String {
        format!("ply\nformat ascii 1.0\n{header}end_header\n{body}")
    }

    #[test]
    fn header_errors_name_the_line() {
        assert_eq!(
            error("PLY\n"),
            "t.ply:1: not a PLY file (the first line must be 'ply')"
        );
        assert_eq!(
            error(""),
            "t.ply:1: not a PLY file (the first line must be 'ply')"
        );
        assert_eq!(
            error("ply\nformat binary 1.0\nend_header\n"),
            "t.ply:2: unknown format 'binary' (expected ascii, binary_little_endian or binary_big_endian)"
        );
        assert_eq!(
            error("ply\nelement vertex 1\nend_header\n"),
            "t.ply:2: the header has no 'format' line"
        );
        assert_eq!(
            error(&ascii("element vertex 1\nproperty float128 x\n", "")),
            "t.ply:4: unknown property type 'float128'"
        );
        assert_eq!(
            error(&ascii("property float x\n", "")),
            "t.ply:3: 'property' before any 'element'"
        );
        assert_eq!(
            error(&ascii("element vertex many\n", "")),
            "t.ply:3: invalid element count 'many'"
        );
        assert_eq!(
            error(&ascii("element vertex 1\nelement vertex 1\n", "")),
            "t.ply:4: element 'vertex' declared twice"
        );
        assert_eq!(
            error(&ascii("element v 1\nproperty list uchar x\n", "")),
            "t.ply:4: 'property list' needs a count type, an item type and a name"
        );
        assert_eq!(
            error(&ascii("element v 1\nproperty float\n", "")),
            "t.ply:4: 'property' needs a type and a name"
        );
        assert_eq!(
            error(&ascii("elements 1\n", "")),
            "t.ply:3: unknown header keyword 'elements'"
        );
        assert_eq!(
            error("ply\nformat ascii 1.0\n"),
            "t.ply:3: the header has no 'end_header' line"
        );
        assert_eq!(
            error(&ascii(
                "element vertex 1\nproperty float x\nproperty float y\n",
                ""
            )),
            "t.ply:3: element 'vertex' has no property 'z'"
        );
        assert_eq!(
            error(&ascii(
                "element vertex 1\nproperty float x\nproperty float y\nproperty list uchar float z\n",
                ""
            )),
            "t.ply:6: property 'z' of element 'vertex' must be a scalar, not a list"
        );
        assert_eq!(
            error(&ascii(
                &format!("{VERTS}element face 1\nproperty int vertex_indices\n"),
                ""
            )),
            "t.ply:8: property 'vertex_indices' of element 'face' must be a list"
        );
        assert_eq!(
            error(&ascii(
                &format!("{VERTS}element face 1\nproperty list uchar int corners\n"),
                ""
            )),
            "t.ply:7: element 'face' has no property 'vertex_indices' or 'vertex_index'"
        );
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
            file("0 0 0\n1 nan 0\n"),
            "t.ply:11: vertex 1: non-finite value 'nan'"
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
    fn binary_element_errors_name_element_and_index() {
        for big_endian in [false, true] {
            let mesh = quad_and_triangle(Scalar::F32, Scalar::U8, Scalar::I32, false);
            let bytes = mesh.binary(big_endian);
            // Cut inside the last face, then inside the third vertex.
            assert_eq!(
                parse(&bytes[..bytes.len() - 2]).unwrap_err().to_string(),
                "t.ply: face 1: file ends inside the element"
            );
            let header_len = bytes.len() - (5 * 12 + 17 + 13);
            assert_eq!(
                parse(&bytes[..header_len + 30]).unwrap_err().to_string(),
                "t.ply: vertex 2: file ends inside the element"
            );
            // Extra bytes after the last element are only a warning.
            let mut longer = bytes.clone();
            longer.extend([0, 0, 0]);
            assert_eq!(
                parse(&longer).unwrap().warnings,
                ["3 bytes after the last element were ignored"]
            );

            let mut bad = quad_and_triangle(Scalar::F32, Scalar::U8, Scalar::I32, false);
            bad.rows[6][2].1 = 5.0;
            assert_eq!(
                parse(&bad.binary(big_endian)).unwrap_err().to_string(),
                "t.ply: face 1: face index 5 out of range (5 vertices defined)"
            );
            bad.rows[6][0].1 = 2.0;
            bad.rows[6].pop();
            assert_eq!(
                parse(&bad.binary(big_endian)).unwrap_err().to_string(),
                "t.ply: face 1: face has 2 vertices, needs at least 3"
            );
            let mut nan = quad_and_triangle(Scalar::F32, Scalar::U8, Scalar::I32, false);
            nan.rows[3][1].1 = f64::NAN;
            assert_eq!(
                parse(&nan.binary(big_endian)).unwrap_err().to_string(),
                "t.ply: vertex 3: non-finite value 'NaN'"
            );
            let mut fraction = quad_and_triangle(Scalar::F32, Scalar::U8, Scalar::F32, false);
            fraction.rows[5][1].1 = 0.5;
            assert_eq!(
                parse(&fraction.binary(big_endian)).unwrap_err().to_string(),
                "t.ply: face 0: invalid number '0.5'"
            );
        }
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

    #[test]
    fn large_binary_files_decode_in_parallel_exactly_like_small_ones() {
        // A triangle strip with normals and texture coordinates, long enough for the
        // parallel paths; the ascii encoding (read in line runs) is the reference.
        let n = PARALLEL_BINARY_ELEMENTS + 100;
        let (f, d, u, i) = (Scalar::F32, Scalar::F64, Scalar::U8, Scalar::U32);
        let mut rows: Vec<Vec<(Scalar, f64)>> = (0..n + 2)
            .map(|k| {
                let (x, y) = ((k / 2) as f64, (k % 2) as f64);
                vec![
                    (f, x),
                    (d, y),
                    (f, 0.5),
                    (f, 0.0),
                    (f, 0.0),
                    (f, 1.0),
                    (u, 7.0),
                    (f, x / 8.0),
                    (f, y),
                ]
            })
            .collect();
        rows.extend((0..n).map(|t| {
            vec![
                (u, 3.0),
                (i, t as f64),
                (i, t as f64 + 1.0),
                (i, t as f64 + 2.0),
            ]
        }));
        let header = format!(
            "element vertex {}\nproperty float x\nproperty double y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nproperty uchar quality\nproperty float u\nproperty float v\nelement face {n}\nproperty list uchar uint vertex_indices\n",
            n + 2
        );
        let mut mesh = Mesh { header, rows };
        let reference = parse(&mesh.ascii()).unwrap();
        assert_eq!(reference.triangles.len(), n);
        assert_eq!(
            reference.texcoords[n + 1],
            Vec2::new((n + 1).div_euclid(2) as f32 / 8.0, 1.0)
        );
        for big_endian in [false, true] {
            let scene = parse(&mesh.binary(big_endian)).unwrap();
            assert_eq!(scene.positions, reference.positions);
            assert_eq!(scene.normals, reference.normals);
            assert_eq!(scene.texcoords, reference.texcoords);
            assert_eq!(scene.triangles, reference.triangles);
        }
        // Bad data late in the file is reported at its own index.
        let late = n - 7;
        mesh.rows[n + 2 + late][2].1 = (n + 2) as f64;
        mesh.rows[late][1].1 = f64::INFINITY;
        for big_endian in [false, true] {
            let message = parse(&mesh.binary(big_endian)).unwrap_err().to_string();
            assert_eq!(
                message,
                format!("t.ply: vertex {late}: non-finite value 'inf'")
            );
        }
        mesh.rows[late][1].1 = 0.0;
        for big_endian in [false, true] {
            let message = parse(&mesh.binary(big_endian)).unwrap_err().to_string();
            assert_eq!(
                message,
                format!(
                    "t.ply: face {late}: face index {} out of range ({} vertices defined)",
                    n + 2,
                    n + 2
                )
            );
        }
        // A quad among the triangles takes the serial path, with the same result.
        mesh.rows[n + 2 + late] = vec![(u, 4.0), (i, 0.0), (i, 1.0), (i, 3.0), (i, 2.0)];
        let scene = parse(&mesh.binary(true)).unwrap();
        assert_eq!(scene.triangles.len(), n + 1);
        assert_eq!(scene.triangles[late].positions, [0, 1, 3]);
        assert_eq!(scene.triangles[late + 1].positions, [0, 3, 2]);
    }

    #[test]
    fn absurd_counts_fail_cleanly() {
        let properties = &VERTS[17..];
        let text = ascii(
            &format!("element vertex 4000000000\n{properties}"),
            "0 0 0\n",
        );
        assert_eq!(
            error(&text),
            "t.ply:9: vertex 1: file ends inside the element"
        );
        let text = ascii(
            &format!("element vertex 99999999999999\n{properties}"),
            "0 0 0\n",
        );
        assert_eq!(
            error(&text),
            "t.ply: vertex 0: too many vertices (the limit is 4294967295)"
        );
        let mut bytes = b"ply\nformat binary_little_endian 1.0\nelement vertex 18446744073709551615\nproperty float x\nproperty float y\nproperty float z\nend_header\n".to_vec();
        bytes.extend([0; 12]);
        assert_eq!(
            parse(&bytes).unwrap_err().to_string(),
            "t.ply: vertex 0: too many vertices (the limit is 4294967295)"
        );
    }
}
