//! Physically based materials: glTF 2.0's metallic-roughness model with its
//! `KHR_materials_*` extensions, which MTL's PBR statements (`Pr`, `Pm`, ...) and TOML
//! materials describe too. Path mode scatters by it exactly
//! ([`crate::bxdfs::gltf`]); full mode shows it through one Phong approximation
//! ([`PbrValues::phong`]), since SPEC's renderer knows only Phong.

use crate::material::SurfaceValues;
use crate::math::{Float, Vec2, Vec3};
use crate::textures::{Encoding, TextureMap};

/// The factors of a physically based material, each multiplied by its map
/// ([`PbrMaps`]) where it has one. Defaults are glTF's.
#[derive(Clone, Debug, PartialEq)]
pub struct PbrMaterial {
    /// `baseColorFactor` (linear RGB; its alpha is the cutout's factor).
    pub base_color: Vec3,
    /// `metallicFactor`, in [0, 1].
    pub metallic: Float,
    /// `roughnessFactor`, in [0, 1]: the microfacet roughness is its square.
    pub roughness: Float,
    /// `KHR_materials_ior`: at least 1 (1.5).
    pub ior: Float,
    /// `KHR_materials_specular` `specularFactor`: scales the dielectric's Fresnel
    /// (1); 0 leaves a pure Lambertian base.
    pub specular: Float,
    /// `KHR_materials_specular` `specularColorFactor`: tints the dielectric's
    /// reflectance at normal incidence (white).
    pub specular_color: Vec3,
    /// `KHR_materials_transmission` `transmissionFactor`: the part of the
    /// dielectric's base that is transmitted rather than diffusely reflected (0).
    pub transmission: Float,
    /// `KHR_materials_volume` `thicknessFactor`: 0 makes the surface thin-walled
    /// (light passes straight through); more makes the mesh the boundary of a volume,
    /// refracted at `ior` and attenuated inside.
    pub thickness: Float,
    /// `KHR_materials_volume` `attenuationColor`: the colour white light turns after
    /// `attenuation_distance` inside the volume (white).
    pub attenuation_color: Vec3,
    /// `KHR_materials_volume` `attenuationDistance` (infinite: no attenuation).
    pub attenuation_distance: Float,
    /// `KHR_materials_clearcoat` `clearcoatFactor` (0).
    pub clearcoat: Float,
    /// `KHR_materials_clearcoat` `clearcoatRoughnessFactor` (0).
    pub clearcoat_roughness: Float,
    /// `KHR_materials_sheen` `sheenColorFactor` (black: no sheen).
    pub sheen_color: Vec3,
    /// `KHR_materials_sheen` `sheenRoughnessFactor` (0).
    pub sheen_roughness: Float,
    /// Multiple-scattering energy compensation of the GGX reflection lobes (TOML's
    /// `multiple_scattering`; off, as glTF's single-scattering model is defined):
    /// Turquin's (2019) scaling, so that a rough white metal loses no energy.
    pub multiple_scattering: bool,
    /// `KHR_materials_anisotropy` `anisotropyStrength`, in [0, 1] (0: isotropic):
    /// the GGX `alpha` along the direction of anisotropy becomes `mix(alpha, 1,
    /// strength^2)`, across it stays `alpha`.
    pub anisotropy: Float,
    /// `KHR_materials_anisotropy` `anisotropyRotation`: the direction of anisotropy,
    /// in radians counter-clockwise from the tangent towards the bitangent (0).
    pub anisotropy_rotation: Float,
    /// `KHR_materials_unlit`: the surface shows its base colour (factor, map and
    /// vertex colour) to the eye, whatever the lights, and scatters nothing: a camera
    /// ray (or one continuing it through mirrors and glass) that meets it sees exactly
    /// that colour; any other ray that meets it ends there, so it casts shadows but
    /// lights no other surface (see `docs/scene-format.md`).
    pub unlit: bool,
}

impl Default for PbrMaterial {
    fn default() -> Self {
        PbrMaterial {
            base_color: Vec3::ONE,
            metallic: 1.0,
            roughness: 1.0,
            ior: 1.5,
            specular: 1.0,
            specular_color: Vec3::ONE,
            transmission: 0.0,
            thickness: 0.0,
            attenuation_color: Vec3::ONE,
            attenuation_distance: Float::INFINITY,
            clearcoat: 0.0,
            clearcoat_roughness: 0.0,
            sheen_color: Vec3::ZERO,
            sheen_roughness: 0.0,
            multiple_scattering: false,
            anisotropy: 0.0,
            anisotropy_rotation: 0.0,
            unlit: false,
        }
    }
}

