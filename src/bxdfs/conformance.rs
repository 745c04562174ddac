//! The conformance suite every lobe and material passes (Mitsuba 3's `chi2` tests
//! and pbrt-v4's BxDF tests check the same): sampled directions follow `pdf` (a
//! chi-square test over the sphere), a sample's weight is `f |cos| / pdf`, the
//! lobes are reciprocal, and none reflects more than it receives.

use std::f64::consts::PI;

use super::gltf::GltfBsdf;
use super::lambert::Lambert;
use super::microfacet::{AnisoGgx, AnisoGgxReflection, Ggx, GgxReflection};
use super::mtl::MtlMixture;
use super::phong::Phong;
use super::sheen::Sheen;
use super::{Lobe, LocalSample};
use crate::material::Material;
use crate::material::pbr::PbrMaterial;
use crate::math::{Float, Vec2, Vec3};

/// A deterministic stream of numbers in [0, 1).
struct Uniforms(u64);

impl Uniforms {
    fn next(&mut self) -> Float {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 40) as Float / (1u64 << 24) as Float
    }
}

fn gltf(pbr: PbrMaterial) -> GltfBsdf {
    GltfBsdf::new(&pbr.constants())
}

fn dielectric(roughness: Float) -> PbrMaterial {
    PbrMaterial {
        base_color: Vec3::new(0.8, 0.6, 0.4),
        metallic: 0.0,
        roughness,
        ..PbrMaterial::default()
    }
}

/// Every lobe and material configuration the suite checks, by name, and whether it
/// is reciprocal (glTF's clearcoat is weighted by the Fresnel of `wo` alone, as the
/// extension defines it, so it is not).
fn subjects() -> Vec<(&'static str, Box<dyn Lobe>, bool)> {
    let mtl = MtlMixture::new(&Material {
        diffuse: Vec3::splat(0.4),
        specular: Vec3::splat(0.4),
        shininess: 10.0,
        albedo: [0.8, 0.2, 0.0],
        ..Material::named("mtl")
    })
    .0;
    vec![
        (
            "lambert",
            Box::new(Lambert {
                reflectance: Vec3::splat(0.8),
            }),
            true,
        ),
        (
            "phong",
            Box::new(Phong {
                reflectance: Vec3::splat(0.9),
                exponent: 12.0,
            }),
            true,
        ),
        (
            "ggx 0.3",
            Box::new(GgxReflection {
                ggx: Ggx { alpha: 0.3 },
            }),
            true,
        ),
        (
            "ggx 0.7",
            Box::new(GgxReflection {
                ggx: Ggx { alpha: 0.7 },
            }),
            true,
        ),
        (
            "anisotropic ggx 0.6 x 0.15",
            Box::new(AnisoGgxReflection {
                ggx: AnisoGgx {
                    alpha_x: 0.6,
                    alpha_y: 0.15,
                },
            }),
            true,
        ),
        (
            "anisotropic ggx 0.2 x 0.9",
            Box::new(AnisoGgxReflection {
                ggx: AnisoGgx {
                    alpha_x: 0.2,
                    alpha_y: 0.9,
                },
            }),
            true,
        ),
        ("sheen", Box::new(Sheen::new(Vec3::ONE, 0.5)), true),
        ("mtl mixture", Box::new(mtl), true),
        ("gltf plastic", Box::new(gltf(dielectric(0.5))), true),
        (
            "gltf rough metal",
            Box::new(gltf(PbrMaterial {
                base_color: Vec3::new(1.0, 0.78, 0.34),
                metallic: 1.0,
                roughness: 0.6,
                ..PbrMaterial::default()
            })),
            true,
        ),
        (
            "gltf half metal",
            Box::new(gltf(PbrMaterial {
                base_color: Vec3::new(0.9, 0.5, 0.3),
                metallic: 0.5,
                roughness: 0.45,
                ..PbrMaterial::default()
            })),
            true,
        ),
        (
            "gltf rough metal, multiple scattering",
            Box::new(gltf(PbrMaterial {
                base_color: Vec3::new(1.0, 0.78, 0.34),
                metallic: 1.0,
                roughness: 0.8,
                multiple_scattering: true,
                ..PbrMaterial::default()
            })),
            false,
        ),
        (
            "gltf white plastic and coat, multiple scattering",
            Box::new(gltf(PbrMaterial {
                base_color: Vec3::ONE,
                clearcoat: 0.5,
                clearcoat_roughness: 0.7,
                multiple_scattering: true,
                ..dielectric(0.9)
            })),
            false,
        ),
        (
            "gltf specular tinted",
            Box::new(gltf(PbrMaterial {
                specular: 0.7,
                specular_color: Vec3::new(1.0, 0.5, 2.0),
                ior: 1.8,
                ..dielectric(0.6)
            })),
            true,
        ),
        (
            "gltf thin transmission",
            Box::new(gltf(PbrMaterial {
                transmission: 1.0,
                ..dielectric(0.6)
            })),
            true,
        ),
        (
            "gltf volume",
            Box::new(gltf(PbrMaterial {
                transmission: 0.8,
                thickness: 1.0,
                ..dielectric(0.6)
            })),
            false,
        ),
        (
            "gltf clearcoat",
            Box::new(gltf(PbrMaterial {
                clearcoat: 1.0,
                clearcoat_roughness: 0.5,
                ..dielectric(0.8)
            })),
            false,
        ),
        (
            "gltf clearcoat, tilted coat normal",
            Box::new(TiltedCoat(
                gltf(PbrMaterial {
                    clearcoat: 0.8,
                    clearcoat_roughness: 0.4,
                    ..dielectric(0.8)
                }),
                Vec3::new(0.4, -0.2, 1.0).normalize(),
            )),
            false,
        ),
        (
            "gltf sheen",
            Box::new(gltf(PbrMaterial {
                sheen_color: Vec3::new(0.9, 0.4, 0.4),
                sheen_roughness: 0.4,
                ..dielectric(0.7)
            })),
            true,
        ),
        (
            "gltf anisotropic metal 0.8",
            Box::new(gltf(PbrMaterial {
                base_color: Vec3::new(0.95, 0.93, 0.88),
                metallic: 1.0,
                roughness: 0.4,
                anisotropy: 0.8,
                ..PbrMaterial::default()
            })),
            true,
        ),
        (
            "gltf anisotropic plastic, turned",
            Box::new(gltf(PbrMaterial {
                anisotropy: 0.5,
                anisotropy_rotation: 0.7,
                ..dielectric(0.5)
            })),
            true,
        ),
        (
            "gltf anisotropic thin transmission",
            Box::new(gltf(PbrMaterial {
                transmission: 1.0,
                anisotropy: 0.6,
                ..dielectric(0.5)
            })),
            true,
        ),
        (
            "gltf anisotropic volume",
            Box::new(gltf(PbrMaterial {
                transmission: 0.8,
                thickness: 1.0,
                anisotropy: 0.7,
                ..dielectric(0.6)
            })),
            false,
        ),
        (
            "gltf everything, smooth coat",
            Box::new(gltf(PbrMaterial {
                metallic: 0.3,
                transmission: 0.5,
                clearcoat: 0.5,
                sheen_color: Vec3::splat(0.3),
                ..dielectric(0.55)
            })),
            false,
        ),
    ]
}

