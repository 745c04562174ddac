//! Punctual lights (glTF's `KHR_lights_punctual`: point, spot, directional) against
//! closed forms written here apart from the renderer: over a Lambertian floor of
//! albedo `rho`, path mode's direct light is `rho/pi * I * atten * window / d^2 * cos`
//! for point and spot lights and `rho/pi * E * cos` for a directional light, with a
//! sharp shadow; full mode's is SPEC's Phong term `Kd * I * atten * cos` (no `1/d^2`);
//! and the readers: glTF lights (a node's rotation turning the direction) and TOML
//! `[[light]]` types, bad values named by file and key.

use std::f32::consts::PI;
use std::path::Path;

use raytracer::bvh::BvhParams;
use raytracer::camera::Camera;
use raytracer::description::{SceneDescription, TriangleDesc};
use raytracer::formats::{self, LoadedScene};
use raytracer::integrators::{Integrator, PathIntegrator, WhittedIntegrator};
use raytracer::math::{Float, Ray, Vec3};
use raytracer::sampler::PixelSampler;
use raytracer::stats::RayCounts;
use raytracer::{Light, LightKind, Material, MaterialId, Mode, RenderOptions, Scene, render};

const RHO: Float = 0.5;

/// `KHR_lights_punctual`'s spot attenuation, from the angle `theta` off the axis.
fn spot(theta_degrees: Float, inner_degrees: Float, outer_degrees: Float) -> Float {
    let (cos_inner, cos_outer) = (
        inner_degrees.to_radians().cos(),
        outer_degrees.to_radians().cos(),
    );
    let scale = 1.0 / (cos_inner - cos_outer).max(0.001);
    let offset = -cos_outer * scale;
    let t = (theta_degrees.to_radians().cos() * scale + offset).clamp(0.0, 1.0);
    t * t
}

fn spot_light(
    position: Vec3,
    direction: Vec3,
    intensity: Float,
    inner: Float,
    outer: Float,
) -> Light {
    Light {
        position,
        intensity: Vec3::splat(intensity),
        kind: LightKind::Spot {
            direction: direction.normalize(),
            cos_inner: inner.to_radians().cos(),
            cos_outer: outer.to_radians().cos(),
        },
        range: None,
    }
}

fn directional(direction: Vec3, illuminance: Float) -> Light {
    Light {
        position: Vec3::ZERO,
        intensity: Vec3::splat(illuminance),
        kind: LightKind::Directional {
            direction: direction.normalize(),
        },
        range: None,
    }
}

/// A square of side `2 * half` at height `y`, facing +y, of material `material`.
fn square(d: &mut SceneDescription, y: Float, half: Float, material: u32) {
    let first = d.positions.len() as u32;
    d.positions.extend([
        Vec3::new(-half, y, -half),
        Vec3::new(-half, y, half),
        Vec3::new(half, y, half),
        Vec3::new(half, y, -half),
    ]);
    for corners in [[0, 1, 2], [0, 2, 3]] {
        d.triangles.push(TriangleDesc {
            positions: corners.map(|c| first + c),
            material: MaterialId(material),
        });
    }
}

/// A Lambertian floor (MTL `Kd = RHO`, no `Ks`) at y = 0, 40 units wide, and
/// optionally a black square occluder of side 1 at y = 1 above the origin.
fn floor_scene(lights: Vec<Light>, occluder: bool) -> Scene {
    let mut d = SceneDescription {
        materials: vec![
            Material {
                diffuse: Vec3::splat(RHO),
                ..Material::named("matte")
            },
            Material::named("black"),
        ],
        lights,
        ..SceneDescription::default()
    };
    square(&mut d, 0.0, 20.0, 0);
    if occluder {
        square(&mut d, 1.0, 0.5, 1);
    }
    Scene::build(d, &BvhParams::default())
}

