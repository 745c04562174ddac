//! SPEC's MTL material in path mode: what an MTL [`Material`] means to a path
//! tracer, as a mixture of four lobes weighted by the spec's `al` weights.
//!
//! | MTL | lobe | Mitsuba 3 | Blender (Principled) |
//! |---|---|---|---|
//! | `al0 * Kd` | Lambertian | `diffuse` | Base Color, Roughness 1 |
//! | `al0 * Ks`, `Ns` | energy-conserving modified Phong (Lafortune and Willems 1994) | (none; `roughplastic` is closest) | Specular |
//! | `al1` | perfect mirror | `conductor`, `material = "none"` | Metallic 1, Roughness 0 |
//! | `al2`, `Ni` | smooth dielectric, exact Fresnel | `dielectric`, `int_ior = Ni` | Transmission 1, IOR |
//! | `Ke` | area light ([`crate::lights`]) | `area` emitter | Emission |
//! | `Ka` | ignored: an ambient term has no physical meaning | | |
//! | `Ns` 0 to 1, `Ks` | the whole material a rough dielectric ([`reads_as_rough_dielectric`]) | `roughplastic` | Roughness `1 - sqrt(Ns / 1000)`, Specular `Ks` |
//!
//! `Kd + Ks` is scaled down to at most 1 per channel so that the Phong part conserves
//! energy ([`MtlMixture::new`] says when it did).
//!
//! It works in world space, the shading normal `ns` facing `wo` (as every material
//! in [`super`]).

use std::f32::consts::{FRAC_1_PI, PI};

use super::fresnel::dielectric as fresnel_dielectric;
use super::lambert::cosine_hemisphere;
use super::phong::{Phong, phong_lobe};
use super::{Frame, Lobe, LocalSample, ScatterSample};
use crate::material::pbr::{PbrMaterial, PbrValues};
use crate::material::{Material, SurfaceValues};
use crate::math::{Float, Vec2, Vec3, reflect};

/// The scattering of one material, derived once per render.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MtlMixture {
    /// `al0 * Kd`, after the energy scaling.
    diffuse: Vec3,
    /// `diffuse` over the probability of sampling it: the weight of a direction
    /// sampled from the Lambertian lobe alone.
    diffuse_weight: Vec3,
    /// `al0 * Ks`, after the energy scaling.
    glossy: Vec3,
    /// `Ns`, at least 0.
    exponent: Float,
    /// `al1`.
    mirror: Float,
    /// `al2`.
    glass: Float,
    /// `Ni`.
    ior: Float,
    /// Probabilities of sampling each lobe, in the order above; sum 1 unless the
    /// material scatters nothing.
    lobe_probability: [Float; 4],
    /// Whether [`MtlMixture::sample`] reads its `u_lobe`: some lobe's probability
    /// lies strictly between 0 and 1. Otherwise one lobe has probability 1 (or none
    /// scatters) and every `u_lobe` in `[0, 1)` picks the same.
    picks_lobe: bool,
}

/// Whether path mode reads the MTL `material` as a rough dielectric
/// ([`rough_dielectric`]) rather than as a mixture: `Ns` at most 1 with some `Ks`,
/// no mirror or glass weight and no `map_Ns`. A Phong exponent of 0 is no highlight
/// but a uniform lobe of albedo `Ks` over the whole hemisphere, and one of 1 a lobe
/// no narrower than Lambert's cosine: either washes the surface out in white, grainy
/// under an environment. `Ns 0` is how Blender 2.8 to 3.x writes a material of
/// roughness 1 (`Ns = 1000 (1 - roughness)^2`, its default Specular 0.5 as `Ks
/// 0.5`); `Ks 0.4` with `Ns 1` is trimesh's default material, which every OBJ it
/// exports carries. Blender's importer reads both as rough dielectrics. Full mode
/// keeps SPEC's Phong reading.
pub fn reads_as_rough_dielectric(material: &Material) -> bool {
    let [local, mirror, glass] = material.albedo;
    material.pbr.is_none()
        && material.shininess <= 1.0
        && material.specular.max_element() > 0.0
        && local == 1.0
        && mirror <= 0.0
        && glass <= 0.0
        && (material.maps.as_ref()).is_none_or(|maps| maps.shininess.is_none())
}

