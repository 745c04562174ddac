//! The TOML scene description: camera and render settings, meshes read from OBJ or
//! PLY files (placed by a transform, optionally given one material), spheres, point
//! lights and materials. `docs/scene-format.md` documents every key.
//!
//! Reading goes in two steps: serde checks the document's shape and types (unknown
//! keys are errors), then the values are checked and the meshes loaded. Both steps
//! report `file:line: key: message`. The camera and render values are the exception:
//! they are only read here, with their lines, and checked once the command line's
//! flags are merged over them ([`crate::options`]), so that a flag can replace a bad
//! value.

use std::collections::HashMap;
use std::ops::Range;
use std::path::Path;

use serde::Deserialize;
use serde::de::{self, Deserializer};
use toml::Spanned;
use toml::de::{DeTable, DeValue};

use super::error::{ParseErrorKind, SceneError};
use super::material_check::{MaterialProblems, check_pbr};
use super::{
    FileAccess, LoadedScene, SceneDescription, SceneFormat, SphereDesc, Transform,
    affine_from_rows, load_mesh_with, read_file,
};
use crate::material::pbr::PbrMaterial;
use crate::material::{Light, LightKind, Material, MaterialId};
use crate::math::{Float, Vec3};
use crate::options::defs::{Kind, Value, choice};
use crate::options::{OptionDef, OptionId, Origin, PartialOptions};

/// Reads a TOML scene file and the meshes it names (relative to its folder).
///
/// # Errors
/// Invalid TOML, an unknown key, a value of the wrong type or out of range, an
/// unknown material name, or a mesh that fails to load: each names the TOML file,
/// line and key (a failing mesh adds its own error). The ranges of the camera and
/// render values are checked by [`PartialOptions::resolve`], not here.
pub fn load_toml(path: &Path) -> Result<LoadedScene, SceneError> {
    load_toml_with(path, &FileAccess::anywhere())
}

/// [`load_toml`], opening the scene file and its meshes through `access`.
///
/// # Errors
/// As [`load_toml`]; a mesh `access` refuses is an error of the line naming it.
pub fn load_toml_with(path: &Path, access: &FileAccess) -> Result<LoadedScene, SceneError> {
    super::admit(path, access)?;
    let bytes = read_file(path)?;
    parse_toml_with(&bytes, path, access)
}

/// Parses a TOML scene; `path` names it in messages and locates its meshes.
///
/// # Errors
/// As [`load_toml`].
pub fn parse_toml(bytes: &[u8], path: &Path) -> Result<LoadedScene, SceneError> {
    parse_toml_with(bytes, path, &FileAccess::anywhere())
}

fn parse_toml_with(
    bytes: &[u8],
    path: &Path,
    access: &FileAccess,
) -> Result<LoadedScene, SceneError> {
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
        access,
        text,
        scene: SceneDescription::default(),
        material_ids: HashMap::new(),
        mesh_ids: HashMap::new(),
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
    camera: OptionTable,
    #[serde(default)]
    render: OptionTable,
    #[serde(default)]
    mesh: Vec<MeshTable>,
    #[serde(default)]
    instance: Vec<Spanned<InstanceTable>>,
    #[serde(default)]
    instances: Vec<Spanned<InstancesTable>>,
    #[serde(default)]
    sphere: Vec<SphereTable>,
    #[serde(default)]
    light: Vec<Spanned<LightTable>>,
    #[serde(default)]
    materials: NamedMaterials,
    environment: Option<EnvironmentTable>,
}

/// `[environment]`: an image `file` (relative to the scene file) or a `color`, with
/// `strength`, `rotation` (degrees about +Y) and what camera rays see instead,
/// `background`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct EnvironmentTable {
    file: Option<Spanned<String>>,
    color: Option<Spanned<Splat>>,
    strength: Option<Spanned<Float>>,
    rotation: Option<Spanned<Float>>,
    background: Option<Splat>,
}

/// `[camera]` or `[render]`: its keys in file order with their values, read as
/// [`OPTIONS`] defines them ([`Builder::options`]).
#[derive(Default)]
struct OptionTable(Vec<(String, Spanned<toml::Value>)>);

impl OptionTable {
    fn get(&self, key: &str) -> Option<&Spanned<toml::Value>> {
        self.0.iter().find(|(k, _)| k == key).map(|(_, v)| v)
    }
}

impl<'de> Deserialize<'de> for OptionTable {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Visitor;
        impl<'de> de::Visitor<'de> for Visitor {
            type Value = OptionTable;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a table of options")
            }
            fn visit_map<A: de::MapAccess<'de>>(self, mut map: A) -> Result<Self::Value, A::Error> {
                let mut entries = Vec::new();
                while let Some(entry) = map.next_entry()? {
                    entries.push(entry);
                }
                Ok(OptionTable(entries))
            }
        }
        deserializer.deserialize_map(Visitor)
    }
}

/// A TOML value as an option of `kind` takes it; serde's message if it is of
/// another type.
fn option_value(kind: Kind, value: &toml::Value) -> Result<Value, String> {
    let v = value.clone();
    let read = match kind {
        Kind::Whole => i64::deserialize(v).map(Value::Whole),
        Kind::Number => Float::deserialize(v).map(Value::Number),
        Kind::Vector => Point::deserialize(v).map(|p| Value::Vector(p.0)),
        Kind::Choice(choices) => {
            let name = String::deserialize(v).map_err(|e| e.message().trim_end().to_owned())?;
            return choice(choices, name);
        }
        Kind::SwitchOff => bool::deserialize(v).map(Value::Switch),
        Kind::Matrix => <[[f64; 4]; 4]>::deserialize(v).map(Value::Matrix),
        Kind::Intrinsics => <[Float; 4]>::deserialize(v).map(Value::Four),
        Kind::FileOrColour | Kind::Background => {
            unreachable!("the [environment] table is read by Builder::add_environment")
        }
    };
    read.map_err(|e| e.message().trim_end().to_owned())
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MeshTable {
    file: Spanned<String>,
    /// A mesh with an id is placed only by `[[instance]]` and `[[instances]]`.
    id: Option<Spanned<String>>,
    material: Option<Spanned<String>>,
    #[serde(default)]
    transform: TransformTable,
}

/// One copy of a mesh with an id: `transform` or `matrix` (row-major world from
/// object), or neither (where the mesh is).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct InstanceTable {
    mesh: Spanned<String>,
    transform: Option<Spanned<TransformTable>>,
    matrix: Option<Spanned<Vec<f64>>>,
}