/// Path mode's value (depth 2: direct light only) of the floor point at `x`, `z`
/// seen from just above.
fn path_value(scene: &Scene, x: Float, z: Float) -> Float {
    let integrator = PathIntegrator::new(scene, 2, true);
    let sampler = PixelSampler::new(4, integrator.dimensions());
    let mut rays = RayCounts::default();
    let ray = Ray::new(Vec3::new(x, 0.5, z), -Vec3::Y);
    let mut sum = Vec3::ZERO;
    for s in 0..4 {
        let mut sample = sampler.sample(3, s);
        sum += integrator.radiance(scene, &ray, &mut sample, &mut rays);
    }
    let value = sum / 4.0;
    assert!((value.x - value.y).abs() <= 1e-6 * value.x.abs().max(1.0));
    value.x
}

/// Full mode's value of the floor point at `x`, `z` seen from just above.
fn full_value(scene: &Scene, x: Float, z: Float) -> Float {
    let integrator = WhittedIntegrator { max_depth: 1 };
    let sampler = PixelSampler::new(1, integrator.dimensions());
    let mut rays = RayCounts::default();
    let ray = Ray::new(Vec3::new(x, 0.5, z), -Vec3::Y);
    integrator
        .radiance(scene, &ray, &mut sampler.sample(0, 0), &mut rays)
        .x
}

fn close(got: Float, expected: Float) -> bool {
    (got - expected).abs() <= 1e-4 * expected.abs().max(1e-3)
}

#[test]
fn a_point_light_over_a_lambertian_floor_gives_rho_over_pi_i_cos_over_d_squared() {
    let (height, intensity) = (2.0, 3.0);
    let scene = floor_scene(
        vec![Light::point(
            Vec3::new(0.0, height, 0.0),
            Vec3::splat(intensity),
        )],
        false,
    );
    for x in [0.0, 1.0, 2.5, -4.0] {
        let d2 = height * height + x * x;
        let cos = height / d2.sqrt();
        let expected = RHO / PI * intensity * cos / d2;
        let got = path_value(&scene, x, 0.0);
        assert!(close(got, expected), "x {x}: {got} vs {expected}");
    }
}

#[test]
fn a_point_lights_range_window_is_the_extensions() {
    let (height, intensity, range) = (2.0, 3.0, 4.0);
    let mut light = Light::point(Vec3::new(0.0, height, 0.0), Vec3::splat(intensity));
    light.range = Some(range);
    let scene = floor_scene(vec![light], false);
    for x in [0.0, 1.0, 3.0, 3.5, 5.0] {
        let d2: Float = height * height + x * x;
        let d = d2.sqrt();
        let window = (1.0 - (d / range).powi(4)).clamp(0.0, 1.0).powi(2);
        let expected = RHO / PI * intensity * window * (height / d) / d2;
        let got = path_value(&scene, x, 0.0);
        assert!(close(got, expected), "x {x}: {got} vs {expected}");
    }
}

#[test]
fn a_spot_light_falls_off_between_its_cones_in_both_modes() {
    let (height, intensity, inner, outer) = (2.0, 5.0, 20.0, 40.0);
    let scene = floor_scene(
        vec![spot_light(
            Vec3::new(0.0, height, 0.0),
            -Vec3::Y,
            intensity,
            inner,
            outer,
        )],
        false,
    );
    // Inside the inner cone, between the cones (two angles), outside the outer one.
    for (theta, expected_atten) in [
        (0.0, 1.0),
        (10.0, 1.0),
        (25.0, spot(25.0, inner, outer)),
        (35.0, spot(35.0, inner, outer)),
        (45.0, 0.0),
        (60.0, 0.0),
    ] {
        let atten = spot(theta, inner, outer);
        assert!((atten - expected_atten).abs() < 1e-6);
        if theta == 25.0 {
            assert!(atten > 0.1 && atten < 0.9, "{atten}");
        }
        let theta_r = (theta as Float).to_radians();
        // Along a direction in the floor that is not an axis, to turn the cone.
        let r = height * theta_r.tan();
        let (x, z) = (r * 0.6, r * 0.8);
        let d2 = height * height + r * r;
        let cos = theta_r.cos();
        let expected = RHO / PI * intensity * atten * cos / d2;
        let got = path_value(&scene, x, z);
        assert!(
            close(got, expected),
            "path, {theta} degrees: {got} vs {expected}"
        );
        // Full mode: SPEC's Phong term, `Kd * I * atten * cos`, no fall off with distance.
        let expected = RHO * intensity * atten * cos;
        let got = full_value(&scene, x, z);
        assert!(
            close(got, expected),
            "full, {theta} degrees: {got} vs {expected}"
        );
    }
}