/// The maps of a physically based material, kept in
/// [`crate::material::MaterialMaps::pbr`]. Colour maps are read as sRGB, scalar maps
/// through their [`crate::textures::Channel`] (glTF's metallic-roughness texture is
/// two maps of one image: roughness from green, metallic from blue).
#[derive(Clone, Debug, PartialEq, Default)]
pub struct PbrMaps {
    /// Base colour (glTF `baseColorTexture`, MTL `map_Kd`).
    pub base_color: Option<TextureMap>,
    /// Metallic (glTF: the metallic-roughness texture's blue; MTL `map_Pm`).
    pub metallic: Option<TextureMap>,
    /// Roughness (glTF: the metallic-roughness texture's green; MTL `map_Pr`).
    pub roughness: Option<TextureMap>,
    /// `specularTexture` (alpha).
    pub specular: Option<TextureMap>,
    /// `specularColorTexture`.
    pub specular_color: Option<TextureMap>,
    /// `transmissionTexture` (red).
    pub transmission: Option<TextureMap>,
    /// `clearcoatTexture` (red).
    pub clearcoat: Option<TextureMap>,
    /// `clearcoatRoughnessTexture` (green).
    pub clearcoat_roughness: Option<TextureMap>,
    /// `clearcoatNormalTexture`: the coat's own tangent-space normal map (its
    /// `scale` in `options.bump_multiplier`), read by the scene into
    /// [`crate::scene::Hit::coat_ns`].
    pub clearcoat_normal: Option<TextureMap>,
    /// `sheenColorTexture`.
    pub sheen_color: Option<TextureMap>,
    /// `sheenRoughnessTexture` (alpha).
    pub sheen_roughness: Option<TextureMap>,
    /// `anisotropyTexture` (linear): red and green the direction in tangent space
    /// (from [0, 1] to [-1, 1]), turned by the rotation; blue multiplies the
    /// strength.
    pub anisotropy: Option<TextureMap>,
}

impl PbrMaps {
    /// Whether no map is set.
    pub fn is_empty(&self) -> bool {
        *self == PbrMaps::default()
    }
}

/// A physically based material's values at one point: its factors times its maps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PbrValues {
    /// Linear base colour.
    pub base_color: Vec3,
    /// In [0, 1].
    pub metallic: Float,
    /// Perceptual roughness, in [0, 1].
    pub roughness: Float,
    /// Index of refraction, at least 1.
    pub ior: Float,
    /// Specular weight, in [0, 1].
    pub specular: Float,
    /// Specular tint.
    pub specular_color: Vec3,
    /// Transmission weight, in [0, 1].
    pub transmission: Float,
    /// Whether the surface bounds a volume (refracts) rather than being thin-walled.
    pub volume: bool,
    /// Attenuation coefficient per unit length inside the volume: `-ln(colour) /
    /// distance` per channel.
    pub attenuation: Vec3,
    /// Clearcoat weight, in [0, 1].
    pub clearcoat: Float,
    /// Clearcoat perceptual roughness.
    pub clearcoat_roughness: Float,
    /// Sheen colour.
    pub sheen_color: Vec3,
    /// Sheen perceptual roughness.
    pub sheen_roughness: Float,
    /// Multiple-scattering compensation ([`PbrMaterial::multiple_scattering`]).
    pub multiple_scattering: bool,
    /// Anisotropy strength, in [0, 1] (0: isotropic, the isotropic GGX exactly).
    pub anisotropy: Float,
    /// The direction of anisotropy in tangent space, `(cos, sin)` of the rotation:
    /// what the BSDF turns its frame's default tangent by where the hit gives no
    /// tangent of its own ([`crate::scene::Hit::tangent`]).
    pub anisotropy_direction: Vec2,
}

impl PbrMaterial {
    /// The values at texture coordinates `uv`: the factors, each times its map there
    /// if `maps` has one.
    #[inline]
    pub fn at(&self, uv: Vec2, maps: Option<&PbrMaps>) -> PbrValues {
        let mut values = self.constants();
        if let Some(maps) = maps {
            maps.apply(uv, &mut values);
        }
        values
    }

    /// The values where no map applies.
    pub fn constants(&self) -> PbrValues {
        let colour = |c: Vec3| c.max(Vec3::ZERO);
        PbrValues {
            base_color: colour(self.base_color),
            metallic: self.metallic.clamp(0.0, 1.0),
            roughness: self.roughness.clamp(0.0, 1.0),
            ior: self.ior.max(1.0),
            specular: self.specular.clamp(0.0, 1.0),
            specular_color: colour(self.specular_color),
            transmission: self.transmission.clamp(0.0, 1.0),
            volume: self.thickness > 0.0,
            attenuation: attenuation(self.attenuation_color, self.attenuation_distance),
            clearcoat: self.clearcoat.clamp(0.0, 1.0),
            clearcoat_roughness: self.clearcoat_roughness.clamp(0.0, 1.0),
            sheen_color: colour(self.sheen_color),
            sheen_roughness: self.sheen_roughness.clamp(0.0, 1.0),
            multiple_scattering: self.multiple_scattering,
            anisotropy: self.anisotropy_strength(),
            anisotropy_direction: rotation_direction(self.anisotropy_rotation),
        }
    }

