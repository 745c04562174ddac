//! `KHR_materials_pbrSpecularGlossiness`, converted as Blender's glTF importer
//! does (a Principled BSDF): the diffuse colour (`diffuseFactor`, `diffuseTexture`,
//! alpha included) is the base colour of a dielectric (metallic 0); its reflectance
//! at normal incidence is the specular colour (`specularFactor` times
//! `specularGlossinessTexture`'s RGB, sRGB), which an ior of 1000 (Fresnel 0.996)
//! with that colour as the specular tint gives; roughness is
//! `1 - glossinessFactor * specularGlossinessTexture's alpha` (Blender bakes an
//! image; here the map reads alpha with `-mm 1 -glossiness`).

use gltf::json::Value;

use super::super::context::{MaterialContext, with_channel};
use super::Extension;
use super::ior::FRESNEL_ONE_IOR;
use crate::math::Vec3;
use crate::textures::Channel;

pub(in crate::formats::gltf) const EXTENSION: Extension = Extension {
    name: "KHR_materials_pbrSpecularGlossiness",
    apply,
};

fn apply(cx: &mut MaterialContext<'_, '_>, ext: &Value) {
    let [r, g, b, a] = cx.colour4(ext, "diffuseFactor", [1.0; 4]);
    cx.pbr.base_color = Vec3::new(r, g, b);
    cx.alpha = a;
    let diffuse = cx.texture(ext, "diffuseTexture");
    cx.alpha_map.clone_from(&diffuse);
    cx.maps.pbr.base_color = diffuse;
    cx.pbr.metallic = 0.0;
    cx.maps.pbr.metallic = None;
    cx.pbr.ior = FRESNEL_ONE_IOR;
    cx.pbr.specular = 1.0;
    cx.pbr.specular_color = cx.colour(ext, "specularFactor", Vec3::ONE);
    let glossiness = cx.number(ext, "glossinessFactor", 1.0);
    let texture = cx.texture(ext, "specularGlossinessTexture");
    match &texture {
        Some(map) => {
            let mut roughness = with_channel(map, Channel::Alpha);
            roughness.options.base = 1.0;
            roughness.options.gain = -glossiness;
            cx.pbr.roughness = 1.0;
            cx.maps.pbr.roughness = Some(roughness);
        }
        None => {
            cx.pbr.roughness = 1.0 - glossiness;
            cx.maps.pbr.roughness = None;
        }
    }
    cx.maps.pbr.specular_color = texture;
}
