//! The PLY reader (Greg Turk's polygon file format): `ascii`, `binary_little_endian`
//! and `binary_big_endian` bodies, every scalar type under both its names.
//!
//! From the `vertex` element it takes `x y z`, and when present `nx ny nz` (as vertex
//! normals) and texture coordinates `u v` (or `s t`, `texture_u texture_v`,
//! `texture_s texture_t`); from `face` the list `vertex_indices` (or `vertex_index`),
//! split into triangles: the fan from the first corner while the body is read (the
//! positions may come after the faces), then, in [`MeshReader::finish`], polygons
//! that are not convex in their plane are cut again by ear clipping, as OBJ faces are
//! ([`polygon::recut_fans`]). Every other element and property is read past and
//! ignored. PLY has no materials: every triangle gets [`Material::fallback`].
//!
//! [`header`] reads the header: its grammar, and what each property means to the
//! reader. [`MeshReader`] then assembles the [`SceneDescription`] from the body,
//! through one [`Body`] per encoding: [`ascii`] (one element per line; long elements
//! are parsed on all threads in runs of lines) and [`binary`] (both byte orders;
//! common layouts are sliced and decoded on all threads).

mod ascii;
mod binary;
mod header;
#[cfg(test)]
mod testing;

use std::path::Path;

use super::error::{IndexKind, ParseErrorKind, SceneError};
use super::polygon::{self, FanPolygon};
use super::{SceneDescription, TriangleDesc, finite, read_file};
use crate::material::{Material, MaterialId};
use crate::math::{Float, Vec2, Vec3};
use ascii::{AsciiBody, PARALLEL_ASCII_ELEMENTS};
use binary::BinaryBody;
use header::{Element, Format, Header, PropertyType, Role, Scalar, parse_header, roles};
use rayon::prelude::*;

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
    let mut scene = reader.finish();
    finite::drop_non_finite_triangles(&mut scene, path);
    if let Some((line, keyword, count)) = header.unknown_lines {
        let s = if count == 1 { "" } else { "s" };
        scene.warnings.insert(
            0,
            format!(
                "{}:{line}: skipped {count} header line{s} of unknown keyword ('{keyword}')",
                path.display()
            ),
        );
    }
    Ok(scene)
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

/// `position`, or a NaN one when the rest of its vertex (normal, texture
/// coordinates, colour) is not finite: such a vertex cannot be shaded, and
/// [`finite::drop_non_finite_triangles`] then drops the triangles using it as it
/// does those at a non-finite position.
#[inline(always)]
fn unusable_unless(usable: bool, position: Vec3) -> Vec3 {
    if usable {
        position
    } else {
        Vec3::splat(Float::NAN)
    }
}

/// `value` as an integer, if it is one (indices and counts stored as floats).
#[inline]
fn integral(value: f64) -> Option<i64> {
    (value.fract() == 0.0 && value.abs() < 1e18).then_some(value as i64)
}

/// Collects the mesh while the body is read.
struct MeshReader {
    scene: SceneDescription,
    /// Vertices declared by the header: the range face indices must fall in.
    vertex_count: usize,
    has_normals: bool,
    has_texcoords: bool,
    /// Whether vertices have `red green blue` (vertex colours).
    has_colours: bool,
    /// The faces of more than three corners, written as fans, for [`MeshReader::finish`].
    polygons: Vec<FanPolygon>,
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
            has_colours: vertex_roles.contains(&Role::Colour(0)),
            polygons: Vec::new(),
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
                    if self.has_colours {
                        self.scene.colours.reserve(count);
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
        let mut colour = [0.0; 3];
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
                (PropertyType::Scalar(ty), Role::Colour(axis)) => {
                    colour[axis] = body.float(ty, name)? / ty.colour_range();
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
            let usable = (normal.iter().chain(&texcoord).chain(&colour)).all(|v| v.is_finite());
            self.scene
                .positions
                .push(unusable_unless(usable, Vec3::from(position)));
            if self.has_normals {
                self.scene.normals.push(Vec3::from(normal));
            }
            if self.has_texcoords {
                self.scene.texcoords.push(Vec2::from(texcoord));
            }
            if self.has_colours {
                self.scene.colours.push(Vec3::from(colour).max(Vec3::ZERO));
            }
        }
        Ok(())
    }

