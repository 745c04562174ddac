//! No NaN or infinity reaches a pixel: over every reference scene and seeded random
//! scenes (degenerate, tiny and huge shapes, lights inside objects, no lights, no
//! hits), and in the degenerate cases one by one: zero-area triangles, zero-length
//! `vn`, rays parallel to a triangle or grazing a sphere, empty images.

use crate::fuzz_checks;
use crate::support;

use std::path::Path;

use fuzz_checks::check_film;
use raytracer::description::{SphereDesc, TriangleDesc};
use raytracer::material::MaterialId;
use raytracer::math::{Float, Ray, Vec3};
use raytracer::{
    BvhParams, Film, Light, Material, Mode, RenderOptions, Scene, SceneDescription, formats, render,
};

const MODES: [Mode; 3] = [Mode::Depth, Mode::Normal, Mode::Full];

#[test]
fn reference_scenes_give_finite_pixels_in_every_mode() {
    let dir = support::reference_dir();
    let cases = support::reference_cases();
    for case in &cases {
        let description = formats::load_obj(&dir.join(&case.scene)).unwrap();
        let scene = Scene::build(description, &BvhParams::default());
        for mode in MODES {
            // A quarter of the size: every kind of ray the case has, at 1/16 the cost.
            let options = RenderOptions {
                width: case.width / 4,
                height: case.height / 4,
                fov_degrees: case.fov_degrees,
                look_from: case.look_from.into(),
                look_to: case.look_to.into(),
                up: Vec3::Y,
                depth: case.depth.max(4),
                mode,
                samples_per_pixel: 1,
                ..RenderOptions::default()
            };
            options.validate().unwrap();
            let film = render(&scene, &options);
            let checked = std::panic::catch_unwind(|| check_film(&film, mode));
            assert!(checked.is_ok(), "{} in {mode:?} mode", case.name);
        }
    }
}

/// splitmix64: a seeded source of numbers, so that a failing scene can be replayed.
struct Random(u64);

impl Random {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    fn unit(&mut self) -> Float {
        (self.next_u64() >> 40) as Float / (1u64 << 24) as Float
    }
    fn range(&mut self, low: Float, high: Float) -> Float {
        low + (high - low) * self.unit()
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }
    fn vec(&mut self, half_extent: Float) -> Vec3 {
        Vec3::new(
            self.range(-half_extent, half_extent),
            self.range(-half_extent, half_extent),
            self.range(-half_extent, half_extent),
        )
    }
    /// A magnitude spread over many orders: tiny, ordinary, huge and near the largest
    /// `f32`, where sums and products overflow.
    fn magnitude(&mut self) -> Float {
        [1e-30, 1e-6, 0.01, 0.5, 1.0, 3.0, 1e6, 1e30, 3e38][self.below(9)]
    }
}

/// A material of random kind: matte, mirror, glass, emissive, with odd values too
/// (negative colours, index 0, huge exponents).
fn random_material(r: &mut Random, index: usize) -> Material {
    let mut m = Material::named(format!("m{index}"));
    m.ambient = Vec3::splat(r.range(-0.2, 0.3));
    m.diffuse = r.vec(1.0).abs();
    m.specular = r.vec(1.0);
    m.emission = Vec3::splat(if r.below(8) == 0 { r.magnitude() } else { 0.0 });
    m.shininess = [0.0, 1.0, 50.0, 1e6, 1e30][r.below(5)];
    m.ior = [0.0, 1e-20, 1.0, 1.5, 2.4, 1e20][r.below(6)];
    m.albedo = match r.below(4) {
        0 => [1.0, 0.0, 0.0],
        1 => [0.2, 0.8, 0.0],
        2 => [0.0, 0.2, 0.8],
        _ => [r.unit(), r.unit(), r.unit()],
    };
    m
}

