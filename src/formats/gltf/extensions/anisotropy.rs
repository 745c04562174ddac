//! `KHR_materials_anisotropy`: anisotropic GGX (`anisotropyStrength`, multiplied by
//! `anisotropyTexture`'s blue; `anisotropyRotation` in radians, counter-clockwise
//! from the tangent, turning the texture's red-green direction, linear). The
//! tangent frame is the one normal maps use here: the triangle's texture
//! coordinates' `u` made orthogonal to the shading normal (`TANGENT` attributes are
//! not read), or where a mesh has none, a default tangent
//! ([`crate::bxdfs::Frame::anisotropic`]).

use gltf::json::Value;

use super::super::context::MaterialContext;
use super::Extension;

pub(in crate::formats::gltf) const EXTENSION: Extension = Extension {
    name: "KHR_materials_anisotropy",
    apply,
};

fn apply(cx: &mut MaterialContext<'_, '_>, ext: &Value) {
    cx.pbr.anisotropy = cx.number(ext, "anisotropyStrength", 0.0);
    cx.pbr.anisotropy_rotation = cx.number(ext, "anisotropyRotation", 0.0);
    cx.maps.pbr.anisotropy = cx.texture(ext, "anisotropyTexture");
}
