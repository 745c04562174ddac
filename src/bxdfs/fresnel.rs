//! Fresnel terms: Schlick's approximation, which glTF's material model is defined
//! with, and the exact unpolarized reflectance of a smooth dielectric boundary, which
//! MTL's glass uses.

use crate::math::{Float, Vec3};

/// Schlick's weight `(1 - cos)^5` of the grazing reflectance.
#[inline]
pub fn schlick_weight(cos: Float) -> Float {
    let m = (1.0 - cos.abs()).clamp(0.0, 1.0);
    let m2 = m * m;
    m2 * m2 * m
}

/// Schlick's Fresnel per channel, from the reflectance at normal incidence `f0` to
/// `f90` at grazing incidence.
#[inline]
pub fn schlick(f0: Vec3, f90: Float, cos: Float) -> Vec3 {
    f0 + (Vec3::splat(f90) - f0) * schlick_weight(cos)
}

/// Schlick's Fresnel of a scalar reflectance `f0` (grazing reflectance 1).
#[inline]
pub fn schlick_scalar(f0: Float, cos: Float) -> Float {
    f0 + (1.0 - f0) * schlick_weight(cos)
}

/// Unpolarized Fresnel reflectance of a smooth dielectric boundary, for cosines of
/// the incident and transmitted angles (both positive) and `eta` = index entered /
/// index left.
#[inline]
pub fn dielectric(cos_i: Float, cos_t: Float, eta: Float) -> Float {
    let parallel = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let perpendicular = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (parallel * parallel + perpendicular * perpendicular)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dielectric_is_four_percent_head_on_for_glass_as_schlick_is() {
        let exact = dielectric(1.0, 1.0, 1.5);
        assert!((exact - 0.04).abs() < 1e-4, "{exact}");
        assert!((schlick_scalar(0.04, 1.0) - 0.04).abs() < 1e-7);
        assert_eq!(schlick(Vec3::splat(0.04), 0.5, 0.0), Vec3::splat(0.5));
    }
}
