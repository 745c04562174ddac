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
//! directions' albedos), and a clearcoat of index 1.5 with its own shading normal
//! (`clearcoatNormalTexture`; `F_cc`, `D_cc` and `V_cc` are then taken about it, and
//! a coat facing away from `wo` reflects nothing). `btdf` is the base-coloured GGX lobe mirrored through
//! the surface for a thin-walled surface (`KHR_materials_transmission` without a
//! volume: light passes straight through a smooth one), or Walter et al.'s rough
//! refraction at `ior` into a volume (`KHR_materials_volume`), whose attenuation the
//! integrator applies over the distance travelled inside. A roughness under
//! `sqrt(DELTA_ALPHA)` makes a lobe a delta (a mirror, a smooth pane), never a NaN.
//!
//! Optionally (`multiple_scattering`, off by default), the GGX reflection lobes
//! (metal, dielectric specular, coat) are scaled by Turquin's multiple-scattering
//! compensation `1 + F0 (1 - E(|N.V|)) / E(|N.V|)`, `E` the white lobe's directional
//! albedo ([`microfacet::albedo`]), `F0` the lobe's reflectance head on: a rough
//! white metal then reflects everything it receives. The factor depends on `wo`
//! alone, so the compensated lobes are not reciprocal.
//!
//! One lobe is picked by its estimated albedo at `wo`; the density of a direction is
//! the mixture of every non-delta lobe's, so that each sample is weighted against
//! all the ways it could have been drawn.

use std::f32::consts::{FRAC_1_PI, PI};

use super::fresnel::{schlick_scalar, schlick_weight};
use super::lambert::cosine_hemisphere;
use super::microfacet::{self, AnisoGgx, Distribution, Ggx, reflection_pdf};
use super::sheen::{self, Sheen};
use super::{Frame, Lobe, LocalSample};
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
    /// Whether the GGX reflection lobes are compensated for multiple scattering.
    multiple_scattering: bool,
    /// The base's anisotropic distribution (`KHR_materials_anisotropy`), which
    /// replaces `ggx` for every base lobe (specular reflection, transmission) when
    /// set; `None` for an anisotropy of 0, which leaves every value as it was.
    aniso: Option<AnisoGgx>,
    /// The direction of anisotropy in tangent space ([`PbrValues::anisotropy_direction`]).
    aniso_direction: Vec2,
    /// Whether the material is the common plain one: a rough metal, dielectric or
    /// mix of both with no transmission, clearcoat, sheen or compensation, whose
    /// value and density take the short path ([`GltfAt::plain_eval_pdf`]).
    plain: bool,
}

/// A plain [`GltfBsdf`]'s parameters ([`GltfBsdf::plain_parameters`]).
#[derive(Clone, Copy, Debug)]
pub(super) struct PlainParameters {
    pub base: Vec3,
    pub f0: Vec3,
    pub metallic: Float,
    /// The GGX distribution's `alpha`.
    pub alpha: Float,
    pub f90: Float,
}

/// The lobes, in the order of [`GltfAt::p`].
const DIFFUSE: usize = 0;
const SPECULAR: usize = 1;
const TRANSMISSION: usize = 2;
const CLEARCOAT: usize = 3;
const SHEEN: usize = 4;

impl GltfBsdf {
    /// The BSDF of `values`.
    pub fn new(values: &PbrValues) -> GltfBsdf {
        let sheened = values.sheen_color.max_element() > 0.0;
        let aniso = (values.anisotropy > 0.0)
            .then(|| AnisoGgx::from_roughness(values.roughness, values.anisotropy));
        let ggx = match aniso {
            // What the compensation's albedo table and the delta test read: the
            // isotropic distribution of the same area, never a delta.
            Some(a) => Ggx {
                alpha: (a.alpha_x * a.alpha_y).sqrt(),
            },
            None => Ggx::from_roughness(values.roughness),
        };
        GltfBsdf {
            plain: !(values.transmission > 0.0
                || values.clearcoat > 0.0
                || sheened
                || values.multiple_scattering
                || aniso.is_some()
                || ggx.is_delta()),
            base: values.base_color,
            metallic: values.metallic,
            ggx,
            aniso,
            aniso_direction: values.anisotropy_direction,
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
            sheened,
            multiple_scattering: values.multiple_scattering,
        }
    }

