//! Path mode's environment against closed forms: a Lambertian sphere under an
//! environment whose radiance is linear in direction, `L(d) = a + b.d`, has radiance
//! `rho (a + 2/3 b.n)` (the cosine-weighted mean of `L` over the hemisphere about
//! `n`), turned with the environment; camera rays that leave the scene see the map at
//! their direction, looking along each axis; `--background` replaces what they see
//! but not what lights the scene.

use std::f32::consts::PI;
use std::sync::Arc;

use raytracer::bvh::BvhParams;
use raytracer::description::{SceneDescription, SphereDesc};
use raytracer::integrators::{Integrator, PathIntegrator};
use raytracer::lights::environment::{EnvironmentDesc, EnvironmentRadiance};
use raytracer::math::{Float, Ray, Vec3};
use raytracer::sampler::PixelSampler;
use raytracer::stats::RayCounts;
use raytracer::textures::Texture;
use raytracer::{Material, MaterialId, Mode, RenderOptions, Scene, render};

/// An equirectangular map of `f` at its texel centres, with the mapping the issue
/// gives (`u = 0.5 + atan2(z, x) / 2 pi`, `v = 0.5 + asin(y) / pi`, `v = 1` the top
/// row), written here apart from the renderer's.
fn map_of(width: u32, height: u32, f: impl Fn(Vec3) -> Vec3) -> Arc<Texture> {
    let mut texels = Vec::new();
    for row in 0..height {
        let v = 1.0 - (row as Float + 0.5) / height as Float;
        let latitude = (v - 0.5) * PI;
        for column in 0..width {
            let u = (column as Float + 0.5) / width as Float;
            let phi = (u - 0.5) * 2.0 * PI;
            let d = Vec3::new(
                latitude.cos() * phi.cos(),
                latitude.sin(),
                latitude.cos() * phi.sin(),
            );
            let c = f(d);
            texels.extend([c.x, c.y, c.z]);
        }
    }
    Arc::new(Texture::from_f32("map.exr".into(), width, height, 3, texels).unwrap())
}

fn environment(map: Arc<Texture>, rotation_degrees: Float) -> EnvironmentDesc {
    EnvironmentDesc {
        radiance: EnvironmentRadiance::Map(map),
        strength: 1.0,
        rotation_degrees,
    }
}

/// A unit sphere at the origin of MTL Lambertian `Kd = rho`, lit by `environment`.
fn lambertian_sphere(rho: Float, environment: EnvironmentDesc) -> Scene {
    let material = Material {
        diffuse: Vec3::splat(rho),
        ..Material::named("matte")
    };
    Scene::build(
        SceneDescription {
            spheres: vec![SphereDesc {
                center: Vec3::ZERO,
                radius: 1.0,
                material: MaterialId(0),
            }],
            materials: vec![material],
            environment: Some(environment),
            ..SceneDescription::default()
        },
        &BvhParams::default(),
    )
}

fn mean_radiance(scene: &Scene, ray: Ray, samples: u32) -> Vec3 {
    let integrator = PathIntegrator::new(scene, 2, true);
    let sampler = PixelSampler::new(samples, integrator.dimensions());
    let mut rays = RayCounts::default();
    let mut sum = Vec3::ZERO;
    for s in 0..samples {
        let mut sample = sampler.sample(7, s);
        sum += integrator.radiance(scene, &ray, &mut sample, &mut rays);
    }
    sum / samples as Float
}

/// `v` turned by `degrees` about +Y, right-handed (+X goes to -Z at 90).
fn turned(v: Vec3, degrees: Float) -> Vec3 {
    let (sin, cos) = degrees.to_radians().sin_cos();
    Vec3::new(v.x * cos + v.z * sin, v.y, -v.x * sin + v.z * cos)
}

