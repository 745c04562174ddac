//! glTF 2.0's metallic-roughness material, exactly as Appendix B of the glTF
//! specification and the `KHR_materials_*` extensions define it (single scattering,
//! as the Khronos sample viewer and three.js compute it):
//!
//! ```text
//! F_d        = f0 + (f90 - f0) (1 - |V.H|)^5     f0 = min(((ior-1)/(ior+1))^2 specularColor, 1) specular
//!                                                f90 = specular   (KHR_materials_specular)
//! dielectric = F_d D V + (1 - max(F_d)) [(1 - transmission) base / pi + transmission btdf]
//! metal      = (base + (1 - base) (1 - |V.H|)^5) D V
//! material   = mix(dielectric, metal, metallic)
//! sheened    = sheenColor D_c V_c + material (1 - max(sheenColor) E(max(|N.V|, |N.L|)))
//! coated     = mix(sheened, D_cc V_cc, clearcoat (0.04 + 0.96 (1 - |N.V|)^5))
//! ```
//!
//! with GGX `D` and the height-correlated Smith `V` of `alpha = roughness^2`
//! ([`super::microfacet`]), the Charlie sheen ([`super::sheen`]; `E` is its
//! directional albedo, the extension's albedo scaling taking the larger of the two
//! directions' albedos), and a clearcoat of index 1.5 over the same normal (its own
//! normal map is not applied). `btdf` is the base-coloured GGX lobe mirrored through
//! the surface for a thin-walled surface (`KHR_materials_transmission` without a
//! volume: light passes straight through a smooth one), or Walter et al.'s rough
//! refraction at `ior` into a volume (`KHR_materials_volume`), whose attenuation the
//! integrator applies over the distance travelled inside. A roughness under
//! `sqrt(DELTA_ALPHA)` makes a lobe a delta (a mirror, a smooth pane), never a NaN.
//!
//! One lobe is picked by its estimated albedo at `wo`; the density of a direction is
//! the mixture of every non-delta lobe's, so that each sample is weighted against
//! all the ways it could have been drawn.

use std::f32::consts::FRAC_1_PI;

use super::fresnel::{schlick_scalar, schlick_weight};
use super::lambert::cosine_hemisphere;
use super::microfacet::{Ggx, reflection_pdf};
use super::sheen::{self, Sheen};
use super::{Lobe, LocalSample};
use crate::material::pbr::PbrValues;
use crate::math::{Float, Vec2, Vec3, reflect, refract};

/// The clearcoat's reflectance at normal incidence (index 1.5).
const CLEARCOAT_F0: Float = 0.04;

/// The glTF BSDF at one point, derived from the material's values there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GltfBsdf {
    base: Vec3,
    metallic: Float,
    ggx: Ggx,
    /// The dielectric's reflectance at normal incidence and at grazing incidence.
    f0: Vec3,
    f90: Float,
    transmission: Float,
    volume: bool,
    ior: Float,
    attenuation: Vec3,
    clearcoat: Float,
    coat: Ggx,
    sheen: Sheen,
    sheen_roughness: Float,
    /// Whether the sheen is not black.
    sheened: bool,
}

/// The lobes, in the order of [`GltfBsdf::lobe_weights`].
const DIFFUSE: usize = 0;
const SPECULAR: usize = 1;
const TRANSMISSION: usize = 2;
const CLEARCOAT: usize = 3;
const SHEEN: usize = 4;

impl GltfBsdf {
    /// The BSDF of `values`.
    pub fn new(values: &PbrValues) -> GltfBsdf {
        GltfBsdf {
            base: values.base_color,
            metallic: values.metallic,
            ggx: Ggx::from_roughness(values.roughness),
            f0: values.dielectric_f0(),
            f90: values.specular,
            transmission: values.transmission,
            volume: values.volume,
            ior: values.ior,
            attenuation: values.attenuation,
            clearcoat: values.clearcoat,
            coat: Ggx::from_roughness(values.clearcoat_roughness),
            sheen: Sheen::new(values.sheen_color, values.sheen_roughness),
            sheen_roughness: values.sheen_roughness,
            sheened: values.sheen_color.max_element() > 0.0,
        }
    }

    /// Whether some lobe is not a delta.
    #[inline]
    pub fn has_smooth_lobes(&self) -> bool {
        let weights = self.lobe_weights(Vec3::Z);
        weights[DIFFUSE] > 0.0
            || weights[SHEEN] > 0.0
            || (weights[SPECULAR] > 0.0 && !self.ggx.is_delta())
            || (weights[TRANSMISSION] > 0.0 && !self.ggx.is_delta())
            || (weights[CLEARCOAT] > 0.0 && !self.coat.is_delta())
    }

