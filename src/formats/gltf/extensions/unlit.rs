//! `KHR_materials_unlit`: the surface shows its base colour (`baseColorFactor`,
//! `baseColorTexture` and `COLOR_0`, the alpha mode as for any material) whatever
//! the lights ([`crate::material::pbr::PbrMaterial::unlit`]). The extension's object
//! is empty; every other property of the material is a fallback for viewers that do
//! not know it, so the emission is dropped (an unlit surface is no light) along with
//! the maps only shading reads.
//!
//! How it renders is chosen as a model viewer (three.js's `MeshBasicMaterial`) shows
//! it: the eye sees the base colour exactly, in both modes; the surface casts shadows
//! (it is opaque) but lights no other surface. Blender's importer instead makes it
//! invisible to every ray but the camera's (no shadow either); we keep the shadow a
//! model viewer's shadow map casts, and which a path tracer gets for free.

use gltf::json::Value;

use super::super::context::MaterialContext;
use super::Extension;
use crate::math::Vec3;

pub(in crate::formats::gltf) const EXTENSION: Extension = Extension {
    name: "KHR_materials_unlit",
    apply,
};

fn apply(cx: &mut MaterialContext<'_, '_>, _: &Value) {
    cx.pbr.unlit = true;
    cx.emission = Vec3::ZERO;
    let base_color = cx.maps.pbr.base_color.take();
    let cutout = cx.maps.cutout.take();
    cx.maps = Default::default();
    cx.maps.pbr.base_color = base_color;
    cx.maps.cutout = cutout;
}