/// Copies of a mesh with an id, one per matrix of an `(N, 4, 4)` `.npy` file.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct InstancesTable {
    mesh: Spanned<String>,
    file: Spanned<String>,
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

/// A light: `type` (point by default), and the keys of its type.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LightTable {
    #[serde(rename = "type")]
    kind: Option<Spanned<LightType>>,
    position: Option<Spanned<Point>>,
    direction: Option<Spanned<Point>>,
    color: Option<Spanned<Splat>>,
    intensity: Option<Spanned<Splat>>,
    inner_cone: Option<Spanned<Finite>>,
    outer_cone: Option<Spanned<Finite>>,
    range: Option<Spanned<Finite>>,
}

#[derive(Deserialize, Clone, Copy, PartialEq)]
#[serde(rename_all = "lowercase")]
enum LightType {
    Point,
    Spot,
    Directional,
}

/// A material's MTL fields, under their MTL names, and the physically based
/// model's (glTF's) under theirs.
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
    // The physically based keys (`docs/scene-format.md`). Numbers may be `nan` or
    // `inf` here: the checks shared with the other readers warn about them (and
    // `attenuation_distance = inf` means no attenuation).
    base_color: Option<Splat>,
    metallic: Option<Float>,
    roughness: Option<Float>,
    #[serde(rename = "ior")]
    index_of_refraction: Option<Float>,
    #[serde(rename = "specular")]
    specular_weight: Option<Float>,
    specular_color: Option<Splat>,
    transmission: Option<Float>,
    thickness: Option<Float>,
    attenuation_color: Option<Splat>,
    attenuation_distance: Option<Float>,
    clearcoat: Option<Float>,
    clearcoat_roughness: Option<Float>,
    sheen_color: Option<Splat>,
    sheen_roughness: Option<Float>,
    multiple_scattering: Option<bool>,
    anisotropy: Option<Float>,
    anisotropy_rotation: Option<Float>,
    #[serde(rename = "emission")]
    emission_colour: Option<Splat>,
    emission_strength: Option<Float>,
}

impl MaterialTable {
    /// Whether any physically based key is given.
    fn any_pbr(&self) -> bool {
        let MaterialTable {
            base_color,
            metallic,
            roughness,
            index_of_refraction,
            specular_weight,
            specular_color,
            transmission,
            thickness,
            attenuation_color,
            attenuation_distance,
            clearcoat,
            clearcoat_roughness,
            sheen_color,
            sheen_roughness,
            emission_colour,
            emission_strength,
            anisotropy,
            anisotropy_rotation,
            ..
        } = self;
        [
            base_color,
            specular_color,
            attenuation_color,
            sheen_color,
            emission_colour,
        ]
        .iter()
        .any(|c| c.is_some())
            || [
                metallic,
                roughness,
                index_of_refraction,
                specular_weight,
                transmission,
                thickness,
                attenuation_distance,
                clearcoat,
                clearcoat_roughness,
                sheen_roughness,
                emission_strength,
                anisotropy,
                anisotropy_rotation,
            ]
            .iter()
            .any(|v| v.is_some())
    }
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

impl From<Point> for Vec3 {
    fn from(p: Point) -> Vec3 {
        p.0
    }
}

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
    /// Where meshes (and what they name) may be read from.
    access: &'a FileAccess,
    text: &'a str,
    scene: SceneDescription,
    material_ids: HashMap<String, MaterialId>,
    /// Meshes placed by instances, by id.
    mesh_ids: HashMap<String, u32>,
    fallback_material: Option<MaterialId>,
}