/// A random scene around the origin; the camera looks from (0, 0, 4) at it.
fn random_scene(seed: u64) -> SceneDescription {
    let r = &mut Random(seed);
    let mut d = SceneDescription {
        materials: (0..4).map(|i| random_material(r, i)).collect(),
        ..SceneDescription::default()
    };
    let material = |r: &mut Random| MaterialId(r.below(4) as u32);
    for _ in 0..r.below(40) {
        let scale = r.magnitude();
        let base = d.positions.len() as u32;
        let a = r.vec(2.0);
        let corners = match r.below(4) {
            // Zero area: a repeated corner, or three corners on a line.
            0 => [a, a, a + r.vec(scale)],
            1 => [a, a + Vec3::X * scale, a + Vec3::X * (2.0 * scale)],
            _ => [a, a + r.vec(scale), a + r.vec(scale)],
        };
        d.positions.extend(corners);
        let normals = (r.below(3) == 0).then(|| {
            let n = d.normals.len() as u32;
            // Some zero-length and some huge normals.
            d.normals.extend([Vec3::ZERO, r.vec(1.0), r.vec(1e30)]);
            [n, n + 1, n + 2]
        });
        d.push_triangle(
            TriangleDesc {
                positions: [base, base + 1, base + 2],
                material: material(r),
            },
            normals,
        );
    }
    for _ in 0..r.below(6) {
        d.spheres.push(SphereDesc {
            center: r.vec(2.0),
            radius: r.magnitude(),
            material: material(r),
        });
    }
    // Sometimes no lights; lights may sit inside objects or be very bright.
    for _ in 0..r.below(4) {
        d.lights
            .push(Light::point(r.vec(2.0), r.vec(1.0).abs() * r.magnitude()));
    }
    d
}

#[test]
fn seeded_random_scenes_give_finite_pixels_in_every_mode() {
    for seed in 0..200 {
        let scene = Scene::build(random_scene(seed), &BvhParams::default());
        if let Err(e) = scene.validate() {
            panic!("seed {seed}: {e}");
        }
        for (look_from, look_to) in [
            (Vec3::new(0.0, 0.0, 4.0), Vec3::ZERO),
            (Vec3::ZERO, Vec3::Y),
        ] {
            for mode in MODES {
                let options = RenderOptions {
                    width: 24,
                    height: 16,
                    look_from,
                    look_to,
                    depth: 5,
                    mode,
                    ..RenderOptions::default()
                };
                let film = render(&scene, &options);
                let checked = std::panic::catch_unwind(|| check_film(&film, mode));
                assert!(
                    checked.is_ok(),
                    "seed {seed}, {mode:?} mode, from {look_from}"
                );
            }
        }
    }
}

/// A one-material description from OBJ text.
fn parse(obj: &str) -> SceneDescription {
    formats::parse_obj(obj.as_bytes(), Path::new("test.obj")).unwrap()
}

fn render_small(scene: &Scene, mode: Mode, look_from: Vec3, look_to: Vec3) -> Film {
    let options = RenderOptions {
        width: 16,
        height: 12,
        look_from,
        look_to,
        mode,
        ..RenderOptions::default()
    };
    render(scene, &options)
}

#[test]
fn zero_area_triangles_are_skipped_with_one_warning_that_counts_them() {
    let description = parse(
        "v 0 0 -1\nv 1 0 -1\nv 2 0 -1\nv 0 1 -1\n\
         f 1 2 3\nf 1 1 4\nf 4 4 4\nf 1 2 4\n",
    );
    let scene = Scene::build(description, &BvhParams::default());
    assert_eq!(scene.prim_count(), 1);
    let counted: Vec<&String> = scene
        .warnings
        .iter()
        .filter(|w| w.contains("degenerate"))
        .collect();
    assert_eq!(counted, ["skipped 3 degenerate (zero-area) triangles"]);
}

#[test]
fn zero_length_vertex_normals_fall_back_to_the_geometric_normal() {
    // A tilted triangle seen from the front: with `vn 0 0 0` at every corner, and at
    // one corner, its normals must be those of the same triangle without `vn`.
    let triangle = "v -1 -1 -2\nv 1 -1 -3\nv 0 1 -2.5\n";
    let plain = Scene::build(
        parse(&format!("{triangle}f 1 2 3\n")),
        &BvhParams::default(),
    );
    let zero = Scene::build(
        parse(&format!("{triangle}vn 0 0 0\nf 1//1 2//1 3//1\n")),
        &BvhParams::default(),
    );
    let film = |s: &Scene| render_small(s, Mode::Normal, Vec3::ZERO, Vec3::NEG_Z);
    let expected = film(&plain);
    assert!(
        expected.pixels.iter().any(|&p| p != Vec3::ZERO),
        "the triangle is seen"
    );
    assert_eq!(film(&zero), expected);

    // One zero corner among real ones: that corner uses the geometric normal, so the
    // result stays finite and unit-length.
    let geometric = (Vec3::new(2.0, 0.0, -1.0))
        .cross(Vec3::new(1.0, 2.0, -0.5))
        .normalize();
    let mixed = Scene::build(
        parse(&format!(
            "{triangle}vn 0 0 0\nvn {} {} {}\nf 1//1 2//2 3//2\n",
            geometric.x, geometric.y, geometric.z
        )),
        &BvhParams::default(),
    );
    let ray = Ray::new(Vec3::ZERO, Vec3::new(0.0, -0.2, -1.0));
    let hit = mixed.intersect(&ray).expect("the ray hits the triangle");
    assert!((hit.ns.length() - 1.0).abs() < 1e-5);
    assert!(
        (hit.ns.dot(hit.n) - 1.0).abs() < 1e-5,
        "{} vs {}",
        hit.ns,
        hit.n
    );
}

