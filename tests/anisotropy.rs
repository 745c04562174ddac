//! Anisotropic GGX (`KHR_materials_anisotropy`) in path mode against closed forms:
//! under a uniform white environment a convex object returns its directional albedo,
//! here from a double-precision quadrature of the extension's own `D` and `V`
//! ("Implementation": `alpha_t = mix(alpha, 1, strength^2)` along the direction of
//! anisotropy, `alpha_b = alpha` across it), at two rotations, on a sphere (whose
//! frame is the BSDF's default tangent turned by the rotation) and on a quad whose
//! texture coordinates give the tangent; the highlight stretches along the tangent;
//! the lobe agrees with Mitsuba 3's anisotropic `roughconductor`; and anisotropy 0
//! is the isotropic material exactly.

use std::f64::consts::PI;

use raytracer::Scene;
use raytracer::bvh::BvhParams;
use raytracer::bxdfs::Bsdf;
use raytracer::bxdfs::gltf::GltfBsdf;
use raytracer::bxdfs::microfacet::AnisoGgx;
use raytracer::description::{SceneDescription, SphereDesc, TriangleDesc};
use raytracer::integrators::{Integrator, PathIntegrator};
use raytracer::material::pbr::PbrMaterial;
use raytracer::material::{Material, MaterialId};
use raytracer::math::{Float, Ray, Vec2, Vec3};
use raytracer::sampler::PixelSampler;
use raytracer::stats::RayCounts;

const BASE: [f64; 3] = [0.95, 0.64, 0.54];
const ROUGHNESS: f64 = 0.5;
const STRENGTH: f64 = 0.8;

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The extension's `D_GGX_anisotropic` and `V_GGX_anisotropic` (without the
/// shader's clamp), `x` the direction of anisotropy, `y` across it, `z` the normal.
fn d_v(at: f64, ab: f64, v: [f64; 3], l: [f64; 3], h: [f64; 3]) -> f64 {
    let a2 = at * ab;
    let f = [ab * h[0], at * h[1], a2 * h[2]];
    let w2 = a2 / dot(f, f);
    let d = a2 * w2 * w2 / PI;
    let length =
        |w: [f64; 3]| dot([at * w[0], ab * w[1], w[2]], [at * w[0], ab * w[1], w[2]]).sqrt();
    let visibility = 0.5 / (l[2] * length(v) + v[2] * length(l));
    d * visibility
}

/// The directional albedo of glTF's metal (`(base + (1 - base) (1 - v.h)^5) D V`)
/// of roughness `ROUGHNESS` and anisotropy `STRENGTH` seen from `v` (in the frame
/// of the direction of anisotropy): a midpoint quadrature over half vectors (`dl = 4
/// |v.h| dh`), dense where `D` peaks (`theta_h = (pi / 2) s^2`).
fn albedo(v: [f64; 3]) -> [f64; 3] {
    let alpha = ROUGHNESS * ROUGHNESS;
    let s2 = STRENGTH * STRENGTH;
    let (at, ab) = (alpha * (1.0 - s2) + s2, alpha);
    crate::support::half_vector_albedo(v, (1500, 1440), 2, false, |l, h, v_h| {
        let w = (1.0 - v_h).powi(5);
        let specular = d_v(at, ab, v, l, h);
        BASE.map(|base| (base + (1.0 - base) * w) * specular)
    })
}

fn metal(rotation: Float) -> PbrMaterial {
    PbrMaterial {
        base_color: Vec3::new(BASE[0] as Float, BASE[1] as Float, BASE[2] as Float),
        metallic: 1.0,
        roughness: ROUGHNESS as Float,
        anisotropy: STRENGTH as Float,
        anisotropy_rotation: rotation,
        ..PbrMaterial::default()
    }
}

/// The mean radiance of `samples` paths along `ray` in `description`'s scene under a
/// uniform white environment.
fn furnace_radiance(description: SceneDescription, ray: Ray, samples: u32) -> Vec3 {
    let scene = Scene::build(description, &BvhParams::default());
    let integrator = PathIntegrator::new(&scene, 64, false).with_environment(&scene, Vec3::ONE);
    let sampler = PixelSampler::new(samples, integrator.dimensions());
    let mut rays = RayCounts::default();
    let mut sum = Vec3::ZERO;
    for s in 0..samples {
        let mut sample = sampler.sample(0, s);
        sum += integrator.radiance(&scene, &ray, &mut sample, &mut rays);
    }
    sum / samples as Float
}

fn check(what: &str, got: Vec3, expected: [f64; 3]) {
    for c in 0..3 {
        let e = expected[c] as Float;
        assert!(
            (got[c] - e).abs() <= 0.015 * e,
            "{what}: pixel {got}, directional albedo {expected:?}"
        );
    }
}

