//! The MTL reader: `newmtl`, `Ka`, `Kd`, `Ks`, `Ke`, `Ns`, `Ni`, `d`, `Tr`, `al`, and
//! the texture maps `map_Ka`, `map_Kd`, `map_Ks`, `map_Ke`, `map_Ns`, `map_d`,
//! `bump`/`map_Bump` and `norm` with their options; and the PBR statements Blender's
//! OBJ exporter writes (as tinyobjloader reads them): `Pr`, `Pm`, `Ps`, `Pc`, `Pcr`,
//! `aniso`, `anisor`, `Tf`, `map_Pr`, `map_Pm`, `map_Ps`. A material with any of
//! `Pr`, `Pm`, `Ps`, `Pc`, `Pcr`, `map_Pr`, `map_Pm`, `map_Ps` becomes a
//! [`Material::physically_based`] (see [`physically_based`] and
//! `docs/scene-format.md`); any other stays SPEC's Phong material.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use rayon::prelude::*;

use super::error::{ParseErrorKind, SceneError};
use super::material_check::{MaterialProblems, check_pbr};
use super::{FileAccess, lex};
use crate::material::pbr::PbrMaterial;
use crate::material::{Cutout, Material, MaterialMaps};
use crate::math::{Float, Vec2, Vec3};
use crate::textures::{Channel, Texture, TextureMap, TextureOptions, Wrap, load_texture};

/// The materials of an MTL file, and what was wrong with it but not fatal.
#[derive(Clone, Debug, Default)]
pub struct MaterialLibrary {
    /// The materials, in file order, with their texture maps loaded.
    pub materials: Vec<Material>,
    /// Warnings, each naming the file and line: textures that cannot be read, map
    /// statements the renderer does not apply.
    pub warnings: Vec<String>,
}

/// Which slot of [`MaterialMaps`] a map statement fills.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum MapKind {
    Ambient,
    Diffuse,
    Specular,
    Emission,
    Shininess,
    Alpha,
    Bump,
    Normal,
    /// `map_Pr`.
    Roughness,
    /// `map_Pm`.
    Metallic,
    /// `map_Ps`.
    Sheen,
}

impl MapKind {
    /// The kind of a map statement's keyword, in any letter case (exporters write
    /// `map_Bump`, `map_bump` and `bump` alike).
    fn of(keyword: &[u8]) -> Option<MapKind> {
        let keyword = keyword.to_ascii_lowercase();
        Some(match keyword.as_slice() {
            b"map_ka" => MapKind::Ambient,
            b"map_kd" => MapKind::Diffuse,
            b"map_ks" => MapKind::Specular,
            b"map_ke" => MapKind::Emission,
            b"map_ns" => MapKind::Shininess,
            b"map_d" => MapKind::Alpha,
            b"bump" | b"map_bump" => MapKind::Bump,
            b"norm" | b"map_kn" => MapKind::Normal,
            b"map_pr" => MapKind::Roughness,
            b"map_pm" => MapKind::Metallic,
            b"map_ps" => MapKind::Sheen,
            _ => return None,
        })
    }
}

/// The statements of one material that matter to its physically based form: the
/// PBR statements, and which classic ones were given.
#[derive(Clone, Debug, Default)]
struct PbrStatements {
    roughness: Option<Float>,
    metallic: Option<Float>,
    sheen: Option<Float>,
    clearcoat: Option<Float>,
    clearcoat_roughness: Option<Float>,
    /// `aniso`: the anisotropy strength; `anisor`: its rotation in turns (1 a full
    /// circle, as Blender's Principled BSDF's "Anisotropic Rotation").
    anisotropy: Option<Float>,
    anisotropy_rotation: Option<Float>,
    /// `Tf`: Blender writes its transmission there (grey).
    transmission: Option<Vec3>,
    /// `map_Pr`, `map_Pm`, `map_Ps`.
    roughness_map: bool,
    metallic_map: bool,
    sheen_map: bool,
    /// Whether `Kd`, `Ks`, `Ns` and `Ni` were given.
    diffuse: bool,
    specular: bool,
    shininess: bool,
    ior: bool,
}