/// The rough dielectric path mode reads an MTL material of `Ns` at most 1
/// ([`reads_as_rough_dielectric`]) as, from its `Kd`, `Ks` and `Ns` at a point:
/// Blender's importer's reading, roughness `1 - sqrt(Ns / 1000)` (1 for `Ns 0`,
/// 0.968 for `Ns 1`) and Specular `mean(Ks)`, in glTF's terms (as
/// [`crate::formats`] reads Blender's `Ps`): base colour `Kd`, specular
/// `min(2 mean(Ks), 1)` (Blender's Specular 0.5 is glTF's reflectance 0.04).
pub fn rough_dielectric(kd: Vec3, ks: Vec3, ns: Float) -> PbrValues {
    PbrMaterial {
        base_color: kd.max(Vec3::ZERO),
        metallic: 0.0,
        roughness: 1.0 - (ns.clamp(0.0, 1000.0) / 1000.0).sqrt(),
        specular: (2.0 * mean(ks.max(Vec3::ZERO))).min(1.0),
        ..PbrMaterial::default()
    }
    .at(Vec2::ZERO, None)
}

impl MtlMixture {
    /// The scattering `material` describes, and whether `Kd + Ks` had to be scaled
    /// down to conserve energy.
    pub fn new(material: &Material) -> (MtlMixture, bool) {
        MtlMixture::from_values(
            material,
            material.diffuse,
            material.specular,
            material.shininess,
        )
    }

    /// The scattering of a textured material at one point, from its values there
    /// (`Kd`, `Ks` and `Ns` times their maps), for each hit on it.
    #[inline]
    pub fn at(material: &Material, surface: &SurfaceValues) -> MtlMixture {
        MtlMixture::from_values(
            material,
            surface.diffuse,
            surface.specular,
            surface.shininess,
        )
        .0
    }

    #[inline]
    fn from_values(material: &Material, kd: Vec3, ks: Vec3, ns: Float) -> (MtlMixture, bool) {
        let [local, mirror, glass] = material.albedo.map(|w| w.max(0.0));
        let mut diffuse = kd.max(Vec3::ZERO) * local;
        let mut glossy = ks.max(Vec3::ZERO) * local;
        let largest = (kd.max(Vec3::ZERO) + ks.max(Vec3::ZERO)).max_element();
        let scaled = largest > 1.0;
        if scaled {
            diffuse /= largest;
            glossy /= largest;
        }
        let weights = [
            mean(diffuse),
            mean(glossy),
            mirror,
            if material.ior > 0.0 { glass } else { 0.0 },
        ];
        let total: Float = weights.iter().sum();
        let lobe_probability = if total > 0.0 && total.is_finite() {
            weights.map(|w| w / total)
        } else {
            [0.0; 4]
        };
        let diffuse_weight = if lobe_probability[0] > 0.0 {
            diffuse / lobe_probability[0]
        } else {
            Vec3::ZERO
        };
        let picks_lobe = lobe_probability.iter().any(|&p| p > 0.0 && p < 1.0);
        let params = MtlMixture {
            diffuse,
            diffuse_weight,
            glossy,
            exponent: ns.max(0.0),
            mirror,
            glass,
            ior: material.ior,
            lobe_probability,
            picks_lobe,
        };
        (params, scaled)
    }

    /// Whether some lobe is not a delta, so that light sampling can reach it.
    #[inline]
    pub fn has_smooth_lobes(&self) -> bool {
        self.lobe_probability[0] + self.lobe_probability[1] > 0.0
    }

    /// Whether [`MtlMixture::sample`] reads its `u_lobe`: `false` when any value in
    /// `[0, 1)` (0 among them) picks the same lobe, so that a caller need not draw
    /// it.
    #[inline]
    pub fn picks_lobe(&self) -> bool {
        self.picks_lobe
    }

