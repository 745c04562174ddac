//! The GGX (Trowbridge-Reitz) microfacet distribution as glTF's Appendix B defines
//! it: `D = alpha^2 / (pi ((n.h)^2 (alpha^2 - 1) + 1)^2)` with `alpha = roughness^2`,
//! the height-correlated Smith masking-shadowing term, and sampling of the normals
//! visible from `wo` (Heitz 2018), whose density cancels most of `D G`.
//!
//! [`GgxReflection`] is the lobe `D V` with `V = G2 / (4 |n.wo| |n.wi|)`, without a
//! Fresnel factor: glTF's model weighs it by Schlick's Fresnel outside
//! ([`super::gltf`]).

use std::f32::consts::PI;

use super::{Lobe, LocalSample};
use crate::math::{Float, Vec2, Vec3, sin_cos};

/// Below this `alpha` a surface is a mirror: its lobe is a delta, sampled exactly,
/// rather than a distribution whose `D` would overflow.
pub const DELTA_ALPHA: Float = 1e-4;

/// An isotropic GGX distribution of microfacet normals.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ggx {
    /// `alpha = roughness^2`.
    pub alpha: Float,
}

impl Ggx {
    /// The distribution of perceptual roughness `roughness` (`alpha = roughness^2`).
    #[inline]
    pub fn from_roughness(roughness: Float) -> Ggx {
        Ggx {
            alpha: roughness * roughness,
        }
    }

    /// Whether the surface is smooth enough to be a delta lobe.
    #[inline]
    pub fn is_delta(&self) -> bool {
        self.alpha < DELTA_ALPHA
    }

    /// `D(h)` for a unit `h` in the shading frame.
    #[inline]
    pub fn d(&self, h: Vec3) -> Float {
        if h.z <= 0.0 {
            return 0.0;
        }
        let a2 = self.alpha * self.alpha;
        let t = h.z * h.z * (a2 - 1.0) + 1.0;
        a2 / (PI * t * t)
    }

    /// Smith's `Lambda(w)`.
    #[inline]
    pub fn lambda(&self, w: Vec3) -> Float {
        let cos2 = w.z * w.z;
        if cos2 <= 0.0 {
            return Float::INFINITY;
        }
        let a2 = self.alpha * self.alpha;
        let tan2 = ((1.0 - cos2) / cos2).max(0.0);
        0.5 * ((1.0 + a2 * tan2).sqrt() - 1.0)
    }

    /// Smith's masking `G1(w) = 1 / (1 + Lambda(w))`.
    #[inline]
    pub fn g1(&self, w: Vec3) -> Float {
        1.0 / (1.0 + self.lambda(w))
    }

    /// The height-correlated masking-shadowing `G2 = 1 / (1 + Lambda(wo) +
    /// Lambda(wi))`.
    #[inline]
    pub fn g2(&self, wo: Vec3, wi: Vec3) -> Float {
        1.0 / (1.0 + self.lambda(wo) + self.lambda(wi))
    }

    /// glTF's visibility `V = G2 / (4 |n.wo| |n.wi|)`, in the form Appendix B writes
    /// it: `0.5 / (|n.wi| sqrt(a^2 + (1 - a^2) (n.wo)^2) + |n.wo| sqrt(a^2 + (1 - a^2)
    /// (n.wi)^2))`, which stays finite at grazing angles.
    #[inline]
    pub fn visibility(&self, wo: Vec3, wi: Vec3) -> Float {
        let a2 = self.alpha * self.alpha;
        let (co, ci) = (wo.z.abs(), wi.z.abs());
        let denominator =
            ci * (a2 + (1.0 - a2) * co * co).sqrt() + co * (a2 + (1.0 - a2) * ci * ci).sqrt();
        if denominator > 0.0 {
            0.5 / denominator
        } else {
            0.0
        }
    }

    /// The separable Smith visibility `G1(wo) G1(wi) / (4 |n.wo| |n.wi|)`: Mitsuba 3's
    /// and pbrt-v3's masking-shadowing, for comparing with them (glTF's is
    /// [`Ggx::visibility`]).
    #[inline]
    pub fn separable_visibility(&self, wo: Vec3, wi: Vec3) -> Float {
        let cosines = 4.0 * wo.z.abs() * wi.z.abs();
        if cosines > 0.0 {
            self.g1(wo) * self.g1(wi) / cosines
        } else {
            0.0
        }
    }

