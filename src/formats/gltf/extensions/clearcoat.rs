//! `KHR_materials_clearcoat`: a clear coat over the material (`clearcoatFactor`,
//! `clearcoatTexture`'s red; `clearcoatRoughnessFactor`,
//! `clearcoatRoughnessTexture`'s green). Its `clearcoatNormalTexture` is read but
//! not applied: the coat shares the base's shading normal (one warning).

use gltf::json::Value;

use super::super::material::MaterialContext;
use super::Extension;
use crate::textures::Channel;

pub(in crate::formats::gltf) const EXTENSION: Extension = Extension {
    name: "KHR_materials_clearcoat",
    apply,
};

fn apply(cx: &mut MaterialContext<'_, '_>, ext: &Value) {
    cx.pbr.clearcoat = cx.number(ext, "clearcoatFactor", 0.0);
    cx.maps.pbr.clearcoat = cx.scalar_texture(ext, "clearcoatTexture", Channel::Red);
    cx.pbr.clearcoat_roughness = cx.number(ext, "clearcoatRoughnessFactor", 0.0);
    cx.maps.pbr.clearcoat_roughness =
        cx.scalar_texture(ext, "clearcoatRoughnessTexture", Channel::Green);
    if cx.texture(ext, "clearcoatNormalTexture").is_some() {
        let index = cx.index;
        cx.warn_once(
            "clearcoat normal",
            format!(
                "material {index}: clearcoat normal textures are not applied; the coat uses the base's normal"
            ),
        );
    }
}
