//! `KHR_materials_volume`: a `thicknessFactor` above 0 makes the mesh the boundary
//! of a volume (refracted at the ior, attenuated to `attenuationColor` over
//! `attenuationDistance`). The thickness itself only says whether there is a volume:
//! a path tracer measures the distance travelled, so `thicknessTexture` is not read.

use gltf::json::Value;

use super::super::context::MaterialContext;
use super::Extension;
use crate::math::{Float, Vec3};

pub(in crate::formats::gltf) const EXTENSION: Extension = Extension {
    name: "KHR_materials_volume",
    apply,
};

fn apply(cx: &mut MaterialContext<'_, '_>, ext: &Value) {
    cx.pbr.thickness = cx.number(ext, "thicknessFactor", 0.0);
    cx.pbr.attenuation_color = cx.colour(ext, "attenuationColor", Vec3::ONE);
    cx.pbr.attenuation_distance = cx.number(ext, "attenuationDistance", Float::INFINITY);
}