#[test]
fn a_lambertian_sphere_under_a_linear_environment_has_the_closed_form_radiance() {
    let (a, b) = (1.0, Vec3::new(0.3, 0.5, -0.2));
    let rho = 0.7;
    let map = map_of(512, 256, |d| Vec3::splat(a + b.dot(d)));
    for rotation in [0.0, 90.0, -30.0] {
        let scene = lambertian_sphere(rho, environment(map.clone(), rotation));
        // The environment turned by `rotation` is linear with b turned.
        let b_seen = turned(b, rotation);
        for n in [
            Vec3::X,
            -Vec3::X,
            Vec3::Y,
            -Vec3::Y,
            Vec3::Z,
            -Vec3::Z,
            Vec3::new(0.6, -0.48, 0.64),
        ] {
            let ray = Ray::new(n * 5.0, -n);
            let got = mean_radiance(&scene, ray, 20_000).x;
            let expected = rho * (a + 2.0 / 3.0 * b_seen.dot(n));
            assert!(
                (got - expected).abs() < 0.01 * expected,
                "rotation {rotation}, n {n}: {got} vs {expected}"
            );
        }
    }
}

#[test]
fn camera_rays_that_leave_see_the_map_at_their_direction_along_every_axis() {
    // A colour that differs along every axis, smooth so that a pixel's footprint
    // averages to its centre's value.
    let f = |d: Vec3| (d + Vec3::ONE) * 0.5 + Vec3::new(0.1, 0.2, 0.3);
    let scene = Scene::build(
        SceneDescription {
            environment: Some(environment(map_of(1024, 512, f), 0.0)),
            ..SceneDescription::default()
        },
        &BvhParams::default(),
    );
    for (axis, up) in [
        (Vec3::X, Vec3::Y),
        (-Vec3::X, Vec3::Y),
        (Vec3::Z, Vec3::Y),
        (-Vec3::Z, Vec3::Y),
        (Vec3::Y, Vec3::Z),
        (-Vec3::Y, Vec3::Z),
    ] {
        let options = RenderOptions {
            mode: Mode::Path,
            width: 9,
            height: 9,
            fov_degrees: 2.0,
            look_from: Vec3::ZERO,
            look_to: axis,
            up,
            samples_per_pixel: 4,
            depth: 4,
            ..RenderOptions::default()
        };
        let film = render(&scene, &options);
        let centre = film.pixels[4 * 9 + 4];
        assert!(
            (centre - f(axis)).abs().max_element() < 2e-3,
            "looking along {axis}: {centre} vs {}",
            f(axis)
        );
    }
}

#[test]
fn a_background_replaces_what_the_camera_sees_but_not_the_light() {
    let map = map_of(64, 32, |_| Vec3::splat(2.0));
    let mut description = SceneDescription {
        spheres: vec![SphereDesc {
            center: Vec3::ZERO,
            radius: 1.0,
            material: MaterialId(0),
        }],
        materials: vec![Material {
            diffuse: Vec3::splat(0.5),
            ..Material::named("matte")
        }],
        environment: Some(environment(map, 0.0)),
        ..SceneDescription::default()
    };
    description.background = Some(Vec3::new(0.1, 0.2, 0.3));
    let scene = Scene::build(description, &BvhParams::default());
    let options = RenderOptions {
        mode: Mode::Path,
        width: 16,
        height: 16,
        fov_degrees: 60.0,
        look_from: Vec3::new(0.0, 0.0, 4.0),
        look_to: Vec3::ZERO,
        samples_per_pixel: 64,
        depth: 4,
        ..RenderOptions::default()
    };
    let film = render(&scene, &options);
    // A corner misses the sphere; the centre sees it lit by the environment of 2.
    assert!(
        (film.pixels[0] - Vec3::new(0.1, 0.2, 0.3))
            .abs()
            .max_element()
            < 1e-6
    );
    // The mean of the 4 x 4 pixels at the centre, all on the sphere: one pixel's 64
    // samples have a standard deviation of about 3%, as large as the tolerance.
    let mut centre = Vec3::ZERO;
    for y in 6..10 {
        for x in 6..10 {
            centre += film.pixels[y * 16 + x] / 16.0;
        }
    }
    assert!((centre - Vec3::ONE).abs().max_element() < 0.03, "{centre}");
}

/// A scene file with `text` in a fresh folder (with `sky.png`, a 2 x 1 image), loaded.
fn load_toml(text: &str) -> Result<raytracer::formats::LoadedScene, String> {
    let folder = tempfile::tempdir().unwrap();
    image::RgbImage::from_raw(2, 1, vec![255, 0, 0, 0, 0, 255])
        .unwrap()
        .save(folder.path().join("sky.png"))
        .unwrap();
    let path = folder.path().join("scene.toml");
    std::fs::write(&path, text).unwrap();
    raytracer::formats::load(&path).map_err(|e| {
        e.to_string()
            .replace(&folder.path().display().to_string(), "DIR")
    })
}