/// A unit sphere of the anisotropic metal, seen along -z where its normal makes
/// `cos` with +z. Spheres have no texture coordinates: the frame is the default
/// tangent (Duff et al.'s, `(cos, 0, -sin)` at the normal `(sin, 0, cos)`) turned by
/// the rotation `r`, so `wo = +z` is `(-sin cos r, sin sin r, cos)` in the frame of
/// the direction of anisotropy.
#[test]
fn an_anisotropic_sphere_returns_its_directional_albedo_at_two_rotations() {
    let rotations = [0.0, std::f64::consts::FRAC_PI_2 * 0.9];
    let mut pixels = Vec::new();
    for rotation in rotations {
        for cos in [0.9f64, 0.5] {
            let sin = (1.0 - cos * cos).sqrt();
            let description = SceneDescription {
                spheres: vec![SphereDesc {
                    center: Vec3::ZERO,
                    radius: 1.0,
                    material: MaterialId(0),
                }],
                materials: vec![Material::physically_based(
                    "brushed",
                    metal(rotation as Float),
                    Vec3::ZERO,
                    None,
                )],
                ..SceneDescription::default()
            };
            let ray = Ray::new(Vec3::new(sin as Float, 0.0, 5.0), -Vec3::Z);
            let got = furnace_radiance(description, ray, 40_000);
            let v = [-sin * rotation.cos(), sin * rotation.sin(), cos];
            check(&format!("rotation {rotation}, cos {cos}"), got, albedo(v));
            pixels.push(got);
        }
    }
    // The rotation matters: seen at an angle, along the rough direction or across it.
    assert!(
        (pixels[1] - pixels[3]).abs().max_element() > 0.02,
        "{pixels:?}"
    );
}

/// A square in z = 0 seen from 60 degrees off its normal in the xz plane, its
/// texture coordinates' `u` along x or along y: the tangent the hit takes from them
/// puts the view along the direction of anisotropy or across it, and the pixel is
/// the directional albedo of each.
#[test]
fn texture_coordinates_give_the_tangent() {
    let (sin, cos) = (60f64.to_radians().sin(), 60f64.to_radians().cos());
    let render = |u_along_y: bool| {
        let uv = |x: Float, y: Float| {
            if u_along_y {
                Vec2::new(y, -x)
            } else {
                Vec2::new(x, y)
            }
        };
        let corners = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];
        let description = SceneDescription {
            positions: corners.iter().map(|&(x, y)| Vec3::new(x, y, 0.0)).collect(),
            texcoords: corners.iter().map(|&(x, y)| uv(x, y)).collect(),
            triangles: vec![
                TriangleDesc {
                    positions: [0, 1, 2],
                    material: MaterialId(0),
                },
                TriangleDesc {
                    positions: [0, 2, 3],
                    material: MaterialId(0),
                },
            ],
            triangle_texcoords: vec![Some([0, 1, 2]), Some([0, 2, 3])],
            materials: vec![Material::physically_based(
                "brushed",
                metal(0.0),
                Vec3::ZERO,
                None,
            )],
            ..SceneDescription::default()
        };
        let from = Vec3::new(sin as Float, 0.0, cos as Float) * 4.0;
        furnace_radiance(description, Ray::new(from, -from.normalize()), 40_000)
    };
    // `u` along x: the tangent is +x, `wo` lies along it.
    check("u along x", render(false), albedo([sin, 0.0, cos]));
    // `u` along y (v along -x): `wo` lies across the tangent.
    check("u along y", render(true), albedo([0.0, sin, cos]));
}

/// The highlight stretches along the direction of anisotropy: lit and seen head on,
/// a metal of anisotropy 0.8 reflects over twice as much towards a direction tilted
/// 25 degrees along the tangent than along the bitangent, and the rotation (or the
/// hit's tangent) turns which; at anisotropy 0 both are the same.
#[test]
fn the_highlight_stretches_along_the_tangent() {
    let tilt = 25f32.to_radians();
    let along_x = Vec3::new(tilt.sin(), 0.0, tilt.cos());
    let along_y = Vec3::new(0.0, tilt.sin(), tilt.cos());
    let eval = |pbr: PbrMaterial, tangent: Vec3, wi: Vec3| {
        let bsdf = Bsdf::Gltf(GltfBsdf::new(&pbr.constants()));
        bsdf.at(Vec3::Z, Vec3::Z, Vec3::Z, Vec3::ZERO, tangent, true)
            .eval(wi)
            .x
    };
    // The hit's tangent along x, then along y.
    let (x, y) = (
        eval(metal(0.0), Vec3::X, along_x),
        eval(metal(0.0), Vec3::X, along_y),
    );
    assert!(x > 2.0 * y, "along the tangent {x}, across it {y}");
    let (x, y) = (
        eval(metal(0.0), Vec3::Y, along_x),
        eval(metal(0.0), Vec3::Y, along_y),
    );
    assert!(y > 2.0 * x, "along the tangent {y}, across it {x}");
    // No tangent of the hit's: the default one (+x at the normal +z) turned by the
    // rotation, a quarter turn putting the direction of anisotropy along y.
    let quarter = std::f32::consts::FRAC_PI_2;
    let (x, y) = (
        eval(metal(quarter), Vec3::ZERO, along_x),
        eval(metal(quarter), Vec3::ZERO, along_y),
    );
    assert!(y > 2.0 * x, "along the turned tangent {y}, across it {x}");
    let isotropic = PbrMaterial {
        anisotropy: 0.0,
        ..metal(0.0)
    };
    assert_eq!(
        eval(isotropic.clone(), Vec3::X, along_x),
        eval(isotropic, Vec3::X, along_y)
    );
}

