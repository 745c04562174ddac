//! File formats: each reader turns a file into a [`SceneDescription`] (and, for TOML
//! scene files, the render settings the file gives). Nothing here knows of BVHs,
//! integrators or images.
//!
//! | format | module | reads |
//! |---|---|---|
//! | Wavefront OBJ + MTL | [`obj`](load_obj), `mtl` | `v vt vn f s`, `S` spheres, `P` lights, `mtllib`/`usemtl` |
//! | PLY (ascii, binary) | [`ply`](load_ply) | vertices, normals, faces |
//! | TOML scene file | [`toml`](load_toml) | camera, render settings, meshes placed by [`Transform`] |
//! | glTF 2.0 (`.gltf`, `.glb`) | [`gltf`](load_gltf) | meshes under node transforms, materials, textures, first camera, point lights |
//!
//! A new format gets a module here, a [`SceneFormat`] variant and an extension in
//! [`SceneFormat::of`]; it produces a [`SceneDescription`] and nothing else.

mod access;
mod compose;
mod decimal;
pub mod environment;
mod error;
mod file;
mod finite;
mod gain_map;
mod gltf;
mod lex;
mod material_check;
mod mtl;
mod npy;
mod obj;
mod ply;
mod polygon;
mod toml;

pub use access::FileAccess;
pub use compose::{Transform, affine_from_rows};
pub use error::{IndexKind, ParseErrorKind, SceneError};
pub use gltf::{load_gltf, load_gltf_with, parse_gltf, parse_gltf_with};
pub use mtl::{MaterialLibrary, parse_mtl, parse_mtl_with};
pub use obj::{load_obj, load_obj_with, parse_obj};
pub use ply::{load_ply, parse_ply};
pub use toml::{load_toml, load_toml_with, parse_toml};

pub(crate) use file::read_file;

use std::path::Path;

use crate::description::{SceneDescription, SphereDesc, TriangleDesc};
use crate::options::{OptionsError, PartialOptions, RenderOptions};

/// A loaded scene file: the scene, and the render settings the file gives (a TOML
/// file's `[camera]` and `[render]`; none for OBJ and PLY).
#[derive(Clone, Debug, Default)]
pub struct LoadedScene {
    /// The scene.
    pub description: SceneDescription,
    /// Settings from the file; command-line flags override them.
    pub options: PartialOptions,
}

impl LoadedScene {
    /// The scene and the options to render it with, as the command line takes them:
    /// each value from `flags` if set, else from the file, else the default; a camera
    /// that frames the whole scene when neither sets one
    /// ([`PartialOptions::framed`]); checked once; then the default lighting of a scene
    /// without lights ([`SceneDescription::add_default_light`]).
    ///
    /// # Errors
    /// The first option out of range, named by where it came from.
    pub fn resolve(
        self,
        flags: PartialOptions,
    ) -> Result<(SceneDescription, RenderOptions), OptionsError> {
        self.resolve_with(flags, false)
    }

    /// [`LoadedScene::resolve`] for a render asked for `extra_outputs` or not
    /// ([`PartialOptions::resolve_for`]).
    ///
    /// # Errors
    /// As [`LoadedScene::resolve`].
    pub fn resolve_with(
        self,
        flags: PartialOptions,
        extra_outputs: bool,
    ) -> Result<(SceneDescription, RenderOptions), OptionsError> {
        // What turned the default light off, if anything did: the flag, else the file.
        let off_by = flags
            .default_light
            .as_ref()
            .or(self.options.default_light.as_ref())
            .filter(|on| !on.value)
            .map(|off| off.origin.clone());
        let unlit = self.description.is_unlit();
        let options = resolve_options(flags, self.options, (unlit, extra_outputs), || {
            (self.description.bounds(), self.description.extent())
        })?;
        let mut description = self.description;
        description.add_default_light_off_by(&options, off_by.as_ref());
        Ok((description, options))
    }
}

/// The options of [`LoadedScene::resolve`] alone, for callers that keep a built scene
/// (the Python bindings): `flags` over `file`, the camera framing the scene's
/// bounds and extent ([`crate::description::SceneDescription::extent`]) when neither
/// sets one, checked once; in full mode a scene that is `unlit` (and so lit by the
/// default rig) takes [`crate::options::RIG_SAMPLES_PER_PIXEL`] samples per pixel
/// unless they are set or the render is asked for extra outputs
/// ([`PartialOptions::resolve_for`]).
///
/// # Errors
/// The first option out of range, named by where it came from.
pub fn resolve_options<E>(
    flags: PartialOptions,
    file: PartialOptions,
    (unlit, extra_outputs): (bool, bool),
    extent: impl FnOnce() -> (crate::math::Aabb, E),
) -> Result<RenderOptions, OptionsError>
where
    E: std::borrow::Borrow<crate::description::Extent>,
{
    let mut options = flags.or(file);
    // The bounds and extent cost passes over the triangles: only when they are
    // needed (no target: a lone position looks at the scene's centre).
    if options.look_to.is_none() {
        let (bounds, extent) = extent();
        let extent = extent.borrow();
        options = options.framed_facing(bounds, |w| extent.support(w), extent.flat_normal());
    }
    options.resolve_for(unlit, extra_outputs)
}

