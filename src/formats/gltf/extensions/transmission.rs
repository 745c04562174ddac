//! `KHR_materials_transmission`: the part of the dielectric base transmitted
//! (`transmissionFactor`, `transmissionTexture`'s red); thin-walled unless
//! `KHR_materials_volume` gives a thickness.

use gltf::json::Value;

use super::super::context::MaterialContext;
use super::Extension;
use crate::textures::Channel;

pub(in crate::formats::gltf) const EXTENSION: Extension = Extension {
    name: "KHR_materials_transmission",
    apply,
};

fn apply(cx: &mut MaterialContext<'_, '_>, ext: &Value) {
    cx.pbr.transmission = cx.number(ext, "transmissionFactor", 0.0);
    cx.maps.pbr.transmission = cx.scalar_texture(ext, "transmissionTexture", Channel::Red);
}