impl PbrStatements {
    /// Whether the material is physically based: any of the PBR statements.
    fn any(&self) -> bool {
        self.roughness.is_some()
            || self.metallic.is_some()
            || self.sheen.is_some()
            || self.clearcoat.is_some()
            || self.clearcoat_roughness.is_some()
            || self.roughness_map
            || self.metallic_map
            || self.sheen_map
    }
}

/// A map statement as read, before its image is loaded.
struct PendingMap {
    material: usize,
    kind: MapKind,
    options: TextureOptions,
    file: String,
    line: usize,
}

/// Parses an MTL file's text and loads the textures it names (relative to its
/// folder, each file once); `path` names it in errors and warnings. Materials keep
/// file order.
///
/// # Errors
/// A malformed supported line, with its line number. A texture that cannot be read
/// is a warning, and the material renders without it; so is an `Ns` below 0, read as 0.
pub fn parse_mtl(text: &[u8], path: &Path) -> Result<MaterialLibrary, SceneError> {
    parse_mtl_with(text, path, &FileAccess::anywhere())
}

/// [`parse_mtl`], opening textures through `access`: one it refuses is a warning of
/// the line naming it, as a missing one is.
///
/// # Errors
/// As [`parse_mtl`].
pub fn parse_mtl_with(
    text: &[u8],
    path: &Path,
    access: &FileAccess,
) -> Result<MaterialLibrary, SceneError> {
    let at = |line, kind| SceneError::Parse {
        path: path.to_path_buf(),
        line,
        kind,
    };
    lex::check_text(text).map_err(|(line, kind)| at(line, kind))?;
    let mut materials: Vec<Material> = Vec::new();
    let mut statements: Vec<PbrStatements> = Vec::new();
    let mut maps = Vec::new();
    let mut warnings = Vec::new();
    // The first line with a negative `Ns`, and how many there are: one warning.
    let mut negative_ns: Option<(usize, usize)> = None;
    for (line_number, line) in lex::lines(text) {
        let mut read = Read {
            materials: &mut materials,
            statements: &mut statements,
            maps: &mut maps,
            warnings: &mut warnings,
        };
        let clamped =
            parse_line(line, line_number, &mut read).map_err(|kind| at(line_number, kind))?;
        if clamped {
            let (_, count) = negative_ns.get_or_insert((line_number, 0));
            *count += 1;
        }
    }
    if let Some((line, count)) = negative_ns {
        let plural = if count == 1 { "" } else { "s" };
        warnings.push((
            line,
            format!("'Ns' below 0 read as 0 ({count} line{plural})"),
        ));
    }
    // A `map_Kd` with no `Kd` is the surface's colour as it is, as three.js's
    // MTLLoader and Blender's importer show it (Blender 4 writes no `Kd` for a base
    // colour taken from a texture), not the texture times the default black.
    for map in &maps {
        if map.kind == MapKind::Diffuse && !statements[map.material].diffuse {
            materials[map.material].diffuse = Vec3::ONE;
        }
    }
    let mut library = MaterialLibrary {
        materials,
        warnings: warnings
            .into_iter()
            .map(|(line, message)| format!("{}:{line}: {message}", path.display()))
            .collect(),
    };
    load_maps(maps, path, access, &mut library);
    let mut problems = MaterialProblems::default();
    for (material, statements) in library.materials.iter_mut().zip(&statements) {
        if statements.any() {
            physically_based(material, statements, &mut problems);
        }
    }
    library.warnings.extend(
        problems
            .messages()
            .into_iter()
            .map(|message| format!("{}: {message}", path.display())),
    );
    Ok(library)
}

/// What one line adds to: the materials so far, their PBR statements, the map
/// statements and the warnings.
struct Read<'a> {
    materials: &'a mut Vec<Material>,
    statements: &'a mut Vec<PbrStatements>,
    maps: &'a mut Vec<PendingMap>,
    warnings: &'a mut Vec<(usize, String)>,
}

