//! Path mode against Mitsuba 3 and against closed forms: the Cornell box of
//! `tests/data/path/` within the noise Mitsuba shows against its own converged image,
//! a white furnace, a point light's inverse-square falloff, one-sided emitters, and
//! determinism across threads, tiles and seeds.

use crate::support;

use std::path::Path;

use raytracer::math::{Float, Vec3};
use raytracer::{BvhParams, Film, Mode, RenderOptions, Scene, Tile, formats, render, render_tile};

fn data() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/path"))
}

fn scene_from(obj: &str) -> Scene {
    let description = formats::parse_obj(obj.as_bytes(), Path::new("test.obj")).unwrap();
    Scene::build(description, &BvhParams::default())
}

/// The relative error of each `block` x `block` block's mean (over its pixels and
/// channels) against the reference, sorted; exactly `block_errors` of
/// make_reference.py.
fn block_errors(image: &[Vec3], reference: &[Vec3], width: usize, block: usize) -> Vec<f64> {
    let height = image.len() / width;
    let mean = |pixels: &[Vec3], bx: usize, by: usize| {
        let mut sum = 0.0f64;
        for y in by..by + block {
            for x in bx..bx + block {
                let v = pixels[y * width + x];
                sum += f64::from(v.x) + f64::from(v.y) + f64::from(v.z);
            }
        }
        sum / (3 * block * block) as f64
    };
    let mut errors = Vec::new();
    for by in (0..height).step_by(block) {
        for bx in (0..width).step_by(block) {
            let (a, r) = (mean(image, bx, by), mean(reference, bx, by));
            errors.push((a - r).abs() / r.max(1e-3));
        }
    }
    errors.sort_by(f64::total_cmp);
    errors
}

fn mean_and_p95(errors: &[f64]) -> (f64, f64) {
    let mean = errors.iter().sum::<f64>() / errors.len() as f64;
    (mean, errors[(0.95 * (errors.len() - 1) as f64) as usize])
}

#[derive(serde::Deserialize)]
struct Noise {
    width: u32,
    height: u32,
    fov: Float,
    max_depth: u32,
    look_from: [Float; 3],
    look_to: [Float; 3],
    block: usize,
    noise: Vec<NoiseAt>,
}

#[derive(serde::Deserialize)]
struct NoiseAt {
    spp: u32,
    mitsuba_mean: Vec<f64>,
    mitsuba_p95: Vec<f64>,
}

#[test]
fn the_cornell_box_matches_mitsuba_within_mitsubas_own_noise() {
    let noise: Noise =
        toml::from_str(&std::fs::read_to_string(data().join("noise.toml")).unwrap()).unwrap();
    let (width, height, channels) = support::read_exr(&data().join("reference.exr"));
    assert_eq!(
        (width, height),
        (noise.width as usize, noise.height as usize)
    );
    let reference: Vec<Vec3> = (0..width * height)
        .map(|i| Vec3::new(channels["R"][i], channels["G"][i], channels["B"][i]))
        .collect();
    let scene = Scene::build(
        formats::load_obj(&data().join("cornell.obj")).unwrap(),
        &BvhParams::default(),
    );
    for at in &noise.noise {
        let options = RenderOptions {
            width: noise.width,
            height: noise.height,
            fov_degrees: noise.fov,
            look_from: noise.look_from.into(),
            look_to: noise.look_to.into(),
            depth: noise.max_depth,
            mode: Mode::Path,
            samples_per_pixel: at.spp,
            ..RenderOptions::default()
        };
        options.validate().unwrap();
        let film = render(&scene, &options);
        let (mean, p95) = mean_and_p95(&block_errors(&film.pixels, &reference, width, noise.block));
        // Within Mitsuba's own scatter: its runs' mean plus three standard deviations
        // (the largest of a handful of runs understates the tail: caustics through
        // the glass sphere, which only BSDF sampling finds, make rare bright samples
        // in both renderers).
        let bound = |runs: &[f64]| {
            let n = runs.len() as f64;
            let m = runs.iter().sum::<f64>() / n;
            let variance = runs.iter().map(|r| (r - m).powi(2)).sum::<f64>() / (n - 1.0);
            m + 3.0 * variance.sqrt()
        };
        let (mean_bound, p95_bound) = (bound(&at.mitsuba_mean), bound(&at.mitsuba_p95));
        println!(
            "{} spp: mean block error {mean:.4} (Mitsuba {:?}, bound {mean_bound:.4}), p95 {p95:.4} (Mitsuba {:?}, bound {p95_bound:.4})",
            at.spp, at.mitsuba_mean, at.mitsuba_p95
        );
        assert!(
            mean <= mean_bound,
            "{} spp: mean block error {mean} > {mean_bound}",
            at.spp
        );
        assert!(
            p95 <= p95_bound,
            "{} spp: p95 block error {p95} > {p95_bound}",
            at.spp
        );
        // No bias: the whole image's mean within 1% of Mitsuba's converged one.
        let total = |pixels: &[Vec3]| {
            pixels
                .iter()
                .map(|v| f64::from(v.x + v.y + v.z))
                .sum::<f64>()
        };
        let ratio = total(&film.pixels) / total(&reference);
        println!("{} spp: image mean / Mitsuba's {ratio:.4}", at.spp);
        assert!(
            (ratio - 1.0).abs() < 0.01,
            "{} spp: image mean ratio {ratio}",
            at.spp
        );
    }
}