#[test]
fn a_tilted_spot_is_brightest_along_its_axis() {
    // A spot at height 2 aimed at (2, 0, 0): the floor point there is on its axis.
    let position = Vec3::new(0.0, 2.0, 0.0);
    let scene = floor_scene(
        vec![spot_light(
            position,
            Vec3::new(2.0, -2.0, 0.0),
            4.0,
            5.0,
            10.0,
        )],
        false,
    );
    let d2: Float = 8.0;
    let expected = RHO / PI * 4.0 * (2.0 / d2.sqrt()) / d2;
    assert!(close(path_value(&scene, 2.0, 0.0), expected));
    // Straight below: 45 degrees off the axis, outside the cone.
    assert_eq!(path_value(&scene, 0.0, 0.0), 0.0);
}

#[test]
fn a_directional_light_gives_rho_over_pi_e_cos_and_a_sharp_shadow() {
    let illuminance = 2.0;
    // Shining down at 45 degrees towards +x: the occluder at y = 1 (x and z within
    // 0.5) shades the floor where x is in [0.5, 1.5] and z in [-0.5, 0.5].
    let scene = floor_scene(
        vec![directional(Vec3::new(1.0, -1.0, 0.0), illuminance)],
        true,
    );
    let lit = RHO / PI * illuminance * (45.0 as Float).to_radians().cos();
    for (x, z, expected) in [
        (-3.0, 0.0, lit),
        (7.0, 4.0, lit),
        (0.45, 0.0, lit),
        (0.55, 0.0, 0.0),
        (1.0, 0.0, 0.0),
        (1.0, 0.45, 0.0),
        (1.0, 0.55, lit),
        (1.45, -0.3, 0.0),
        (1.55, -0.3, lit),
    ] {
        let got = path_value(&scene, x, z);
        assert!(close(got, expected), "path ({x}, {z}): {got} vs {expected}");
        let full = full_value(&scene, x, z);
        let expected = if expected == 0.0 {
            0.0
        } else {
            RHO * illuminance * 0.5f32.sqrt()
        };
        assert!(
            close(full, expected),
            "full ({x}, {z}): {full} vs {expected}"
        );
    }
}

/// Full mode renders scenes with spots and directional lights through the scalar
/// shading (the packets' lanes know plain point lights only): the film is each
/// pixel's `WhittedIntegrator::radiance`, bit for bit.
#[test]
fn full_mode_renders_every_kind_as_the_scalar_integrator_shades_it() {
    let scene = floor_scene(
        vec![
            Light::point(Vec3::new(-1.0, 3.0, 1.0), Vec3::splat(0.3)),
            spot_light(Vec3::new(1.0, 3.0, 0.0), -Vec3::Y, 0.6, 15.0, 30.0),
            directional(Vec3::new(1.0, -2.0, 0.5), 0.4),
        ],
        true,
    );
    let options = RenderOptions {
        mode: Mode::Full,
        width: 24,
        height: 20,
        look_from: Vec3::new(0.0, 6.0, 4.0),
        look_to: Vec3::ZERO,
        depth: 2,
        samples_per_pixel: 1,
        ..RenderOptions::default()
    };
    let film = render(&scene, &options);
    let camera = Camera::for_options(&options);
    let integrator = WhittedIntegrator { max_depth: 2 };
    let sampler = PixelSampler::new(1, 0);
    let mut rays = RayCounts::default();
    let mut lit = 0;
    for row in 0..options.height {
        for column in 0..options.width {
            let ray = camera.pixel_ray(column, row);
            let expected = integrator.radiance(&scene, &ray, &mut sampler.sample(0, 0), &mut rays);
            let got = film.pixels[(row * options.width + column) as usize];
            assert_eq!(
                got.to_array().map(f32::to_bits),
                expected.to_array().map(f32::to_bits)
            );
            lit += usize::from(got.x > 0.0);
        }
    }
    assert!(lit > 100, "{lit}");
}

fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

fn near(a: Vec3, b: Vec3) -> bool {
    (a - b).abs().max_element() < 1e-5
}