/// Turns `material`, read with `statements`, into its physically based form, as
/// Blender's OBJ importer reads its exporter's statements:
///
/// - base colour `Kd` (`map_Kd` its map, sRGB), metallic `Pm` (0 if absent; 1 times
///   `map_Pm` if only the map is given, as Blender then writes no `Pm`), roughness
///   `Pr` (likewise with `map_Pr`; without either, from `Ns` by the inverse of
///   Blender's `Ns = 1000 (1 - roughness)^2`);
/// - `ior` from `Ni` (1.5 if absent); `specular` twice the mean of `Ks` (Blender
///   writes its Specular, 0.5 for glTF's 4% at ior 1.5), at most 1, and `map_Ks`
///   likewise twice; transmission the mean of `Tf` (Blender writes its transmission
///   there, and only for PBR materials);
/// - sheen colour `Ps` grey (`map_Ps` its map) at roughness 0.5 (Blender's default),
///   clearcoat `Pc`, clearcoat roughness `Pcr`; anisotropy `aniso`
///   (`KHR_materials_anisotropy`'s strength) turned by `anisor` turns (`2 pi
///   anisor` radians, Blender's "Anisotropic Rotation");
/// - emission `Ke` (which may exceed 1), `map_Ke`; `map_d` stays the cutout, and
///   `bump`/`norm` the shading normal (`-bm` scaling a normal map's tilt, as
///   Blender's normal map strength).
///
/// `Ka` is no ambient colour here (Blender writes the metallic value there): the
/// ambient term is 0, and `map_Ka` and `map_Ns` are dropped.
fn physically_based(
    material: &mut Material,
    statements: &PbrStatements,
    problems: &mut MaterialProblems,
) {
    let mut maps = material.maps.take().map(|maps| *maps).unwrap_or_default();
    maps.pbr.base_color = maps.diffuse.take();
    maps.ambient = None;
    maps.shininess = None;
    maps.pbr.specular = maps.specular.take().map(|mut map| {
        map.options.gain *= 2.0;
        map.options.base *= 2.0;
        map
    });
    let mean = |v: Vec3| (v.x + v.y + v.z) / 3.0;
    // A map alone means the factor 1; neither, the default.
    let factor = |value: Option<Float>, map: bool, default: Float| {
        value.unwrap_or(if map { 1.0 } else { default })
    };
    let roughness = match statements.roughness {
        Some(r) => r,
        None if statements.roughness_map => 1.0,
        None if statements.shininess => {
            1.0 - (material.shininess.clamp(0.0, 1000.0) / 1000.0).sqrt()
        }
        None => 1.0,
    };
    let sheen = factor(statements.sheen, statements.sheen_map, 0.0);
    let mut pbr = PbrMaterial {
        base_color: material.diffuse,
        metallic: factor(statements.metallic, statements.metallic_map, 0.0),
        roughness,
        ior: if statements.ior { material.ior } else { 1.5 },
        specular: if statements.specular {
            (2.0 * mean(material.specular)).min(1.0)
        } else {
            1.0
        },
        transmission: statements.transmission.map_or(0.0, mean),
        clearcoat: statements.clearcoat.unwrap_or(0.0),
        clearcoat_roughness: statements.clearcoat_roughness.unwrap_or(0.0),
        sheen_color: Vec3::splat(sheen),
        sheen_roughness: 0.5,
        anisotropy: statements.anisotropy.unwrap_or(0.0),
        anisotropy_rotation: statements
            .anisotropy_rotation
            .map_or(0.0, |turns| turns * std::f32::consts::TAU),
        ..PbrMaterial::default()
    };
    let defaults = PbrMaterial {
        metallic: 0.0,
        ..PbrMaterial::default()
    };
    check_pbr(&mut pbr, &defaults, &material.name, problems);
    let name = std::mem::take(&mut material.name);
    let emission = material.emission;
    let (opacity, albedo) = (material.opacity, material.albedo);
    *material = Material::physically_based(
        name,
        pbr,
        emission,
        (!maps.is_empty()).then(|| Box::new(maps)),
    );
    material.opacity = opacity;
    material.albedo = albedo;
}