/// Anisotropy 0 is the isotropic material bit for bit: every value and sample of a
/// material with a rotation but no strength equals the plain material's.
#[test]
fn anisotropy_zero_is_the_isotropic_material_exactly() {
    let plain = PbrMaterial {
        anisotropy: 0.0,
        ..metal(0.0)
    };
    let turned = PbrMaterial {
        anisotropy: 0.0,
        anisotropy_rotation: 1.0,
        ..metal(0.0)
    };
    let (a, b) = (
        GltfBsdf::new(&plain.constants()),
        GltfBsdf::new(&turned.constants()),
    );
    assert!(a.is_plain() && b.is_plain());
    let (a, b) = (Bsdf::Gltf(a), Bsdf::Gltf(b));
    let n = Vec3::new(0.2, -0.3, 1.0).normalize();
    let wo = Vec3::new(0.5, 0.1, 0.8).normalize();
    let (a, b) = (
        a.at(wo, n, n, Vec3::ZERO, Vec3::ZERO, true),
        b.at(wo, n, n, Vec3::ZERO, Vec3::X, true),
    );
    for i in 0..64 {
        let u = Vec2::new((i % 8) as Float / 8.0 + 0.03, (i / 8) as Float / 8.0 + 0.05);
        let (sa, sb) = (a.sample(0.5, u), b.sample(0.5, u));
        assert_eq!(sa, sb);
        if let Some(s) = sa {
            assert_eq!(a.eval_and_pdf(s.wi), b.eval_and_pdf(s.wi));
        }
    }
}

/// Mitsuba 3's anisotropic `roughconductor` (GGX, `alpha_u` along the frame's `s`,
/// `alpha_v` along `t`, a perfect conductor) at fixed pairs of directions, from
/// `tests/data/materials/make_mitsuba.py --anisotropic`: our anisotropic `D` with
/// Mitsuba's separable Smith term swapped in gives the same `f`.
#[test]
fn anisotropic_ggx_matches_mitsubas_roughconductor() {
    let pairs =
        crate::support::check_against_mitsuba_table("roughconductor_anisotropic.toml", |pair| {
            AnisoGgx {
                alpha_x: pair["alpha_u"].as_float().unwrap() as Float,
                alpha_y: pair["alpha_v"].as_float().unwrap() as Float,
            }
        });
    assert!(pairs >= 100);
}

/// Without a tangent of the hit's, the default runs round the up axis (`+Y x n`):
/// continuous across the equator, where the shading frame's own tangent flips with
/// the sign of `n.z` (a seam across every brushed sphere), and a unit tangent
/// perpendicular to the normal at the poles too.
#[test]
fn the_default_tangent_runs_round_the_up_axis_without_a_seam() {
    use raytracer::bxdfs::Frame;
    let along = Vec2::new(1.0, 0.0);
    for x in [1.0, 0.3, -0.7] {
        let above = Frame::anisotropic(Vec3::new(x, 0.2, 0.01).normalize(), Vec3::ZERO, along);
        let below = Frame::anisotropic(Vec3::new(x, 0.2, -0.01).normalize(), Vec3::ZERO, along);
        assert!(
            above.t.dot(below.t) > 0.99,
            "x {x}: {:?} above the equator, {:?} below",
            above.t,
            below.t
        );
        let n = Vec3::new(x, 0.2, 0.01).normalize();
        let expected = Vec3::Y.cross(n).normalize();
        assert!(
            (above.t - expected).length() < 1e-5,
            "{:?} against {expected:?}",
            above.t
        );
    }
    for n in [Vec3::Y, -Vec3::Y] {
        let frame = Frame::anisotropic(n, Vec3::ZERO, along);
        assert!((frame.t.length() - 1.0).abs() < 1e-5 && frame.t.dot(n).abs() < 1e-5);
    }
}