/// A glTF file of no meshes whose nodes hold the lights `lights` (JSON objects),
/// node `i` holding light `i` under the transform `nodes[i]` (JSON members).
fn gltf_with_lights(lights: &[&str], nodes: &[&str]) -> String {
    let nodes: Vec<String> = nodes
        .iter()
        .enumerate()
        .map(|(i, members)| {
            let sep = if members.is_empty() { "" } else { "," };
            format!(
                r#"{{{members}{sep} "extensions": {{"KHR_lights_punctual": {{"light": {i}}}}}}}"#
            )
        })
        .collect();
    let roots: Vec<String> = (0..nodes.len()).map(|i| i.to_string()).collect();
    format!(
        r#"{{"asset": {{"version": "2.0"}},
  "extensionsUsed": ["KHR_lights_punctual"],
  "extensions": {{"KHR_lights_punctual": {{"lights": [{}]}}}},
  "scene": 0, "scenes": [{{"nodes": [{}]}}],
  "nodes": [{}]}}"#,
        lights.join(", "),
        roots.join(", "),
        nodes.join(", ")
    )
}

#[test]
fn gltf_point_spot_and_directional_lights_are_read_with_their_node_directions() {
    let dir = tempfile::tempdir().unwrap();
    let half = 0.5f32.sqrt();
    let text = gltf_with_lights(
        &[
            r#"{"type": "point", "color": [1, 0.5, 0.25], "intensity": 10, "range": 5}"#,
            r#"{"type": "spot", "intensity": 20, "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.6}}"#,
            r#"{"type": "directional", "intensity": 3}"#,
            r#"{"type": "spot", "intensity": 1, "spot": {}}"#,
        ],
        &[
            r#""translation": [1, 2, 3]"#,
            // -90 degrees about +x: -z turns to -y.
            &format!(r#""translation": [0, 4, 0], "rotation": [-{half}, 0, 0, {half}]"#),
            // +90 degrees about +y: -z turns to -x.
            &format!(r#""rotation": [0, {half}, 0, {half}]"#),
            "",
        ],
    );
    let path = write(dir.path(), "lights.gltf", &text);
    let loaded = formats::load(&path).unwrap();
    let d = &loaded.description;
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    assert_eq!(d.lights.len(), 4);

    let point = &d.lights[0];
    assert_eq!(point.kind, LightKind::Point);
    assert!(near(point.position, Vec3::new(1.0, 2.0, 3.0)));
    assert!(near(point.intensity, Vec3::new(10.0, 5.0, 2.5)));
    assert_eq!(point.range, Some(5.0));

    let LightKind::Spot {
        direction,
        cos_inner,
        cos_outer,
    } = d.lights[1].kind
    else {
        panic!("{:?}", d.lights[1]);
    };
    assert!(near(direction, -Vec3::Y), "{direction}");
    assert!((cos_inner - 0.2f32.cos()).abs() < 1e-6);
    assert!((cos_outer - 0.6f32.cos()).abs() < 1e-6);
    assert!(near(d.lights[1].position, Vec3::new(0.0, 4.0, 0.0)));
    assert_eq!(d.lights[1].intensity, Vec3::splat(20.0));
    assert_eq!(d.lights[1].range, None);

    let LightKind::Directional { direction } = d.lights[2].kind else {
        panic!("{:?}", d.lights[2]);
    };
    assert!(near(direction, -Vec3::X), "{direction}");
    assert_eq!(d.lights[2].intensity, Vec3::splat(3.0));

    // The extension's defaults: inner 0, outer pi/4, shining along -z.
    let LightKind::Spot {
        direction,
        cos_inner,
        cos_outer,
    } = d.lights[3].kind
    else {
        panic!("{:?}", d.lights[3]);
    };
    assert_eq!(direction, -Vec3::Z);
    assert_eq!(cos_inner, 1.0);
    assert!((cos_outer - half).abs() < 1e-6);
}

#[test]
fn a_gltf_spot_renders_its_cone_in_path_mode() {
    // The glTF spot above a floor, rendered through the reader: one floor point
    // inside the inner cone, one between, one outside.
    let dir = tempfile::tempdir().unwrap();
    let half = 0.5f32.sqrt();
    let text = gltf_with_lights(
        &[
            r#"{"type": "spot", "intensity": 8, "spot": {"innerConeAngle": 0.3, "outerConeAngle": 0.5}}"#,
        ],
        &[&format!(
            r#""translation": [0, 2, 0], "rotation": [-{half}, 0, 0, {half}]"#
        )],
    );
    let loaded = formats::load(&write(dir.path(), "spot.gltf", &text)).unwrap();
    let scene = floor_scene(loaded.description.lights.clone(), false);
    for theta in [0.2f32, 0.4, 0.6] {
        let (inner, outer) = (0.3f32.to_degrees(), 0.5f32.to_degrees());
        let atten = spot(theta.to_degrees(), inner, outer);
        let x = 2.0 * theta.tan();
        let d2 = 4.0 + x * x;
        let expected = RHO / PI * 8.0 * atten * theta.cos() / d2;
        let got = path_value(&scene, x, 0.0);
        assert!(
            (got - expected).abs() <= 1e-3 * expected.max(1e-3),
            "{theta} rad: {got} vs {expected}"
        );
    }
}

#[test]
fn bad_gltf_lights_are_warnings_naming_file_light_and_key() {
    let dir = tempfile::tempdir().unwrap();
    let text = gltf_with_lights(
        &[
            r#"{"type": "spot", "intensity": 1, "spot": {"innerConeAngle": 0.7, "outerConeAngle": 0.5}}"#,
            r#"{"type": "spot", "intensity": 1, "spot": {"outerConeAngle": 2.0}}"#,
            r#"{"type": "point", "intensity": -4}"#,
            r#"{"type": "point", "intensity": 1, "range": 0}"#,
        ],
        &["", "", "", ""],
    );
    let path = write(dir.path(), "bad.gltf", &text);
    let loaded = formats::load(&path).unwrap();
    let d = &loaded.description;
    let file = path.display().to_string();
    let has = |needle: &str| {
        d.warnings
            .iter()
            .any(|w| w.starts_with(&file) && w.contains(needle))
    };
    assert!(has("light 0: spot.innerConeAngle: 0.7"), "{:?}", d.warnings);
    assert!(has("light 1: spot.outerConeAngle: 2"), "{:?}", d.warnings);
    assert!(has("light 2: intensity: negative"), "{:?}", d.warnings);
    assert!(has("light 3: range: 0"), "{:?}", d.warnings);
    // The mended spots and the point without a range stay; the negative one goes.
    assert_eq!(d.lights.len(), 3);
    let LightKind::Spot {
        cos_inner,
        cos_outer,
        ..
    } = d.lights[0].kind
    else {
        panic!()
    };
    assert_eq!(cos_inner, cos_outer);
    let LightKind::Spot { cos_outer, .. } = d.lights[1].kind else {
        panic!()
    };
    assert!(cos_outer.abs() < 1e-6);
    assert_eq!(d.lights[2].range, None);
}

fn load_toml(dir: &Path, text: &str) -> Result<LoadedScene, String> {
    formats::load(&write(dir, "s.toml", text)).map_err(|e| e.to_string())
}

#[test]
fn toml_lights_have_types() {
    let dir = tempfile::tempdir().unwrap();
    let loaded = load_toml(
        dir.path(),
        r#"
[[light]]
position = [0, 5, 0]
intensity = [1, 0.5, 0.25]

[[light]]
type = "point"
position = [1, 2, 3]
color = [1, 0.5, 0]
intensity = 4
range = 10

[[light]]
type = "spot"
position = [0, 3, 0]
direction = [0, -2, 0]
intensity = 7
inner_cone = 10
outer_cone = 30

[[light]]
type = "directional"
direction = [1, -1, 0]
color = 0.5
intensity = 2

[[light]]
type = "spot"
position = [0, 0, 0]
direction = [0, 0, -1]
"#,
    )
    .unwrap();
    let lights = &loaded.description.lights;
    assert_eq!(lights.len(), 5);
    // Today's lights: a position and a colour as intensity, unchanged.
    assert_eq!(
        lights[0],
        Light::point(Vec3::new(0.0, 5.0, 0.0), Vec3::new(1.0, 0.5, 0.25))
    );
    assert_eq!(lights[1].kind, LightKind::Point);
    assert_eq!(lights[1].intensity, Vec3::new(4.0, 2.0, 0.0));
    assert_eq!(lights[1].range, Some(10.0));
    assert_eq!(
        lights[2].kind,
        LightKind::Spot {
            direction: -Vec3::Y,
            cos_inner: (10.0 as Float).to_radians().cos(),
            cos_outer: (30.0 as Float).to_radians().cos(),
        }
    );
    assert_eq!(lights[2].intensity, Vec3::splat(7.0));
    let LightKind::Directional { direction } = lights[3].kind else {
        panic!("{:?}", lights[3]);
    };
    assert!(near(direction, Vec3::new(1.0, -1.0, 0.0).normalize()));
    assert_eq!(lights[3].intensity, Vec3::splat(1.0));
    // glTF's defaults: 0 and 45 degrees, intensity 1.
    let LightKind::Spot {
        cos_inner,
        cos_outer,
        ..
    } = lights[4].kind
    else {
        panic!()
    };
    assert_eq!(cos_inner, 1.0);
    assert!((cos_outer - 0.5f32.sqrt()).abs() < 1e-6);
    assert_eq!(lights[4].intensity, Vec3::ONE);
}

#[test]
fn bad_toml_lights_are_errors_naming_file_line_and_key() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("s.toml").display().to_string();
    for (text, expected) in [
        (
            "[[light]]\ntype = \"spot\"\nposition = [0, 0, 0]\ndirection = [0, -1, 0]\ninner_cone = 40\nouter_cone = 30\n",
            ":5: light.inner_cone: 40 degrees is wider than outer_cone (30 degrees)",
        ),
        (
            "[[light]]\ntype = \"spot\"\nposition = [0, 0, 0]\ndirection = [0, -1, 0]\nouter_cone = 120\n",
            ":5: light.outer_cone: 120 degrees is not in (0, 90]",
        ),
        (
            "[[light]]\ntype = \"directional\"\ndirection = [0, 0, 0]\n",
            ":3: light.direction: a direction of zero length",
        ),
        (
            "[[light]]\nposition = [0, 0, 0]\nintensity = -2\n",
            ":3: light.intensity: [-2, -2, -2] is negative",
        ),
        (
            "[[light]]\ntype = \"spot\"\nposition = [0, 0, 0]\n",
            ": light.direction: a spot light needs a direction",
        ),
        (
            "[[light]]\ntype = \"point\"\nposition = [0, 0, 0]\ninner_cone = 3\n",
            ":4: light.inner_cone: a point light has no inner_cone",
        ),
        (
            "[[light]]\ntype = \"area\"\nposition = [0, 0, 0]\n",
            "light.type: unknown variant `area`, expected one of `point`, `spot`, `directional`",
        ),
    ] {
        let error = load_toml(dir.path(), text).err().unwrap_or_default();
        assert!(
            error.starts_with(&file) && error.contains(expected),
            "{text}: {error}"
        );
    }
}

#[test]
fn a_toml_mesh_transform_turns_the_directions_of_its_gltf_lights() {
    let dir = tempfile::tempdir().unwrap();
    let text = gltf_with_lights(
        &[
            r#"{"type": "directional", "intensity": 2}"#,
            r#"{"type": "spot", "intensity": 1, "spot": {}}"#,
        ],
        &["", r#""translation": [0, 0, 1]"#],
    );
    write(dir.path(), "lights.gltf", &text);
    // Turned 90 degrees about +y (right-handed: -z goes to -x), then moved up 3.
    let loaded = load_toml(
        dir.path(),
        "[[mesh]]\nfile = \"lights.gltf\"\ntransform.rotate = [0, 90, 0]\ntransform.translate = [0, 3, 0]\n",
    )
    .unwrap();
    let lights = &loaded.description.lights;
    assert_eq!(lights.len(), 2);
    assert!(near(lights[0].direction().unwrap(), -Vec3::X));
    assert!(near(lights[1].direction().unwrap(), -Vec3::X));
    assert!(
        near(lights[1].position, Vec3::new(1.0, 3.0, 0.0)),
        "{}",
        lights[1].position
    );
}