    /// Adds the triangle fan of a face of `n` vertices (noting it as a polygon if
    /// `n > 3`); `index(k)` reads the k-th vertex index (called for k = 0, 1, ... in
    /// turn).
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
        let first_triangle = self.scene.triangles.len();
        for k in 2..n as usize {
            let next = vertex(k)?;
            let positions = [first, previous, next];
            self.scene.triangles.push(TriangleDesc {
                positions,
                material: MaterialId(0),
            });
            previous = next;
        }
        self.note_polygon(first_triangle, n as usize);
        Ok(())
    }

    /// Notes the face of `corners` corners whose fan starts at triangle `first`, if it
    /// is a polygon (more than three corners).
    #[inline(always)]
    fn note_polygon(&mut self, first: usize, corners: usize) {
        if corners > 3 {
            // Both fit: the triangle count is held below `u32::MAX`.
            self.polygons.push(FanPolygon {
                first: first as u32,
                corners: corners as u32,
            });
        }
    }

    /// The description, with the polygons that are not convex cut by ear clipping
    /// (every position is known now).
    fn finish(mut self) -> SceneDescription {
        if !self.polygons.is_empty() {
            polygon::recut_fans(
                &self.scene.positions,
                &mut self.scene.triangles,
                &self.polygons,
            );
        }
        if self.has_normals {
            // A normal per vertex: each corner's normal is its position's.
            self.scene.triangle_normals = (self.scene.triangles.par_iter())
                .map(|t| Some(t.positions))
                .collect();
        }
        if !self.scene.triangles.is_empty() {
            self.scene.materials.push(Material::fallback());
        }
        self.scene
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formats::ply::testing::{
        Mesh, SCALARS, VERTS, ascii, error, parse, quad_and_triangle, triangles,
    };

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
                        assert!(scene.triangle_normals.is_empty());
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
            assert_eq!(scene.normals_of(0), Some([0, 1, 2]), "{format}");
        }
    }

    #[test]
    fn concave_faces_are_cut_by_ear_clipping() {
        // A triangle, then an L of six corners starting next to its notch, so that
        // the fan from the first corner would cover the notch (the triangle
        // (2, 1), (1, 1), (1, 2) lies outside the L). Faces come before the vertices:
        // the positions are known only at the end.
        let points = [
            [2.0, 1.0],
            [1.0, 1.0],
            [1.0, 2.0],
            [0.0, 2.0],
            [0.0, 0.0],
            [2.0, 0.0],
        ];
        let (f, b, i) = (Scalar::F32, Scalar::U8, Scalar::I32);
        let mut rows = vec![
            vec![(b, 3.0), (i, 4.0), (i, 5.0), (i, 3.0)],
            vec![
                (b, 6.0),
                (i, 0.0),
                (i, 1.0),
                (i, 2.0),
                (i, 3.0),
                (i, 4.0),
                (i, 5.0),
            ],
        ];
        rows.extend(points.iter().map(|p| vec![(f, p[0]), (f, p[1]), (f, 0.5)]));
        let mesh = Mesh {
            header: format!("element face 2\nproperty list uchar int vertex_indices\n{VERTS}")
                .replace("vertex 3", "vertex 6"),
            rows,
        };
        for (format, bytes) in mesh.encodings() {
            let scene = parse(&bytes).unwrap_or_else(|e| panic!("{format}: {e}"));
            let t = triangles(&scene);
            assert_eq!(t.len(), 5, "{format}");
            assert_eq!(t[0], [4, 5, 3], "{format}");
            assert_ne!(t[1], [0, 1, 2], "{format}: the fan");
            let corner = |k: u32| {
                let p = scene.positions[k as usize];
                (p.x, p.y)
            };
            // The L's triangles turn one way, add up to its area (3), and none
            // covers the notch at (1.25, 1.25).
            let mut area = 0.0;
            for &[a, b, c] in &t[1..] {
                let [a, b, c] = [a, b, c].map(corner);
                let cross = |p: (f32, f32), q: (f32, f32), r: (f32, f32)| {
                    (q.0 - p.0) * (r.1 - p.1) - (q.1 - p.1) * (r.0 - p.0)
                };
                let twice = cross(a, b, c);
                assert!(twice >= 0.0, "{format}: {t:?}");
                area += twice / 2.0;
                let notch = (1.25, 1.25);
                let inside = cross(a, b, notch) > 0.0
                    && cross(b, c, notch) > 0.0
                    && cross(c, a, notch) > 0.0;
                assert!(!inside, "{format}: a triangle covers the notch: {t:?}");
            }
            assert_eq!(area, 3.0, "{format}");
        }
    }

    #[test]
    fn a_point_cloud_has_no_material() {
        let text = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n";
        let scene = parse(text.as_bytes()).unwrap();
        assert_eq!(scene.positions, [Vec3::new(1.0, 2.0, 3.0)]);
        assert!(scene.triangles.is_empty() && scene.materials.is_empty());
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