impl Builder<'_> {
    fn build(mut self, file: SceneFile) -> Result<LoadedScene, SceneError> {
        let options = self.options(&file.camera, &file.render)?;
        let mut problems = MaterialProblems::default();
        for (name, table) in file.materials.0 {
            let id = MaterialId(self.scene.materials.len() as u32);
            self.scene
                .materials
                .push(material(&name, &table, &mut problems));
            self.material_ids.insert(name, id);
        }
        for message in problems.messages() {
            self.scene
                .warnings
                .push(format!("{}: {message}", self.path.display()));
        }
        for mesh in &file.mesh {
            self.add_mesh(mesh)?;
        }
        for instance in &file.instance {
            self.add_instance(instance)?;
        }
        for instances in &file.instances {
            self.add_instances(instances)?;
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
        for light in &file.light {
            let light = self.light(light)?;
            self.scene.lights.push(light);
        }
        if let Some(environment) = &file.environment {
            self.add_environment(environment)?;
        }
        Ok(LoadedScene {
            description: self.scene,
            options,
        })
    }

    /// The file's render settings, each with its line, read as [`OPTIONS`]
    /// defines the keys of `[camera]` and `[render]`. Not checked here: a flag may
    /// replace a bad value. A camera `matrix` is read here (into `look_from`,
    /// `look_to` and `up`, by [`crate::options::pose_from_matrix`]), and refused with
    /// a LookAt key.
    ///
    /// [`OPTIONS`]: crate::options::OPTIONS
    fn options(
        &self,
        camera: &OptionTable,
        render: &OptionTable,
    ) -> Result<PartialOptions, SceneError> {
        let mut options = PartialOptions::default();
        if let Some(matrix) = camera.get("matrix")
            && ["look_from", "look_to", "up"]
                .iter()
                .any(|k| camera.get(k).is_some())
        {
            return Err(self.error(
                matrix.span(),
                "camera.matrix",
                "give either a matrix or look_from, look_to and up, not both".into(),
            ));
        }
        for (section, table) in [("camera", camera), ("render", render)] {
            for (key, value) in &table.0 {
                let span = value.span();
                let Some((def, _)) = OptionDef::in_section(section).find(|(_, k)| k == key) else {
                    let expected: Vec<String> = OptionDef::in_section(section)
                        .map(|(_, k)| format!("`{k}`"))
                        .collect();
                    return Err(self.error(
                        span,
                        &format!("{section}.{key}"),
                        format!(
                            "unknown field `{key}`, expected one of {}",
                            expected.join(", ")
                        ),
                    ));
                };
                let dotted = def.toml.unwrap_or(def.python);
                let read = option_value(def.kind, value.get_ref())
                    .map_err(|e| self.error(span.clone(), dotted, e))?;
                def.store(&mut options, read, self.origin(span.clone(), dotted))
                    .map_err(|e| self.error(span, dotted, e))?;
            }
        }
        Ok(options)
    }

    /// Where the value at `span` of `key` came from.
    fn origin(&self, span: Range<usize>, key: &'static str) -> Origin {
        Origin::File {
            path: self.path.to_path_buf(),
            line: line_of(self.text.as_bytes(), span.start),
            key,
        }
    }

    fn add_environment(&mut self, table: &EnvironmentTable) -> Result<(), SceneError> {
        use super::environment::{environment_colour, load_environment_map};
        // The ranges of `--env-strength` and `--env-rotation`.
        for (id, value) in [
            (OptionId::EnvStrength, &table.strength),
            (OptionId::EnvRotation, &table.rotation),
        ] {
            if let Some(value) = value {
                let def = OptionDef::of(id);
                def.range
                    .check((*value.get_ref()).into())
                    .map_err(|e| self.error(value.span(), def.toml.unwrap_or(def.python), e))?;
            }
        }
        let strength = table.strength.as_ref().map_or(1.0, |s| *s.get_ref());
        let rotation = table.rotation.as_ref().map_or(0.0, |r| *r.get_ref());
        let mut desc = match (&table.file, &table.color) {
            (Some(file), None) => {
                let path = match self.path.parent() {
                    Some(dir) => dir.join(file.get_ref()),
                    None => file.get_ref().into(),
                };
                self.access
                    .admit(&path)
                    .map_err(|e| self.error(file.span(), "environment.file", e.to_string()))?;
                let (desc, warning) = load_environment_map(&path, strength, rotation)
                    .map_err(|e| self.error(file.span(), "environment.file", e))?;
                self.scene.warnings.extend(warning);
                desc
            }
            (None, Some(colour)) => {
                let c = colour.get_ref().0;
                if !c.is_finite() || c.min_element() < 0.0 {
                    return Err(self.error(
                        colour.span(),
                        "environment.color",
                        "components must be finite and 0 or more".into(),
                    ));
                }
                environment_colour(c, strength)
            }
            (Some(file), Some(_)) => {
                return Err(self.error(
                    file.span(),
                    "environment",
                    "give a file or a color, not both".into(),
                ));
            }
            // Only a background: the scene keeps its lighting.
            (None, None) => {
                self.scene.background = table.background.as_ref().map(|b| b.0);
                return Ok(());
            }
        };
        desc.rotation_degrees = rotation;
        self.scene.environment = Some(desc);
        self.scene.background = table.background.as_ref().map(|b| b.0);
        Ok(())
    }

    fn add_mesh(&mut self, mesh: &MeshTable) -> Result<(), SceneError> {
        // Everything the TOML says is checked before the (maybe large) file is read.
        let file = mesh.file.get_ref();
        let file_span = mesh.file.span();
        let mesh_path = match self.path.parent() {
            Some(dir) => dir.join(file),
            None => file.into(),
        };
        match SceneFormat::of(&mesh_path) {
            Some(SceneFormat::Obj | SceneFormat::Ply | SceneFormat::Gltf) => {}
            Some(SceneFormat::Toml) => {
                return Err(self.error(
                    file_span,
                    "mesh.file",
                    format!("'{file}' is a scene file, not a mesh (OBJ, PLY or glTF)"),
                ));
            }
            None => {
                return Err(self.error(
                    file_span,
                    "mesh.file",
                    format!("'{file}' is not a mesh file the renderer reads (.obj, .ply, .gltf or .glb, each optionally .gz)"),
                ));
            }
        }
        let material = match &mesh.material {
            Some(name) => Some(self.material(Some(name), "mesh.material")?),
            None => None,
        };
        let (transform, scale_span) =
            self.transform(&mesh.transform, file_span.clone(), "mesh.transform.scale")?;
        if let Some(id) = &mesh.id {
            if self.mesh_ids.contains_key(id.get_ref()) {
                return Err(self.error(
                    id.span(),
                    "mesh.id",
                    format!("mesh id '{}' is given twice", id.get_ref()),
                ));
            }
            if mesh.transform.translate.is_some()
                || mesh.transform.rotate.is_some()
                || mesh.transform.scale.is_some()
            {
                return Err(self.error(
                    id.span(),
                    "mesh.transform",
                    "a mesh with an id is placed by its instances: give the transform to each [[instance]]".into(),
                ));
            }
        }

        let mut description =
            load_mesh_with(&mesh_path, self.access).map_err(|error| SceneError::Included {
                path: self.path.to_path_buf(),
                line: line_of(self.text.as_bytes(), file_span.start),
                key: "mesh.file".into(),
                error: Box::new(error),
            })?;
        if material.is_some() {
            // The mesh's own material assignments are replaced, so what its reader
            // said about them (a missing `usemtl`, an unknown name) no longer holds.
            description.warnings.retain(|w| !w.contains("material"));
        }
        if let Some(id) = &mesh.id {
            let index = self
                .scene
                .add_instanced_mesh(description, material)
                .map_err(|kind| self.error(file_span.clone(), "mesh.file", kind.to_string()))?;
            self.mesh_ids.insert(id.get_ref().clone(), index);
            return Ok(());
        }
        self.scene
            .append(description, &transform, material)
            .map_err(|kind| match kind {
                ParseErrorKind::NonUniformSphereScale => {
                    self.error(scale_span, "mesh.transform.scale", kind.to_string())
                }
                _ => self.error(file_span, "mesh.file", kind.to_string()),
            })
    }

    /// A `transform` table as a placement, and the span of its scale (or `span`
    /// without one) for errors about it.
    fn transform(
        &self,
        t: &TransformTable,
        span: Range<usize>,
        scale_key: &str,
    ) -> Result<(Transform, Range<usize>), SceneError> {
        let scale = t.scale.as_ref().map_or(Vec3::ONE, |s| s.get_ref().0);
        let scale_span = t.scale.as_ref().map_or(span, Spanned::span);
        if scale.cmpeq(Vec3::ZERO).any() {
            return Err(self.error(
                scale_span,
                scale_key,
                "scale components must not be zero".into(),
            ));
        }
        let transform = Transform::new(
            scale,
            t.rotate.map_or(Vec3::ZERO, |r| r.0),
            t.translate.map_or(Vec3::ZERO, |r| r.0),
        );
        Ok((transform, scale_span))
    }

    /// The mesh an instance names by id.
    fn instanced_mesh(&self, name: &Spanned<String>, key: &str) -> Result<u32, SceneError> {
        self.mesh_ids.get(name.get_ref()).copied().ok_or_else(|| {
            self.error(
                name.span(),
                key,
                format!(
                    "unknown mesh '{}' (no [[mesh]] has this id)",
                    name.get_ref()
                ),
            )
        })
    }

    fn add_instance(&mut self, table: &Spanned<InstanceTable>) -> Result<(), SceneError> {
        let instance = table.get_ref();
        let mesh = self.instanced_mesh(&instance.mesh, "instance.mesh")?;
        let placement = match (&instance.transform, &instance.matrix) {
            (Some(_), Some(matrix)) => {
                return Err(self.error(
                    matrix.span(),
                    "instance.matrix",
                    "give either transform or matrix, not both".into(),
                ));
            }
            (Some(transform), None) => self
                .transform(
                    transform.get_ref(),
                    transform.span(),
                    "instance.transform.scale",
                )?
                .0
                .to_affine(),
            (None, Some(matrix)) => {
                let values: &[f64; 16] = matrix.get_ref().as_slice().try_into().map_err(|_| {
                    self.error(
                        matrix.span(),
                        "instance.matrix",
                        format!(
                            "{} numbers: a matrix is 16 numbers, row-major world from object",
                            matrix.get_ref().len()
                        ),
                    )
                })?;
                affine_from_rows(values)
                    .map_err(|message| self.error(matrix.span(), "instance.matrix", message))?
            }
            (None, None) => glam::Affine3A::IDENTITY,
        };
        self.scene.add_instance(mesh, placement, false);
        Ok(())
    }

    fn add_instances(&mut self, table: &Spanned<InstancesTable>) -> Result<(), SceneError> {
        let table = table.get_ref();
        let mesh = self.instanced_mesh(&table.mesh, "instances.mesh")?;
        let file = table.file.get_ref();
        let path = match self.path.parent() {
            Some(dir) => dir.join(file),
            None => file.into(),
        };
        let included = |error: SceneError| SceneError::Included {
            path: self.path.to_path_buf(),
            line: line_of(self.text.as_bytes(), table.file.span().start),
            key: "instances.file".into(),
            error: Box::new(error),
        };
        let bytes = super::admit(&path, self.access)
            .and_then(|()| read_file(&path))
            .map_err(included)?;
        let matrices = super::npy::parse_matrices(&bytes, &path).map_err(included)?;
        drop(bytes);
        self.scene.instances.reserve(matrices.len());
        for matrix in matrices {
            self.scene.add_instance(mesh, matrix, false);
        }
        Ok(())
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

    /// A `[[light]]` table as a light, its keys checked against its type.
    fn light(&self, table: &Spanned<LightTable>) -> Result<Light, SceneError> {
        let light = table.get_ref();
        let kind = light
            .kind
            .as_ref()
            .map_or(LightType::Point, |k| *k.get_ref());
        let type_name = match kind {
            LightType::Point => "point",
            LightType::Spot => "spot",
            LightType::Directional => "directional",
        };
        // A key the type does not use is an error: it was surely meant to do something.
        let unused = |span: Option<Range<usize>>, key: &str| match span {
            Some(span) => Err(self.error(
                span,
                &format!("light.{key}"),
                format!("a {type_name} light has no {key}"),
            )),
            None => Ok(()),
        };
        let colour = |value: &Option<Spanned<Splat>>, key: &str| match value {
            None => Ok(Vec3::ONE),
            Some(v) if v.get_ref().0.cmplt(Vec3::ZERO).any() => Err(self.error(
                v.span(),
                &format!("light.{key}"),
                format!("{} is negative", v.get_ref().0),
            )),
            Some(v) => Ok(v.get_ref().0),
        };
        let intensity = colour(&light.color, "color")? * colour(&light.intensity, "intensity")?;
        let position = match (&light.position, kind) {
            (Some(p), LightType::Point | LightType::Spot) => p.get_ref().0,
            (None, LightType::Point | LightType::Spot) => {
                return Err(self.error(
                    table.span(),
                    "light.position",
                    format!("a {type_name} light needs a position"),
                ));
            }
            (p, LightType::Directional) => {
                unused(p.as_ref().map(Spanned::span), "position")?;
                Vec3::ZERO
            }
        };
        let direction = match (&light.direction, kind) {
            (None, LightType::Spot | LightType::Directional) => {
                return Err(self.error(
                    table.span(),
                    "light.direction",
                    format!("a {type_name} light needs a direction"),
                ));
            }
            (Some(d), LightType::Spot | LightType::Directional) => {
                match d.get_ref().0.try_normalize() {
                    Some(unit) => unit,
                    None => {
                        return Err(self.error(
                            d.span(),
                            "light.direction",
                            "a direction of zero length".to_owned(),
                        ));
                    }
                }
            }
            (d, LightType::Point) => {
                unused(d.as_ref().map(Spanned::span), "direction")?;
                Vec3::NEG_Z
            }
        };
        let range = match (&light.range, kind) {
            (Some(r), LightType::Directional) => {
                unused(Some(r.span()), "range")?;
                None
            }
            (Some(r), _) if r.get_ref().0 <= 0.0 => {
                return Err(self.error(
                    r.span(),
                    "light.range",
                    format!("{} is not positive", r.get_ref().0),
                ));
            }
            (r, _) => r.as_ref().map(|r| r.get_ref().0),
        };
        let kind = match kind {
            LightType::Point | LightType::Directional => {
                unused(light.inner_cone.as_ref().map(Spanned::span), "inner_cone")?;
                unused(light.outer_cone.as_ref().map(Spanned::span), "outer_cone")?;
                if kind == LightType::Point {
                    LightKind::Point
                } else {
                    LightKind::Directional { direction }
                }
            }
            LightType::Spot => {
                // glTF's defaults: 0 and 45 degrees.
                let outer = light.outer_cone.as_ref().map_or(45.0, |c| c.get_ref().0);
                let inner = light.inner_cone.as_ref().map_or(0.0, |c| c.get_ref().0);
                let span =
                    |c: &Option<Spanned<Finite>>| c.as_ref().map_or(table.span(), Spanned::span);
                if !(outer > 0.0 && outer <= 90.0) {
                    return Err(self.error(
                        span(&light.outer_cone),
                        "light.outer_cone",
                        format!("{outer} degrees is not in (0, 90]"),
                    ));
                }
                if inner < 0.0 {
                    return Err(self.error(
                        span(&light.inner_cone),
                        "light.inner_cone",
                        format!("{inner} degrees is negative"),
                    ));
                }
                if inner > outer {
                    return Err(self.error(
                        span(&light.inner_cone),
                        "light.inner_cone",
                        format!("{inner} degrees is wider than outer_cone ({outer} degrees)"),
                    ));
                }
                LightKind::Spot {
                    direction,
                    cos_inner: inner.to_radians().cos(),
                    cos_outer: outer.to_radians().cos(),
                }
            }
        };
        Ok(Light {
            position,
            intensity,
            kind,
            range,
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

/// A material from its table: MTL defaults for what is not given; a physically
/// based material when any of its physically based keys is given (see
/// [`physically_based`]).
fn material(name: &str, table: &MaterialTable, problems: &mut MaterialProblems) -> Material {
    if table.any_pbr() {
        return physically_based(name, table, problems);
    }
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

/// A physically based material from its table: glTF's defaults for what is not
/// given, except `metallic`, 0 (a table giving `base_color` alone describes a
/// plastic). `Ke` and `Ni` stand for `emission` and `ior` when those are not given;
/// `d` and `al` are kept (as for MTL materials, path mode does not read them);
/// `Ka`, `Kd`, `Ks` and `Ns` would contradict the physically based keys and are
/// ignored, with one warning.
fn physically_based(
    name: &str,
    table: &MaterialTable,
    problems: &mut MaterialProblems,
) -> Material {
    let p = table;
    let defaults = PbrMaterial {
        metallic: 0.0,
        ..PbrMaterial::default()
    };
    let colour = |v: Option<Splat>, default: Vec3| v.map_or(default, |s| s.0);
    let mut pbr = PbrMaterial {
        base_color: colour(p.base_color, defaults.base_color),
        metallic: p.metallic.unwrap_or(defaults.metallic),
        roughness: p.roughness.unwrap_or(defaults.roughness),
        ior: p
            .index_of_refraction
            .or(table.ior.map(|v| v.0))
            .unwrap_or(defaults.ior),
        specular: p.specular_weight.unwrap_or(defaults.specular),
        specular_color: colour(p.specular_color, defaults.specular_color),
        transmission: p.transmission.unwrap_or(defaults.transmission),
        thickness: p.thickness.unwrap_or(defaults.thickness),
        attenuation_color: colour(p.attenuation_color, defaults.attenuation_color),
        attenuation_distance: p
            .attenuation_distance
            .unwrap_or(defaults.attenuation_distance),
        clearcoat: p.clearcoat.unwrap_or(defaults.clearcoat),
        clearcoat_roughness: p
            .clearcoat_roughness
            .unwrap_or(defaults.clearcoat_roughness),
        sheen_color: colour(p.sheen_color, defaults.sheen_color),
        sheen_roughness: p.sheen_roughness.unwrap_or(defaults.sheen_roughness),
        multiple_scattering: p.multiple_scattering.unwrap_or(false),
        anisotropy: p.anisotropy.unwrap_or(defaults.anisotropy),
        anisotropy_rotation: p
            .anisotropy_rotation
            .unwrap_or(defaults.anisotropy_rotation),
        unlit: false,
    };
    let phong_keys = [
        ("Ka", table.ambient.is_some()),
        ("Kd", table.diffuse.is_some()),
        ("Ks", table.specular.is_some()),
        ("Ns", table.shininess.is_some()),
    ];
    let given: Vec<&str> = phong_keys
        .iter()
        .filter(|(_, given)| *given)
        .map(|(key, _)| *key)
        .collect();
    if !given.is_empty() {
        problems.note(
            format!(
                "MTL keys ({}) beside physically based keys are ignored",
                given.join(", ")
            ),
            name,
        );
    }
    check_pbr(&mut pbr, &defaults, name, problems);
    let strength = p.emission_strength.unwrap_or(1.0);
    let emission = colour(p.emission_colour.or(table.emission), Vec3::ZERO) * strength;
    let emission = if emission.is_finite() && emission.min_element() >= 0.0 {
        emission
    } else {
        problems.note(
            "an emission that is negative or not finite, read as 0",
            name,
        );
        Vec3::ZERO
    };
    let mut m = Material::physically_based(name, pbr, emission, None);
    m.opacity = table.opacity.map_or(m.opacity, |v| v.0);
    m.albedo = table.albedo.map_or(m.albedo, |v| v.0.into());
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::options::{Mode, OPTIONS};
    use std::fs;

    /// A folder with `tri.obj` (one triangle with `vn` normals, material `red` from
    /// `tri.mtl`) and `bad.obj`, and a way to parse TOML text placed in it.
    struct Folder(tempfile::TempDir);

    impl Folder {
        fn new() -> Folder {
            let dir = tempfile::tempdir().unwrap();
            let write = |name: &str, text: &str| fs::write(dir.path().join(name), text).unwrap();
            write("tri.mtl", "newmtl red\nKd 1 0 0\n");
            write(
                "tri.obj",
                "mtllib tri.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nusemtl red\nf 1//1 2//1 3//1\n",
            );
            write("ball.obj", "S 0 0 0 1\nP 0 5 0 1 1 1\n");
            write("bad.obj", "v 0 x 0\n");
            Folder(dir)
        }

        fn path(&self) -> std::path::PathBuf {
            self.0.path().join("s.toml")
        }

        fn parse(&self, text: &str) -> Result<LoadedScene, SceneError> {
            parse_toml(text.as_bytes(), &self.path())
        }

        fn error(&self, text: &str) -> String {
            let message = self.parse(text).unwrap_err().to_string();
            message.replace(&self.0.path().display().to_string(), "DIR")
        }
    }

    #[test]
    fn every_key_is_read() {
        let folder = Folder::new();
        let loaded = folder
            .parse(
                r#"
[camera]
look_from = [1, 2, 3]
look_to = [0, 0.5, 0]
up = [0, 0, 1]
fov = 35.5
width = 32
height = 24

[render]
mode = "normal"
depth = 7
spp = 9

[[mesh]]
file = "tri.obj"

[[mesh]]
file = "tri.obj"
material = "glass"
transform = { translate = [10, 0, 0], rotate = [0, 0, 90], scale = 2 }

[[mesh]]
file = "tri.obj"
[mesh.transform]
scale = [1, 3, 1]

[[sphere]]
center = [0, 1, 0]
radius = 0.5
material = "glass"

[[sphere]]
center = [0, 0, 0]
radius = 0

[[light]]
position = [0, 9, 0]
intensity = 0.5

[[light]]
position = [1, 9, 0]
intensity = [1, 0.5, 0.25]

[materials.glass]
Ka = 0.1
Kd = [0.1, 0.2, 0.3]
Ks = [1, 1, 1]
Ke = [0, 0, 2]
Ns = 64
Ni = 1.5
d = 0.25
al = [0.1, 0.2, 0.7]

[materials.plain]
"#,
            )
            .unwrap();
        let origin = &loaded.options.height.as_ref().unwrap().origin;
        assert_eq!(
            origin,
            &Origin::File {
                path: folder.path(),
                line: 8,
                key: "camera.height"
            }
        );
        let o = loaded.options.resolve().unwrap();
        assert_eq!(o.look_from, Vec3::new(1.0, 2.0, 3.0));
        assert_eq!(o.look_to, Vec3::new(0.0, 0.5, 0.0));
        assert_eq!(o.up, Vec3::Z);
        assert_eq!(o.fov_degrees, 35.5);
        assert_eq!((o.width, o.height), (32, 24));
        assert_eq!((o.mode, o.depth), (Mode::Normal, 7));
        assert_eq!(o.samples_per_pixel, 9);

        let d = loaded.description;
        let names: Vec<&str> = d.materials.iter().map(|m| m.name.as_str()).collect();
        // TOML materials in file order, then the first and third mesh's own, then the
        // default material of the sphere that names none.
        assert_eq!(names, ["glass", "plain", "red", "red", "default"]);
        let glass = &d.materials[0];
        assert_eq!(glass.ambient, Vec3::splat(0.1));
        assert_eq!(glass.diffuse, Vec3::new(0.1, 0.2, 0.3));
        assert_eq!(glass.specular, Vec3::ONE);
        assert_eq!(glass.emission, Vec3::new(0.0, 0.0, 2.0));
        assert_eq!(
            (glass.shininess, glass.ior, glass.opacity),
            (64.0, 1.5, 0.25)
        );
        assert_eq!(glass.albedo, [0.1, 0.2, 0.7]);
        assert_eq!(d.materials[1], Material::named("plain"));

        let material_ids: Vec<u32> = d.triangles.iter().map(|t| t.material.0).collect();
        assert_eq!(material_ids, [2, 0, 3]);
        // Mesh 2: scaled by 2, turned 90 degrees about z (x -> y), moved by +10 x.
        let close = |a: Vec3, b: Vec3| (a - b).length() < 1e-5;
        assert!(close(d.positions[4], Vec3::new(10.0, 2.0, 0.0)));
        assert!(close(d.positions[5], Vec3::new(8.0, 0.0, 0.0)));
        assert!(close(d.positions[8], Vec3::new(0.0, 3.0, 0.0)));
        assert_eq!(d.triangles[1].positions, [3, 4, 5]);
        assert!(close(d.normals[1].normalize(), Vec3::Z));

        assert_eq!(d.spheres.len(), 2);
        assert_eq!(d.spheres[0].material, MaterialId(0));
        assert_eq!(
            (d.spheres[1].radius, d.spheres[1].material),
            (0.0, MaterialId(4))
        );
        assert_eq!(d.lights[0].intensity, Vec3::splat(0.5));
        assert_eq!(d.lights[1].intensity, Vec3::new(1.0, 0.5, 0.25));
        assert_eq!(d.lights[1].position, Vec3::new(1.0, 9.0, 0.0));
    }

    #[test]
    fn an_empty_file_is_an_empty_scene_with_no_settings() {
        let loaded = Folder::new().parse("# nothing\n").unwrap();
        assert_eq!(loaded.options, PartialOptions::default());
        assert!(loaded.description.triangles.is_empty());
    }

    #[test]
    fn path_mode_exposure_and_seed_are_read_with_their_lines() {
        let loaded = Folder::new()
            .parse("[render]\nmode = \"path\"\nexposure = -1.5\nseed = 42\n")
            .unwrap();
        let o = loaded.options.resolve().unwrap();
        assert_eq!((o.mode, o.exposure, o.seed), (Mode::Path, -1.5, 42));
        assert_eq!(
            (o.depth, o.samples_per_pixel),
            crate::options::PATH_DEFAULTS
        );
        let exposure = loaded.options.exposure.unwrap();
        assert!(
            matches!(exposure.origin, Origin::File { line: 3, .. }),
            "{:?}",
            exposure.origin
        );
    }

    #[test]
    fn obj_spheres_and_lights_follow_the_transform() {
        let folder = Folder::new();
        let text =
            "[[mesh]]\nfile = \"ball.obj\"\ntransform = { scale = -3, translate = [0, 1, 0] }\n";
        let d = folder.parse(text).unwrap().description;
        assert_eq!(d.spheres[0].radius, 3.0);
        assert_eq!(d.spheres[0].center, Vec3::Y);
        assert_eq!(d.lights[0].position, Vec3::new(0.0, -14.0, 0.0));
        assert_eq!(
            folder.error("[[mesh]]\nfile = \"ball.obj\"\ntransform = { scale = [1, 2, 1] }\n"),
            "DIR/s.toml:3: mesh.transform.scale: spheres need the same scale on every axis"
        );
    }

    /// `[environment]` is read by a table of its own (`EnvironmentTable`: a file or
    /// a colour, read and checked together), not key by key from `OPTIONS`: its keys
    /// must still be the table's, so that the documentation made from `OPTIONS`
    /// lists what the reader takes.
    #[test]
    fn the_environment_keys_are_those_of_the_options_table() {
        let message = Folder::new().error("[environment]\nbogus = 1\n");
        let (_, listed) = message.split_once("expected one of ").unwrap();
        let mut read: Vec<&str> = listed.split(", ").map(|k| k.trim_matches('`')).collect();
        let mut declared: Vec<&str> = (OPTIONS.iter())
            .flat_map(OptionDef::toml_keys)
            .filter_map(|k| k.strip_prefix("environment."))
            .collect();
        read.sort_unstable();
        declared.sort_unstable();
        assert_eq!(read, declared, "{message}");
    }

    #[test]
    fn errors_name_file_line_and_key() {
        let folder = Folder::new();
        let cases = [
            (
                "[camera]\nfov = \"wide\"\n",
                "DIR/s.toml:2: camera.fov: invalid type: string \"wide\", expected f32",
            ),
            (
                "[camera]\nzoom = 2\n",
                "DIR/s.toml:2: camera.zoom: unknown field `zoom`, expected one of `width`, `height`, `fov`, `look_from`, `look_to`, `up`, `matrix`, `intrinsics`, `aperture_radius`, `focus_distance`",
            ),
            (
                "title = \"x\"\n",
                "DIR/s.toml:1: title: unknown field `title`, expected one of `camera`, `render`, `mesh`, `instance`, `instances`, `sphere`, `light`, `materials`, `environment`",
            ),
            (
                "[camera]\nlook_from = [1, 2]\n",
                "DIR/s.toml:2: camera.look_from: invalid length 2, expected an array of length 3",
            ),
            (
                "[camera]\nlook_to = [1, nan, 2]\n",
                "DIR/s.toml:2: camera.look_to: NaN is not a finite number",
            ),
            (
                "[camera]\nwidth = 1.5\n",
                "DIR/s.toml:2: camera.width: invalid type: floating point `1.5`, expected i64",
            ),
            (
                "[render]\nmode = \"fast\"\n",
                "DIR/s.toml:2: render.mode: unknown variant `fast`, expected one of `full`, `depth`, `normal`, `path`",
            ),
            (
                "[[sphere]]\ncenter = [0, 0, 0]\n",
                "DIR/s.toml:1: sphere: missing field `radius`",
            ),
            (
                "[[sphere]]\ncenter = [0, 0, 0]\nradius = -1\n",
                "DIR/s.toml:3: sphere.radius: -1 is negative",
            ),
            (
                "[[sphere]]\ncenter = [0, 0, 0]\nradius = inf\n",
                "DIR/s.toml:3: sphere.radius: inf is not a finite number",
            ),
            (
                "[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"gold\"\n",
                "DIR/s.toml:4: sphere.material: unknown material 'gold'",
            ),
            (
                "[[light]]\nposition = [0, 0, 0]\nintensity = \"bright\"\n",
                "DIR/s.toml:3: light.intensity: a number or an array of three numbers",
            ),
            (
                "[materials.m]\nKd = [1, 1]\n",
                "DIR/s.toml:2: materials.m.Kd: a number or an array of three numbers",
            ),
            (
                "[materials.m]\nTr = 0.5\n",
                "DIR/s.toml:2: materials.m.Tr: unknown field `Tr`, expected one of `Ka`, `Kd`, `Ks`, `Ke`, `Ns`, `Ni`, `d`, `al`, `base_color`, `metallic`, `roughness`, `ior`, `specular`, `specular_color`, `transmission`, `thickness`, `attenuation_color`, `attenuation_distance`, `clearcoat`, `clearcoat_roughness`, `sheen_color`, `sheen_roughness`, `multiple_scattering`, `anisotropy`, `anisotropy_rotation`, `emission`, `emission_strength`",
            ),
            (
                "[[mesh]]\nfile = \"tri.obj\"\nmaterial = \"gold\"\n",
                "DIR/s.toml:3: mesh.material: unknown material 'gold'",
            ),
            (
                "[[mesh]]\nfile = \"missing.obj\"\n",
                "DIR/s.toml:2: mesh.file: DIR/missing.obj: No such file or directory (os error 2)",
            ),
            (
                "[[mesh]]\nfile = \"bad.obj\"\n",
                "DIR/s.toml:2: mesh.file: DIR/bad.obj:1: invalid number 'x'",
            ),
            (
                "[[mesh]]\nfile = \"other.toml\"\n",
                "DIR/s.toml:2: mesh.file: 'other.toml' is a scene file, not a mesh (OBJ, PLY or glTF)",
            ),
            (
                "[[mesh]]\nmaterial = \"m\"\n",
                "DIR/s.toml:1: mesh: missing field `file`",
            ),
            (
                "[[mesh]]\nfile = \"tri.obj\"\ntransform = { scale = [1, 0, 1] }\n",
                "DIR/s.toml:3: mesh.transform.scale: scale components must not be zero",
            ),
            (
                "[[mesh]]\nfile = \"tri.obj\"\ntransform = { shear = 1 }\n",
                "DIR/s.toml:3: mesh.transform.shear: unknown field `shear`, expected one of `translate`, `rotate`, `scale`",
            ),
            ("[camera\n", "DIR/s.toml:1: unclosed table, expected `]`"),
            ("a = 1\na = 2\n", "DIR/s.toml:2: duplicate key"),
        ];
        for (text, expected) in cases {
            assert_eq!(folder.error(text), expected, "for {text:?}");
        }
        assert_eq!(
            parse_toml(b"a = 1\n\xff", &folder.path())
                .unwrap_err()
                .to_string()
                .replace(&folder.0.path().display().to_string(), "DIR"),
            "DIR/s.toml:2: invalid UTF-8"
        );
    }

    #[test]
    fn camera_and_render_values_are_checked_when_resolved_naming_file_line_and_key() {
        let folder = Folder::new();
        let cases = [
            (
                "[camera]\nwidth = -4\n",
                "DIR/s.toml:2: camera.width: -4 is not in 1..=65536",
            ),
            (
                "[camera]\nheight = 70000\n",
                "DIR/s.toml:2: camera.height: 70000 is not in 1..=65536",
            ),
            (
                "[camera]\nwidth = 60000\nheight = 60000\n",
                "DIR/s.toml:2: camera.width: 60000x60000 has more than 268435456 pixels (with DIR/s.toml:3: camera.height)",
            ),
            (
                "[camera]\nfov = 180\n",
                "DIR/s.toml:2: camera.fov: 180 is not strictly between 0 and 180",
            ),
            (
                "[camera]\n\nlook_from = [0, 0, -1]\n",
                "DIR/s.toml:3: camera.look_from: the camera cannot look at its own position",
            ),
            (
                "[camera]\nup = [0, 0, 0]\n",
                "DIR/s.toml:2: camera.up: components must be finite and not all zero",
            ),
            (
                "[render]\ndepth = 65\n",
                "DIR/s.toml:2: render.depth: 65 is not in 1..=64",
            ),
            (
                "[render]\nmode = \"depth\"\nspp = 0\n",
                "DIR/s.toml:3: render.spp: 0 is not in 1..=65536",
            ),
        ];
        for (text, expected) in cases {
            // The file reads: a flag could still replace the value.
            let loaded = folder.parse(text).unwrap();
            let message = loaded.options.resolve().unwrap_err().to_string();
            let message = message.replace(&folder.0.path().display().to_string(), "DIR");
            assert_eq!(message, expected, "for {text:?}");
        }
    }

    #[test]
    fn a_material_override_silences_the_mesh_reader_on_materials() {
        let folder = Folder::new();
        fs::write(
            folder.0.path().join("plain.obj"),
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl unknown\nf 1 2 3\n",
        )
        .unwrap();
        let without = folder.parse("[[mesh]]\nfile = \"plain.obj\"\n").unwrap();
        assert_eq!(without.description.warnings.len(), 1);
        let with = folder
            .parse("[materials.m]\n[[mesh]]\nfile = \"plain.obj\"\nmaterial = \"m\"\n")
            .unwrap();
        assert!(with.description.warnings.is_empty());
        assert_eq!(with.description.materials.len(), 1);
    }
}
