//! The OBJ reader: `v`, `vt`, `vn`, `f` (any polygon, all four vertex forms, negative
//! indices), `mtllib`, `usemtl`, and the extensions `S` (sphere) and `P` (point light).

use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

use super::error::{IndexKind, ParseErrorKind, SceneError};
use super::{SceneDescription, SphereDesc, TriangleDesc, lex, mtl, read_file};
use crate::material::{Material, MaterialId, PointLight};
use crate::math::Vec2;

/// Reads an OBJ file and the MTL files it names (relative to its folder).
///
/// # Errors
/// A missing or unreadable file (naming its path), or a malformed supported line
/// (naming file and line).
pub fn load_obj(path: &Path) -> Result<SceneDescription, SceneError> {
    let text = read_file(path)?;
    parse_obj(&text, path)
}

/// Parses OBJ text; `path` names it in messages and locates `mtllib` files.
///
/// # Errors
/// As [`load_obj`].
pub fn parse_obj(text: &[u8], path: &Path) -> Result<SceneDescription, SceneError> {
    // Robustness: binary data is refused, not read as lines of unknown statements.
    lex::check_text(text).map_err(|(line, kind)| LineError::from(kind).at(path, line))?;
    let mut reader = ObjReader {
        path,
        scene: SceneDescription::default(),
        material_ids: HashMap::new(),
        current_material: None,
        fallback_material: None,
        warned_no_usemtl: false,
        loaded_libraries: HashSet::new(),
    };
    for (line_number, line) in lex::lines(text) {
        reader
            .parse_line(line, line_number)
            .map_err(|e| e.at(path, line_number))?;
    }
    Ok(reader.scene)
}

/// An error from one line: either the line itself is malformed, or a file it names
/// failed (which carries its own location).
enum LineError {
    Parse(ParseErrorKind),
    Nested(SceneError),
}

impl From<ParseErrorKind> for LineError {
    fn from(kind: ParseErrorKind) -> Self {
        LineError::Parse(kind)
    }
}

impl LineError {
    fn at(self, path: &Path, line: usize) -> SceneError {
        match self {
            LineError::Parse(kind) => SceneError::Parse {
                path: path.to_path_buf(),
                line,
                kind,
            },
            LineError::Nested(e) => e,
        }
    }
}

struct ObjReader<'a> {
    path: &'a Path,
    scene: SceneDescription,
    material_ids: HashMap<String, MaterialId>,
    current_material: Option<MaterialId>,
    fallback_material: Option<MaterialId>,
    warned_no_usemtl: bool,
    /// Canonical paths of the `mtllib` files read so far.
    loaded_libraries: HashSet<PathBuf>,
}

/// One corner of a face, resolved to 0-based indices.
#[derive(Clone, Copy)]
struct Corner {
    position: u32,
    normal: Option<u32>,
}