#[test]
fn rays_parallel_to_a_triangle_miss_it_and_stay_finite() {
    let scene = Scene::build(
        parse("v -1 0 -1\nv 1 0 -1\nv 0 0 -3\nf 1 2 3\nP 0 1 0 1 1 1\n"),
        &BvhParams::default(),
    );
    // In the triangle's plane, through its middle.
    let ray = Ray::new(Vec3::new(0.0, 0.0, 0.0), Vec3::NEG_Z);
    assert_eq!(scene.intersect(&ray), None);
    assert_eq!(scene.intersect_linear(&ray), None);
    // A camera in the plane looking along it: the triangle is edge-on, nothing to see.
    for mode in MODES {
        let film = render_small(
            &scene,
            mode,
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(0.0, 0.0, -1.0),
        );
        check_film(&film, mode);
    }
}

#[test]
fn rays_grazing_a_sphere_give_finite_hits() {
    let scene = Scene::build(parse("S 0 0 -3 1\nP 0 0 0 1 1 1\n"), &BvhParams::default());
    // Tangent to the sphere, and just inside and outside the tangent.
    for offset in [1.0, 1.0 - 1e-7, 1.0 + 1e-7, 0.999_999, 1.000_001] {
        let ray = Ray::new(Vec3::new(offset, 0.0, 0.0), Vec3::NEG_Z);
        if let Some(hit) = scene.intersect(&ray) {
            assert!(
                hit.t.is_finite() && hit.p.is_finite(),
                "offset {offset}: {hit:?}"
            );
            assert!(
                (hit.n.length() - 1.0).abs() < 1e-5,
                "offset {offset}: {hit:?}"
            );
        }
    }
    // A camera whose edge rays graze the sphere.
    for mode in MODES {
        let film = render_small(
            &scene,
            mode,
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, -3.0),
        );
        check_film(&film, mode);
    }
}

#[test]
fn images_without_lights_or_hits_divide_by_nothing() {
    // No lights: full mode is black (no ambient here), depth and normal still work.
    let dark = Scene::build(parse("S 0 0 -3 1\n"), &BvhParams::default());
    let film = render_small(&dark, Mode::Full, Vec3::ZERO, Vec3::NEG_Z);
    check_film(&film, Mode::Full);
    assert!(film.to_image(Mode::Full).rgb.iter().all(|&b| b == 0));

    // No hits: depth is white, normal and full are black.
    let empty = Scene::build(parse("P 0 0 0 1 1 1\n"), &BvhParams::default());
    for (mode, byte) in [(Mode::Depth, 255), (Mode::Normal, 0), (Mode::Full, 0)] {
        let film = render_small(&empty, mode, Vec3::ZERO, Vec3::NEG_Z);
        check_film(&film, mode);
        assert!(
            film.to_image(mode).rgb.iter().all(|&b| b == byte),
            "{mode:?}"
        );
    }
}

#[test]
fn tone_mapping_stays_in_range_for_extreme_films() {
    for values in [
        [1e-40, 0.0, 5e-41],
        [Float::MAX, 1.0, 0.0],
        [Float::MAX, Float::MAX, 1e-30],
        [-1.0, 0.5, -Float::MAX],
    ] {
        let film = Film {
            width: 3,
            height: 1,
            pixels: values.map(Vec3::splat).to_vec(),
        };
        let checked = std::panic::catch_unwind(|| check_film(&film, Mode::Full));
        assert!(checked.is_ok(), "{values:?}");
        // The brightest pixel is white after tone mapping.
        let image = film.to_image(Mode::Full);
        let brightest = values.iter().copied().fold(Float::MIN, Float::max);
        let i = values.iter().position(|&v| v == brightest).unwrap();
        if brightest > 0.0 {
            assert_eq!(image.rgb[3 * i], 255, "{values:?}");
        }
    }
}
