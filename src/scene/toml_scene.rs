//! The TOML scene description: camera and render settings, meshes read from OBJ or
//! PLY files (placed by a transform, optionally given one material), spheres, point
//! lights and materials. `docs/scene-format.md` documents every key.
//!
//! Reading goes in two steps: serde checks the document's shape and types (unknown
//! keys are errors), then the values are checked and the meshes loaded. Both steps
//! report `file:line: key: message`.

use std::collections::HashMap;
use std::ops::Range;
use std::path::Path;

use serde::Deserialize;
use serde::de::{self, Deserializer};
use toml::Spanned;
use toml::de::{DeTable, DeValue};

use super::error::{ParseErrorKind, SceneError};
use super::{
    LoadedScene, SceneDescription, SceneFormat, SphereDesc, Transform, load_mesh, read_file,
};
use crate::integrators::Mode;
use crate::material::{Material, MaterialId, PointLight};
use crate::math::{Float, Vec3};
use crate::options::PartialOptions;

/// Reads a TOML scene file and the meshes it names (relative to its folder).
///
/// # Errors
/// Invalid TOML, an unknown key, a value of the wrong type or out of range, an
/// unknown material name, or a mesh that fails to load: each names the TOML file,
/// line and key (a failing mesh adds its own error).
pub fn load_toml(path: &Path) -> Result<LoadedScene, SceneError> {
    let bytes = read_file(path)?;
    parse_toml(&bytes, path)
}

/// Parses a TOML scene; `path` names it in messages and locates its meshes.
///
/// # Errors
/// As [`load_toml`].
pub fn parse_toml(bytes: &[u8], path: &Path) -> Result<LoadedScene, SceneError> {
    let text = std::str::from_utf8(bytes).map_err(|e| SceneError::Parse {
        path: path.to_path_buf(),
        line: line_of(&bytes[..e.valid_up_to()], e.valid_up_to()),
        kind: ParseErrorKind::TomlSyntax("invalid UTF-8".into()),
    })?;
    let file: SceneFile = toml::from_str(text).map_err(|e| {
        let offset = e.span().map_or(0, |s| s.start);
        let message = e.message().trim_end().to_owned();
        let kind = match key_at(text, offset) {
            Some(key) => ParseErrorKind::TomlValue { key, message },
            None => ParseErrorKind::TomlSyntax(message),
        };
        SceneError::Parse {
            path: path.to_path_buf(),
            line: line_of(text.as_bytes(), offset),
            kind,
        }
    })?;
    Builder {
        path,
        text,
        scene: SceneDescription::default(),
        material_ids: HashMap::new(),
        fallback_material: None,
    }
    .build(file)
}

/// 1-based line of byte `offset`.
fn line_of(text: &[u8], offset: usize) -> usize {
    1 + text[..offset.min(text.len())]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
}

/// The dotted key (`camera.fov`, `mesh.transform.scale`) whose key or value holds
/// byte `offset`: the innermost one. `None` if the document does not parse, or the
/// offset is outside every entry.
fn key_at(text: &str, offset: usize) -> Option<String> {
    fn consider(span: Range<usize>, offset: usize, path: &str, best: &mut Option<(usize, String)>) {
        let inside = span.contains(&offset) || span.start == offset;
        if inside && best.as_ref().is_none_or(|(len, _)| span.len() <= *len) {
            *best = Some((span.len(), path.to_owned()));
        }
    }
    fn visit_table(
        table: &DeTable,
        prefix: &str,
        offset: usize,
        best: &mut Option<(usize, String)>,
    ) {
        for (key, value) in table.iter() {
            let path = match prefix {
                "" => key.get_ref().to_string(),
                _ => format!("{prefix}.{}", key.get_ref()),
            };
            consider(key.span(), offset, &path, best);
            consider(value.span(), offset, &path, best);
            visit_value(value.get_ref(), &path, offset, best);
        }
    }
    fn visit_value(value: &DeValue, path: &str, offset: usize, best: &mut Option<(usize, String)>) {
        match value {
            DeValue::Table(table) => visit_table(table, path, offset, best),
            DeValue::Array(items) => {
                for item in items {
                    consider(item.span(), offset, path, best);
                    visit_value(item.get_ref(), path, offset, best);
                }
            }
            _ => {}
        }
    }
    let root = DeTable::parse(text).ok()?;
    let mut best = None;
    visit_table(root.get_ref(), "", offset, &mut best);
    best.map(|(_, path)| path)
}

