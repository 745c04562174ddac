//! `KHR_materials_emissive_strength`: multiplies the emission, which the core
//! limits to 1.

use gltf::json::Value;

use super::super::context::MaterialContext;
use super::Extension;

pub(in crate::formats::gltf) const EXTENSION: Extension = Extension {
    name: "KHR_materials_emissive_strength",
    apply,
};

fn apply(cx: &mut MaterialContext<'_, '_>, ext: &Value) {
    cx.emission_strength = cx.number(ext, "emissiveStrength", 1.0);
}
