//! `KHR_materials_clearcoat`: a clear coat over the material (`clearcoatFactor`,
//! `clearcoatTexture`'s red; `clearcoatRoughnessFactor`,
//! `clearcoatRoughnessTexture`'s green) with its own shading normal
//! (`clearcoatNormalTexture` and its `scale`; without one the coat takes the
//! surface's normal before the base's normal map, as the extension says).

use gltf::json::Value;

use super::super::context::MaterialContext;
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
    cx.maps.pbr.clearcoat_normal =
        cx.normal_texture(ext, "clearcoatNormalTexture", "a clearcoat normal texture");
}