/// A glTF material whose clear coat has its own normal (a clearcoat normal map's),
/// given in the local frame.
struct TiltedCoat(GltfBsdf, Vec3);

impl Lobe for TiltedCoat {
    fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        self.0.at(wo, true, Some(self.1)).eval(wi)
    }

    fn pdf(&self, wo: Vec3, wi: Vec3) -> Float {
        self.0.at(wo, true, Some(self.1)).pdf(wi)
    }

    fn sample(&self, wo: Vec3, u_lobe: Float, u: Vec2) -> Option<LocalSample> {
        self.0.at(wo, true, Some(self.1)).sample(u_lobe, u)
    }
}

/// Directions `wo` the checks look from: head on, oblique, near grazing.
fn outgoing() -> [Vec3; 3] {
    [
        Vec3::new(0.0, 0.0, 1.0),
        Vec3::new(0.6, 0.2, 0.77).normalize(),
        Vec3::new(0.95, -0.1, 0.2).normalize(),
    ]
}

const THETA_BINS: usize = 24;
const PHI_BINS: usize = 48;

/// The bin of a unit direction: equal steps of `cos theta` over the sphere, and of
/// azimuth.
fn bin(w: Vec3) -> usize {
    let z = ((w.z as f64 + 1.0) * 0.5 * THETA_BINS as f64) as usize;
    let phi = (w.y as f64).atan2(w.x as f64).rem_euclid(2.0 * PI);
    let p = (phi / (2.0 * PI) * PHI_BINS as f64) as usize;
    z.min(THETA_BINS - 1) * PHI_BINS + p.min(PHI_BINS - 1)
}