/// Loads the images of `maps` (in parallel, each file once) and gives them to their
/// materials; a file that cannot be loaded is a warning at each line that names it.
fn load_maps(
    maps: Vec<PendingMap>,
    mtl_path: &Path,
    access: &FileAccess,
    library: &mut MaterialLibrary,
) {
    if maps.is_empty() {
        return;
    }
    let folder = mtl_path.parent().unwrap_or(Path::new(""));
    let mut files: Vec<&str> = maps.iter().map(|m| m.file.as_str()).collect();
    files.sort_unstable();
    files.dedup();
    let loaded: HashMap<&str, Result<Arc<Texture>, String>> = files
        .into_par_iter()
        .map(|file| (file, load_named(folder, file, access)))
        .collect();
    for map in &maps {
        let texture = match &loaded[map.file.as_str()] {
            Ok(texture) => texture.clone(),
            Err(reason) => {
                library.warnings.push(format!(
                    "{}:{}: cannot read texture '{}': {reason}; the surface renders without it",
                    mtl_path.display(),
                    map.line,
                    map.file
                ));
                continue;
            }
        };
        // A `bump` image that is a normal map is used as one.
        let kind = match map.kind {
            MapKind::Bump if texture.looks_like_normal_map() => MapKind::Normal,
            kind => kind,
        };
        let texture_map = TextureMap {
            texture,
            options: map.options,
        };
        let maps = library.materials[map.material]
            .maps
            .get_or_insert_with(|| Box::new(MaterialMaps::default()));
        let slot = match kind {
            MapKind::Ambient => &mut maps.ambient,
            MapKind::Diffuse => &mut maps.diffuse,
            MapKind::Specular => &mut maps.specular,
            MapKind::Emission => &mut maps.emission,
            MapKind::Shininess => &mut maps.shininess,
            MapKind::Bump => &mut maps.bump,
            MapKind::Normal => &mut maps.normal,
            MapKind::Roughness => &mut maps.pbr.roughness,
            MapKind::Metallic => &mut maps.pbr.metallic,
            MapKind::Sheen => &mut maps.pbr.sheen_color,
            MapKind::Alpha => {
                maps.cutout = Some(Cutout {
                    map: Some(texture_map),
                    factor: 1.0,
                    cutoff: 0.5,
                    blend: false,
                });
                continue;
            }
        };
        *slot = Some(texture_map);
    }
}

/// Loads texture `file` named in an MTL file in `folder`. Exporters write Windows
/// paths and absolute paths of the machine the model was made on: when the file is
/// not where it says, it is looked for with `\` read as `/`, then by its bare name
/// beside the MTL file.
fn load_named(folder: &Path, file: &str, access: &FileAccess) -> Result<Arc<Texture>, String> {
    let open = |path: &Path| {
        access.admit(path).map_err(|e| e.to_string())?;
        load_texture(path)
    };
    let first = open(&folder.join(file));
    if first.is_ok() {
        return first;
    }
    let slashed = file.replace('\\', "/");
    let mut candidates: Vec<PathBuf> = Vec::new();
    if slashed != file {
        candidates.push(folder.join(&slashed));
    }
    if let Some(name) = Path::new(&slashed).file_name()
        && Path::new(name) != Path::new(&slashed)
    {
        candidates.push(folder.join(name));
    }
    candidates
        .iter()
        .find(|candidate| access.admit(candidate).is_ok() && candidate.is_file())
        .map_or(first, |candidate| open(candidate))
}

