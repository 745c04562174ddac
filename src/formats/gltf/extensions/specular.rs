//! `KHR_materials_specular`: the strength (`specularFactor`, `specularTexture`'s
//! alpha) and tint (`specularColorFactor`, `specularColorTexture`, sRGB) of the
//! dielectric's reflection.

use gltf::json::Value;

use super::super::context::MaterialContext;
use super::Extension;
use crate::math::Vec3;
use crate::textures::Channel;

pub(in crate::formats::gltf) const EXTENSION: Extension = Extension {
    name: "KHR_materials_specular",
    apply,
};

fn apply(cx: &mut MaterialContext<'_, '_>, ext: &Value) {
    cx.pbr.specular = cx.number(ext, "specularFactor", 1.0);
    cx.maps.pbr.specular = cx.scalar_texture(ext, "specularTexture", Channel::Alpha);
    cx.pbr.specular_color = cx.colour(ext, "specularColorFactor", Vec3::ONE);
    cx.maps.pbr.specular_color = cx.texture(ext, "specularColorTexture");
}