    /// The density of [`Ggx::sample_visible`] at the microfacet normal `h`:
    /// `G1(wo) max(0, wo.h) D(h) / |wo.z|`.
    #[inline]
    pub fn visible_pdf(&self, wo: Vec3, h: Vec3) -> Float {
        let cos_o = wo.z.abs();
        if cos_o <= 0.0 {
            return 0.0;
        }
        self.g1(wo) * wo.dot(h).max(0.0) * self.d(h) / cos_o
    }

    /// A microfacet normal seen from `wo` (`wo.z > 0`), distributed as
    /// [`Ggx::visible_pdf`] (Heitz 2018, "Sampling the GGX Distribution of Visible
    /// Normals").
    #[inline]
    pub fn sample_visible(&self, wo: Vec3, u: Vec2) -> Vec3 {
        let a = self.alpha;
        // The view direction in the hemisphere configuration.
        let v = Vec3::new(a * wo.x, a * wo.y, wo.z).normalize();
        let length2 = v.x * v.x + v.y * v.y;
        let t1 = if length2 > 0.0 {
            Vec3::new(-v.y, v.x, 0.0) / length2.sqrt()
        } else {
            Vec3::X
        };
        let t2 = v.cross(t1);
        let r = u.x.sqrt();
        let (sin, cos) = sin_cos(2.0 * PI * u.y);
        let p1 = r * cos;
        let s = 0.5 * (1.0 + v.z);
        let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * sin;
        let nh = p1 * t1 + p2 * t2 + (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt() * v;
        Vec3::new(a * nh.x, a * nh.y, nh.z.max(1e-6)).normalize()
    }
}

/// The reflection lobe `D V` of a GGX surface (white, no Fresnel).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GgxReflection {
    /// The distribution.
    pub ggx: Ggx,
}

impl Lobe for GgxReflection {
    #[inline]
    fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        let h = (wo + wi).normalize();
        Vec3::splat(self.ggx.d(h) * self.ggx.visibility(wo, wi))
    }

    #[inline]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> Float {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let h = (wo + wi).normalize();
        reflection_pdf(&self.ggx, wo, h)
    }

    #[inline]
    fn sample(&self, wo: Vec3, _u_lobe: Float, u: Vec2) -> Option<LocalSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let h = self.ggx.sample_visible(wo, u);
        let wi = crate::math::reflect(-wo, h);
        let pdf = self.pdf(wo, wi);
        (pdf > 0.0).then(|| LocalSample::smooth(wi, self.eval(wo, wi) * wi.z / pdf, pdf))
    }
}

/// The density of the reflected direction whose half vector is `h`, when `h` is
/// sampled from the normals visible from `wo`: `visible_pdf / (4 wo.h)`.
#[inline]
pub fn reflection_pdf(ggx: &Ggx, wo: Vec3, h: Vec3) -> Float {
    let cos = wo.dot(h);
    if cos <= 0.0 {
        return 0.0;
    }
    ggx.visible_pdf(wo, h) / (4.0 * cos)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `D` is normalized: the projected area of the microfacets is the macro
    /// surface's, `integral D(h) (n.h) dh = 1`, by a midpoint quadrature.
    #[test]
    fn projected_microfacet_area_is_one() {
        for alpha in [0.05, 0.3, 0.8, 1.0] {
            let ggx = Ggx { alpha };
            let n = 4000;
            let mut sum = 0.0f64;
            for i in 0..n {
                // Substituting cos^2 makes the narrow lobes resolvable.
                let t = (i as f64 + 0.5) / n as f64;
                let cos = t.sqrt();
                let h = Vec3::new((1.0 - t).sqrt() as Float, 0.0, cos as Float);
                // dw = 2 pi sin dtheta = pi d(cos^2) / cos.
                sum += ggx.d(h) as f64 * cos * std::f64::consts::PI / cos / n as f64;
            }
            assert!((sum - 1.0).abs() < 2e-3, "alpha {alpha}: {sum}");
        }
    }
}