    /// The anisotropy strength in [0, 1]; 0 for NaN.
    #[inline]
    fn anisotropy_strength(&self) -> Float {
        if self.anisotropy > 0.0 {
            self.anisotropy.min(1.0)
        } else {
            0.0
        }
    }

    /// Whether the material is anisotropic somewhere: a strength above 0 (the
    /// texture's blue only multiplies it).
    #[inline]
    pub fn is_anisotropic(&self) -> bool {
        self.anisotropy_strength() > 0.0
    }

    /// The unit direction of anisotropy at `uv` in tangent space (x along the
    /// tangent, y along the bitangent): the `anisotropyTexture`'s red and green
    /// mapped to [-1, 1] and normalised, or the tangent, turned counter-clockwise by
    /// the rotation, as the extension's "Implementation" section does.
    pub fn anisotropy_direction(&self, uv: Vec2, maps: Option<&PbrMaps>) -> Vec2 {
        let rotation = rotation_direction(self.anisotropy_rotation);
        let Some(map) = maps.and_then(|m| m.anisotropy.as_ref()) else {
            return rotation;
        };
        let texel = map.colour(uv, Encoding::Linear);
        // In the image's axes, which the map's texture transform may have turned.
        let direction = map
            .options
            .image_to_surface(Vec2::new(2.0 * texel.x - 1.0, 2.0 * texel.y - 1.0))
            .try_normalize()
            .unwrap_or(Vec2::X);
        Vec2::new(
            rotation.x * direction.x - rotation.y * direction.y,
            rotation.y * direction.x + rotation.x * direction.y,
        )
    }
}

/// `(cos, sin)` of `radians`; `(1, 0)` when it is not finite.
fn rotation_direction(radians: Float) -> Vec2 {
    if radians.is_finite() {
        let (sin, cos) = radians.sin_cos();
        Vec2::new(cos, sin)
    } else {
        Vec2::X
    }
}

/// The attenuation coefficient that turns white into `colour` over `distance`.
fn attenuation(colour: Vec3, distance: Float) -> Vec3 {
    if distance.is_nan() || distance <= 0.0 || distance.is_infinite() {
        return Vec3::ZERO;
    }
    let channel = |c: Float| {
        if c >= 1.0 {
            0.0
        } else if c <= 0.0 {
            Float::INFINITY
        } else {
            -c.ln() / distance
        }
    };
    Vec3::new(channel(colour.x), channel(colour.y), channel(colour.z))
}

impl PbrMaps {
    /// Multiplies `values` by the maps at `uv`.
    #[inline(never)]
    fn apply(&self, uv: Vec2, values: &mut PbrValues) {
        let colour = |map: &Option<TextureMap>, value: &mut Vec3| {
            if let Some(map) = map {
                *value *= map.colour(uv, Encoding::Srgb).max(Vec3::ZERO);
            }
        };
        let scalar = |map: &Option<TextureMap>, value: &mut Float| {
            if let Some(map) = map {
                *value = (*value * map.scalar(uv, false)).clamp(0.0, 1.0);
            }
        };
        colour(&self.base_color, &mut values.base_color);
        scalar(&self.metallic, &mut values.metallic);
        scalar(&self.roughness, &mut values.roughness);
        scalar(&self.specular, &mut values.specular);
        colour(&self.specular_color, &mut values.specular_color);
        scalar(&self.transmission, &mut values.transmission);
        scalar(&self.clearcoat, &mut values.clearcoat);
        scalar(&self.clearcoat_roughness, &mut values.clearcoat_roughness);
        colour(&self.sheen_color, &mut values.sheen_color);
        scalar(&self.sheen_roughness, &mut values.sheen_roughness);
        if let Some(map) = &self.anisotropy {
            let strength = map.colour(uv, Encoding::Linear).z.clamp(0.0, 1.0);
            values.anisotropy *= strength;
            // The direction stays the rotation's: the scene turns the hit's tangent
            // by the map ([`crate::scene::Hit::tangent`]).
        }
    }
}

/// The greatest Phong exponent the approximation gives (a mirror-like surface).
pub const MAX_SHININESS: Float = 10_000.0;

impl PbrValues {
    /// The dielectric's reflectance at normal incidence, per channel:
    /// `min(((ior - 1) / (ior + 1))^2 * specular_color, 1) * specular`, as
    /// `KHR_materials_specular` defines it (0.04 for glTF's defaults).
    #[inline]
    pub fn dielectric_f0(&self) -> Vec3 {
        let r = (self.ior - 1.0) / (self.ior + 1.0);
        (r * r * self.specular_color).min(Vec3::ONE) * self.specular
    }