#[test]
fn a_scene_file_sets_the_environment_and_names_its_mistakes() {
    let loaded = load_toml(
        "[environment]\ncolor = [0.25, 0.5, 1.0]\nstrength = 2\nbackground = [0, 0, 0]\n",
    )
    .unwrap();
    let scene = Scene::build(loaded.description, &BvhParams::default());
    let environment = scene.environment.as_ref().unwrap();
    assert_eq!(environment.radiance(Vec3::Y), Vec3::new(0.5, 1.0, 2.0));
    assert_eq!(scene.background, Some(Vec3::ZERO));

    // An 8-bit image, read as sRGB: its left half red, its right half blue.
    let loaded = load_toml("[environment]\nfile = \"sky.png\"\nrotation = 90\n").unwrap();
    let scene = Scene::build(loaded.description, &BvhParams::default());
    let environment = scene.environment.as_ref().unwrap();
    // Unturned, -Z (u = 0.25) is red and +Z (u = 0.75) blue; turned by 90 degrees
    // what was along -Z is seen along -X.
    let seen = environment.radiance(-Vec3::X);
    assert!(seen.x > 0.99 && seen.z < 0.01, "{seen}");

    for (text, expected) in [
        ("[environment]\nfile = \"none.hdr\"\n", "environment.file"),
        (
            "[environment]\nfile = \"sky.png\"\ncolor = [1, 1, 1]\n",
            "give a file or a color, not both",
        ),
        (
            "[environment]\ncolor = 1\nstrength = -1\n",
            "environment.strength",
        ),
        ("[environment]\ncolour = 1\n", "colour"),
    ] {
        let message = load_toml(text).unwrap_err();
        assert!(
            message.contains(expected) && message.contains("scene.toml"),
            "{text}: {message}"
        );
    }
}

/// Mitsuba 3's image of a Lambertian sphere in the bundled HDR environment
/// (`tests/data/environment/make_mitsuba.py`: its `envmap` turned by 90 degrees
/// about +Y, which its direction-to-texel convention needs to show what ours shows)
/// against ours: each 8 x 8 block's mean within 3% of Mitsuba's, the whole image's
/// within 1%. A wrong orientation, rotation sign or sampling density would move
/// blocks by far more.
#[test]
fn the_environment_lit_sphere_matches_mitsuba() {
    let root = env!("CARGO_MANIFEST_DIR");
    let reference = image::open(format!("{root}/tests/data/environment/mitsuba.exr"))
        .unwrap()
        .to_rgb32f();
    let (width, height) = reference.dimensions();
    let scene = Scene::build(
        raytracer::formats::load(std::path::Path::new(&format!(
            "{root}/tests/data/environment/sphere.toml"
        )))
        .unwrap()
        .description,
        &BvhParams::default(),
    );
    let options = RenderOptions {
        mode: Mode::Path,
        width,
        height,
        fov_degrees: 50.0,
        look_from: Vec3::new(0.0, 0.5, 4.0),
        look_to: Vec3::ZERO,
        samples_per_pixel: 256,
        depth: 8,
        ..RenderOptions::default()
    };
    let film = render(&scene, &options);
    let (mut ours_total, mut theirs_total) = (0.0f64, 0.0f64);
    for by in 0..height / 8 {
        for bx in 0..width / 8 {
            let (mut ours, mut theirs) = (0.0f64, 0.0f64);
            for y in by * 8..by * 8 + 8 {
                for x in bx * 8..bx * 8 + 8 {
                    let p = film.pixels[(y * width + x) as usize];
                    ours += f64::from(p.x + p.y + p.z);
                    let q = reference.get_pixel(x, y);
                    theirs += f64::from(q[0] + q[1] + q[2]);
                }
            }
            assert!(
                (ours - theirs).abs() <= 0.03 * theirs,
                "block ({bx}, {by}): ours {ours:.3}, Mitsuba {theirs:.3}"
            );
            ours_total += ours;
            theirs_total += theirs;
        }
    }
    assert!(
        (ours_total - theirs_total).abs() <= 0.01 * theirs_total,
        "{ours_total} vs {theirs_total}"
    );
}

