//! Path mode against closed forms for glTF's metallic-roughness material: under a
//! uniform white environment, a convex object seen at angle `theta` returns its
//! directional albedo there, `integral f(wo, wi) cos(wi) dwi`, which a quadrature of
//! the glTF specification's formulas (Appendix B, `KHR_materials_specular`,
//! `KHR_materials_clearcoat`), written here apart from the renderer in double
//! precision, gives. A lossless thin pane vanishes in the furnace, and light crossing
//! a volume is attenuated by Beer-Lambert's law over the chord. A clear coat's own
//! normal map turns its mirror reflection where the law of reflection says, and a
//! blended surface of alpha `a` lets `1 - a` of the light through.

use std::f64::consts::PI;
use std::sync::Arc;

use raytracer::Scene;
use raytracer::bvh::BvhParams;
use raytracer::bxdfs::microfacet::Ggx;
use raytracer::description::{SceneDescription, SphereDesc, TriangleDesc};
use raytracer::integrators::{Integrator, PathIntegrator, WhittedIntegrator};
use raytracer::material::pbr::{PbrMaps, PbrMaterial};
use raytracer::material::{Cutout, Light, Material, MaterialId, MaterialMaps};
use raytracer::math::{Float, Ray, Vec2, Vec3};
use raytracer::sampler::PixelSampler;
use raytracer::stats::RayCounts;
use raytracer::textures::{Channel, Texture, TextureMap};

/// The glTF parameters the reference formulas read.
#[derive(Clone, Copy, Debug)]
struct Params {
    base: [f64; 3],
    metallic: f64,
    roughness: f64,
    ior: f64,
    specular: f64,
    clearcoat: f64,
    clearcoat_roughness: f64,
}

const PLASTIC: Params = Params {
    base: [0.8, 0.3, 0.1],
    metallic: 0.0,
    roughness: 0.5,
    ior: 1.5,
    specular: 1.0,
    clearcoat: 0.0,
    clearcoat_roughness: 0.0,
};

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn normalize(a: [f64; 3]) -> [f64; 3] {
    let l = dot(a, a).sqrt();
    [a[0] / l, a[1] / l, a[2] / l]
}

/// GGX `D` and the height-correlated visibility of Appendix B, for `alpha`.
fn d_v(alpha: f64, n_h: f64, n_l: f64, n_v: f64) -> f64 {
    let a2 = alpha * alpha;
    let t = n_h * n_h * (a2 - 1.0) + 1.0;
    let d = a2 / (PI * t * t);
    let v = 0.5
        / (n_l * (n_v * n_v * (1.0 - a2) + a2).sqrt() + n_v * (n_l * n_l * (1.0 - a2) + a2).sqrt());
    d * v
}

/// The glTF BRDF (metallic-roughness, `KHR_materials_specular` with white
/// `specularColor`, `KHR_materials_ior`, `KHR_materials_clearcoat` over the same
/// normal) for unit `v` and `l` in the frame of the normal `+z`; the clearcoat's
/// delta lobe (roughness 0) is left out.
fn brdf(p: &Params, v: [f64; 3], l: [f64; 3]) -> [f64; 3] {
    let h = normalize([v[0] + l[0], v[1] + l[1], v[2] + l[2]]);
    let v_h = dot(v, h).abs();
    let w = (1.0 - v_h).powi(5);
    let specular = d_v(p.roughness * p.roughness, h[2], l[2], v[2]);
    let f0 = ((p.ior - 1.0) / (p.ior + 1.0)).powi(2).min(1.0) * p.specular;
    let f90 = p.specular;
    let fd = f0 + (f90 - f0) * w;
    let coat = p.clearcoat * (0.04 + 0.96 * (1.0 - v[2]).powi(5));
    let coat_brdf = if p.clearcoat_roughness > 0.0 {
        d_v(
            p.clearcoat_roughness * p.clearcoat_roughness,
            h[2],
            l[2],
            v[2],
        )
    } else {
        0.0
    };
    let mut f = [0.0; 3];
    for (c, out) in f.iter_mut().enumerate() {
        let base = p.base[c];
        let dielectric = fd * specular + (1.0 - fd) * base / PI;
        let metal = (base + (1.0 - base) * w) * specular;
        let material = (1.0 - p.metallic) * dielectric + p.metallic * metal;
        *out = (1.0 - coat) * material + coat * coat_brdf;
    }
    f
}