    /// `f(wo, wi)` of the non-delta lobes (delta lobes are zero for any given `wi`).
    /// `ns` is the unit shading normal facing `wo`, `ng` the geometric one.
    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3, ns: Vec3, ng: Vec3) -> Vec3 {
        let cos_i = wi.dot(ns);
        // Both normals must agree that `wi` leaves on the side `wo` came from: a
        // shading normal alone would let light leak through the surface.
        if cos_i <= 0.0 || wi.dot(ng) <= 0.0 {
            return Vec3::ZERO;
        }
        let mut f = self.diffuse * FRAC_1_PI;
        if self.glossy != Vec3::ZERO {
            let lobe = Phong::lobe(reflect(-wo, ns), wi, self.exponent);
            f += self.glossy * ((self.exponent + 2.0) / (2.0 * PI) * lobe);
        }
        f
    }

    /// The density (solid angle) with which [`MtlMixture::sample`] picks `wi`
    /// through its non-delta lobes.
    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3, ns: Vec3, ng: Vec3) -> Float {
        let cos_i = wi.dot(ns);
        if cos_i <= 0.0 || wi.dot(ng) <= 0.0 {
            return 0.0;
        }
        let [p_diffuse, p_glossy, ..] = self.lobe_probability;
        let mut pdf = p_diffuse * cos_i * FRAC_1_PI;
        if p_glossy > 0.0 {
            let lobe = Phong::lobe(reflect(-wo, ns), wi, self.exponent);
            pdf += p_glossy * (self.exponent + 1.0) / (2.0 * PI) * lobe;
        }
        pdf
    }

    /// Picks the direction the path continues in: a lobe by `u_lobe`, a direction in
    /// it by `u`. `front` says whether the ray hit the side the surface's geometric
    /// normal (winding, or a sphere's outside) faces, which tells entering glass from
    /// leaving it. `None` when the material scatters nothing that way. Inlined, so
    /// that the caller reads the sample from registers.
    #[inline(always)]
    pub fn sample(
        &self,
        wo: Vec3,
        ns: Vec3,
        ng: Vec3,
        front: bool,
        u_lobe: Float,
        u: Vec2,
    ) -> Option<ScatterSample> {
        let [p_diffuse, p_glossy, p_mirror, _] = self.lobe_probability;
        let smooth = |wi: Vec3| {
            let pdf = self.pdf(wo, wi, ns, ng);
            (pdf > 0.0).then(|| ScatterSample {
                wi,
                weight: self.eval(wo, wi, ns, ng) * wi.dot(ns) / pdf,
                pdf,
                delta: false,
                eta: 1.0,
            })
        };
        if u_lobe < p_diffuse {
            let wi = Frame::from_normal(ns).to_world(cosine_hemisphere(u));
            if p_glossy > 0.0 {
                return smooth(wi);
            }
            // Lambertian alone (the common case): `f * cos / pdf` reduces to the
            // albedo over the lobe's probability.
            let cos_i = wi.dot(ns);
            if cos_i <= 0.0 || wi.dot(ng) <= 0.0 {
                return None;
            }
            Some(ScatterSample {
                wi,
                weight: self.diffuse_weight,
                pdf: p_diffuse * cos_i * FRAC_1_PI,
                delta: false,
                eta: 1.0,
            })
        } else if u_lobe < p_diffuse + p_glossy {
            smooth(Frame::from_normal(reflect(-wo, ns)).to_world(phong_lobe(u, self.exponent)))
        } else if u_lobe < p_diffuse + p_glossy + p_mirror {
            Some(ScatterSample {
                wi: reflect(-wo, ns),
                weight: Vec3::splat(self.mirror / p_mirror),
                pdf: 0.0,
                delta: true,
                eta: 1.0,
            })
        } else if self.lobe_probability[3] > 0.0 {
            self.sample_glass(wo, ns, front, u.x)
        } else {
            None
        }
    }

    /// The smooth dielectric: reflection with the Fresnel probability, refraction
    /// otherwise, so the Fresnel factors cancel in the weight. Radiance crossing into
    /// a denser medium is scaled by `1 / eta^2`, as Mitsuba does in radiance mode.
    #[inline]
    fn sample_glass(&self, wo: Vec3, ns: Vec3, front: bool, u: Float) -> Option<ScatterSample> {
        let weight = self.glass / self.lobe_probability[3];
        // eta = index entered / index left.
        let eta = if front { self.ior } else { 1.0 / self.ior };
        let cos_o = wo.dot(ns).clamp(0.0, 1.0);
        let sin2_t = (1.0 - cos_o * cos_o) / (eta * eta);
        let reflected = ScatterSample {
            wi: reflect(-wo, ns),
            weight: Vec3::splat(weight),
            pdf: 0.0,
            delta: true,
            eta: 1.0,
        };
        if sin2_t >= 1.0 {
            return Some(reflected);
        }
        let cos_t = (1.0 - sin2_t).sqrt();
        if u < fresnel_dielectric(cos_o, cos_t, eta) {
            return Some(reflected);
        }
        let wi = -wo / eta + (cos_o / eta - cos_t) * ns;
        Some(ScatterSample {
            wi: wi.normalize(),
            weight: Vec3::splat(weight / (eta * eta)),
            pdf: 0.0,
            delta: true,
            eta,
        })
    }
}