/// The standard deviation and mean of `values`.
fn spread(values: &[Float]) -> (f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().map(|&v| f64::from(v)).sum::<f64>() / n;
    let variance = values
        .iter()
        .map(|&v| (f64::from(v) - mean).powi(2))
        .sum::<f64>()
        / (n - 1.0);
    (variance.sqrt(), mean)
}

#[test]
fn a_pixels_samples_share_out_a_small_sun_evenly() {
    // A matte sphere seen where a 5-degree sun in a dim sky lights it from 40
    // degrees: a pixel's 64 samples (stratified, and the sun found by inverting
    // the map's distribution) estimate its radiance with under half the spread of
    // 64 independent samples (one-sample pixels), about the same mean.
    let sun = Vec3::new(0.0, 40.0f32.to_radians().sin(), 40.0f32.to_radians().cos());
    let map = map_of(256, 128, |d| {
        Vec3::splat(if d.dot(sun) > 5.0f32.to_radians().cos() {
            100.0
        } else {
            0.3
        })
    });
    let scene = lambertian_sphere(0.8, environment(map, 0.0));
    let integrator = PathIntegrator::new(&scene, 2, true);
    let ray = Ray::new(Vec3::new(0.0, 0.0, 5.0), -Vec3::Z);
    let mut rays = RayCounts::default();
    let mut estimate = |sampler: &PixelSampler, sample_of: &dyn Fn(u32) -> (u64, u32)| {
        (0..64)
            .map(|i| {
                let (pixel, sample) = sample_of(i);
                let mut values = sampler.sample(pixel, sample);
                integrator.radiance(&scene, &ray, &mut values, &mut rays).x
            })
            .sum::<Float>()
            / 64.0
    };
    let stratified = PixelSampler::new(64, integrator.dimensions());
    let independent = PixelSampler::new(1, integrator.dimensions());
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for pixel in 0..300u64 {
        a.push(estimate(&stratified, &|s| (pixel, s)));
        b.push(estimate(&independent, &|s| (pixel * 64 + u64::from(s), 0)));
    }
    let ((a_spread, a_mean), (b_spread, b_mean)) = (spread(&a), spread(&b));
    assert!(
        (a_mean - b_mean).abs() < 0.02 * b_mean,
        "means {a_mean} and {b_mean}"
    );
    assert!(
        a_spread < 0.5 * b_spread,
        "spread {a_spread} stratified, {b_spread} independent (mean {b_mean})"
    );
}

/// A JPEG of `width` x `height` grey texels, `value(x)` in each column.
fn grey_jpeg(width: u32, height: u32, value: impl Fn(u32) -> u8) -> Vec<u8> {
    let image = image::GrayImage::from_fn(width, height, |x, _| image::Luma([value(x)]));
    let mut bytes = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, 100)
        .encode_image(&image)
        .unwrap();
    bytes
}

/// `jpeg` with an APP1 XMP segment holding `xmp` after its start marker.
fn with_xmp(jpeg: &[u8], xmp: &str) -> Vec<u8> {
    let mut payload = b"http://ns.adobe.com/xap/1.0/\0".to_vec();
    payload.extend(xmp.as_bytes());
    let mut out = jpeg[..2].to_vec();
    out.extend([0xFF, 0xE1]);
    out.extend(u16::try_from(payload.len() + 2).unwrap().to_be_bytes());
    out.extend(payload);
    out.extend(&jpeg[2..]);
    out
}

