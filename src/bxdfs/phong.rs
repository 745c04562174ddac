//! The energy-conserving modified Phong lobe (Lafortune and Willems 1994), MTL's
//! `Ks`/`Ns` in path mode: `f = Ks (n + 2) / (2 pi) cos^n(alpha)`, `alpha` the angle
//! between `wi` and the mirror direction of `wo`, sampled by `cos^n` about it.

use std::f32::consts::PI;

use super::{Frame, Lobe, LocalSample};
use crate::math::{Float, Vec2, Vec3, sin_cos};

/// A modified Phong lobe.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Phong {
    /// `Ks`.
    pub reflectance: Vec3,
    /// `Ns`, at least 0.
    pub exponent: Float,
}

impl Phong {
    /// `cos^n(alpha)` of the angle between `wi` and the mirror direction `mirror`.
    #[inline]
    pub fn lobe(mirror: Vec3, wi: Vec3, exponent: Float) -> Float {
        wi.dot(mirror).max(0.0).powf(exponent)
    }

    /// The density of [`phong_lobe`] about `mirror` at `wi`.
    #[inline]
    pub fn lobe_pdf(mirror: Vec3, wi: Vec3, exponent: Float) -> Float {
        (exponent + 1.0) / (2.0 * PI) * Phong::lobe(mirror, wi, exponent)
    }
}

impl Lobe for Phong {
    #[inline]
    fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        let mirror = Vec3::new(-wo.x, -wo.y, wo.z);
        self.reflectance
            * ((self.exponent + 2.0) / (2.0 * PI) * Phong::lobe(mirror, wi, self.exponent))
    }

    #[inline]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> Float {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        Phong::lobe_pdf(Vec3::new(-wo.x, -wo.y, wo.z), wi, self.exponent)
    }

    #[inline]
    fn sample(&self, wo: Vec3, _u_lobe: Float, u: Vec2) -> Option<LocalSample> {
        let mirror = Vec3::new(-wo.x, -wo.y, wo.z);
        let wi = Frame::from_normal(mirror).to_world(phong_lobe(u, self.exponent));
        let pdf = self.pdf(wo, wi);
        (pdf > 0.0).then(|| LocalSample::smooth(wi, self.eval(wo, wi) * wi.z / pdf, pdf))
    }
}

/// A direction about +z with density proportional to `cos^exponent`.
#[inline]
pub fn phong_lobe(u: Vec2, exponent: Float) -> Vec3 {
    let cos = u.x.powf(1.0 / (exponent + 1.0));
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    let (sin_phi, cos_phi) = sin_cos(2.0 * PI * u.y);
    Vec3::new(sin * cos_phi, sin * sin_phi, cos)
}
