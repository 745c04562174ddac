//! `KHR_materials_ior`: the dielectric's index of refraction.

use gltf::json::Value;

use super::super::context::MaterialContext;
use super::Extension;

pub(in crate::formats::gltf) const EXTENSION: Extension = Extension {
    name: "KHR_materials_ior",
    apply,
};

/// The index of refraction `ior` 0 stands for: the extension allows 0 to mean a
/// Fresnel reflectance of 1 at normal incidence, which an ior of 1000 gives within
/// 0.4% (as Blender's importer sets for specular-glossiness materials).
pub(in crate::formats::gltf) const FRESNEL_ONE_IOR: f32 = 1000.0;

fn apply(cx: &mut MaterialContext<'_, '_>, ext: &Value) {
    let ior = cx.number(ext, "ior", 1.5);
    cx.pbr.ior = if ior == 0.0 {
        cx.note("ior 0 (a Fresnel reflectance of 1) read as ior 1000");
        FRESNEL_ONE_IOR
    } else {
        ior
    };
}
