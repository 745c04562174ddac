//! glTF extensions, one file each. A material extension is an [`Extension`]: its
//! name and what it does to a [`MaterialContext`] given its JSON object; adding one
//! is a new file here and one line in [`MATERIAL_EXTENSIONS`]. Extensions named in
//! a file's `extensionsUsed` that are in none of the lists (the others read, and
//! [`IGNORED_EXTENSIONS`]) get one warning each; those in `extensionsRequired` are
//! an error (see [`super::check_extensions`]).

pub(super) mod anisotropy;
pub(super) mod clearcoat;
pub(super) mod draco;
pub(super) mod emissive_strength;
pub(super) mod gpu_instancing;
pub(super) mod image_sources;
pub(super) mod ior;
pub(super) mod meshopt;
pub(super) mod pbr_specular_glossiness;
pub(super) mod sheen;
pub(super) mod specular;
pub(super) mod texture_transform;
pub(super) mod transmission;
pub(super) mod unlit;
pub(super) mod volume;

use gltf::json::Value;

use super::context::MaterialContext;

/// A material extension: applied, in the order of [`MATERIAL_EXTENSIONS`], to every
/// material whose `extensions` object names it.
pub(super) struct Extension {
    /// The extension's name, as in `extensionsUsed`.
    pub(super) name: &'static str,
    /// Reads the extension's object into the material.
    pub(super) apply: fn(&mut MaterialContext<'_, '_>, &Value),
}

/// The material extensions read, in the order they are applied: specular-glossiness
/// first, since it replaces the core model's base colour, metallic and roughness;
/// unlit last, since it drops what the others set but the base colour.
pub(super) const MATERIAL_EXTENSIONS: &[Extension] = &[
    pbr_specular_glossiness::EXTENSION,
    ior::EXTENSION,
    specular::EXTENSION,
    transmission::EXTENSION,
    volume::EXTENSION,
    clearcoat::EXTENSION,
    sheen::EXTENSION,
    anisotropy::EXTENSION,
    emissive_strength::EXTENSION,
    unlit::EXTENSION,
];

/// The other extensions read: lights and mesh instancing (by the scene walk), Draco
/// compressed primitives (by the mesh reader), meshopt compressed buffer views
/// (decoded as the buffers are read), quantized attributes (by the mesh reader),
/// texture transforms (on every texture reference), and WebP and KTX2 images (each
/// texture pointed at its extension's image before the document is validated).
pub(super) const OTHER_EXTENSIONS: &[&str] = &[
    "KHR_lights_punctual",
    draco::NAME,
    gpu_instancing::NAME,
    meshopt::NAME,
    meshopt::KHR_NAME,
    "KHR_mesh_quantization",
    texture_transform::NAME,
    image_sources::WEBP,
    image_sources::BASISU,
];

/// Extensions read and ignored, without a warning, because ignoring them renders the
/// file as it should look.
pub(super) const IGNORED_EXTENSIONS: &[&str] = &[
    // Alternative materials a viewer may switch to; a primitive's own `material`
    // is its default look, and is what the mesh reader reads.
    "KHR_materials_variants",
    // XMP metadata (authorship, licence) in JSON-LD: nothing to render.
    "KHR_xmp_json_ld",
];

/// Whether extension `name` is read (or ignored on purpose).
pub(super) fn supported(name: &str) -> bool {
    OTHER_EXTENSIONS.contains(&name)
        || IGNORED_EXTENSIONS.contains(&name)
        || MATERIAL_EXTENSIONS.iter().any(|e| e.name == name)
}
