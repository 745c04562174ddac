//! Picking the reader for a scene file by its name.

use std::path::Path;

use super::error::SceneError;
use super::{SceneDescription, load_obj, load_ply, load_toml};
use crate::options::PartialOptions;

/// A loaded scene file: the scene, and the render settings the file gives (a TOML
/// file's `[camera]` and `[render]`; none for OBJ and PLY).
#[derive(Clone, Debug, Default)]
pub struct LoadedScene {
    /// The scene.
    pub description: SceneDescription,
    /// Settings from the file; command-line flags override them.
    pub options: PartialOptions,
}

/// The kinds of scene file, told apart by name.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SceneFormat {
    /// Wavefront OBJ (with MTL files beside it): any name not matched below.
    Obj,
    /// PLY: `.ply` or `.ply.gz`.
    Ply,
    /// A TOML scene description: `.toml`.
    Toml,
}

impl SceneFormat {
    /// The format of `path` by its extension, ignoring case and a final `.gz`.
    /// Anything unrecognised is OBJ, as it always was.
    pub fn of(path: &Path) -> SceneFormat {
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        let name = name.strip_suffix(".gz").unwrap_or(&name);
        if name.ends_with(".ply") {
            SceneFormat::Ply
        } else if name.ends_with(".toml") {
            SceneFormat::Toml
        } else {
            SceneFormat::Obj
        }
    }
}

/// Reads any scene file: OBJ, PLY or TOML, each possibly gzip-compressed.
///
/// # Errors
/// Whatever the format's reader reports, naming file and line.
pub fn load(path: &Path) -> Result<LoadedScene, SceneError> {
    match SceneFormat::of(path) {
        SceneFormat::Toml => load_toml(path),
        _ => load_mesh(path).map(|description| LoadedScene {
            description,
            options: PartialOptions::default(),
        }),
    }
}

/// Reads a mesh file: PLY by name, OBJ otherwise (a TOML name is read as OBJ too,
/// so callers that must refuse it check [`SceneFormat::of`] first).
///
/// # Errors
/// As [`load_obj`] and [`load_ply`].
pub fn load_mesh(path: &Path) -> Result<SceneDescription, SceneError> {
    match SceneFormat::of(path) {
        SceneFormat::Ply => load_ply(path),
        _ => load_obj(path),
    }
}