    /// The attenuation coefficient inside the volume this surface bounds, if it
    /// bounds one.
    #[inline]
    pub fn attenuation(&self) -> Option<Vec3> {
        (self.volume && self.transmission > 0.0).then_some(self.attenuation)
    }

    /// The clearcoat's weight seen from `wo`: `clearcoat * F_coat(|n.wo|)`.
    #[inline]
    fn coat_weight(&self, wo: Vec3) -> Float {
        if self.clearcoat > 0.0 {
            self.clearcoat * schlick_scalar(CLEARCOAT_F0, wo.z)
        } else {
            0.0
        }
    }

    /// What the sheen leaves of the material under it, for the pair of directions.
    #[inline]
    fn sheen_scale(&self, wo: Vec3, wi: Vec3) -> Float {
        if !self.sheened {
            return 1.0;
        }
        let max = self.sheen.color.max_element();
        let albedo = sheen::albedo(wo.z.abs(), self.sheen_roughness)
            .max(sheen::albedo(wi.z.abs(), self.sheen_roughness));
        (1.0 - max * albedo).max(0.0)
    }

    /// The estimated albedo of each lobe seen from `wo`, by which one is picked.
    #[inline]
    fn lobe_weights(&self, wo: Vec3) -> [Float; 5] {
        let w = schlick_weight(wo.z);
        let fd = self.f0 + (Vec3::splat(self.f90) - self.f0) * w;
        let fm = self.base + (Vec3::ONE - self.base) * w;
        let coat = self.coat_weight(wo);
        let sheen_albedo = if self.sheened {
            sheen::albedo(wo.z.abs(), self.sheen_roughness)
        } else {
            0.0
        };
        let scale = (1.0 - coat) * (1.0 - self.sheen.color.max_element() * sheen_albedo).max(0.0);
        let dielectric = 1.0 - self.metallic;
        let under = scale * dielectric * (1.0 - fd.max_element()) * mean(self.base);
        [
            under * (1.0 - self.transmission),
            scale * (dielectric * mean(fd) + self.metallic * mean(fm)),
            under * self.transmission,
            coat,
            mean(self.sheen.color) * sheen_albedo,
        ]
    }

    /// The lobe probabilities at `wo`, summing to 1 (all 0 if nothing scatters).
    #[inline]
    fn lobe_probabilities(&self, wo: Vec3) -> [Float; 5] {
        let weights = self.lobe_weights(wo);
        let total: Float = weights.iter().sum();
        if total > 0.0 && total.is_finite() {
            weights.map(|w| w / total)
        } else {
            [0.0; 5]
        }
    }

    /// The relative index `wi`'s side over `wo`'s, crossing from the front or back.
    #[inline]
    fn eta(&self, front: bool) -> Float {
        if front { self.ior } else { 1.0 / self.ior }
    }

    /// `f(wo, wi)` of the non-delta lobes, in the local frame, `front` saying whether
    /// `wo` is outside the volume the surface bounds.
    #[inline]
    pub fn eval_sided(&self, wo: Vec3, wi: Vec3, front: bool) -> Vec3 {
        if wo.z <= 0.0 || wi.z == 0.0 {
            return Vec3::ZERO;
        }
        let base_layer = if wi.z > 0.0 {
            self.reflection(wo, wi)
        } else if self.transmission > 0.0 && self.metallic < 1.0 && !self.ggx.is_delta() {
            self.transmitted(wo, wi, front)
        } else {
            Vec3::ZERO
        };
        let mut f = base_layer * self.sheen_scale(wo, wi);
        if self.sheened && wi.z > 0.0 {
            f += self.sheen.eval(wo, wi);
        }
        let coat = self.coat_weight(wo);
        if coat > 0.0 {
            f *= 1.0 - coat;
            if wi.z > 0.0 && !self.coat.is_delta() {
                let h = (wo + wi).normalize();
                f += Vec3::splat(coat * self.coat.d(h) * self.coat.visibility(wo, wi));
            }
        }
        f
    }

    /// The metal and dielectric reflection under the sheen and the coat.
    #[inline]
    fn reflection(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        let h = (wo + wi).normalize();
        let w = schlick_weight(wo.dot(h));
        let specular = if self.ggx.is_delta() {
            0.0
        } else {
            self.ggx.d(h) * self.ggx.visibility(wo, wi)
        };
        let fd = self.f0 + (Vec3::splat(self.f90) - self.f0) * w;
        let diffuse =
            self.base * ((1.0 - fd.max_element()) * (1.0 - self.transmission) * FRAC_1_PI);
        let dielectric = fd * specular + diffuse;
        let metal = (self.base + (Vec3::ONE - self.base) * w) * specular;
        dielectric.lerp(metal, self.metallic)
    }