fn options(mode: Mode, width: u32, height: u32, spp: u32) -> RenderOptions {
    RenderOptions {
        width,
        height,
        fov_degrees: 60.0,
        look_from: Vec3::new(0.0, 0.0, 3.0),
        look_to: Vec3::ZERO,
        mode,
        samples_per_pixel: spp,
        depth: 64,
        ..RenderOptions::default()
    }
}

/// A Lambertian sphere of albedo `albedo` at the origin in a uniform white
/// environment.
fn sphere_of_albedo(albedo: Float) -> Scene {
    let mut description = formats::parse_obj(b"S 0 0 0 1\n", Path::new("sphere.obj")).unwrap();
    description.materials[0].diffuse = Vec3::splat(albedo);
    in_white_sky(description)
}

/// The scene of `description` under a uniform white environment.
fn in_white_sky(mut description: raytracer::SceneDescription) -> Scene {
    description.environment = Some(raytracer::formats::environment::environment_colour(
        Vec3::ONE,
        1.0,
    ));
    Scene::build(description, &BvhParams::default())
}

#[test]
fn a_white_furnace_returns_the_environment_exactly() {
    // Every path that leaves the sphere sees 1, and the sphere returns all it receives.
    let film = render(&sphere_of_albedo(1.0), &options(Mode::Path, 24, 24, 16));
    for (i, v) in film.pixels.iter().enumerate() {
        for c in v.to_array() {
            assert!((c - 1.0).abs() < 1e-4, "pixel {i}: {v}");
        }
    }
}

#[test]
fn a_grey_sphere_in_the_furnace_returns_its_albedo_from_the_first_bounce() {
    let film = render(&sphere_of_albedo(0.5), &options(Mode::Path, 16, 16, 4));
    // The centre sees the sphere (0.5: one bounce into the sky), the corners the sky.
    let centre = film.pixels[8 * 16 + 8];
    assert!(
        (centre - Vec3::splat(0.5)).abs().max_element() < 1e-4,
        "{centre}"
    );
    assert_eq!(film.pixels[0], Vec3::ONE);
}

/// A glTF material of base colour `rho` that is Lambertian: a dielectric of
/// `specular` 0 (`KHR_materials_specular`), which path mode shades in its sixteen-lane
/// step.
fn lambertian_gltf(rho: Float) -> raytracer::material::Material {
    raytracer::material::Material::physically_based(
        "lambert",
        raytracer::material::pbr::PbrMaterial {
            base_color: Vec3::splat(rho),
            metallic: 0.0,
            specular: 0.0,
            ..Default::default()
        },
        Vec3::ZERO,
        None,
    )
}

/// A square in the plane z = 0 whose vertex normals all lean 45 degrees towards -x,
/// made of `material` (the OBJ default, a Lambertian grey of 0.8, if `None`), in a
/// uniform white environment.
fn leaning_square(material: Option<raytracer::material::Material>) -> Scene {
    let obj = "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvn -1 0 1\n\
               f 1//1 2//1 3//1\nf 1//1 3//1 4//1\n";
    let mut description = formats::parse_obj(obj.as_bytes(), Path::new("square.obj")).unwrap();
    if let Some(material) = material {
        description.materials[0] = material;
    }
    in_white_sky(description)
}