fn parse_line(
    line: &[u8],
    line_number: usize,
    read: &mut Read<'_>,
) -> Result<bool, ParseErrorKind> {
    let Read {
        materials,
        statements,
        maps,
        warnings,
    } = read;
    let mut tokens = lex::tokens(line);
    let Some(keyword) = tokens.next() else {
        return Ok(false);
    };
    if let Some(kind) = MapKind::of(keyword) {
        let material = materials
            .len()
            .checked_sub(1)
            .ok_or_else(|| ParseErrorKind::PropertyBeforeNewmtl(lex::show(keyword)))?;
        let (options, file) = parse_map(line, keyword, tokens, warnings, line_number)?;
        let pbr = &mut statements[material];
        match kind {
            MapKind::Roughness => pbr.roughness_map = true,
            MapKind::Metallic => pbr.metallic_map = true,
            MapKind::Sheen => pbr.sheen_map = true,
            _ => {}
        }
        maps.push(PendingMap {
            material,
            kind,
            options,
            file,
            line: line_number,
        });
        return Ok(false);
    }
    if keyword == b"newmtl" {
        // Blender writes `newmtl` with no name for a material it has none for (and
        // `usemtl` with none to use it): the empty name is a name.
        let name = lex::rest_of_line(line, b"newmtl");
        materials.push(Material::named(String::from_utf8_lossy(name)));
        statements.push(PbrStatements::default());
        return Ok(false);
    }
    let known = matches!(
        keyword,
        b"Ka"
            | b"Kd"
            | b"Ks"
            | b"Ke"
            | b"Ns"
            | b"Ni"
            | b"d"
            | b"Tr"
            | b"al"
            | b"Tf"
            | b"Pr"
            | b"Pm"
            | b"Ps"
            | b"Pc"
            | b"Pcr"
            | b"aniso"
            | b"anisor"
    );
    if !known {
        return Ok(false);
    }
    // `Ka spectral file.rfl` and `Ka xyz x y z` are other colour spaces we do not model.
    let mut peek = tokens.clone();
    if matches!(peek.next(), Some(b"spectral" | b"xyz")) {
        return Ok(false);
    }
    let material = materials
        .last_mut()
        .ok_or_else(|| ParseErrorKind::PropertyBeforeNewmtl(lex::show(keyword)))?;
    let pbr = statements.last_mut().expect("one per material");
    let mut one = |name: &'static str| lex::floats::<1>(name, &mut tokens).map(|[v]| Some(v));
    match keyword {
        b"Pr" => pbr.roughness = one("Pr")?,
        b"Pm" => pbr.metallic = one("Pm")?,
        b"Ps" => pbr.sheen = one("Ps")?,
        b"Pc" => pbr.clearcoat = one("Pc")?,
        b"Pcr" => pbr.clearcoat_roughness = one("Pcr")?,
        b"aniso" => pbr.anisotropy = one("aniso")?,
        b"anisor" => pbr.anisotropy_rotation = one("anisor")?,
        _ => {}
    }
    match keyword {
        b"Ka" => material.ambient = colour("Ka", &mut tokens)?,
        b"Kd" => {
            material.diffuse = colour("Kd", &mut tokens)?;
            pbr.diffuse = true;
        }
        b"Ks" => {
            material.specular = colour("Ks", &mut tokens)?;
            pbr.specular = true;
        }
        b"Ke" => material.emission = colour("Ke", &mut tokens)?,
        b"Tf" => pbr.transmission = Some(colour("Tf", &mut tokens)?),
        b"Ns" => {
            // Some exporters write a negative exponent; other readers clamp it to 0
            // (a negative one would make highlights infinite where they should fade).
            let ns = lex::floats::<1>("Ns", &mut tokens)?[0];
            material.shininess = ns.max(0.0);
            pbr.shininess = true;
            return Ok(ns < 0.0);
        }
        b"Ni" => {
            material.ior = lex::floats::<1>("Ni", &mut tokens)?[0];
            pbr.ior = true;
        }
        b"d" => material.opacity = lex::floats::<1>("d", &mut tokens)?[0],
        b"Tr" => material.opacity = 1.0 - lex::floats::<1>("Tr", &mut tokens)?[0],
        b"al" => material.albedo = colour("al", &mut tokens)?.into(),
        _ => {}
    }
    Ok(false)
}

