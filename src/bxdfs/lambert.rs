//! The Lambertian lobe: `f = R / pi` on the side `wo` is on, sampled by the cosine.

use std::f32::consts::{FRAC_1_PI, PI};

use super::{Lobe, LocalSample, same_hemisphere};
use crate::math::{Float, Vec2, Vec3, sin_cos};

/// Ideal diffuse reflection of reflectance `R`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lambert {
    /// Reflectance per channel.
    pub reflectance: Vec3,
}

impl Lobe for Lambert {
    #[inline]
    fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if same_hemisphere(wo, wi) {
            self.reflectance * FRAC_1_PI
        } else {
            Vec3::ZERO
        }
    }

    #[inline]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> Float {
        cosine_pdf(wo, wi)
    }

    #[inline]
    fn sample(&self, wo: Vec3, _u_lobe: Float, u: Vec2) -> Option<LocalSample> {
        let wi = cosine_on_the_side_of(wo, u);
        let pdf = cosine_pdf(wo, wi);
        (pdf > 0.0).then(|| LocalSample::smooth(wi, self.reflectance, pdf))
    }
}

/// The density of [`cosine_on_the_side_of`]: `|cos| / pi` on `wo`'s side.
#[inline]
pub fn cosine_pdf(wo: Vec3, wi: Vec3) -> Float {
    if same_hemisphere(wo, wi) {
        wi.z.abs() * FRAC_1_PI
    } else {
        0.0
    }
}

/// A cosine-distributed direction on the side of the surface `wo` is on.
#[inline]
pub fn cosine_on_the_side_of(wo: Vec3, u: Vec2) -> Vec3 {
    let mut wi = cosine_hemisphere(u);
    if wo.z < 0.0 {
        wi.z = -wi.z;
    }
    wi
}

/// A cosine-distributed direction about +z (Malley's method).
#[inline]
pub fn cosine_hemisphere(u: Vec2) -> Vec3 {
    let r = u.x.sqrt();
    let (sin, cos) = sin_cos(2.0 * PI * u.y);
    Vec3::new(r * cos, r * sin, (1.0 - u.x).max(0.0).sqrt())
}