    /// Whether the material is plain: a rough metal, dielectric or mix of both with
    /// no transmission, clearcoat, sheen or compensation, which path mode shades
    /// sixteen vertices at a time ([`super::gltf_lanes`]).
    #[inline]
    pub fn is_plain(&self) -> bool {
        self.plain
    }

    /// What a plain material's lobes read, if it is plain ([`GltfBsdf::is_plain`]).
    #[inline]
    pub(super) fn plain_parameters(&self) -> Option<PlainParameters> {
        self.plain.then_some(PlainParameters {
            base: self.base,
            f0: self.f0,
            metallic: self.metallic,
            alpha: self.ggx.alpha,
            f90: self.f90,
        })
    }

    /// The direction of anisotropy in tangent space, if the material is anisotropic:
    /// what the shading frame's tangent is turned by where the hit has no tangent
    /// of its own.
    #[inline]
    pub fn anisotropy_direction(&self) -> Option<Vec2> {
        self.aniso.map(|_| self.aniso_direction)
    }

    /// The base distribution's `D(h)`.
    #[inline]
    fn base_d(&self, h: Vec3) -> Float {
        match &self.aniso {
            Some(a) => a.d(h),
            None => self.ggx.d(h),
        }
    }

    /// The base distribution's `G2(wo, wi)`.
    #[inline]
    fn base_g2(&self, wo: Vec3, wi: Vec3) -> Float {
        match &self.aniso {
            Some(a) => a.g2(wo, wi),
            None => self.ggx.g2(wo, wi),
        }
    }

    /// The base distribution's visibility `V(wo, wi)`.
    #[inline]
    fn base_visibility(&self, wo: Vec3, wi: Vec3) -> Float {
        match &self.aniso {
            Some(a) => a.visibility(wo, wi),
            None => self.ggx.visibility(wo, wi),
        }
    }

    /// The base distribution's density of visible normals.
    #[inline]
    fn base_visible_pdf(&self, wo: Vec3, h: Vec3) -> Float {
        match &self.aniso {
            Some(a) => a.visible_pdf(wo, h),
            None => self.ggx.visible_pdf(wo, h),
        }
    }

    /// A visible normal of the base distribution.
    #[inline]
    fn base_sample_visible(&self, wo: Vec3, u: Vec2) -> Vec3 {
        match &self.aniso {
            Some(a) => a.sample_visible(wo, u),
            None => self.ggx.sample_visible(wo, u),
        }
    }

    /// Whether some lobe is not a delta.
    #[inline]
    pub fn has_smooth_lobes(&self) -> bool {
        self.at(Vec3::Z, true, None).has_smooth_lobes()
    }

    /// The attenuation coefficient inside the volume this surface bounds, if it
    /// bounds one.
    #[inline]
    pub fn attenuation(&self) -> Option<Vec3> {
        (self.volume && self.transmission > 0.0).then_some(self.attenuation)
    }