impl ObjReader<'_> {
    fn parse_line(&mut self, line: &[u8], line_number: usize) -> Result<(), LineError> {
        let mut tokens = lex::tokens(line);
        let Some(keyword) = tokens.next() else {
            return Ok(());
        };
        match keyword {
            b"v" => {
                let p = lex::vec3("v", &mut tokens)?;
                self.scene.positions.push(p);
            }
            b"vn" => {
                let n = lex::vec3("vn", &mut tokens)?;
                self.scene.normals.push(n);
            }
            b"vt" => {
                let u = lex::floats::<1>("vt", &mut tokens)?[0];
                let v = match tokens.next() {
                    Some(t) => lex::float(t)?,
                    None => 0.0,
                };
                self.scene.texcoords.push(Vec2::new(u, v));
            }
            b"f" => self.parse_face(tokens, line_number)?,
            b"S" => {
                let [x, y, z, radius] = lex::floats::<4>("S", &mut tokens)?;
                if radius < 0.0 {
                    return Err(ParseErrorKind::NegativeRadius(radius).into());
                }
                let material = self.material_for_shape(line_number);
                self.scene.spheres.push(SphereDesc {
                    center: [x, y, z].into(),
                    radius,
                    material,
                });
            }
            b"P" => {
                let [x, y, z, r, g, b] = lex::floats::<6>("P", &mut tokens)?;
                self.scene.lights.push(PointLight {
                    position: [x, y, z].into(),
                    intensity: [r, g, b].into(),
                });
            }
            b"mtllib" => {
                let mut any = false;
                for name in tokens {
                    any = true;
                    self.load_mtl(name)?;
                }
                if !any {
                    return Err(ParseErrorKind::MissingName("mtllib").into());
                }
            }
            b"usemtl" => {
                let name = lex::rest_of_line(line, b"usemtl");
                if name.is_empty() {
                    return Err(ParseErrorKind::MissingName("usemtl").into());
                }
                let shown = lex::show(name);
                let name = String::from_utf8_lossy(name);
                self.current_material = Some(match self.material_ids.get(name.as_ref()) {
                    Some(&id) => id,
                    None => {
                        // Robustness: the name is shown cut, as tokens in errors are.
                        self.warn(
                            line_number,
                            &format!("unknown material '{shown}'; using the default material"),
                        );
                        self.fallback_material()
                    }
                });
            }
            _ => {}
        }
        Ok(())
    }

    fn parse_face<'t>(
        &mut self,
        tokens: impl Iterator<Item = &'t [u8]>,
        line_number: usize,
    ) -> Result<(), LineError> {
        let mut first: Option<Corner> = None;
        let mut previous: Option<Corner> = None;
        let mut count = 0usize;
        let material = self.material_for_shape(line_number);
        for token in tokens {
            let corner = self.parse_corner(token)?;
            count += 1;
            if let (Some(a), Some(b), 3..) = (first, previous, count) {
                if self.scene.triangles.len() >= u32::MAX as usize {
                    return Err(ParseErrorKind::TooMany("triangles").into());
                }
                let normals = match (a.normal, b.normal, corner.normal) {
                    (Some(na), Some(nb), Some(nc)) => Some([na, nb, nc]),
                    _ => None,
                };
                self.scene.triangles.push(TriangleDesc {
                    positions: [a.position, b.position, corner.position],
                    normals,
                    material,
                });
            }
            first.get_or_insert(corner);
            previous = Some(corner);
        }
        if count < 3 {
            return Err(ParseErrorKind::TooFewVertices(count).into());
        }
        Ok(())
    }

    /// Parses `v`, `v/vt`, `v//vn` or `v/vt/vn`.
    fn parse_corner(&self, token: &[u8]) -> Result<Corner, ParseErrorKind> {
        let bad = || ParseErrorKind::BadFaceVertex(lex::show(token));
        let mut parts = token.split(|&b| b == b'/');
        let position = parts.next().filter(|p| !p.is_empty()).ok_or_else(bad)?;
        let texcoord = parts.next().filter(|p| !p.is_empty());
        let normal = parts.next();
        if parts.next().is_some() || normal.is_some_and(|n| n.is_empty()) {
            return Err(bad());
        }
        let position = resolve(position, IndexKind::Vertex, self.scene.positions.len())?;
        if let Some(vt) = texcoord {
            resolve(vt, IndexKind::TexCoord, self.scene.texcoords.len())?;
        }
        let normal = normal
            .map(|vn| resolve(vn, IndexKind::Normal, self.scene.normals.len()))
            .transpose()?;
        Ok(Corner { position, normal })
    }

    fn load_mtl(&mut self, name: &[u8]) -> Result<(), LineError> {
        let relative = PathBuf::from(String::from_utf8_lossy(name).as_ref());
        let mtl_path = match self.path.parent() {
            Some(dir) => dir.join(&relative),
            None => relative,
        };
        // Robustness: a library named again (under any spelling of its path) is not
        // read again, so `mtllib a.mtl a.mtl ...` cannot multiply memory use.
        let identity =
            std::fs::canonicalize(&mtl_path).map_err(|error| library_error(&mtl_path, &error))?;
        if !self.loaded_libraries.insert(identity) {
            return Ok(());
        }
        // Robustness: a library that cannot be read is reported at the `mtllib` line.
        let text = read_file(&mtl_path).map_err(|e| match e {
            SceneError::Io { path, error } => library_error(&path, &error),
            other => LineError::Nested(other),
        })?;
        let materials = mtl::parse_mtl(&text, &mtl_path).map_err(LineError::Nested)?;
        for material in materials {
            let id = MaterialId(self.scene.materials.len() as u32);
            self.material_ids.insert(material.name.clone(), id);
            self.scene.materials.push(material);
        }
        Ok(())
    }

    /// The material for a new face or sphere, falling back (with one warning) when no
    /// `usemtl` came before.
    fn material_for_shape(&mut self, line_number: usize) -> MaterialId {
        if let Some(id) = self.current_material {
            return id;
        }
        if !self.warned_no_usemtl {
            self.warned_no_usemtl = true;
            self.warn(
                line_number,
                "shapes before any 'usemtl' get the default material",
            );
        }
        self.fallback_material()
    }

    fn fallback_material(&mut self) -> MaterialId {
        *self.fallback_material.get_or_insert_with(|| {
            self.scene.materials.push(Material::fallback());
            MaterialId(self.scene.materials.len() as u32 - 1)
        })
    }

    fn warn(&mut self, line_number: usize, message: &str) {
        self.scene
            .warnings
            .push(format!("{}:{line_number}: {message}", self.path.display()));
    }
}

/// A material library that cannot be read, as an error of the `mtllib` line.
fn library_error(path: &Path, error: &std::io::Error) -> LineError {
    LineError::Parse(ParseErrorKind::MaterialLibrary {
        path: path.to_path_buf(),
        reason: error.to_string(),
    })
}

/// Resolves a 1-based (or negative, counting back) index against `defined` elements.
fn resolve(token: &[u8], kind: IndexKind, defined: usize) -> Result<u32, ParseErrorKind> {
    let index =
        parse_index(token).ok_or_else(|| ParseErrorKind::BadFaceVertex(lex::show(token)))?;
    let resolved = match index {
        0 => return Err(ParseErrorKind::ZeroIndex(kind)),
        i if i > 0 => i - 1,
        i => defined as i64 + i,
    };
    if resolved < 0 || resolved >= defined as i64 {
        return Err(ParseErrorKind::IndexOutOfRange {
            kind,
            index,
            defined,
        });
    }
    Ok(resolved as u32)
}

/// Parses an optionally negative decimal integer; `None` if malformed or beyond 18
/// digits (no file defines that many elements).
fn parse_index(token: &[u8]) -> Option<i64> {
    let (negative, digits) = match token.split_first() {
        Some((b'-', rest)) => (true, rest),
        Some((b'+', rest)) => (false, rest),
        _ => (false, token),
    };
    if digits.is_empty() || digits.len() > 18 {
        return None;
    }
    let mut value: i64 = 0;
    for &d in digits {
        if !d.is_ascii_digit() {
            return None;
        }
        value = value * 10 + (d - b'0') as i64;
    }
    Some(if negative { -value } else { value })
}