    /// The transmitted part, `wi` below the surface.
    #[inline]
    fn transmitted(&self, wo: Vec3, wi: Vec3, front: bool) -> Vec3 {
        let weight = (1.0 - self.metallic) * self.transmission;
        if !self.volume {
            // Thin-walled: the reflection lobe mirrored through the surface.
            let mirrored = Vec3::new(wi.x, wi.y, -wi.z);
            let h = (wo + mirrored).normalize();
            let w = schlick_weight(wo.dot(h));
            let fd = self.f0 + (Vec3::splat(self.f90) - self.f0) * w;
            let btdf = self.ggx.d(h) * self.ggx.visibility(wo, mirrored);
            return self.base * (weight * (1.0 - fd.max_element()) * btdf);
        }
        let eta = self.eta(front);
        let Some(h) = refraction_half_vector(wo, wi, eta) else {
            return Vec3::ZERO;
        };
        let (o, i) = (wo.dot(h), wi.dot(h));
        let w = schlick_weight(o);
        let fd = self.f0 + (Vec3::splat(self.f90) - self.f0) * w;
        let denominator = (i + o / eta) * (i + o / eta) * wi.z.abs() * wo.z;
        let btdf = self.ggx.d(h) * self.ggx.g2(wo, wi) * (i * o).abs() / denominator;
        // Radiance crossing into a denser medium is compressed into a smaller solid
        // angle: divided by eta^2, as pbrt and Mitsuba do in radiance mode.
        self.base * (weight * (1.0 - fd.max_element()) * btdf / (eta * eta))
    }

    /// The density of the non-delta lobes at `wi`.
    #[inline]
    pub fn pdf_sided(&self, wo: Vec3, wi: Vec3, front: bool) -> Float {
        if wo.z <= 0.0 || wi.z == 0.0 {
            return 0.0;
        }
        let p = self.lobe_probabilities(wo);
        let mut pdf = 0.0;
        if wi.z > 0.0 {
            let cosine = wi.z * FRAC_1_PI;
            pdf += (p[DIFFUSE] + p[SHEEN]) * cosine;
            let h = (wo + wi).normalize();
            if p[SPECULAR] > 0.0 && !self.ggx.is_delta() {
                pdf += p[SPECULAR] * reflection_pdf(&self.ggx, wo, h);
            }
            if p[CLEARCOAT] > 0.0 && !self.coat.is_delta() {
                pdf += p[CLEARCOAT] * reflection_pdf(&self.coat, wo, h);
            }
        } else if p[TRANSMISSION] > 0.0 && !self.ggx.is_delta() {
            pdf += p[TRANSMISSION] * self.transmission_pdf(wo, wi, front);
        }
        pdf
    }

    /// The density of a transmitted direction drawn through a visible normal.
    #[inline]
    fn transmission_pdf(&self, wo: Vec3, wi: Vec3, front: bool) -> Float {
        if !self.volume {
            let h = (wo + Vec3::new(wi.x, wi.y, -wi.z)).normalize();
            return reflection_pdf(&self.ggx, wo, h);
        }
        let eta = self.eta(front);
        let Some(h) = refraction_half_vector(wo, wi, eta) else {
            return 0.0;
        };
        let (o, i) = (wo.dot(h), wi.dot(h));
        let jacobian = i.abs() / ((i + o / eta) * (i + o / eta));
        self.ggx.visible_pdf(wo, h) * jacobian
    }