#[test]
fn a_jpeg_with_an_hdr_gain_map_is_read_at_its_full_range() {
    // An Ultra HDR file (as viser ships Poly Haven's HDRIs): a grey SDR image of
    // sRGB 128, then a gain map of 0 on the left and 1 on the right, log2 gains from
    // 0 to 2: the right half is (0.216 + 1/64) * 4 - 1/64 = 0.910 at full range,
    // where the SDR image alone gives 0.216.
    let gain = with_xmp(
        &grey_jpeg(16, 4, |x| if x < 8 { 0 } else { 255 }),
        r#"<x:xmpmeta xmlns:x="adobe:ns:meta/"><rdf:RDF xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#"><rdf:Description xmlns:hdrgm="http://ns.adobe.com/hdr-gain-map/1.0/" hdrgm:Version="1.0" hdrgm:GainMapMin="0" hdrgm:GainMapMax="2" hdrgm:HDRCapacityMax="2"/></rdf:RDF></x:xmpmeta>"#,
    );
    let primary = with_xmp(
        &grey_jpeg(16, 4, |_| 128),
        &format!(
            r#"<x:xmpmeta xmlns:x="adobe:ns:meta/"><rdf:RDF xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#"><rdf:Description xmlns:Container="http://ns.google.com/photos/1.0/container/" xmlns:Item="http://ns.google.com/photos/1.0/container/item/" xmlns:hdrgm="http://ns.adobe.com/hdr-gain-map/1.0/" hdrgm:Version="1.0"><Container:Directory><rdf:Seq><rdf:li rdf:parseType="Resource"><Container:Item Item:Semantic="Primary" Item:Mime="image/jpeg"/></rdf:li><rdf:li rdf:parseType="Resource"><Container:Item Item:Semantic="GainMap" Item:Mime="image/jpeg" Item:Length="{}"/></rdf:li></rdf:Seq></Container:Directory></rdf:Description></rdf:RDF></x:xmpmeta>"#,
            gain.len()
        ),
    );
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sky.jpg");
    std::fs::write(&path, [primary, gain].concat()).unwrap();
    let (desc, warning) =
        raytracer::formats::environment::load_environment_map(&path, 1.0, 0.0).unwrap();
    assert_eq!(warning, None);
    let EnvironmentRadiance::Map(texture) = desc.radiance else {
        panic!("not a map");
    };
    let sdr = raytracer::textures::srgb_to_linear(128.0 / 255.0);
    let hdr = (sdr + 1.0 / 64.0) * 4.0 - 1.0 / 64.0;
    for y in 0..4 {
        // Columns away from the halves' edge, where the JPEG rings.
        for (x, expected) in [(0, sdr), (2, sdr), (13, hdr), (15, hdr)] {
            let t = texture.texel(x, y, raytracer::textures::Encoding::Linear);
            for c in &t[..3] {
                assert!(
                    (c - expected).abs() < 0.02 * expected,
                    "({x}, {y}): {t:?}, expected {expected}"
                );
            }
        }
    }
}

#[test]
fn dwa_compressed_maps_read_as_the_reference_openexr_library_decodes_them() {
    // HDRI packages ship lossy DWAA/DWAB maps (drei's presets are DWAB): each fixture
    // must read texel for texel as OpenEXR's own decoding of it, kept losslessly (ZIP)
    // beside it by tests/data/environment/dwa/make_dwa.py.
    let folder = format!("{}/tests/data/environment/dwa", env!("CARGO_MANIFEST_DIR"));
    let texture_of = |name: &str| {
        let path = std::path::PathBuf::from(format!("{folder}/{name}"));
        let (desc, _) = raytracer::formats::environment::load_environment_map(&path, 1.0, 0.0)
            .unwrap_or_else(|e| panic!("{e}"));
        let EnvironmentRadiance::Map(texture) = desc.radiance else {
            panic!("{name}: not a map");
        };
        texture
    };
    for compression in ["dwaa", "dwab"] {
        let ours = texture_of(&format!("map-{compression}.exr"));
        let reference = texture_of(&format!("map-{compression}-decoded.exr"));
        assert_eq!(ours.size(), (96, 48));
        assert_eq!(reference.size(), (96, 48));
        let mut brightest: Float = 0.0;
        for y in 0..48 {
            for x in 0..96 {
                let encoding = raytracer::textures::Encoding::Linear;
                let (a, b) = (ours.texel(x, y, encoding), reference.texel(x, y, encoding));
                assert_eq!(a[..3], b[..3], "{compression} texel ({x}, {y})");
                brightest = brightest.max(a[0]);
            }
        }
        // The sun survives the lossy blocks.
        assert!(brightest > 20.0, "{compression}: brightest {brightest}");
    }
}