/// Each bin's integral of `pdf`, by a midpoint rule of `n x n` points (equal steps
/// of `cos theta` and azimuth are equal solid angles); `8n` steps of `cos theta` in
/// the bins at the poles, where lobes about the normal peak.
fn expected_bins(lobe: &dyn Lobe, wo: Vec3, n: usize) -> Vec<f64> {
    let mut bins = vec![0.0; THETA_BINS * PHI_BINS];
    for t in 0..THETA_BINS {
        let n_z = if !(2..THETA_BINS - 2).contains(&t) {
            8 * n
        } else {
            n
        };
        let cell = (2.0 / THETA_BINS as f64) * (2.0 * PI / PHI_BINS as f64) / (n * n_z) as f64;
        for p in 0..PHI_BINS {
            let mut sum = 0.0;
            for i in 0..n_z {
                let z = -1.0 + (t as f64 + (i as f64 + 0.5) / n_z as f64) * 2.0 / THETA_BINS as f64;
                let r = (1.0 - z * z).max(0.0).sqrt();
                for j in 0..n {
                    let phi = (p as f64 + (j as f64 + 0.5) / n as f64) * 2.0 * PI / PHI_BINS as f64;
                    let wi = Vec3::new(
                        (r * phi.cos()) as Float,
                        (r * phi.sin()) as Float,
                        z as Float,
                    );
                    sum += lobe.pdf(wo, wi) as f64;
                }
            }
            bins[t * PHI_BINS + p] = sum * cell;
        }
    }
    bins
}

/// The probability that a chi-square variable of `dof` degrees of freedom exceeds
/// `x`, by the Wilson-Hilferty normal approximation.
fn chi_square_tail(x: f64, dof: f64) -> f64 {
    let z = ((x / dof).powf(1.0 / 3.0) - (1.0 - 2.0 / (9.0 * dof))) / (2.0 / (9.0 * dof)).sqrt();
    // Upper tail of the standard normal, by the complementary error function
    // (Abramowitz and Stegun 7.1.26).
    let t = 1.0 / (1.0 + 0.3275911 * z.abs() / 2f64.sqrt());
    let poly = t
        * (0.254829592
            + t * (-0.284496736 + t * (1.421413741 + t * (-1.453152027 + t * 1.061405429))));
    let erfc = poly * (-(z * z) / 2.0).exp();
    if z >= 0.0 {
        0.5 * erfc
    } else {
        1.0 - 0.5 * erfc
    }
}

fn draw(lobe: &dyn Lobe, wo: Vec3, rng: &mut Uniforms) -> Option<LocalSample> {
    let u_lobe = rng.next();
    let u = Vec2::new(rng.next(), rng.next());
    lobe.sample(wo, u_lobe, u)
}

#[test]
fn sampled_directions_follow_the_pdf() {
    let samples = 400_000;
    for (name, lobe, _) in subjects() {
        for wo in outgoing() {
            let mut rng = Uniforms(0x9E37_79B9_7F4A_7C15);
            let mut observed = vec![0.0f64; THETA_BINS * PHI_BINS];
            for _ in 0..samples {
                if let Some(s) = draw(lobe.as_ref(), wo, &mut rng)
                    && !s.delta
                {
                    observed[bin(s.wi)] += 1.0;
                }
            }
            let expected: Vec<f64> = expected_bins(lobe.as_ref(), wo, 6)
                .into_iter()
                .map(|p| p * samples as f64)
                .collect();
            // Bins expecting fewer than 5 samples are pooled into one.
            let (mut chi2, mut dof, mut pooled_o, mut pooled_e) = (0.0, 0usize, 0.0, 0.0);
            for (o, e) in observed.iter().zip(&expected) {
                if *e < 5.0 {
                    pooled_o += o;
                    pooled_e += e;
                } else {
                    chi2 += (o - e) * (o - e) / e;
                    dof += 1;
                }
            }
            if pooled_e >= 5.0 {
                chi2 += (pooled_o - pooled_e) * (pooled_o - pooled_e) / pooled_e;
                dof += 1;
            } else {
                assert!(
                    pooled_o <= 5.0 + 3.0 * pooled_e,
                    "{name} {wo}: {pooled_o} samples where the pdf expects {pooled_e}"
                );
            }
            let p = chi_square_tail(chi2, (dof.max(2) - 1) as f64);
            assert!(
                p > 1e-4,
                "{name} {wo}: chi-square {chi2:.1} over {dof} bins, p = {p:e}"
            );
        }
    }
}

#[test]
fn weights_are_f_cos_over_pdf_and_pdfs_are_what_sampling_reports() {
    for (name, lobe, _) in subjects() {
        for wo in outgoing() {
            let mut rng = Uniforms(0x2545_F491_4F6C_DD1D);
            for _ in 0..2000 {
                let Some(s) = draw(lobe.as_ref(), wo, &mut rng) else {
                    continue;
                };
                if s.delta {
                    continue;
                }
                let pdf = lobe.pdf(wo, s.wi);
                assert!(
                    (pdf - s.pdf).abs() <= 1e-4 * pdf.max(1.0),
                    "{name} {wo} {}: {pdf} vs {}",
                    s.wi,
                    s.pdf
                );
                let expected = lobe.eval(wo, s.wi) * s.wi.z.abs() / pdf;
                let error = (expected - s.weight).abs().max_element();
                assert!(
                    error <= 1e-3 * expected.max_element().max(1.0),
                    "{name} {wo} {}: {} vs {expected}",
                    s.wi,
                    s.weight
                );
            }
        }
    }
}

