//! Checks of physically based materials shared by the readers (glTF, MTL, TOML):
//! values outside their ranges are clamped or replaced, and each kind of problem
//! becomes one warning naming the materials it was found in, with a count, however
//! many materials have it.

use crate::material::pbr::PbrMaterial;
use crate::math::{Float, Vec3};

/// Problems found in materials, by kind, with the materials that have each.
#[derive(Debug, Default)]
pub(crate) struct MaterialProblems {
    kinds: Vec<(String, Vec<String>)>,
}

/// How many material names a warning lists before `...`.
const NAMES_SHOWN: usize = 3;

impl MaterialProblems {
    /// Notes that material `material` has problem `kind` (a phrase such as
    /// "roughness outside [0, 1], clamped").
    pub(crate) fn note(&mut self, kind: impl Into<String>, material: &str) {
        let kind = kind.into();
        let names = match self.kinds.iter_mut().find(|(k, _)| *k == kind) {
            Some((_, names)) => names,
            None => {
                self.kinds.push((kind, Vec::new()));
                &mut self.kinds.last_mut().expect("just pushed").1
            }
        };
        if !names.iter().any(|n| n == material) {
            names.push(material.to_owned());
        }
    }

    /// One line per kind, in the order first met: `material 'a': kind`, or
    /// `3 materials ('a', 'b', 'c'): kind`, or `5 materials ('a', 'b', 'c', ...): kind`.
    pub(crate) fn messages(&self) -> Vec<String> {
        self.kinds
            .iter()
            .map(|(kind, names)| {
                let quoted: Vec<String> = names
                    .iter()
                    .take(NAMES_SHOWN)
                    .map(|n| format!("'{n}'"))
                    .collect();
                if names.len() == 1 {
                    format!("material {}: {kind}", quoted[0])
                } else {
                    let more = if names.len() > NAMES_SHOWN {
                        ", ..."
                    } else {
                        ""
                    };
                    format!(
                        "{} materials ({}{more}): {kind}",
                        names.len(),
                        quoted.join(", ")
                    )
                }
            })
            .collect()
    }
}

/// Checks `pbr` (of material `name`): a factor that should lie in [0, 1] is clamped
/// into it, a NaN takes the reader's default (`defaults`: glTF's, but for MTL and
/// TOML a metallic of 0), a negative colour channel is read as 0, an
/// `ior` below 1 is read as 1, a negative thickness as 0 and an attenuation distance
/// of 0 or less as none (infinite); each is noted in `problems`.
pub(crate) fn check_pbr(
    pbr: &mut PbrMaterial,
    defaults: &PbrMaterial,
    name: &str,
    problems: &mut MaterialProblems,
) {
    let mut unit = |value: &mut Float, default: Float, what: &str| {
        if value.is_nan() {
            *value = default;
            problems.note(format!("{what} is NaN, read as {default}"), name);
        } else if !(0.0..=1.0).contains(value) {
            *value = value.clamp(0.0, 1.0);
            problems.note(format!("{what} outside [0, 1], clamped"), name);
        }
    };
    unit(&mut pbr.metallic, defaults.metallic, "metallic");
    unit(&mut pbr.roughness, defaults.roughness, "roughness");
    unit(&mut pbr.specular, defaults.specular, "specular");
    unit(&mut pbr.transmission, defaults.transmission, "transmission");
    unit(&mut pbr.clearcoat, defaults.clearcoat, "clearcoat");
    unit(
        &mut pbr.clearcoat_roughness,
        defaults.clearcoat_roughness,
        "clearcoat roughness",
    );
    unit(
        &mut pbr.sheen_roughness,
        defaults.sheen_roughness,
        "sheen roughness",
    );
    unit(&mut pbr.anisotropy, defaults.anisotropy, "anisotropy");
    if !pbr.anisotropy_rotation.is_finite() {
        pbr.anisotropy_rotation = defaults.anisotropy_rotation;
        problems.note(
            format!(
                "anisotropy rotation is not finite, read as {}",
                defaults.anisotropy_rotation
            ),
            name,
        );
    }
    let mut colour = |value: &mut Vec3, default: Vec3, what: &str| {
        if value.is_nan() {
            *value = default;
            problems.note(format!("{what} is NaN, read as the default"), name);
        } else if value.min_element() < 0.0 {
            *value = value.max(Vec3::ZERO);
            problems.note(format!("{what} below 0, read as 0"), name);
        }
    };
    colour(&mut pbr.base_color, defaults.base_color, "base colour");
    colour(
        &mut pbr.specular_color,
        defaults.specular_color,
        "specular colour",
    );
    colour(
        &mut pbr.attenuation_color,
        defaults.attenuation_color,
        "attenuation colour",
    );
    colour(&mut pbr.sheen_color, defaults.sheen_color, "sheen colour");
    if pbr.ior.is_nan() {
        pbr.ior = defaults.ior;
        problems.note("ior is NaN, read as 1.5", name);
    } else if pbr.ior < 1.0 {
        pbr.ior = 1.0;
        problems.note("ior below 1, read as 1", name);
    }
    if pbr.thickness.is_nan() || pbr.thickness < 0.0 {
        pbr.thickness = 0.0;
        problems.note("thickness below 0 or NaN, read as 0 (thin-walled)", name);
    }
    if pbr.attenuation_distance.is_nan() || pbr.attenuation_distance <= 0.0 {
        pbr.attenuation_distance = Float::INFINITY;
        problems.note(
            "attenuation distance of 0 or less, read as infinite (no attenuation)",
            name,
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_line_per_kind_with_a_count() {
        let mut problems = MaterialProblems::default();
        for name in ["a", "b", "c", "d"] {
            let mut pbr = PbrMaterial {
                roughness: 2.0,
                ..PbrMaterial::default()
            };
            check_pbr(&mut pbr, &PbrMaterial::default(), name, &mut problems);
            assert_eq!(pbr.roughness, 1.0);
        }
        let mut pbr = PbrMaterial {
            ior: 0.5,
            metallic: Float::NAN,
            attenuation_distance: 0.0,
            ..PbrMaterial::default()
        };
        check_pbr(&mut pbr, &PbrMaterial::default(), "e", &mut problems);
        assert_eq!((pbr.ior, pbr.metallic), (1.0, 1.0));
        assert_eq!(pbr.attenuation_distance, Float::INFINITY);
        assert_eq!(
            problems.messages(),
            [
                "4 materials ('a', 'b', 'c', ...): roughness outside [0, 1], clamped",
                "material 'e': metallic is NaN, read as 1",
                "material 'e': ior below 1, read as 1",
                "material 'e': attenuation distance of 0 or less, read as infinite (no attenuation)",
            ]
        );
    }
}