/// Seen from 60 degrees towards +x, the leaning normals face away from the eye, as
/// interpolated normals do along a low-poly silhouette: every lobe would see the
/// eye from below and the surface render black. The normal bent towards the eye
/// until it mirrors the eye 0.01 (in cosine) above the surface, as Cycles bends
/// it, leans `phi` from the geometric normal, and a Lambertian surface of albedo
/// `rho` in a white sky then returns the sky's view factor of a plane tilted by
/// `phi`, `rho (1 + cos phi) / 2` (its cosine-weighted directions below the
/// surface are dropped). Both the scalar step (an MTL material) and the
/// sixteen-lane one (a glTF material of `specular` 0) bend it.
#[test]
fn a_shading_normal_facing_away_from_the_eye_is_bent_towards_it() {
    let (s60, c60) = (60f64.to_radians().sin(), 60f64.to_radians().cos());
    let wo = [s60, 0.0, c60];
    let ns = [-(0.5f64.sqrt()), 0.0, 0.5f64.sqrt()];
    let cos_o = wo[0] * ns[0] + wo[2] * ns[2];
    let mirrored = [2.0 * cos_o * ns[0] - wo[0], 2.0 * cos_o * ns[2] - wo[2]];
    assert!(cos_o < 0.0 && mirrored[1] < 0.0);
    // Above the surface by 0.01 on the mirrored direction's side (-x).
    let threshold = (0.9 * wo[2]).min(0.01);
    let wanted = [-(1.0 - threshold * threshold).sqrt(), threshold];
    let bent = [wo[0] + wanted[0], wo[2] + wanted[1]];
    let cos_phi = bent[1] / (bent[0] * bent[0] + bent[1] * bent[1]).sqrt();
    let view_factor = (1.0 + cos_phi) / 2.0;
    let mut options = options(Mode::Path, 8, 8, 64);
    options.look_from = Vec3::new(5.0 * s60 as Float, 0.0, 5.0 * c60 as Float);
    options.fov_degrees = 1.0;
    let gltf_lambert = lambertian_gltf(0.6);
    for (material, rho) in [(None, 0.8), (Some(gltf_lambert), 0.6)] {
        let film = render(&leaning_square(material), &options);
        let mean = film
            .pixels
            .iter()
            .map(|v| f64::from(v.x + v.y + v.z) / 3.0)
            .sum::<f64>()
            / film.pixels.len() as f64;
        let expected = rho * view_factor;
        assert!(
            (mean - expected).abs() < 0.01 * expected,
            "albedo {rho}: mean {mean}, expected {expected} (cos phi {cos_phi})"
        );
    }
}

/// An octahedron of "radius" 1 whose vertex normals point out from its centre, as a
/// coarse sphere's do, made of `material` (the OBJ default, a Lambertian grey of
/// 0.8, if `None`), lit by a directional light from `towards_light` of illuminance
/// `illuminance`.
fn smooth_octahedron_lit(
    material: Option<raytracer::material::Material>,
    towards_light: Vec3,
    illuminance: Float,
) -> Scene {
    let obj = support::smooth_octahedron_obj();
    let mut description = formats::parse_obj(obj.as_bytes(), Path::new("octahedron.obj")).unwrap();
    if let Some(material) = material {
        description.materials[0] = material;
    }
    description.lights.push(raytracer::material::Light {
        position: Vec3::ZERO,
        intensity: Vec3::splat(illuminance),
        kind: raytracer::material::LightKind::Directional {
            direction: -towards_light.normalize(),
        },
        range: None,
    });
    Scene::build(description, &BvhParams::default())
}

/// The shadow terminator in path mode. At the point (0.8, 0.1, 0.1) of the
/// octahedron's face in the positive octant, a light from (1, -0.7, -0.7) lies
/// behind the flat triangle while the interpolated normal still faces it. A convex
/// smooth surface cannot shadow a point of itself that faces the light, so the point
/// must be lit as a sphere's would: `rho / pi * E * cos(ns, l)`, the light sampled
/// past the terminator and its shadow ray started from the smooth surface the
/// vertex normals describe. Before, the triangle's own plane cut the light off in
/// steps of whole triangles along a coarse sphere's terminator. Both the scalar step
/// (an MTL material) and the sixteen-lane one (a glTF material of `specular` 0).
#[test]
fn past_a_smooth_meshs_terminator_the_light_reaches_what_the_shading_normal_faces() {
    let p = Vec3::new(0.8, 0.1, 0.1);
    let ns = p.normalize();
    let towards_light = Vec3::new(1.0, -0.7, -0.7).normalize();
    assert!(towards_light.dot(Vec3::ONE) < 0.0 && towards_light.dot(ns) > 0.5);
    let illuminance = 2.0;
    let mut options = options(Mode::Path, 4, 4, 16);
    options.look_from = p + Vec3::new(1.0, -0.3, -0.3).normalize() * 2.0;
    options.look_to = p;
    // A narrow view: the eye sees the face at a grazing angle, and across a wider
    // one the shading normal's cosine to the light changes by percents.
    options.fov_degrees = 0.02;
    let gltf_lambert = lambertian_gltf(0.6);
    for (material, rho) in [(None, 0.8), (Some(gltf_lambert), 0.6)] {
        let scene = smooth_octahedron_lit(material, towards_light, illuminance);
        let film = render(&scene, &options);
        let expected = rho / std::f32::consts::PI * illuminance * ns.dot(towards_light);
        for v in &film.pixels {
            assert!(
                (v.x - expected).abs() < 0.01 * expected,
                "albedo {rho}: pixel {v}, expected {expected}"
            );
        }
    }
}