#[test]
fn lobes_are_reciprocal() {
    let mut rng = Uniforms(0x1234_5678_9ABC_DEF1);
    let direction = |rng: &mut Uniforms| {
        let z = rng.next().max(0.05);
        let phi = 2.0 * std::f32::consts::PI * rng.next();
        let r = (1.0 - z * z).sqrt();
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    };
    for (name, lobe, reciprocal) in subjects() {
        if !reciprocal {
            continue;
        }
        for _ in 0..500 {
            let (a, b) = (direction(&mut rng), direction(&mut rng));
            let (ab, ba) = (lobe.eval(a, b), lobe.eval(b, a));
            let error = (ab - ba).abs().max_element();
            assert!(
                error <= 1e-4 * ab.max_element().max(1.0),
                "{name}: f({a}, {b}) = {ab}, f({b}, {a}) = {ba}"
            );
        }
    }
}

/// The directional albedo `integral f |cos| dwi` (delta lobes included), as the mean
/// sampled weight; energy, not radiance, so that a weight crossing into a denser
/// medium is not divided by `eta^2` (in the quadrature's `eval` it is).
fn sampled_albedo(lobe: &dyn Lobe, wo: Vec3, samples: usize, radiance: bool) -> Vec3 {
    let mut rng = Uniforms(0x0DDB_1A5E_5BAD_5EED);
    let mut sum = Vec3::ZERO;
    for _ in 0..samples {
        if let Some(s) = draw(lobe, wo, &mut rng) {
            sum += s.weight * if radiance { 1.0 } else { s.eta * s.eta };
        }
    }
    sum / samples as Float
}

#[test]
fn no_lobe_reflects_more_than_it_receives() {
    for (name, lobe, _) in subjects() {
        for wo in outgoing() {
            let albedo = sampled_albedo(lobe.as_ref(), wo, 100_000, false);
            assert!(albedo.max_element() <= 1.01, "{name} {wo}: albedo {albedo}");
        }
    }
    // White furnace cases that must keep everything: a smooth thin pane and smooth
    // glass pass or reflect all that arrives.
    for pbr in [
        PbrMaterial {
            base_color: Vec3::ONE,
            transmission: 1.0,
            ..dielectric(0.0)
        },
        PbrMaterial {
            base_color: Vec3::ONE,
            transmission: 1.0,
            thickness: 1.0,
            ..dielectric(0.0)
        },
    ] {
        for wo in outgoing() {
            let albedo = sampled_albedo(&gltf(pbr.clone()), wo, 20_000, false);
            assert!(
                (albedo - Vec3::ONE).abs().max_element() < 0.01,
                "{pbr:?} {wo}: {albedo}"
            );
        }
    }
}

/// The sampled albedo of the glTF material equals a quadrature of its `eval`: what
/// sampling does and what light sampling evaluates are one function.
#[test]
fn gltf_sampling_integrates_its_eval() {
    for (name, lobe, _) in subjects() {
        for wo in outgoing() {
            let sampled = sampled_albedo(lobe.as_ref(), wo, 200_000, true);
            // Midpoint quadrature over the sphere, in cos theta and azimuth.
            let (n_z, n_phi) = (400, 200);
            let mut sum = Vec3::ZERO;
            let mut delta = false;
            for i in 0..n_z {
                let z = -1.0 + (i as Float + 0.5) * 2.0 / n_z as Float;
                let r = (1.0 - z * z).max(0.0).sqrt();
                for j in 0..n_phi {
                    let phi = (j as Float + 0.5) * 2.0 * std::f32::consts::PI / n_phi as Float;
                    let wi = Vec3::new(r * phi.cos(), r * phi.sin(), z);
                    sum += lobe.eval(wo, wi) * z.abs();
                }
            }
            let quadrature = sum * (4.0 * std::f32::consts::PI / (n_z * n_phi) as Float);
            let mut rng = Uniforms(7);
            for _ in 0..1000 {
                delta |= draw(lobe.as_ref(), wo, &mut rng).is_some_and(|s| s.delta);
            }
            if delta {
                continue;
            }
            let error = (sampled - quadrature).abs().max_element();
            assert!(
                error < 0.01 + 0.02 * quadrature.max_element(),
                "{name} {wo}: sampled {sampled}, quadrature {quadrature}"
            );
        }
    }
}