/// The mixture in its local frame (`ns = ng = +z`, hit from the front), for the
/// conformance suite.
impl Lobe for MtlMixture {
    fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        MtlMixture::eval(self, wo, wi, Vec3::Z, Vec3::Z)
    }

    fn pdf(&self, wo: Vec3, wi: Vec3) -> Float {
        MtlMixture::pdf(self, wo, wi, Vec3::Z, Vec3::Z)
    }

    fn sample(&self, wo: Vec3, u_lobe: Float, u: Vec2) -> Option<LocalSample> {
        let s = MtlMixture::sample(self, wo, Vec3::Z, Vec3::Z, true, u_lobe, u)?;
        Some(LocalSample {
            wi: s.wi,
            weight: s.weight,
            pdf: s.pdf,
            delta: s.delta,
            eta: s.eta,
        })
    }
}

#[inline]
fn mean(v: Vec3) -> Float {
    (v.x + v.y + v.z) / 3.0
}

#[cfg(test)]
mod tests {
    use super::*;

    fn material(kd: Float, ks: Float, ns: Float, al: [Float; 3]) -> Material {
        Material {
            diffuse: Vec3::splat(kd),
            specular: Vec3::splat(ks),
            shininess: ns,
            ior: 1.5,
            albedo: al,
            ..Material::named("m")
        }
    }

    /// A deterministic stream of numbers in [0, 1).
    fn uniforms(n: usize) -> impl Iterator<Item = Float> {
        let mut next = crate::math::xorshift(0x2545_F491_4F6C_DD1D);
        (0..n).map(move |_| next())
    }

    #[test]
    fn the_basis_is_orthonormal_for_any_axis() {
        for axis in [
            Vec3::Z,
            -Vec3::Z,
            Vec3::X,
            Vec3::new(0.3, -0.5, 0.81).normalize(),
        ] {
            let d = Frame::from_normal(axis).to_world(Vec3::new(0.6, 0.0, 0.8));
            assert!((d.length() - 1.0).abs() < 1e-5, "{axis}");
            assert!((d.dot(axis) - 0.8).abs() < 1e-5, "{axis}");
        }
    }

    #[test]
    fn sampled_weights_average_to_the_albedo() {
        // Monte Carlo estimate of the directional albedo: the mean sampled weight.
        let n = Vec3::new(0.2, 0.9, 0.1).normalize();
        let wo = Vec3::new(0.5, 0.7, -0.3).normalize();
        let wo = if wo.dot(n) < 0.0 { -wo } else { wo };
        for (m, expected) in [
            (material(0.7, 0.0, 1.0, [1.0, 0.0, 0.0]), 0.7),
            (material(0.5, 0.0, 1.0, [0.5, 0.5, 0.0]), 0.25 + 0.5),
            (material(0.0, 0.0, 1.0, [0.0, 0.0, 1.0]), 1.0),
        ] {
            let (params, _) = MtlMixture::new(&m);
            let samples = 20_000;
            let mut u = uniforms(3 * samples);
            let mut sum = Vec3::ZERO;
            for _ in 0..samples {
                let (a, b, c) = (u.next().unwrap(), u.next().unwrap(), u.next().unwrap());
                if let Some(s) = params.sample(wo, n, n, true, a, Vec2::new(b, c)) {
                    sum += s.weight * if s.eta != 1.0 { s.eta * s.eta } else { 1.0 };
                }
            }
            let mean = sum.x / samples as Float;
            assert!(
                (mean - expected).abs() < 0.02,
                "{m:?}: {mean} vs {expected}"
            );
        }
    }