    /// A direction, in the local frame, `front` saying whether `wo` is outside the
    /// volume the surface bounds.
    #[inline]
    pub fn sample(&self, wo: Vec3, front: bool, u_lobe: Float, u: Vec2) -> Option<LocalSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let p = self.lobe_probabilities(wo);
        let mut lobe = 0;
        let mut below = 0.0;
        while lobe < SHEEN && u_lobe >= below + p[lobe] {
            below += p[lobe];
            lobe += 1;
        }
        // Rounding may carry `u_lobe` past the last lobe that has any weight.
        while p[lobe] <= 0.0 {
            if lobe == DIFFUSE {
                return None;
            }
            lobe -= 1;
        }
        let mirror = Vec3::new(-wo.x, -wo.y, wo.z);
        let wi = match lobe {
            DIFFUSE | SHEEN => cosine_hemisphere(u),
            SPECULAR if self.ggx.is_delta() => return Some(self.delta_reflection(wo, p[SPECULAR])),
            SPECULAR => reflect(-wo, self.ggx.sample_visible(wo, u)),
            TRANSMISSION if self.ggx.is_delta() => {
                return self.delta_transmission(wo, front, p[TRANSMISSION]);
            }
            TRANSMISSION => {
                let h = self.ggx.sample_visible(wo, u);
                if self.volume {
                    refract(-wo, h, 1.0 / self.eta(front))?
                } else {
                    let r = reflect(-wo, h);
                    if r.z <= 0.0 {
                        return None;
                    }
                    Vec3::new(r.x, r.y, -r.z)
                }
            }
            _ if self.coat.is_delta() => {
                let coat = self.coat_weight(wo);
                return Some(LocalSample {
                    wi: mirror,
                    weight: Vec3::splat(coat / p[CLEARCOAT]),
                    pdf: p[CLEARCOAT],
                    delta: true,
                    eta: 1.0,
                });
            }
            _ => reflect(-wo, self.coat.sample_visible(wo, u)),
        };
        // A reflection through a microfacet may leave below the surface: not a
        // direction the reflection lobes have, and not for the transmission's pdf.
        if (wi.z <= 0.0) != (lobe == TRANSMISSION) {
            return None;
        }
        let pdf = self.pdf_sided(wo, wi, front);
        if pdf.is_nan() || pdf <= 0.0 {
            return None;
        }
        let f = self.eval_sided(wo, wi, front);
        let crossed = wi.z < 0.0 && self.volume;
        Some(LocalSample {
            wi,
            weight: f * wi.z.abs() / pdf,
            pdf,
            delta: false,
            eta: if crossed { self.eta(front) } else { 1.0 },
        })
    }

    /// The mirror reflection of a smooth surface, chosen with probability `p`.
    #[inline]
    fn delta_reflection(&self, wo: Vec3, p: Float) -> LocalSample {
        let wi = Vec3::new(-wo.x, -wo.y, wo.z);
        let w = schlick_weight(wo.z);
        let fd = self.f0 + (Vec3::splat(self.f90) - self.f0) * w;
        let fm = self.base + (Vec3::ONE - self.base) * w;
        let layers = (1.0 - self.coat_weight(wo)) * self.sheen_scale(wo, wi);
        LocalSample {
            wi,
            weight: fd.lerp(fm, self.metallic) * (layers / p),
            pdf: p,
            delta: true,
            eta: 1.0,
        }
    }

    /// Light passing a smooth surface: straight through a thin one, refracted into
    /// (or out of) a volume; chosen with probability `p`.
    #[inline]
    fn delta_transmission(&self, wo: Vec3, front: bool, p: Float) -> Option<LocalSample> {
        let fd = self.f0 + (Vec3::splat(self.f90) - self.f0) * schlick_weight(wo.z);
        let (wi, eta) = if self.volume {
            let eta = self.eta(front);
            match refract(-wo, Vec3::Z, 1.0 / eta) {
                Some(wi) => (wi, eta),
                // Total internal reflection: what would have passed is reflected.
                None => (Vec3::new(-wo.x, -wo.y, wo.z), 1.0),
            }
        } else {
            (-wo, 1.0)
        };
        let layers = (1.0 - self.coat_weight(wo)) * self.sheen_scale(wo, wi);
        let passed = (1.0 - self.metallic) * self.transmission * (1.0 - fd.max_element()) * layers;
        Some(LocalSample {
            wi,
            weight: self.base * (passed / (p * eta * eta)),
            pdf: p,
            delta: true,
            eta,
        })
    }
}

/// The microfacet normal that refracts `wo` into `wi` at relative index `eta`
/// (`wi`'s side over `wo`'s), facing `+z`; `None` unless both lie on the sides a
/// refraction through it puts them.
#[inline]
fn refraction_half_vector(wo: Vec3, wi: Vec3, eta: Float) -> Option<Vec3> {
    let h = (wo + wi * eta).try_normalize()?;
    let h = if h.z < 0.0 { -h } else { h };
    (wo.dot(h) > 0.0 && wi.dot(h) < 0.0).then_some(h)
}

#[inline]
fn mean(v: Vec3) -> Float {
    (v.x + v.y + v.z) / 3.0
}

/// The BSDF seen from outside its volume, for the conformance suite.
impl Lobe for GltfBsdf {
    fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        self.eval_sided(wo, wi, true)
    }

    fn pdf(&self, wo: Vec3, wi: Vec3) -> Float {
        self.pdf_sided(wo, wi, true)
    }

    fn sample(&self, wo: Vec3, u_lobe: Float, u: Vec2) -> Option<LocalSample> {
        GltfBsdf::sample(self, wo, true, u_lobe, u)
    }
}