    /// The Phong material full mode shows for these values (documented in
    /// `docs/scene-format.md`). With `alpha = roughness^2`: `Ks` is the reflectance
    /// at normal incidence (the dielectric's `f0`, turning into the base colour as
    /// the material turns metal, so that a metal keeps its colour in its
    /// highlights), less the part `alpha` of the metal's, which goes to `Kd` beside
    /// what the dielectric base diffuses (`base * (1 - metallic) * (1 - transmission)`);
    /// `Ns` is the exponent whose highlight is as wide as a GGX lobe of that `alpha`
    /// (Walter et al. 2007: `Ns = 2 / alpha^2 - 2`), at least 1. A rough metal
    /// scatters broadly, as a diffuser does; in `Ks` alone, with a lobe of exponent 1
    /// around the mirror direction, it came out as a black mirror with a grey
    /// highlight wherever the light was not behind the eye. The ambient and emission
    /// are left as they are.
    pub fn phong(&self, values: &mut SurfaceValues) {
        let alpha_squared = self.roughness.powi(4);
        values.shininess = if alpha_squared > 0.0 {
            (2.0 / alpha_squared - 2.0).clamp(1.0, MAX_SHININESS)
        } else {
            MAX_SHININESS
        };
        let alpha = self.roughness * self.roughness;
        let metal = self.base_color * self.metallic;
        values.diffuse =
            self.base_color * ((1.0 - self.metallic) * (1.0 - self.transmission)) + metal * alpha;
        values.specular = self.dielectric_f0() * (1.0 - self.metallic) + metal * (1.0 - alpha);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Phong values for `phong` to fill in, all zero.
    fn blank() -> SurfaceValues {
        SurfaceValues {
            ambient: Vec3::ZERO,
            diffuse: Vec3::ZERO,
            specular: Vec3::ZERO,
            emission: Vec3::ZERO,
            shininess: 0.0,
        }
    }

    #[test]
    fn glass_defaults_reflect_four_percent_head_on() {
        let values = PbrMaterial::default().constants();
        assert!(
            (values.dielectric_f0() - Vec3::splat(0.04))
                .abs()
                .max_element()
                < 1e-6
        );
        let no_specular = PbrValues {
            specular: 0.0,
            ..values
        };
        assert_eq!(no_specular.dielectric_f0(), Vec3::ZERO);
    }

    #[test]
    fn attenuation_turns_white_into_the_colour_over_the_distance() {
        let sigma = attenuation(Vec3::new(0.5, 1.0, 0.25), 2.0);
        let after = (-sigma * 2.0).exp();
        assert!((after - Vec3::new(0.5, 1.0, 0.25)).abs().max_element() < 1e-6);
        assert_eq!(attenuation(Vec3::splat(0.5), Float::INFINITY), Vec3::ZERO);
    }

    #[test]
    fn the_phong_approximation_keeps_a_metal_coloured() {
        let gold = PbrMaterial {
            base_color: Vec3::new(1.0, 0.8, 0.3),
            metallic: 1.0,
            roughness: 0.3,
            ..PbrMaterial::default()
        };
        let mut values = blank();
        gold.constants().phong(&mut values);
        // alpha = 0.09 of the metal diffuses, the rest stays in the highlight: both
        // in the base colour, which they add up to.
        let close = |a: Vec3, b: Vec3| (a - b).abs().max_element() < 1e-6;
        assert!(close(values.specular, gold.base_color * 0.91), "{values:?}");
        assert!(close(values.diffuse, gold.base_color * 0.09), "{values:?}");
        assert!(values.shininess > 200.0);
    }

    #[test]
    fn the_roughest_metal_diffuses_its_colour() {
        // Roughness 1 scatters broadly: all of the metal goes to `Kd`, none to a
        // highlight around the mirror direction (which showed a black mirror).
        let rough = PbrMaterial {
            base_color: Vec3::new(0.9, 0.6, 0.2),
            metallic: 1.0,
            roughness: 1.0,
            ..PbrMaterial::default()
        };
        let mut values = blank();
        rough.constants().phong(&mut values);
        assert_eq!(values.shininess, 1.0);
        assert_eq!(values.specular, Vec3::ZERO);
        assert_eq!(values.diffuse, rough.base_color);
        // Smoother surfaces keep Walter's exponent: roughness 0.5 gives 2/0.0625 - 2.
        let half = PbrMaterial {
            roughness: 0.5,
            ..rough
        };
        half.constants().phong(&mut values);
        assert!(
            (values.shininess - 30.0).abs() < 1e-3,
            "{}",
            values.shininess
        );
        assert!(
            (values.diffuse - half.base_color * 0.25)
                .abs()
                .max_element()
                < 1e-6
        );
    }
}