/// The options and the file name of a map statement (`tokens` follow the keyword).
/// The file name is the rest of the line after the options, inner spaces kept.
fn parse_map(
    line: &[u8],
    keyword: &[u8],
    mut tokens: lex::Tokens<'_>,
    warnings: &mut Vec<(usize, String)>,
    line_number: usize,
) -> Result<(TextureOptions, String), ParseErrorKind> {
    let mut options = TextureOptions::default();
    let statement = map_statement(keyword);
    loop {
        let Some(token) = tokens.next() else {
            return Err(ParseErrorKind::MissingName(statement));
        };
        let Some(option) = token
            .strip_prefix(b"-")
            .filter(|o| o.first().is_some_and(u8::is_ascii_alphabetic))
        else {
            // The file name: from this token to the end of the line.
            let start = token.as_ptr() as usize - line.as_ptr() as usize;
            let name = line[start..].trim_ascii();
            let name = strip_quotes(name);
            return Ok((options, String::from_utf8_lossy(name).into_owned()));
        };
        match option {
            b"o" | b"s" | b"t" => {
                let values = up_to_three(&mut tokens, option)?;
                match option {
                    b"o" => options.offset = Vec2::new(values[0], values[1]),
                    b"s" => options.scale = Vec2::new(values[0], values[1]),
                    _ => {}
                }
            }
            b"mm" => {
                let [base, gain] = lex::floats::<2>("-mm", &mut tokens)?;
                (options.base, options.gain) = (base, gain);
            }
            b"bm" => options.bump_multiplier = lex::floats::<1>("-bm", &mut tokens)?[0],
            b"boost" => {
                lex::floats::<1>("-boost", &mut tokens)?;
            }
            b"texres" => {
                lex::floats::<1>("-texres", &mut tokens)?;
            }
            b"clamp" => {
                let wrap = if on_off("-clamp", tokens.next())? {
                    Wrap::Clamp
                } else {
                    Wrap::Repeat
                };
                (options.wrap_u, options.wrap_v) = (wrap, wrap);
            }
            b"blendu" | b"blendv" | b"cc" => {
                on_off(option_name(option), tokens.next())?;
            }
            b"imfchan" => {
                options.channel = match tokens.next() {
                    Some(b"r") => Channel::Red,
                    Some(b"g") => Channel::Green,
                    Some(b"b") => Channel::Blue,
                    Some(b"m") => Channel::Alpha,
                    Some(b"l" | b"z") => Channel::Luminance,
                    Some(other) => {
                        return Err(ParseErrorKind::BadOption {
                            option: "-imfchan",
                            value: lex::show(other),
                            expected: "r, g, b, m, l or z",
                        });
                    }
                    None => {
                        return Err(ParseErrorKind::TooFewValues {
                            statement: "-imfchan",
                            expected: 1,
                            found: 0,
                        });
                    }
                }
            }
            b"type" => {
                if tokens.next().is_none() {
                    return Err(ParseErrorKind::TooFewValues {
                        statement: "-type",
                        expected: 1,
                        found: 0,
                    });
                }
            }
            other => warnings.push((
                line_number,
                format!(
                    "unknown option '-{}' of '{statement}' ignored",
                    lex::show(other)
                ),
            )),
        }
    }
}

/// The statement's name for messages.
fn map_statement(keyword: &[u8]) -> &'static str {
    match keyword.to_ascii_lowercase().as_slice() {
        b"map_ka" => "map_Ka",
        b"map_kd" => "map_Kd",
        b"map_ks" => "map_Ks",
        b"map_ke" => "map_Ke",
        b"map_ns" => "map_Ns",
        b"map_d" => "map_d",
        b"bump" => "bump",
        b"map_bump" => "map_Bump",
        b"map_pr" => "map_Pr",
        b"map_pm" => "map_Pm",
        b"map_ps" => "map_Ps",
        _ => "norm",
    }
}

fn option_name(option: &[u8]) -> &'static str {
    match option {
        b"blendu" => "-blendu",
        b"blendv" => "-blendv",
        _ => "-cc",
    }
}

/// `on` or `off`.
fn on_off(option: &'static str, token: Option<&[u8]>) -> Result<bool, ParseErrorKind> {
    match token {
        Some(b"on") => Ok(true),
        Some(b"off") => Ok(false),
        Some(other) => Err(ParseErrorKind::BadOption {
            option,
            value: lex::show(other),
            expected: "on or off",
        }),
        None => Err(ParseErrorKind::TooFewValues {
            statement: option,
            expected: 1,
            found: 0,
        }),
    }
}

/// One to three numbers: `-o`, `-s` and `-t` take `u [v [w]]`, and a missing `v` or
/// `w` keeps the option's default (0 for offsets and turbulence, 1 for scales).
fn up_to_three(tokens: &mut lex::Tokens<'_>, option: &[u8]) -> Result<[Float; 3], ParseErrorKind> {
    let name = match option {
        b"o" => "-o",
        b"s" => "-s",
        _ => "-t",
    };
    let default = if option == b"s" { 1.0 } else { 0.0 };
    let mut values = [default; 3];
    values[0] = lex::floats::<1>(name, tokens)?[0];
    for value in &mut values[1..] {
        let mut peek = tokens.clone();
        match peek.next().map(lex::float) {
            Some(Ok(v)) => {
                *value = v;
                *tokens = peek;
            }
            _ => break,
        }
    }
    Ok(values)
}

/// A file name without the double quotes some exporters put around names with
/// spaces.
fn strip_quotes(name: &[u8]) -> &[u8] {
    match name {
        [b'"', inner @ .., b'"'] => inner,
        _ => name,
    }
}