/// `integral f cos dl` over the hemisphere for `v` at `cos_v` to the normal, by a
/// midpoint quadrature over half vectors (`dl = 4 |v.h| dh`), dense where `D`
/// peaks: `theta_h = (pi / 2) s^3`. Adds the clearcoat's mirror when it is smooth.
fn albedo(p: &Params, cos_v: f64) -> [f64; 3] {
    let v = [(1.0 - cos_v * cos_v).sqrt(), 0.0, cos_v];
    // Symmetric about the plane of v and the normal: half the circle, twice.
    let mut sum =
        crate::support::half_vector_albedo(v, (3000, 720), 3, true, |l, _, _| brdf(p, v, l));
    if p.clearcoat > 0.0 && p.clearcoat_roughness == 0.0 {
        let coat = p.clearcoat * (0.04 + 0.96 * (1.0 - cos_v).powi(5));
        sum = sum.map(|s| s + coat);
    }
    sum
}

fn pbr(p: &Params) -> PbrMaterial {
    PbrMaterial {
        base_color: Vec3::new(p.base[0] as Float, p.base[1] as Float, p.base[2] as Float),
        metallic: p.metallic as Float,
        roughness: p.roughness as Float,
        ior: p.ior as Float,
        specular: p.specular as Float,
        clearcoat: p.clearcoat as Float,
        clearcoat_roughness: p.clearcoat_roughness as Float,
        ..PbrMaterial::default()
    }
}

/// A unit sphere at the origin made of `material`, in a white furnace.
fn furnace(material: Material) -> (Scene, PathIntegrator) {
    let description = SceneDescription {
        spheres: vec![SphereDesc {
            center: Vec3::ZERO,
            radius: 1.0,
            material: MaterialId(0),
        }],
        materials: vec![material],
        ..SceneDescription::default()
    };
    let scene = Scene::build(description, &BvhParams::default());
    let integrator = PathIntegrator::new(&scene, 64, false).with_environment(&scene, Vec3::ONE);
    (scene, integrator)
}

/// The mean radiance of `samples` paths along `ray`.
fn mean_radiance(scene: &Scene, integrator: &PathIntegrator, ray: Ray, samples: u32) -> Vec3 {
    let sampler = PixelSampler::new(samples, integrator.dimensions());
    let mut rays = RayCounts::default();
    let mut sum = Vec3::ZERO;
    for s in 0..samples {
        let mut sample = sampler.sample(0, s);
        sum += integrator.radiance(scene, &ray, &mut sample, &mut rays);
    }
    sum / samples as Float
}

/// A ray along -z hitting the unit sphere where its normal makes `cos` with +z.
fn ray_at(cos: f64) -> Ray {
    let sin = (1.0 - cos * cos).sqrt();
    Ray::new(Vec3::new(sin as Float, 0.0, 5.0), -Vec3::Z)
}

fn check_albedo(name: &str, p: &Params, material: Material) {
    let (scene, integrator) = furnace(material);
    for cos in [1.0, 0.7, 0.3] {
        let expected = albedo(p, cos);
        let got = mean_radiance(&scene, &integrator, ray_at(cos), 40_000);
        for c in 0..3 {
            let e = expected[c] as Float;
            assert!(
                (got[c] - e).abs() <= 0.015 * e.max(0.05),
                "{name} at cos {cos}: pixel {got}, directional albedo {expected:?}"
            );
        }
    }
}

fn check(name: &str, p: Params) {
    check_albedo(
        name,
        &p,
        Material::physically_based(name, pbr(&p), Vec3::ZERO, None),
    );
}

#[test]
fn a_rough_plastic_returns_its_directional_albedo() {
    check("plastic", PLASTIC);
}

