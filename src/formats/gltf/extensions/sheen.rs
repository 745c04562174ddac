//! `KHR_materials_sheen`: a Charlie sheen (`sheenColorFactor`,
//! `sheenColorTexture`, sRGB; `sheenRoughnessFactor`, `sheenRoughnessTexture`'s
//! alpha).

use gltf::json::Value;

use super::super::context::MaterialContext;
use super::Extension;
use crate::math::Vec3;
use crate::textures::Channel;

pub(in crate::formats::gltf) const EXTENSION: Extension = Extension {
    name: "KHR_materials_sheen",
    apply,
};

fn apply(cx: &mut MaterialContext<'_, '_>, ext: &Value) {
    cx.pbr.sheen_color = cx.colour(ext, "sheenColorFactor", Vec3::ZERO);
    cx.maps.pbr.sheen_color = cx.texture(ext, "sheenColorTexture");
    cx.pbr.sheen_roughness = cx.number(ext, "sheenRoughnessFactor", 0.0);
    cx.maps.pbr.sheen_roughness = cx.scalar_texture(ext, "sheenRoughnessTexture", Channel::Alpha);
}