/// An RGB triple; a single value means grey.
fn colour<'a>(
    statement: &'static str,
    tokens: &mut (impl Iterator<Item = &'a [u8]> + Clone),
) -> Result<Vec3, ParseErrorKind> {
    if tokens.clone().take(3).count() == 1 {
        let grey: Float = lex::floats::<1>(statement, tokens)?[0];
        return Ok(Vec3::splat(grey));
    }
    lex::vec3(statement, tokens)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Vec<Material>, SceneError> {
        parse_mtl(text.as_bytes(), Path::new("test.mtl")).map(|library| library.materials)
    }

    #[test]
    fn a_diffuse_map_without_kd_is_the_colour_as_it_is() {
        // Blender 4's exporter writes `map_Kd` and no `Kd` for a base colour taken
        // from a texture: the texture times 1, not times the default black. A `Kd`
        // given, black too, stays.
        let m = parse(
            "newmtl a\nKa 1 1 1\nmap_Kd box.png\nnewmtl b\nKd 0.5 0.5 0.5\nmap_Kd box.png\n\
             newmtl c\nKd 0 0 0\nmap_Kd box.png\nnewmtl d\n",
        )
        .unwrap();
        let diffuse: Vec<Vec3> = m.iter().map(|m| m.diffuse).collect();
        assert_eq!(
            diffuse,
            [Vec3::ONE, Vec3::splat(0.5), Vec3::ZERO, Vec3::ZERO]
        );
    }

    #[test]
    fn reads_every_field_and_defaults() {
        let m = parse(
            "newmtl a\n Ka 0.1 0.2 0.3\n\tKd 0.5\nKs 1 1 1\nKe 0 0 2\nNs 64\nNi 1.5\nd 0.25\nal 0.1 0.2 0.7\nnewmtl b b\nTr 0.75\nillum 2\n",
        )
        .unwrap();
        assert_eq!(m.len(), 2);
        assert_eq!(m[0].ambient, Vec3::new(0.1, 0.2, 0.3));
        assert_eq!(m[0].diffuse, Vec3::splat(0.5));
        assert_eq!(m[0].specular, Vec3::ONE);
        assert_eq!(m[0].emission, Vec3::new(0.0, 0.0, 2.0));
        assert_eq!((m[0].shininess, m[0].ior, m[0].opacity), (64.0, 1.5, 0.25));
        assert_eq!(m[0].albedo, [0.1, 0.2, 0.7]);
        assert_eq!(m[1].name, "b b");
        assert_eq!(m[1].opacity, 0.25);
        assert_eq!(m[1].albedo, [1.0, 0.0, 0.0]);
    }

    #[test]
    fn errors_name_file_and_line() {
        let err = parse("newmtl a\nKd 0.5 x 0.5\n").unwrap_err();
        assert_eq!(err.to_string(), "test.mtl:2: invalid number 'x'");
        let err = parse("Kd 1 1 1\n").unwrap_err();
        assert_eq!(err.to_string(), "test.mtl:1: 'Kd' before any 'newmtl'");
        let err = parse("newmtl a\nKs 1 1\n").unwrap_err();
        assert_eq!(err.to_string(), "test.mtl:2: 'Ks' needs 3 values, found 2");
        let err = parse("newmtl a\nNs\n").unwrap_err();
        assert_eq!(err.to_string(), "test.mtl:2: 'Ns' needs 1 value, found 0");
    }

    #[test]
    fn a_negative_ns_is_read_as_zero_with_one_warning() {
        let text = "newmtl a\nNs -5\nnewmtl b\nNs 10\nnewmtl c\nNs -0.5\n";
        let library = parse_mtl(text.as_bytes(), Path::new("t.mtl")).unwrap();
        assert_eq!(
            library
                .materials
                .iter()
                .map(|m| m.shininess)
                .collect::<Vec<_>>(),
            [0.0, 10.0, 0.0]
        );
        assert_eq!(
            library.warnings,
            ["t.mtl:2: 'Ns' below 0 read as 0 (2 lines)"]
        );
        let library = parse_mtl(b"newmtl a\nNs 0\n", Path::new("t.mtl")).unwrap();
        assert!(library.warnings.is_empty());
    }
}