    #[test]
    fn a_lobe_is_picked_by_u_lobe_only_in_a_mixture() {
        let wo = Vec3::new(0.3, 0.1, 0.9).normalize();
        let u = Vec2::new(0.3, 0.6);
        for (m, mixed) in [
            (material(0.7, 0.0, 1.0, [1.0, 0.0, 0.0]), false),
            (material(0.0, 0.5, 20.0, [1.0, 0.0, 0.0]), false),
            (material(0.0, 0.0, 1.0, [0.0, 1.0, 0.0]), false),
            (material(0.0, 0.0, 1.0, [0.0, 0.0, 1.0]), false),
            (material(0.0, 0.0, 1.0, [0.0, 0.0, 0.0]), false),
            (material(0.5, 0.0, 1.0, [0.5, 0.5, 0.0]), true),
            (material(0.4, 0.4, 10.0, [1.0, 0.0, 0.0]), true),
        ] {
            let (params, _) = MtlMixture::new(&m);
            assert_eq!(params.picks_lobe(), mixed, "{m:?}");
            if !mixed {
                // Any `u_lobe` samples what 0 does.
                let first = params.sample(wo, Vec3::Z, Vec3::Z, true, 0.0, u);
                for u_lobe in [0.25, 0.5, 0.999, crate::math::ONE_BELOW_ONE] {
                    let s = params.sample(wo, Vec3::Z, Vec3::Z, true, u_lobe, u);
                    assert_eq!(s, first, "{m:?}, {u_lobe}");
                }
            }
        }
    }

    #[test]
    fn phong_conserves_energy_and_kd_plus_ks_is_scaled_to_one() {
        let (params, scaled) = MtlMixture::new(&material(0.8, 0.6, 20.0, [1.0, 0.0, 0.0]));
        assert!(scaled);
        assert!((params.diffuse.x + params.glossy.x - 1.0).abs() < 1e-6);
        // Albedo at normal incidence stays at most 1.
        let n = Vec3::Z;
        let samples = 40_000;
        let mut u = uniforms(3 * samples);
        let mut sum = 0.0;
        for _ in 0..samples {
            let (a, b, c) = (u.next().unwrap(), u.next().unwrap(), u.next().unwrap());
            if let Some(s) = params.sample(n, n, n, true, a, Vec2::new(b, c)) {
                sum += s.weight.x;
            }
        }
        assert!(
            sum / (samples as Float) <= 1.01,
            "{}",
            sum / samples as Float
        );
        let (_, scaled) = MtlMixture::new(&material(0.5, 0.5, 20.0, [1.0, 0.0, 0.0]));
        assert!(!scaled);
    }

    #[test]
    fn pdf_matches_the_sampled_density() {
        // The pdf integrates to the smooth lobes' probability over the hemisphere.
        let (params, _) = MtlMixture::new(&material(0.4, 0.4, 10.0, [0.8, 0.2, 0.0]));
        let n = Vec3::Z;
        let wo = Vec3::new(0.3, 0.0, 0.95).normalize();
        let samples = 200_000;
        let mut u = uniforms(2 * samples);
        let mut integral = 0.0;
        for _ in 0..samples {
            // Uniform directions on the hemisphere: density 1 / (2 pi).
            let (a, b) = (u.next().unwrap(), u.next().unwrap());
            let z = a;
            let r = (1.0 - z * z).sqrt();
            let wi = Vec3::new(r * (2.0 * PI * b).cos(), r * (2.0 * PI * b).sin(), z);
            integral += params.pdf(wo, wi, n, n) * 2.0 * PI;
        }
        let smooth = params.lobe_probability[0] + params.lobe_probability[1];
        let integral = integral / samples as Float;
        assert!(
            (integral - smooth).abs() < 0.02 * smooth,
            "{integral} vs {smooth}"
        );
    }

    #[test]
    fn fresnel_is_four_percent_head_on_for_glass_and_total_past_the_critical_angle() {
        let head_on = fresnel_dielectric(1.0, 1.0, 1.5);
        assert!((head_on - 0.04).abs() < 1e-4, "{head_on}");
        // Leaving glass at a grazing angle: total internal reflection, the mirror way.
        let (params, _) = MtlMixture::new(&material(0.0, 0.0, 1.0, [0.0, 0.0, 1.0]));
        let wo = Vec3::new(0.9, 0.0, 0.1).normalize();
        let s = params
            .sample(wo, Vec3::Z, Vec3::Z, false, 0.5, Vec2::new(0.99, 0.5))
            .unwrap();
        assert!(s.wi.z > 0.0 && s.delta, "{s:?}");
    }
}