/// Asks `access` whether the scene file `path` may be read: an I/O error naming it if
/// not.
fn admit(path: &Path, access: &FileAccess) -> Result<(), SceneError> {
    access.admit(path).map_err(|error| SceneError::Io {
        path: path.to_path_buf(),
        error,
    })
}

/// The kinds of scene file, told apart by name.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SceneFormat {
    /// Wavefront OBJ, with MTL files beside it: `.obj`.
    Obj,
    /// PLY: `.ply`.
    Ply,
    /// A TOML scene description: `.toml`.
    Toml,
    /// glTF 2.0: `.gltf` (JSON, with `.bin` files or data URIs) or `.glb` (binary).
    Gltf,
}

/// The extensions [`SceneFormat::of`] knows, for messages.
pub const SUPPORTED_EXTENSIONS: &str = ".obj, .ply, .toml, .gltf, .glb";

impl SceneFormat {
    /// The format of `path` by its extension, in any letter case, after an optional
    /// final `.gz`; `None` for any other name.
    pub fn of(path: &Path) -> Option<SceneFormat> {
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        let name = name.strip_suffix(".gz").unwrap_or(&name);
        let (_, extension) = name.rsplit_once('.')?;
        match extension {
            "obj" => Some(SceneFormat::Obj),
            "ply" => Some(SceneFormat::Ply),
            "toml" => Some(SceneFormat::Toml),
            "gltf" | "glb" => Some(SceneFormat::Gltf),
            _ => None,
        }
    }

    /// [`SceneFormat::of`], or the error that names `path` and the supported formats.
    ///
    /// # Errors
    /// The name has none of the supported extensions: an I/O error saying "is a
    /// directory" for a folder, else [`SceneError::UnknownFormat`].
    pub fn require(path: &Path) -> Result<SceneFormat, SceneError> {
        SceneFormat::of(path).ok_or_else(|| {
            // `render examples/` is a slip for a file inside: saying what the path is
            // helps more than listing the extensions (a folder named `x.obj` gets the
            // same message from the reader).
            if path.is_dir() {
                SceneError::Io {
                    path: path.to_path_buf(),
                    error: std::io::Error::new(std::io::ErrorKind::IsADirectory, "is a directory"),
                }
            } else {
                SceneError::UnknownFormat {
                    path: path.to_path_buf(),
                }
            }
        })
    }
}

/// Reads any scene file: OBJ, PLY, TOML or glTF, each possibly gzip-compressed.
///
/// # Errors
/// The name has no supported extension, or the format's reader reports an error,
/// naming file and line.
pub fn load(path: &Path) -> Result<LoadedScene, SceneError> {
    load_with(path, &FileAccess::anywhere())
}

/// [`load`], opening the scene file and every file it names through `access`: a
/// shipped scene is read with [`FileAccess::confined_to`] its folder, and
/// [`FileAccess::asked`] lists the files a scene reads.
///
/// # Errors
/// As [`load`]; a file `access` refuses is an error as an unreadable one is (a
/// warning for a texture).
pub fn load_with(path: &Path, access: &FileAccess) -> Result<LoadedScene, SceneError> {
    match SceneFormat::require(path)? {
        SceneFormat::Toml => load_toml_with(path, access),
        SceneFormat::Gltf => load_gltf_with(path, access),
        _ => load_mesh_with(path, access).map(|description| LoadedScene {
            description,
            options: PartialOptions::default(),
        }),
    }
}

/// Reads a mesh file: OBJ, PLY or glTF (its meshes, materials and lights; a glTF
/// camera is ignored here). A TOML scene file is no mesh: an error.
///
/// # Errors
/// As [`load_obj`], [`load_ply`] and [`load_gltf`]; the name is none of theirs.
pub fn load_mesh(path: &Path) -> Result<SceneDescription, SceneError> {
    load_mesh_with(path, &FileAccess::anywhere())
}

/// [`load_mesh`] through `access`, as [`load_with`].
///
/// # Errors
/// As [`load_mesh`] and [`load_with`].
pub fn load_mesh_with(path: &Path, access: &FileAccess) -> Result<SceneDescription, SceneError> {
    let mut description = read_mesh_with(path, access)?;
    // A file whose reader named no objects is one object, named after the file.
    if description.objects.is_empty() {
        let name = path
            .file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        description.objects.push(crate::description::ObjectDesc {
            name,
            first_triangle: 0,
            first_sphere: 0,
        });
    }
    Ok(description)
}

/// [`load_mesh_with`] but for the objects.
fn read_mesh_with(path: &Path, access: &FileAccess) -> Result<SceneDescription, SceneError> {
    match SceneFormat::require(path)? {
        SceneFormat::Obj => load_obj_with(path, access),
        SceneFormat::Ply => {
            admit(path, access)?;
            load_ply(path)
        }
        SceneFormat::Gltf => load_gltf_with(path, access).map(|loaded| loaded.description),
        SceneFormat::Toml => Err(SceneError::UnknownFormat {
            path: path.to_path_buf(),
        }),
    }
}