#[test]
fn a_point_light_falls_off_with_the_square_of_the_distance() {
    // A Lambertian quad (the default material, Kd 0.8) facing the camera, lit by a
    // point light at the camera: the centre pixel is Kd / pi * I * cos / r^2, cos = 1.
    for (distance, intensity) in [(2.0f32, 4.0f32), (4.0, 4.0), (3.0, 9.0)] {
        let obj = format!(
            "v -5 -5 {z}\nv 5 -5 {z}\nv 5 5 {z}\nv -5 5 {z}\nf 1 2 3 4\nP 0 0 3 {intensity} {intensity} {intensity}\n",
            z = 3.0 - distance
        );
        let scene = scene_from(&obj);
        let film = render(&scene, &options(Mode::Path, 9, 9, 1));
        let centre = film.pixels[4 * 9 + 4];
        let expected = 0.8 / std::f32::consts::PI * intensity / (distance * distance);
        assert!(
            (centre.x - expected).abs() < 1e-4 * expected.max(1.0),
            "r = {distance}: {centre} vs {expected}"
        );
    }
}

/// A unit quad at z = 0 emitting radiance 2, wound so that it faces `+z` (towards the
/// camera) or away from it, and nothing else.
fn emitter(facing_camera: bool) -> Scene {
    let face = if facing_camera {
        "f 1 2 3 4"
    } else {
        "f 4 3 2 1"
    };
    let text = format!("v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n{face}\n");
    let mut description = formats::parse_obj(text.as_bytes(), Path::new("light.obj")).unwrap();
    description.materials[0].diffuse = Vec3::ZERO;
    description.materials[0].emission = Vec3::splat(2.0);
    Scene::build(description, &BvhParams::default())
}

#[test]
fn triangles_emit_on_the_side_their_winding_faces_only() {
    let front = render(&emitter(true), &options(Mode::Path, 8, 8, 1));
    let back = render(&emitter(false), &options(Mode::Path, 8, 8, 1));
    let centre = 4 * 8 + 4;
    assert_eq!(front.pixels[centre], Vec3::splat(2.0));
    assert_eq!(back.pixels[centre], Vec3::ZERO);
}

#[test]
fn path_images_are_the_same_on_any_thread_count_and_tiles_equal_the_whole() {
    let scene = Scene::build(
        formats::load_obj(&data().join("cornell.obj")).unwrap(),
        &BvhParams::default(),
    );
    let options = RenderOptions {
        look_from: Vec3::new(0.0, 1.0, 3.4),
        look_to: Vec3::new(0.0, 1.0, 0.0),
        fov_degrees: 40.0,
        ..options(Mode::Path, 40, 30, 8)
    };
    let on = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| render(&scene, &options))
    };
    let whole = on(1);
    assert_eq!(whole, on(3));
    let tile = Tile {
        x: 13,
        y: 7,
        width: 11,
        height: 9,
    };
    let part: Film = render_tile(&scene, &options, tile).unwrap();
    for row in 0..tile.height {
        for column in 0..tile.width {
            assert_eq!(
                part.pixels[(row * tile.width + column) as usize],
                whole.pixels[((row + tile.y) * options.width + column + tile.x) as usize]
            );
        }
    }
    // Another seed, another (equally valid) image; the same seed, the same image.
    let seeded = RenderOptions { seed: 7, ..options };
    assert_ne!(render(&scene, &seeded), whole);
    assert_eq!(render(&scene, &seeded), render(&scene, &seeded));
}

#[cfg(not(feature = "denoise"))]
#[test]
fn denoising_without_the_feature_is_refused_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.png");
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_raytracer"))
        .args([
            "render",
            "tests/data/path/cornell.obj",
            "--mode",
            "path",
            "--denoise",
            "-o",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("--features denoise"), "{stderr}");
    assert!(!out.exists());
}