    /// This BSDF seen from `wo` (local, `wo.z > 0` for anything to scatter), `front`
    /// saying whether `wo` is outside the volume the surface bounds and `coat_normal`
    /// the clear coat's own unit normal in the local frame, if it has one: what
    /// [`GltfAt::eval`], [`GltfAt::pdf`] and [`GltfAt::sample`] share, computed once
    /// per path vertex.
    #[inline]
    pub fn at(&self, wo: Vec3, front: bool, coat_normal: Option<Vec3>) -> GltfAt<'_> {
        let coat_frame = match coat_normal {
            Some(n) if self.clearcoat > 0.0 && n != Vec3::Z => Some(Frame::from_normal(n)),
            _ => None,
        };
        let mut at = GltfAt {
            bsdf: self,
            wo,
            front,
            p: [0.0; 5],
            coat: 0.0,
            coat_frame,
            sheen_albedo: 0.0,
            compensation: Compensation::NONE,
            visibility_o: 0.0,
            pdf_scale: 0.0,
        };
        if wo.z <= 0.0 {
            return at;
        }
        at.visibility_o = match &self.aniso {
            Some(a) => a.stretched_length(wo),
            None => {
                let a2 = self.ggx.alpha * self.ggx.alpha;
                (a2 + (1.0 - a2) * wo.z * wo.z).sqrt()
            }
        };
        // G1 = 1 / (1 + Lambda) and 2 Lambda + 1 = visibility_o / n.wo, so
        // G1 / (4 n.wo) = 1 / (2 (n.wo + visibility_o)).
        at.pdf_scale = 0.5 / (wo.z + at.visibility_o);
        if self.clearcoat > 0.0 {
            let cos = at.in_coat(wo).z.max(0.0);
            at.coat = self.clearcoat * schlick_scalar(CLEARCOAT_F0, cos);
        }
        if self.multiple_scattering {
            let e = microfacet::albedo(wo.z, self.ggx.alpha);
            let e_coat = microfacet::albedo(at.in_coat(wo).z.max(0.0), self.coat.alpha);
            at.compensation = Compensation {
                dielectric: microfacet::compensation(self.f0, e),
                metal: microfacet::compensation(self.base.min(Vec3::ONE), e),
                coat: microfacet::compensation(Vec3::splat(CLEARCOAT_F0), e_coat).x,
            };
        }
        if self.sheened {
            at.sheen_albedo = sheen::albedo(wo.z, self.sheen_roughness);
        }
        at.p = at.lobe_probabilities();
        at
    }

    /// The relative index `wi`'s side over `wo`'s, crossing from the front or back.
    #[inline]
    fn eta(&self, front: bool) -> Float {
        if front { self.ior } else { 1.0 / self.ior }
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
            let btdf = self.base_d(h) * self.base_visibility(wo, mirrored);
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
        let btdf = self.base_d(h) * self.base_g2(wo, wi) * (i * o).abs() / denominator;
        // Radiance crossing into a denser medium is compressed into a smaller solid
        // angle: divided by eta^2, as pbrt and Mitsuba do in radiance mode.
        self.base * (weight * (1.0 - fd.max_element()) * btdf / (eta * eta))
    }

    /// The density of a transmitted direction drawn through a visible normal.
    #[inline]
    fn transmission_pdf(&self, wo: Vec3, wi: Vec3, front: bool) -> Float {
        if !self.volume {
            let h = (wo + Vec3::new(wi.x, wi.y, -wi.z)).normalize();
            return match &self.aniso {
                Some(a) => reflection_pdf(a, wo, h),
                None => reflection_pdf(&self.ggx, wo, h),
            };
        }
        let eta = self.eta(front);
        let Some(h) = refraction_half_vector(wo, wi, eta) else {
            return 0.0;
        };
        let (o, i) = (wo.dot(h), wi.dot(h));
        let jacobian = i.abs() / ((i + o / eta) * (i + o / eta));
        self.base_visible_pdf(wo, h) * jacobian
    }
}

/// A [`GltfBsdf`] seen from one direction `wo` ([`GltfBsdf::at`]): the lobe
/// probabilities, the coat's weight and frame and the sheen's albedo at `wo`, which
/// light sampling's `eval` and `pdf` and the bounce's `sample` all read.
#[derive(Clone, Copy, Debug)]
pub struct GltfAt<'a> {
    bsdf: &'a GltfBsdf,
    wo: Vec3,
    front: bool,
    /// The lobe probabilities at `wo`, summing to 1 (all 0 if nothing scatters).
    p: [Float; 5],
    /// The clearcoat's weight seen from `wo`: `clearcoat * F_coat(|n_coat.wo|)`.
    coat: Float,
    /// The coat's frame in the local one, where its normal differs from the base's.
    coat_frame: Option<Frame>,
    /// The white sheen's directional albedo at `wo` (0 without sheen).
    sheen_albedo: Float,
    /// What the GGX reflection lobes are scaled by at `wo`.
    compensation: Compensation,
    /// The base distribution's `sqrt(a^2 + (1 - a^2) (n.wo)^2)` (`a = alpha`), the
    /// half of [`Ggx::visibility`] that depends on `wo` alone.
    visibility_o: Float,
    /// The base distribution's masking over four cosines, `G1(wo) / (4 n.wo)`:
    /// what turns `D(h)` into the density of the reflection through `h`.
    pdf_scale: Float,
}