/// The whole document.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    #[serde(default)]
    camera: CameraTable,
    #[serde(default)]
    render: RenderTable,
    #[serde(default)]
    mesh: Vec<MeshTable>,
    #[serde(default)]
    sphere: Vec<SphereTable>,
    #[serde(default)]
    light: Vec<LightTable>,
    #[serde(default)]
    materials: NamedMaterials,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct CameraTable {
    look_from: Option<Spanned<Point>>,
    look_to: Option<Spanned<Point>>,
    up: Option<Spanned<Point>>,
    fov: Option<Spanned<Float>>,
    width: Option<Spanned<u32>>,
    height: Option<Spanned<u32>>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct RenderTable {
    mode: Option<ModeName>,
    depth: Option<Spanned<u32>>,
}

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "lowercase")]
enum ModeName {
    Full,
    Depth,
    Normal,
}

impl From<ModeName> for Mode {
    fn from(m: ModeName) -> Mode {
        match m {
            ModeName::Full => Mode::Full,
            ModeName::Depth => Mode::Depth,
            ModeName::Normal => Mode::Normal,
        }
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MeshTable {
    file: Spanned<String>,
    material: Option<Spanned<String>>,
    #[serde(default)]
    transform: TransformTable,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct TransformTable {
    translate: Option<Point>,
    rotate: Option<Point>,
    scale: Option<Spanned<Splat>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SphereTable {
    center: Point,
    radius: Spanned<Finite>,
    material: Option<Spanned<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LightTable {
    position: Point,
    intensity: Splat,
}

/// A material's MTL fields, under their MTL names.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MaterialTable {
    #[serde(rename = "Ka")]
    ambient: Option<Splat>,
    #[serde(rename = "Kd")]
    diffuse: Option<Splat>,
    #[serde(rename = "Ks")]
    specular: Option<Splat>,
    #[serde(rename = "Ke")]
    emission: Option<Splat>,
    #[serde(rename = "Ns")]
    shininess: Option<Finite>,
    #[serde(rename = "Ni")]
    ior: Option<Finite>,
    #[serde(rename = "d")]
    opacity: Option<Finite>,
    #[serde(rename = "al")]
    albedo: Option<Splat>,
}

/// `[materials.NAME]` tables in file order (which fixes their [`MaterialId`]s).
#[derive(Default)]
struct NamedMaterials(Vec<(String, MaterialTable)>);

impl<'de> Deserialize<'de> for NamedMaterials {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Visitor;
        impl<'de> de::Visitor<'de> for Visitor {
            type Value = NamedMaterials;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a table of materials")
            }
            fn visit_map<A: de::MapAccess<'de>>(self, mut map: A) -> Result<Self::Value, A::Error> {
                let mut materials = Vec::new();
                while let Some(entry) = map.next_entry()? {
                    materials.push(entry);
                }
                Ok(NamedMaterials(materials))
            }
        }
        deserializer.deserialize_map(Visitor)
    }
}

/// A finite number.
#[derive(Clone, Copy)]
struct Finite(Float);

impl<'de> Deserialize<'de> for Finite {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let value = f64::deserialize(deserializer)?;
        finite(value).map(Finite).map_err(de::Error::custom)
    }
}

fn finite(value: f64) -> Result<Float, String> {
    let narrowed = value as Float;
    if narrowed.is_finite() {
        Ok(narrowed)
    } else {
        Err(format!("{value} is not a finite number"))
    }
}

/// A point or direction: an array of three finite numbers.
#[derive(Clone, Copy)]
struct Point(Vec3);

