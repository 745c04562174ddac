//! The PLY header: its grammar (`ply`, `format`, `element`, `property`, `comment`,
//! `obj_info`, `end_header`), and the [`Role`] each property plays for the reader,
//! checked against its type before any of the body is read.

use crate::formats::error::ParseErrorKind;
use crate::formats::lex;
use crate::math::Float;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Format {
    Ascii,
    BinaryLittleEndian,
    BinaryBigEndian,
}

/// A PLY scalar type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Scalar {
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

    /// What a colour channel of this type is divided by to be read in 0..1: an
    /// integer type's largest value maps to 1 (`uchar` 255, `ushort` 65535), floats
    /// are read as they are.
    pub(super) fn colour_range(self) -> Float {
        match self {
            Scalar::I8 => i8::MAX as Float,
            Scalar::U8 => u8::MAX as Float,
            Scalar::I16 => i16::MAX as Float,
            Scalar::U16 => u16::MAX as Float,
            Scalar::I32 => i32::MAX as Float,
            Scalar::U32 => u32::MAX as Float,
            Scalar::F32 | Scalar::F64 => 1.0,
        }
    }

    /// Bytes in a binary body.
    pub(super) fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    pub(super) fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum PropertyType {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Clone, Debug)]
pub(super) struct Property {
    pub(super) name: String,
    pub(super) ty: PropertyType,
    /// Header line, for errors about the property's type.
    line: usize,
}

#[derive(Clone, Debug)]
pub(super) struct Element {
    pub(super) name: String,
    pub(super) count: usize,
    pub(super) properties: Vec<Property>,
    /// Header line, for errors about missing properties.
    line: usize,
}

impl Element {
    /// Bytes of one element in a binary body, counting lists as empty: a lower bound
    /// used to cap allocations by what the file can hold.
    pub(super) fn min_binary_size(&self) -> usize {
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
pub(super) struct Header {
    pub(super) format: Format,
    pub(super) elements: Vec<Element>,
    /// Byte offset of the body: just past the `end_header` line's newline.
    pub(super) body_offset: usize,
    /// 1-based line number of the body's first line.
    pub(super) body_line: usize,
    /// Header lines of no known keyword (some writers add their own, such as
    /// `Created by ...`), skipped: the first one's line and keyword, and how many.
    pub(super) unknown_lines: Option<(usize, String, usize)>,
}

pub(super) type HeaderError = (usize, ParseErrorKind);

pub(super) fn parse_header(bytes: &[u8]) -> Result<Header, HeaderError> {
    let header_error = |line: usize, message: String| (line, ParseErrorKind::PlyHeader(message));
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut unknown_lines: Option<(usize, String, usize)> = None;
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
                // Cut as tokens are (`lex::show`): names reach messages, and the
                // names the reader knows are all short.
                let name = lex::show(name);
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
                    name: lex::show(name),
                    ty,
                    line: line_number,
                });
            }
            b"end_header" => break,
            // Other readers (Blender's, trimesh, tinyply) skip lines they do not
            // know; the elements and properties still say how to read the body.
            other => match &mut unknown_lines {
                Some((_, _, count)) => *count += 1,
                None => unknown_lines = Some((line_number, lex::show(other), 1)),
            },
        }
    }
    let format = format.ok_or_else(|| header_error(2, "the header has no 'format' line".into()))?;
    Ok(Header {
        format,
        elements,
        body_offset: offset,
        body_line: line_number + 1,
        unknown_lines,
    })
}

/// What the reader does with one property's value.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Role {
    Skip,
    Position(usize),
    Normal(usize),
    TexCoord(usize),
    /// A vertex colour channel (red, green, blue), divided by [`Scalar::colour_range`].
    Colour(usize),
    Indices,
}

/// The roles of an element's properties, checked against their types.
pub(super) fn roles(element: &Element) -> Result<Vec<Role>, HeaderError> {
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
            // As MeshLab, Open3D and scanners write them (`alpha` is read past).
            let colours: &[&[&str]] = &[
                &["red", "diffuse_red", "r"],
                &["green", "diffuse_green", "g"],
                &["blue", "diffuse_blue", "b"],
            ];
            for (names, role) in [
                (normals, Role::Normal as fn(usize) -> Role),
                (texcoords, Role::TexCoord),
                (colours, Role::Colour),
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

#[cfg(test)]
mod tests {
    use crate::formats::ply::testing::{FACES, VERTS, ascii, error, parse, triangles};

    #[test]
    fn unknown_header_lines_are_skipped_with_one_warning() {
        // As written by some exporters: a line of their own between the format and the
        // elements.
        let text = format!(
            "ply\nformat ascii 1.0\nCreated by Some Modeller 2.1\n{VERTS}Created again\n{FACES}end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"
        );
        let scene = parse(text.as_bytes()).unwrap();
        assert_eq!(triangles(&scene), [[0, 1, 2]]);
        assert_eq!(
            scene.warnings,
            ["t.ply:3: skipped 2 header lines of unknown keyword ('Created')"]
        );
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
}