/// An MTL material of `Ns 0` with `Ks 0.8`, as Blender 2.8 to 3.x writes roughness 1
/// with its default specular: in path mode it is the rough dielectric Blender's
/// importer reads (base colour `Kd`, specular `min(2 Ks, 1)`), not a uniform lobe of
/// albedo 0.8 white that washes the colour out.
#[test]
fn an_mtl_material_of_shininess_zero_is_blenders_rough_dielectric() {
    let material = Material {
        diffuse: Vec3::new(0.8, 0.3, 0.1),
        specular: Vec3::splat(0.8),
        shininess: 0.0,
        ..Material::named("blender roughness 1")
    };
    let p = Params {
        roughness: 1.0,
        specular: 1.0,
        ..PLASTIC
    };
    check_albedo("Ns 0", &p, material);
}

/// trimesh's default material, which every OBJ it exports carries (`Ka 0.4`, `Ks
/// 0.4`, `Ns 1`; Genesis's bathtub, duck, dragon, boat): an exponent of 1 is no
/// highlight either, so path mode reads it as Blender's importer does, a rough
/// dielectric of roughness `1 - sqrt(1 / 1000)` and specular `min(2 Ks, 1)`, not a
/// lobe of albedo 0.4 white over the whole hemisphere.
#[test]
fn an_mtl_material_of_shininess_one_is_blenders_rough_dielectric() {
    let material = Material {
        diffuse: Vec3::new(0.8, 0.3, 0.1),
        specular: Vec3::splat(0.4),
        shininess: 1.0,
        ..Material::named("trimesh default")
    };
    let p = Params {
        roughness: 1.0 - (0.001f64).sqrt(),
        specular: 0.8,
        ..PLASTIC
    };
    check_albedo("Ns 1", &p, material);
}

#[test]
fn a_rough_dielectric_without_diffuse_colour_returns_its_directional_albedo() {
    check(
        "rough dielectric",
        Params {
            base: [0.0; 3],
            roughness: 0.7,
            ..PLASTIC
        },
    );
}

#[test]
fn rough_and_near_mirror_metals_return_their_directional_albedo() {
    let gold = Params {
        base: [1.0, 0.78, 0.34],
        metallic: 1.0,
        ..PLASTIC
    };
    check(
        "rough gold",
        Params {
            roughness: 0.6,
            ..gold
        },
    );
    check(
        "near-mirror gold",
        Params {
            roughness: 0.05,
            ..gold
        },
    );
}

/// With multiple-scattering compensation (not the default), a rough white metal in
/// the white furnace returns all the light it receives, within 1.5%, where single
/// scattering loses most of it at roughness 1 (0.31 returned head on: `1 - ln 2`,
/// since `D = 1 / pi` and `V = 0.5 / (cos_o + cos_i)` there); a near-mirror is left
/// as it was.
#[test]
fn multiple_scattering_compensation_makes_a_rough_white_metal_lossless() {
    for roughness in [1.0, 0.6] {
        let white = PbrMaterial {
            base_color: Vec3::ONE,
            metallic: 1.0,
            roughness,
            multiple_scattering: true,
            ..PbrMaterial::default()
        };
        let (scene, integrator) =
            furnace(Material::physically_based("white", white, Vec3::ZERO, None));
        for cos in [1.0, 0.7, 0.3] {
            let got = mean_radiance(&scene, &integrator, ray_at(cos), 20_000);
            assert!(
                (got - Vec3::ONE).abs().max_element() < 0.015,
                "roughness {roughness}, cos {cos}: {got}"
            );
        }
    }
    // The same metal without compensation: the single-scattering albedo.
    let white = Params {
        base: [1.0; 3],
        metallic: 1.0,
        roughness: 1.0,
        ..PLASTIC
    };
    assert!((albedo(&white, 1.0)[0] - (1.0 - 2f64.ln())).abs() < 0.01);
    check("white metal, single scattering", white);
    let mirror = PbrMaterial {
        multiple_scattering: true,
        ..pbr(&Params {
            roughness: 0.05,
            ..white
        })
    };
    check_albedo(
        "near-mirror, compensated",
        &Params {
            roughness: 0.05,
            ..white
        },
        Material::physically_based("mirror", mirror, Vec3::ZERO, None),
    );
}

