//! Phong materials as read from MTL files.

use crate::math::{Float, Vec3};

/// Index of a material in [`crate::Scene::materials`] (and in the description's list).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct MaterialId(pub u32);

/// A material of SPEC's lighting model. Defaults are those of an MTL `newmtl` with no
/// further lines: black, `Ns 1`, `Ni 1`, `d 1`, `al 1 0 0`.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// The name given by `newmtl`.
    pub name: String,
    /// `Ka`: ambient colour, added as is.
    pub ambient: Vec3,
    /// `Kd`: diffuse reflectance.
    pub diffuse: Vec3,
    /// `Ks`: specular reflectance.
    pub specular: Vec3,
    /// `Ke`: emission, added exactly like `Ka`.
    pub emission: Vec3,
    /// `Ns`: Phong exponent.
    pub shininess: Float,
    /// `Ni`: index of refraction.
    pub ior: Float,
    /// `d` (or `1 - Tr`): opacity. Read and kept, but not used by the default
    /// renderer: the reference images weight refraction by `al2` alone.
    pub opacity: Float,
    /// `al`: weights of local shading, reflection and refraction.
    pub albedo: [Float; 3],
}

impl Material {
    /// A material with MTL defaults and the given name.
    pub fn named(name: impl Into<String>) -> Material {
        Material {
            name: name.into(),
            ambient: Vec3::ZERO,
            diffuse: Vec3::ZERO,
            specular: Vec3::ZERO,
            emission: Vec3::ZERO,
            shininess: 1.0,
            ior: 1.0,
            opacity: 1.0,
            albedo: [1.0, 0.0, 0.0],
        }
    }

    /// What faces get when no (known) material was named: a matte light grey, so that
    /// a scene without an MTL file still shows its shapes.
    pub fn fallback() -> Material {
        Material {
            diffuse: Vec3::splat(0.8),
            ..Material::named("default")
        }
    }
}

/// A point light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointLight {
    /// Position.
    pub position: Vec3,
    /// Intensity per channel; may exceed 1.
    pub intensity: Vec3,
}