impl<'de> Deserialize<'de> for Point {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let [x, y, z] = <[f64; 3]>::deserialize(deserializer)?;
        let v = [finite(x), finite(y), finite(z)];
        match v {
            [Ok(x), Ok(y), Ok(z)] => Ok(Point(Vec3::new(x, y, z))),
            _ => Err(de::Error::custom(
                v.into_iter().find_map(Result::err).unwrap_or_default(),
            )),
        }
    }
}

/// A colour or scale: three finite numbers, or one for all three.
#[derive(Clone, Copy)]
struct Splat(Vec3);

impl<'de> Deserialize<'de> for Splat {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged, expecting = "a number or an array of three numbers")]
        enum Raw {
            One(Finite),
            Three(Point),
        }
        Ok(match Raw::deserialize(deserializer)? {
            Raw::One(Finite(v)) => Splat(Vec3::splat(v)),
            Raw::Three(Point(v)) => Splat(v),
        })
    }
}

/// Turns the checked document into a description.
struct Builder<'a> {
    path: &'a Path,
    text: &'a str,
    scene: SceneDescription,
    material_ids: HashMap<String, MaterialId>,
    fallback_material: Option<MaterialId>,
}

impl Builder<'_> {
    fn build(mut self, file: SceneFile) -> Result<LoadedScene, SceneError> {
        let options = self.options(&file.camera, &file.render)?;
        for (name, table) in file.materials.0 {
            let id = MaterialId(self.scene.materials.len() as u32);
            self.scene.materials.push(material(&name, &table));
            self.material_ids.insert(name, id);
        }
        for mesh in &file.mesh {
            self.add_mesh(mesh)?;
        }
        for sphere in &file.sphere {
            let radius = sphere.radius.get_ref().0;
            if radius < 0.0 {
                return Err(self.error(
                    sphere.radius.span(),
                    "sphere.radius",
                    format!("{radius} is negative"),
                ));
            }
            let material = self.material(sphere.material.as_ref(), "sphere.material")?;
            self.scene.spheres.push(SphereDesc {
                center: sphere.center.0,
                radius,
                material,
            });
        }
        self.scene
            .lights
            .extend(file.light.iter().map(|light| PointLight {
                position: light.position.0,
                intensity: light.intensity.0,
            }));
        Ok(LoadedScene {
            description: self.scene,
            options,
        })
    }

    /// The file's render settings, checked as if rendered with no flags: a scene
    /// file must be renderable on its own.
    fn options(
        &self,
        camera: &CameraTable,
        render: &RenderTable,
    ) -> Result<PartialOptions, SceneError> {
        let value = |v: &Option<Spanned<Point>>| v.as_ref().map(|s| s.get_ref().0);
        let options = PartialOptions {
            width: camera.width.as_ref().map(|s| *s.get_ref()),
            height: camera.height.as_ref().map(|s| *s.get_ref()),
            fov_degrees: camera.fov.as_ref().map(|s| *s.get_ref()),
            look_from: value(&camera.look_from),
            look_to: value(&camera.look_to),
            up: value(&camera.up),
            depth: render.depth.as_ref().map(|s| *s.get_ref()),
            mode: render.mode.map(Mode::from),
        };
        if let Err(e) = options.resolve().validate() {
            // Name the key behind the flag the library's message speaks of.
            let (key, span) = match e.option {
                "--width" => ("camera.width", span_of(&camera.width)),
                "--height" => ("camera.height", span_of(&camera.height)),
                "--width/--height" => (
                    "camera.width",
                    span_of(&camera.width).or(span_of(&camera.height)),
                ),
                "--fov" => ("camera.fov", span_of(&camera.fov)),
                "--up" => ("camera.up", span_of(&camera.up)),
                "--depth" => ("render.depth", span_of(&render.depth)),
                _ if camera.look_from.is_some() => ("camera.look_from", span_of(&camera.look_from)),
                _ => ("camera.look_to", span_of(&camera.look_to)),
            };
            return Err(self.error(span.unwrap_or(0..0), key, e.message));
        }
        Ok(options)
    }

    fn add_mesh(&mut self, mesh: &MeshTable) -> Result<(), SceneError> {
        let file = mesh.file.get_ref();
        let file_span = mesh.file.span();
        let mesh_path = match self.path.parent() {
            Some(dir) => dir.join(file),
            None => file.into(),
        };
        if SceneFormat::of(&mesh_path) == SceneFormat::Toml {
            return Err(self.error(
                file_span,
                "mesh.file",
                format!("'{file}' is a scene file, not a mesh (OBJ or PLY)"),
            ));
        }
        let description = load_mesh(&mesh_path).map_err(|source| SceneError::Included {
            path: self.path.to_path_buf(),
            line: line_of(self.text.as_bytes(), file_span.start),
            key: "mesh.file".into(),
            source: Box::new(source),
        })?;
        let material = match &mesh.material {
            Some(name) => Some(self.material(Some(name), "mesh.material")?),
            None => None,
        };
        let mut description = description;
        if material.is_some() {
            // The mesh's own material assignments are replaced, so what its reader
            // said about them (a missing `usemtl`, an unknown name) no longer holds.
            description.warnings.retain(|w| !w.contains("material"));
        }
        let t = &mesh.transform;
        let scale = t.scale.as_ref().map_or(Vec3::ONE, |s| s.get_ref().0);
        let scale_span = t.scale.as_ref().map_or(file_span.clone(), Spanned::span);
        if scale.cmpeq(Vec3::ZERO).any() {
            return Err(self.error(
                scale_span,
                "mesh.transform.scale",
                "scale components must not be zero".into(),
            ));
        }
        let transform = Transform::new(
            scale,
            t.rotate.map_or(Vec3::ZERO, |r| r.0),
            t.translate.map_or(Vec3::ZERO, |r| r.0),
        );
        self.scene
            .append(description, &transform, material)
            .map_err(|kind| match kind {
                ParseErrorKind::NonUniformSphereScale => {
                    self.error(scale_span, "mesh.transform.scale", kind.to_string())
                }
                _ => self.error(file_span, "mesh.file", kind.to_string()),
            })
    }

    /// The id of a named material, or of the default material when there is no name.
    fn material(
        &mut self,
        name: Option<&Spanned<String>>,
        key: &str,
    ) -> Result<MaterialId, SceneError> {
        let Some(name) = name else {
            return Ok(*self.fallback_material.get_or_insert_with(|| {
                self.scene.materials.push(Material::fallback());
                MaterialId(self.scene.materials.len() as u32 - 1)
            }));
        };
        self.material_ids
            .get(name.get_ref())
            .copied()
            .ok_or_else(|| {
                self.error(
                    name.span(),
                    key,
                    format!("unknown material '{}'", name.get_ref()),
                )
            })
    }

    fn error(&self, span: Range<usize>, key: &str, message: String) -> SceneError {
        SceneError::Parse {
            path: self.path.to_path_buf(),
            line: line_of(self.text.as_bytes(), span.start),
            kind: ParseErrorKind::TomlValue {
                key: key.to_owned(),
                message,
            },
        }
    }
}

fn span_of<T>(value: &Option<Spanned<T>>) -> Option<Range<usize>> {
    value.as_ref().map(Spanned::span)
}

/// A material from its table: MTL defaults for what is not given.
fn material(name: &str, table: &MaterialTable) -> Material {
    let mut m = Material::named(name);
    let colour = |v: Option<Splat>, default: Vec3| v.map_or(default, |s| s.0);
    m.ambient = colour(table.ambient, m.ambient);
    m.diffuse = colour(table.diffuse, m.diffuse);
    m.specular = colour(table.specular, m.specular);
    m.emission = colour(table.emission, m.emission);
    m.shininess = table.shininess.map_or(m.shininess, |v| v.0);
    m.ior = table.ior.map_or(m.ior, |v| v.0);
    m.opacity = table.opacity.map_or(m.opacity, |v| v.0);
    m.albedo = table.albedo.map_or(m.albedo, |v| v.0.into());
    m
}