#[test]
fn index_1_keeps_schlicks_grazing_term_and_index_2_reflects_more() {
    check(
        "ior 1",
        Params {
            ior: 1.0,
            ..PLASTIC
        },
    );
    check(
        "ior 2",
        Params {
            ior: 2.0,
            ..PLASTIC
        },
    );
}

#[test]
fn specular_0_is_pure_lambert() {
    let p = Params {
        specular: 0.0,
        ..PLASTIC
    };
    for cos in [1.0, 0.3] {
        let a = albedo(&p, cos);
        for c in 0..3 {
            assert!((a[c] - p.base[c]).abs() < 1e-3, "{a:?}");
        }
    }
    check("specular 0", p);
}

#[test]
fn clearcoats_return_their_directional_albedo() {
    check(
        "rough clearcoat",
        Params {
            clearcoat: 1.0,
            clearcoat_roughness: 0.3,
            ..PLASTIC
        },
    );
    check(
        "smooth clearcoat",
        Params {
            clearcoat: 0.7,
            ..PLASTIC
        },
    );
}

/// A 1 x 1 texture of the given RGB bytes, linear.
fn texel(rgb: [u8; 3]) -> Arc<Texture> {
    Arc::new(Texture::from_u8("texel.png".into(), 1, 1, 3, rgb.to_vec()).unwrap())
}

#[test]
fn a_metallic_roughness_texture_sets_both_through_its_green_and_blue() {
    // Factors of 1 (glTF's defaults), the texture saying roughness 0.5, metallic 0.
    let image = texel([255, 128, 0]);
    let channel = |channel| {
        let mut map = TextureMap::new(image.clone());
        map.options.channel = channel;
        Some(map)
    };
    let maps = MaterialMaps {
        pbr: PbrMaps {
            roughness: channel(Channel::Green),
            metallic: channel(Channel::Blue),
            ..PbrMaps::default()
        },
        ..MaterialMaps::default()
    };
    let factors = PbrMaterial {
        metallic: 1.0,
        roughness: 1.0,
        ..pbr(&PLASTIC)
    };
    let material =
        Material::physically_based("textured", factors, Vec3::ZERO, Some(Box::new(maps)));
    check_albedo(
        "textured",
        &Params {
            roughness: 128.0 / 255.0,
            metallic: 0.0,
            ..PLASTIC
        },
        material,
    );
}

#[test]
fn a_lossless_thin_pane_vanishes_in_the_furnace() {
    // Every path returns exactly 1 until Russian roulette (from the fifth bounce)
    // starts ending some and weighting the others up: near grazing, where the pane
    // reflects most, that adds noise around 1.
    for roughness in [0.0] {
        let pane = PbrMaterial {
            base_color: Vec3::ONE,
            metallic: 0.0,
            roughness,
            transmission: 1.0,
            ..PbrMaterial::default()
        };
        let (scene, integrator) =
            furnace(Material::physically_based("pane", pane, Vec3::ZERO, None));
        for cos in [1.0, 0.5, 0.1] {
            let got = mean_radiance(&scene, &integrator, ray_at(cos), 20_000);
            assert!(
                (got - Vec3::ONE).abs().max_element() < 0.01,
                "cos {cos}: {got}"
            );
        }
    }
}