/// Only in builds with `--features denoise` (OIDN_DIR set, its `lib` on the library
/// path): 16 denoised samples per pixel come closer to Mitsuba's converged image than
/// 16 noisy ones.
#[cfg(feature = "denoise")]
#[test]
fn denoising_brings_a_noisy_render_closer_to_the_reference() {
    let (width, height, channels) = support::read_exr(&data().join("reference.exr"));
    let reference: Vec<Vec3> = (0..width * height)
        .map(|i| Vec3::new(channels["R"][i], channels["G"][i], channels["B"][i]))
        .collect();
    let scene = Scene::build(
        formats::load_obj(&data().join("cornell.obj")).unwrap(),
        &BvhParams::default(),
    );
    let options = RenderOptions {
        width: width as u32,
        height: height as u32,
        fov_degrees: 40.0,
        look_from: Vec3::new(0.0, 1.0, 3.4),
        look_to: Vec3::new(0.0, 1.0, 0.0),
        ..options(Mode::Path, 1, 1, 16)
    };
    let outputs = raytracer::render_outputs(
        &scene,
        &options,
        &[raytracer::Aov::Albedo, raytracer::Aov::Normal],
    );
    let noisy = &outputs.film;
    let clean = noisy.denoised(&raytracer::AovPlanes::default()).unwrap();
    let guided = noisy.denoised(&outputs.aovs).unwrap();
    let error = |film: &Film| mean_and_p95(&block_errors(&film.pixels, &reference, width, 4)).0;
    eprintln!(
        "noisy {}, denoised {}, guided by albedo and normal {}",
        error(noisy),
        error(&clean),
        error(&guided)
    );
    assert!(
        error(&clean) < error(noisy),
        "{} vs {}",
        error(&clean),
        error(noisy)
    );
    assert!(
        error(&guided) < error(noisy),
        "{} vs {}",
        error(&guided),
        error(noisy)
    );
}

/// Only in builds with `--features denoise`: a checkerboard of albedos lit evenly,
/// plus strong noise, denoised with its albedo as the guide comes back far closer to
/// the noise-free image (the albedo itself) than denoised without: the guide keeps
/// the edges the noise hides. With the normal too (flat: one direction), as well.
#[cfg(feature = "denoise")]
#[test]
fn the_albedo_and_normal_guide_the_denoiser() {
    let (width, height) = (64u32, 64u32);
    let albedo: Vec<Vec3> = (0..width * height)
        .map(|i| {
            let (x, y) = (i % width, i / width);
            if (x / 3 + y / 3) % 2 == 0 {
                Vec3::new(0.8, 0.7, 0.2)
            } else {
                Vec3::new(0.1, 0.2, 0.6)
            }
        })
        .collect();
    // Deterministic noise, as Monte Carlo's: a hash of the pixel and channel.
    let noise = |i: u32, c: u32| {
        let mut h = (i * 3 + c).wrapping_mul(0x9E37_79B9) ^ 0x85EB_CA6B;
        h ^= h >> 15;
        h = h.wrapping_mul(0x2C1B_3C6D);
        h ^= h >> 12;
        (h as Float / u32::MAX as Float - 0.5) * 0.8
    };
    let noisy = Film {
        width,
        height,
        pixels: (albedo.iter().enumerate())
            .map(|(i, a)| {
                let i = i as u32;
                (*a + Vec3::new(noise(i, 0), noise(i, 1), noise(i, 2))).max(Vec3::ZERO)
            })
            .collect(),
    };
    let error = |film: &Film| {
        let sum: f64 = (film.pixels.iter().zip(&albedo))
            .map(|(p, a)| f64::from((*p - *a).abs().element_sum()))
            .sum();
        sum / film.pixels.len() as f64
    };
    let unguided = noisy.denoised(&raytracer::AovPlanes::default()).unwrap();
    let mut guides = raytracer::AovPlanes {
        albedo: Some(albedo.clone()),
        ..raytracer::AovPlanes::default()
    };
    let by_albedo = noisy.denoised(&guides).unwrap();
    guides.normal = Some(vec![Vec3::Z; albedo.len()]);
    let by_both = noisy.denoised(&guides).unwrap();
    eprintln!(
        "noisy {}, unguided {}, albedo {}, albedo and normal {}",
        error(&noisy),
        error(&unguided),
        error(&by_albedo),
        error(&by_both)
    );
    assert!(error(&by_albedo) < 0.75 * error(&unguided));
    assert!(error(&by_both) < 0.75 * error(&unguided));
}