/// Multiple-scattering compensation factors of the GGX reflection lobes at one `wo`
/// ([`microfacet::compensation`]); 1 when it is off.
#[derive(Clone, Copy, Debug)]
struct Compensation {
    dielectric: Vec3,
    metal: Vec3,
    coat: Float,
}

impl Compensation {
    const NONE: Compensation = Compensation {
        dielectric: Vec3::ONE,
        metal: Vec3::ONE,
        coat: 1.0,
    };
}

impl GltfAt<'_> {
    /// `v` (in the local frame) in the coat's frame.
    #[inline]
    fn in_coat(&self, v: Vec3) -> Vec3 {
        match &self.coat_frame {
            Some(frame) => frame.to_local(v),
            None => v,
        }
    }

    /// `v` in the coat's frame, in the local frame.
    #[inline]
    fn out_of_coat(&self, v: Vec3) -> Vec3 {
        match &self.coat_frame {
            Some(frame) => frame.to_world(v),
            None => v,
        }
    }

    /// What the sheen leaves of the material under it, towards `wi`.
    #[inline]
    fn sheen_scale(&self, wi: Vec3) -> Float {
        let g = self.bsdf;
        if !g.sheened {
            return 1.0;
        }
        let max = g.sheen.color.max_element();
        let albedo = self
            .sheen_albedo
            .max(sheen::albedo(wi.z.abs(), g.sheen_roughness));
        (1.0 - max * albedo).max(0.0)
    }

    /// The estimated albedo of each lobe seen from `wo`, normalised to the
    /// probabilities by which one is picked.
    #[inline]
    fn lobe_probabilities(&self) -> [Float; 5] {
        let g = self.bsdf;
        let w = schlick_weight(self.wo.z);
        let fd = g.f0 + (Vec3::splat(g.f90) - g.f0) * w;
        let fm = g.base + (Vec3::ONE - g.base) * w;
        let scale =
            (1.0 - self.coat) * (1.0 - g.sheen.color.max_element() * self.sheen_albedo).max(0.0);
        let dielectric = 1.0 - g.metallic;
        let under = scale * dielectric * (1.0 - fd.max_element()) * mean(g.base);
        // A coat tilted away from `wo` darkens the base but reflects nothing.
        let coat_lobe = if self.in_coat(self.wo).z > 0.0 {
            self.coat
        } else {
            0.0
        };
        let weights = [
            under * (1.0 - g.transmission),
            scale * (dielectric * mean(fd) + g.metallic * mean(fm)),
            under * g.transmission,
            coat_lobe,
            mean(g.sheen.color) * self.sheen_albedo,
        ];
        let total: Float = weights.iter().sum();
        if total > 0.0 && total.is_finite() {
            let scale = 1.0 / total;
            weights.map(|w| w * scale)
        } else {
            [0.0; 5]
        }
    }

    /// Whether some lobe seen from `wo` is not a delta.
    #[inline]
    pub fn has_smooth_lobes(&self) -> bool {
        let (g, p) = (self.bsdf, &self.p);
        p[DIFFUSE] > 0.0
            || p[SHEEN] > 0.0
            || ((p[SPECULAR] > 0.0 || p[TRANSMISSION] > 0.0) && !g.ggx.is_delta())
            || (p[CLEARCOAT] > 0.0 && !g.coat.is_delta())
    }

    /// `f(wo, wi)` of the non-delta lobes, in the local frame.
    #[inline]
    pub fn eval(&self, wi: Vec3) -> Vec3 {
        self.eval_pdf(wi).0
    }

    /// The density of the non-delta lobes at `wi`.
    #[inline]
    pub fn pdf(&self, wi: Vec3) -> Float {
        self.eval_pdf(wi).1
    }

    /// `f(wo, wi)` of the non-delta lobes and their density at `wi`, for light
    /// sampling's MIS: one half vector and one `D` for both.
    #[inline]
    pub fn eval_and_pdf(&self, wi: Vec3) -> (Vec3, Float) {
        self.eval_pdf(wi)
    }

    /// `f(wo, wi)` and the density at `wi`, sharing the half vector and `D` (inlined
    /// into [`GltfAt::eval`] and [`GltfAt::pdf`], each keeps only its half).
    #[inline(always)]
    fn eval_pdf(&self, wi: Vec3) -> (Vec3, Float) {
        let (g, wo, p) = (self.bsdf, self.wo, &self.p);
        if wo.z <= 0.0 || wi.z == 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        if g.plain {
            return self.plain_eval_pdf(wi);
        }
        let mut pdf = 0.0;
        let mut half = Vec3::Z;
        let base_layer = if wi.z > 0.0 {
            let h = (wo + wi).normalize();
            half = h;
            let d = if g.ggx.is_delta() { 0.0 } else { g.base_d(h) };
            pdf += (p[DIFFUSE] + p[SHEEN]) * (wi.z * FRAC_1_PI);
            if p[SPECULAR] > 0.0 {
                pdf += p[SPECULAR] * self.specular_pdf(d, h);
            }
            self.reflection(wi, h, d)
        } else {
            if p[TRANSMISSION] > 0.0 && !g.ggx.is_delta() {
                pdf += p[TRANSMISSION] * g.transmission_pdf(wo, wi, self.front);
            }
            if g.transmission > 0.0 && g.metallic < 1.0 && !g.ggx.is_delta() {
                g.transmitted(wo, wi, self.front)
            } else {
                Vec3::ZERO
            }
        };
        let mut f = base_layer * self.sheen_scale(wi);
        if g.sheened && wi.z > 0.0 {
            f += g.sheen.eval(wo, wi);
        }
        if self.coat > 0.0 {
            f *= 1.0 - self.coat;
            if wi.z > 0.0 && !g.coat.is_delta() {
                let (o, i) = (self.in_coat(wo), self.in_coat(wi));
                if o.z > 0.0 && i.z > 0.0 {
                    let h = self.in_coat(half);
                    let coat = self.coat * self.compensation.coat;
                    f += Vec3::splat(coat * g.coat.d(h) * g.coat.visibility(o, i));
                    if p[CLEARCOAT] > 0.0 {
                        pdf += p[CLEARCOAT] * reflection_pdf(&g.coat, o, h);
                    }
                }
            }
        }
        (f, pdf)
    }

    /// [`GltfAt::eval_pdf`] of a plain material ([`GltfBsdf::plain`]): the diffuse
    /// and specular reflection lobes alone, nothing below the surface.
    #[inline(always)]
    fn plain_eval_pdf(&self, wi: Vec3) -> (Vec3, Float) {
        if wi.z < 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let p = &self.p;
        let h = (self.wo + wi).normalize();
        let (d, specular) = self.plain_d_dv(h, wi);
        let mut pdf = p[DIFFUSE] * (wi.z * FRAC_1_PI);
        if p[SPECULAR] > 0.0 {
            pdf += p[SPECULAR] * self.specular_pdf(d, h);
        }
        (self.reflected(h, specular), pdf)
    }

    /// `D(h)` and `D(h) V(wo, wi)` of a plain material's (not delta) distribution
    /// for `wi` above the surface, from one division where [`Ggx::d`] and
    /// [`GltfAt::visibility`] take one each (divisions are most of a BSDF's cost).
    #[inline(always)]
    fn plain_d_dv(&self, h: Vec3, wi: Vec3) -> (Float, Float) {
        if h.z <= 0.0 {
            return (0.0, 0.0);
        }
        let a2 = self.bsdf.ggx.alpha * self.bsdf.ggx.alpha;
        let t = h.z * h.z * (a2 - 1.0) + 1.0;
        // Positive: `wo.z > 0` and `a2 > 0` (not a delta lobe).
        let denominator = self.visibility_denominator(wi);
        let product = PI * t * t * denominator;
        if product.is_nan() || product < Float::MIN_POSITIVE {
            // Tiny enough to lose bits (or NaN): the two quotients apart.
            let d = self.bsdf.ggx.d(h);
            return (d, d * self.visibility(wi));
        }
        // D = a2 / (pi t^2), V = 0.5 / denominator.
        let q = 1.0 / product;
        (a2 * denominator * q, 0.5 * a2 * q)
    }

    /// [`GltfAt::sample`]'s specular lobe of a plain material: the direction
    /// reflected through a visible normal `h` and its weight `F G2 / G1`
    /// straight from `h` (the density cancels `D`, which is computed only for the
    /// density itself), `D V` and the mixture's density otherwise as
    /// [`GltfAt::plain_eval_pdf`] gives them.
    #[inline(always)]
    fn plain_specular_sample(&self, u: Vec2) -> Option<LocalSample> {
        let (g, wo, p) = (self.bsdf, self.wo, &self.p);
        let h = g.ggx.sample_visible(wo, u);
        let o = wo.dot(h);
        let wi = h * (2.0 * o) - wo;
        if wi.z <= 0.0 || o <= 0.0 {
            return None;
        }
        if p[DIFFUSE] == 0.0 {
            // A metal: f cos / pdf = F D V cos / (p_specular D pdf_scale)
            // = F cos / (2 p_specular pdf_scale denominator), V = 0.5 / denominator;
            // `D` only for the density.
            let pdf = p[SPECULAR] * (self.pdf_scale * g.ggx.d(h));
            if pdf.is_nan() || pdf <= 0.0 {
                return None;
            }
            let w = schlick_weight(o);
            let fm = g.base + (Vec3::ONE - g.base) * w;
            let fd = g.f0 + (Vec3::splat(g.f90) - g.f0) * w;
            let scale = self.visibility_denominator(wi) * self.pdf_scale * p[SPECULAR];
            let weight = fd.lerp(fm, g.metallic) * (0.5 * wi.z / scale);
            return Some(LocalSample::smooth(wi, weight, pdf));
        }
        let (d, specular) = self.plain_d_dv(h, wi);
        let pdf = p[DIFFUSE] * (wi.z * FRAC_1_PI) + p[SPECULAR] * (self.pdf_scale * d);
        if pdf.is_nan() || pdf <= 0.0 {
            return None;
        }
        let weight = self.reflected(h, specular) * (wi.z / pdf);
        Some(LocalSample::smooth(wi, weight, pdf))
    }

    /// The metal and dielectric reflection under the sheen and the coat towards
    /// `wi` (above the surface), of half vector `h` where the GGX distribution is
    /// `d` (0 for a delta lobe), their specular lobes scaled by the compensation.
    #[inline(always)]
    fn reflection(&self, wi: Vec3, h: Vec3, d: Float) -> Vec3 {
        self.reflected(h, d * self.visibility(wi))
    }

    /// [`GltfAt::reflection`] where `D V` is `specular`.
    #[inline(always)]
    fn reflected(&self, h: Vec3, specular: Float) -> Vec3 {
        let g = self.bsdf;
        let w = schlick_weight(self.wo.dot(h));
        let fd = g.f0 + (Vec3::splat(g.f90) - g.f0) * w;
        let diffuse = g.base * ((1.0 - fd.max_element()) * (1.0 - g.transmission) * FRAC_1_PI);
        let dielectric = fd * self.compensation.dielectric * specular + diffuse;
        let metal = (g.base + (Vec3::ONE - g.base) * w) * self.compensation.metal * specular;
        dielectric.lerp(metal, g.metallic)
    }

    /// [`Ggx::visibility`] of the base's distribution from `wo` towards `wi`, its
    /// `wo` half computed once in [`GltfBsdf::at`].
    #[inline(always)]
    fn visibility(&self, wi: Vec3) -> Float {
        if let Some(a) = &self.bsdf.aniso {
            let denominator = wi.z.abs() * self.visibility_o + self.wo.z * a.stretched_length(wi);
            return if denominator > 0.0 {
                0.5 / denominator
            } else {
                0.0
            };
        }
        let denominator = self.visibility_denominator(wi);
        if denominator > 0.0 {
            0.5 / denominator
        } else {
            0.0
        }
    }

    /// `0.5 / V(wo, wi)` of the base's distribution ([`GltfAt::visibility`]).
    #[inline(always)]
    fn visibility_denominator(&self, wi: Vec3) -> Float {
        let a2 = self.bsdf.ggx.alpha * self.bsdf.ggx.alpha;
        let ci = wi.z.abs();
        ci * self.visibility_o + self.wo.z * (a2 + (1.0 - a2) * ci * ci).sqrt()
    }

    /// [`reflection_pdf`] of the base's distribution where `D(h)` is `d`:
    /// `G1(wo) D(h) / (4 n.wo)` for `wo.h > 0`, `G1(wo) / (4 n.wo)` computed once.
    #[inline(always)]
    fn specular_pdf(&self, d: Float, h: Vec3) -> Float {
        if self.wo.dot(h) <= 0.0 {
            return 0.0;
        }
        self.pdf_scale * d
    }

    /// A direction, in the local frame: `u_lobe` picks a lobe, `u` a direction in it.
    #[inline]
    pub fn sample(&self, u_lobe: Float, u: Vec2) -> Option<LocalSample> {
        let (g, wo, p, front) = (self.bsdf, self.wo, &self.p, self.front);
        if wo.z <= 0.0 {
            return None;
        }
        if g.plain {
            if u_lobe >= p[DIFFUSE] && p[SPECULAR] > 0.0 {
                return self.plain_specular_sample(u);
            }
            if p[DIFFUSE] <= 0.0 {
                return None;
            }
            let wi = cosine_hemisphere(u);
            if wi.z <= 0.0 {
                return None;
            }
            let (f, pdf) = self.plain_eval_pdf(wi);
            if pdf.is_nan() || pdf <= 0.0 {
                return None;
            }
            return Some(LocalSample::smooth(wi, f * wi.z / pdf, pdf));
        }
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
        let wi = match lobe {
            DIFFUSE | SHEEN => cosine_hemisphere(u),
            SPECULAR if g.ggx.is_delta() => return Some(self.delta_reflection(p[SPECULAR])),
            SPECULAR => reflect(-wo, g.base_sample_visible(wo, u)),
            TRANSMISSION if g.ggx.is_delta() => {
                return self.delta_transmission(p[TRANSMISSION]);
            }
            TRANSMISSION => {
                let h = g.base_sample_visible(wo, u);
                if g.volume {
                    refract(-wo, h, 1.0 / g.eta(front))?
                } else {
                    let r = reflect(-wo, h);
                    if r.z <= 0.0 {
                        return None;
                    }
                    Vec3::new(r.x, r.y, -r.z)
                }
            }
            _ if g.coat.is_delta() => {
                let o = self.in_coat(wo);
                let wi = self.out_of_coat(Vec3::new(-o.x, -o.y, o.z));
                if wi.z <= 0.0 {
                    return None;
                }
                return Some(LocalSample {
                    wi,
                    weight: Vec3::splat(self.coat / p[CLEARCOAT]),
                    pdf: p[CLEARCOAT],
                    delta: true,
                    eta: 1.0,
                });
            }
            _ => {
                let o = self.in_coat(wo);
                self.out_of_coat(reflect(-o, g.coat.sample_visible(o, u)))
            }
        };
        // A reflection through a microfacet may leave below the surface: not a
        // direction the reflection lobes have, and not for the transmission's pdf.
        if (wi.z <= 0.0) != (lobe == TRANSMISSION) {
            return None;
        }
        let (f, pdf) = self.eval_pdf(wi);
        if pdf.is_nan() || pdf <= 0.0 {
            return None;
        }
        let crossed = wi.z < 0.0 && g.volume;
        Some(LocalSample {
            wi,
            weight: f * wi.z.abs() / pdf,
            pdf,
            delta: false,
            eta: if crossed { g.eta(front) } else { 1.0 },
        })
    }

    /// The mirror reflection of a smooth surface, chosen with probability `p`.
    #[inline]
    fn delta_reflection(&self, p: Float) -> LocalSample {
        let (g, wo) = (self.bsdf, self.wo);
        let wi = Vec3::new(-wo.x, -wo.y, wo.z);
        let w = schlick_weight(wo.z);
        let fd = g.f0 + (Vec3::splat(g.f90) - g.f0) * w;
        let fm = g.base + (Vec3::ONE - g.base) * w;
        let layers = (1.0 - self.coat) * self.sheen_scale(wi);
        LocalSample {
            wi,
            weight: fd.lerp(fm, g.metallic) * (layers / p),
            pdf: p,
            delta: true,
            eta: 1.0,
        }
    }

    /// Light passing a smooth surface: straight through a thin one, refracted into
    /// (or out of) a volume; chosen with probability `p`.
    #[inline]
    fn delta_transmission(&self, p: Float) -> Option<LocalSample> {
        let (g, wo) = (self.bsdf, self.wo);
        let fd = g.f0 + (Vec3::splat(g.f90) - g.f0) * schlick_weight(wo.z);
        let (wi, eta) = if g.volume {
            let eta = g.eta(self.front);
            match refract(-wo, Vec3::Z, 1.0 / eta) {
                Some(wi) => (wi, eta),
                // Total internal reflection: what would have passed is reflected.
                None => (Vec3::new(-wo.x, -wo.y, wo.z), 1.0),
            }
        } else {
            (-wo, 1.0)
        };
        let layers = (1.0 - self.coat) * self.sheen_scale(wi);
        let passed = (1.0 - g.metallic) * g.transmission * (1.0 - fd.max_element()) * layers;
        Some(LocalSample {
            wi,
            weight: g.base * (passed / (p * eta * eta)),
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
    (v.x + v.y + v.z) * (1.0 / 3.0)
}

/// The BSDF seen from outside its volume, for the conformance suite.
impl Lobe for GltfBsdf {
    fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        self.at(wo, true, None).eval(wi)
    }

    fn pdf(&self, wo: Vec3, wi: Vec3) -> Float {
        self.at(wo, true, None).pdf(wi)
    }

    fn sample(&self, wo: Vec3, u_lobe: Float, u: Vec2) -> Option<LocalSample> {
        self.at(wo, true, None).sample(u_lobe, u)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::pbr::PbrMaterial;

    fn plain(metallic: Float, roughness: Float) -> GltfBsdf {
        let g = GltfBsdf::new(
            &PbrMaterial {
                base_color: Vec3::new(1.0, 0.766, 0.336),
                metallic,
                roughness,
                ..PbrMaterial::default()
            }
            .constants(),
        );
        assert!(g.plain);
        g
    }

    /// A direction above the surface from two numbers in [0, 1).
    fn above(a: Float, b: Float) -> Vec3 {
        let z = (1.0 - a).max(1e-7);
        let r = (1.0 - z * z).sqrt();
        let phi = 2.0 * std::f32::consts::PI * b;
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    }

    /// The plain material's one-division `D` and `D V` equal `Ggx::d` and the
    /// visibility's two quotients to float rounding, down to the smoothest plain
    /// roughness and grazing directions (where the product falls back to two
    /// quotients); and the metal's short sample weight equals `f cos / pdf`.
    #[test]
    fn plain_quotients_agree_with_the_general_ones() {
        let mut checked = 0;
        for &roughness in &[0.011, 0.05, 0.3, 0.4, 1.0] {
            for &metallic in &[0.0, 1.0] {
                let g = plain(metallic, roughness);
                for i in 0..24 {
                    for j in 0..24 {
                        let wo = above(i as Float / 24.0, 0.37);
                        let wi = above((j as Float + 0.5) / 24.0, j as Float / 7.0);
                        let at = g.at(wo, true, None);
                        let h = (wo + wi).normalize();
                        let (d, dv) = at.plain_d_dv(h, wi);
                        let (d0, v0) = (g.ggx.d(h), at.visibility(wi));
                        let close = |a: Float, b: Float| a == b || (a - b).abs() <= 4e-6 * b.abs();
                        assert!(close(d, d0), "D {d} vs {d0} at {roughness} {wo} {wi}");
                        assert!(close(dv, d0 * v0), "DV {dv} vs {} {wo} {wi}", d0 * v0);
                        let u = Vec2::new(i as Float / 24.0, j as Float / 24.0);
                        // (Not the smooth ones: there `h` normalised again from `wo +
                        // wi` moves far up `D`'s steep peak.)
                        if metallic == 1.0
                            && roughness >= 0.3
                            && let Some(s) = at.sample(0.5, u)
                            && s.pdf.is_finite()
                        {
                            let (f, pdf) = at.eval_and_pdf(s.wi);
                            let expected = f * s.wi.z / pdf;
                            // `h` sampled, against `h` normalised again from `wo + wi`.
                            let near = |a: Float, b: Float| (a - b).abs() <= 1e-4 * b.abs();
                            assert!(near(s.pdf, pdf), "pdf {} vs {pdf}", s.pdf);
                            for c in 0..3 {
                                assert!(near(s.weight[c], expected[c]), "{s:?} {expected}");
                            }
                            checked += 1;
                        }
                    }
                }
            }
        }
        assert!(checked > 800, "{checked}");
    }
}