#[test]
fn a_volume_attenuates_by_beer_lambert_over_the_chord() {
    let colour = Vec3::new(0.8, 0.5, 0.2);
    let distance = 0.7;
    let volume = PbrMaterial {
        base_color: Vec3::ONE,
        metallic: 0.0,
        roughness: 0.0,
        ior: 1.0,
        specular: 0.0,
        transmission: 1.0,
        thickness: 1.0,
        attenuation_color: colour,
        attenuation_distance: distance,
        ..PbrMaterial::default()
    };
    let (scene, integrator) = furnace(Material::physically_based(
        "volume",
        volume,
        Vec3::ZERO,
        None,
    ));
    for offset in [0.0f32, 0.5, 0.9] {
        let chord = 2.0 * (1.0 - offset * offset).sqrt();
        let ray = Ray::new(Vec3::new(offset, 0.0, 5.0), -Vec3::Z);
        let got = mean_radiance(&scene, &integrator, ray, 64);
        let expected = Vec3::new(
            colour.x.powf(chord / distance),
            colour.y.powf(chord / distance),
            colour.z.powf(chord / distance),
        );
        assert!(
            (got - expected).abs().max_element() < 1e-3,
            "offset {offset}: {got} vs {expected}"
        );
    }
}

/// Mitsuba 3's `roughconductor` (GGX, a perfect conductor: Fresnel 1, our metal of
/// white base colour) at fixed pairs of directions, from
/// `tests/data/materials/make_mitsuba.py`: our GGX `D` with Mitsuba's separable
/// Smith term swapped in for glTF's height-correlated one gives the same `f`.
#[test]
fn ggx_matches_mitsubas_roughconductor_with_its_separable_smith_term() {
    let pairs = crate::support::check_against_mitsuba_table("roughconductor.toml", |pair| Ggx {
        alpha: pair["alpha"].as_float().unwrap() as Float,
    });
    assert_eq!(pairs, 96);
}

/// A smooth clear coat over a black base reflects by its own normal map
/// (`clearcoatNormalTexture` with its `scale`): seen head on, a coat tilted by
/// `theta` mirrors the camera ray to `2 theta` from the normal, where a small lamp
/// returns `Le clearcoat F_coat(cos theta)`; the untilted direction, and a lamp
/// where the unscaled tilt would send the ray, stay dark.
#[test]
fn a_clearcoat_normal_map_turns_the_coats_reflection() {
    // A tangent-space normal tilted towards +u, as 8-bit texels store it.
    let bytes = [160u8, 128, 238];
    let decoded = |b: u8| b as f64 / 255.0 * 2.0 - 1.0;
    let lamp_radiance = 2.0;
    // The coat's normal in the world, for a quad in z = 0 whose u runs along +x.
    let tilted = |scale: f64| {
        let n = [
            decoded(bytes[0]) * scale,
            decoded(bytes[1]) * scale,
            decoded(bytes[2]),
        ];
        normalize(n)
    };
    let render = |scale: f64, lamp_along: [f64; 3]| {
        let mut map = TextureMap::new(texel(bytes));
        map.options.bump_multiplier = scale as Float;
        let maps = MaterialMaps {
            pbr: PbrMaps {
                clearcoat_normal: Some(map),
                ..PbrMaps::default()
            },
            ..MaterialMaps::default()
        };
        let coat = PbrMaterial {
            base_color: Vec3::ZERO,
            metallic: 0.0,
            specular: 0.0,
            clearcoat: 1.0,
            clearcoat_roughness: 0.0,
            ..PbrMaterial::default()
        };
        let lamp = Material {
            emission: Vec3::splat(lamp_radiance as Float),
            ..Material::named("lamp")
        };
        let at = |v: [f64; 3]| Vec3::new(v[0] as Float, v[1] as Float, v[2] as Float);
        let corner = |x: Float, y: Float| Vec3::new(x, y, 0.0);
        let description = SceneDescription {
            positions: vec![
                corner(-1.0, -1.0),
                corner(1.0, -1.0),
                corner(1.0, 1.0),
                corner(-1.0, 1.0),
            ],
            texcoords: vec![
                Vec2::new(0.0, 0.0),
                Vec2::new(1.0, 0.0),
                Vec2::new(1.0, 1.0),
                Vec2::new(0.0, 1.0),
            ],
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
            spheres: vec![SphereDesc {
                center: at(lamp_along) * 3.0,
                radius: 0.3,
                material: MaterialId(1),
            }],
            materials: vec![
                Material::physically_based("coat", coat, Vec3::ZERO, Some(Box::new(maps))),
                lamp,
            ],
            ..SceneDescription::default()
        };
        let scene = Scene::build(description, &BvhParams::default());
        let integrator = PathIntegrator::new(&scene, 4, false);
        let ray = Ray::new(Vec3::new(0.0, 0.0, 5.0), -Vec3::Z);
        mean_radiance(&scene, &integrator, ray, 16)
    };
    let mirrored = |n: [f64; 3]| {
        // The reflection of +z about n.
        let c = n[2];
        [2.0 * c * n[0], 2.0 * c * n[1], 2.0 * c * n[2] - 1.0]
    };
    for scale in [1.0, 0.5] {
        let n = tilted(scale);
        let expected = lamp_radiance * (0.04 + 0.96 * (1.0 - n[2]).powi(5));
        let got = render(scale, mirrored(n));
        assert!(
            (got - Vec3::splat(expected as Float)).abs().max_element() < 1e-4,
            "scale {scale}: the lamp where the tilted coat mirrors the ray shows {got}, expected {expected}"
        );
    }
    // The coat at half the tilt misses a lamp where the full tilt would send the ray,
    // and the tilted coat one off to the side of the untilted mirror direction.
    assert_eq!(render(0.5, mirrored(tilted(1.0))), Vec3::ZERO);
    assert_eq!(render(1.0, normalize([-0.3, 0.0, 1.0])), Vec3::ZERO);
}

/// A blended surface (glTF's `alphaMode: BLEND`) of alpha 0.3 and no scattering of
/// its own, in front of a white environment, lets 0.7 of the light through: each ray
/// decides by a hash of itself and the triangle, so a grid of rays sees a fraction
/// 0.7 of white, and shadow rays are blocked by a fraction 0.3, each ray deciding as
/// its closest-hit query did.
#[test]
fn a_blended_surface_lets_one_minus_alpha_of_the_light_through() {
    let alpha = 0.3;
    let black = PbrMaterial {
        base_color: Vec3::ZERO,
        metallic: 0.0,
        specular: 0.0,
        ..PbrMaterial::default()
    };
    let maps = MaterialMaps {
        cutout: Some(Cutout {
            map: None,
            factor: alpha,
            cutoff: 0.5,
            blend: true,
        }),
        ..MaterialMaps::default()
    };
    let corner = |x: Float, y: Float| Vec3::new(x, y, 0.0);
    let description = SceneDescription {
        positions: vec![
            corner(-1.0, -1.0),
            corner(1.0, -1.0),
            corner(1.0, 1.0),
            corner(-1.0, 1.0),
        ],
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
        materials: vec![Material::physically_based(
            "veil",
            black,
            Vec3::ZERO,
            Some(Box::new(maps)),
        )],
        ..SceneDescription::default()
    };
    let scene = Scene::build(description, &BvhParams::default());
    let integrator = PathIntegrator::new(&scene, 4, false).with_environment(&scene, Vec3::ONE);
    let sampler = PixelSampler::new(1, integrator.dimensions());
    let mut rays = RayCounts::default();
    let n = 64;
    let (mut through, mut blocked) = (0.0, 0);
    for i in 0..n {
        for j in 0..n {
            let at = |k: usize| (k as Float + 0.5) / n as Float - 0.5;
            let ray = Ray::new(Vec3::new(at(i), at(j), 3.0), -Vec3::Z);
            let mut sample = sampler.sample((i * n + j) as u64, 0);
            let radiance = integrator.radiance(&scene, &ray, &mut sample, &mut rays);
            through += radiance.x as f64;
            let occluded = scene.occluded(&ray, 10.0);
            blocked += occluded as u32;
            assert_eq!(occluded, scene.intersect(&ray).is_some());
        }
    }
    let count = (n * n) as f64;
    let (through, blocked) = (through / count, blocked as f64 / count);
    // 4096 rays: the binomial's standard deviation is 0.007.
    assert!((through - 0.7).abs() < 0.025, "light through: {through}");
    assert!(
        (blocked - 0.3).abs() < 0.025,
        "shadow rays blocked: {blocked}"
    );
}

/// In a scene that blends in layers (full mode's), a blended surface of alpha `a`
/// over a floor is its own value composited over the floor's,
/// `a * surface + (1 - a) * behind`, at every pixel (no dither), where `surface` is its value when opaque
/// and `behind` the floor's seen from behind it; it casts a shadow from alpha 0.5:
/// the floor behind a veil of 0.3 is lit as with no veil, behind one of 0.7 as
/// behind an opaque one.
#[test]
fn full_mode_composites_a_blended_surface_over_what_lies_behind_it() {
    let quad = |z: Float, half: Float, material: u32, d: &mut SceneDescription| {
        let first = d.positions.len() as u32;
        for (x, y) in [(-half, -half), (half, -half), (half, half), (-half, half)] {
            d.positions.push(Vec3::new(x, y, z));
        }
        for corners in [[0, 1, 2], [0, 2, 3]] {
            d.triangles.push(TriangleDesc {
                positions: corners.map(|k| first + k),
                material: MaterialId(material),
            });
        }
    };
    // `veil`: none, blended of this alpha, or opaque.
    let scene = |veil: Option<(Float, bool)>| {
        let colour = |rgb: [Float; 3]| PbrMaterial {
            base_color: Vec3::from(rgb),
            metallic: 0.0,
            roughness: 0.6,
            ..PbrMaterial::default()
        };
        let (alpha, blend) = veil.unwrap_or((1.0, false));
        let maps = MaterialMaps {
            cutout: Some(Cutout {
                map: None,
                factor: alpha,
                cutoff: 0.5,
                blend,
            }),
            ..MaterialMaps::default()
        };
        let mut d = SceneDescription {
            materials: vec![
                Material::physically_based("floor", colour([0.2, 0.7, 0.3]), Vec3::ZERO, None),
                Material::physically_based(
                    "veil",
                    colour([0.9, 0.3, 0.1]),
                    Vec3::ZERO,
                    Some(Box::new(maps)),
                ),
            ],
            lights: vec![Light::point(Vec3::new(0.3, 0.4, 3.0), Vec3::ONE)],
            ..SceneDescription::default()
        };
        quad(-1.0, 3.0, 0, &mut d);
        if veil.is_some() {
            quad(0.0, 1.0, 1, &mut d);
        }
        let mut scene = Scene::build(d, &BvhParams::default());
        scene.set_blend_in_layers(true);
        scene
    };
    let integrator = WhittedIntegrator { max_depth: 4 };
    let sampler = PixelSampler::new(1, integrator.dimensions());
    let value = |scene: &Scene, x: Float, y: Float, z: Float| {
        let ray = Ray::new(Vec3::new(x, y, z), -Vec3::Z);
        let mut rays = RayCounts::default();
        integrator.radiance(scene, &ray, &mut sampler.sample(0, 0), &mut rays)
    };
    let (bare, shut) = (scene(None), scene(Some((1.0, false))));
    for alpha in [0.3, 0.7] {
        let (blended, opaque) = (scene(Some((alpha, true))), scene(Some((1.0, true))));
        for i in 0..8 {
            for j in 0..8 {
                let at = |k: i32| (k as Float + 0.5) / 4.0 - 1.0;
                let (x, y) = (at(i), at(j));
                let behind = value(&blended, x, y, -0.5);
                let lit_as = if alpha < 0.5 { &bare } else { &shut };
                assert!(
                    (behind - value(lit_as, x, y, -0.5)).abs().max_element() < 1e-6,
                    "alpha {alpha}: the floor behind the veil at ({x}, {y}) is {behind}"
                );
                let surface = value(&opaque, x, y, 3.0);
                let want = alpha * surface + (1.0 - alpha) * behind;
                let got = value(&blended, x, y, 3.0);
                assert!(
                    (got - want).abs().max_element() < 1e-5,
                    "alpha {alpha} at ({x}, {y}): {got}, expected {want} ({surface} over {behind})"
                );
            }
        }
    }
}
