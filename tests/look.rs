//! Lens, camera and look: path mode's tone maps against their reference formulas
//! applied to the linear EXR, the thin lens's defocus disc, glTF orthographic cameras,
//! a lone `--look-from` aiming at the scene's centre, and bad lens values named.

use crate::support;

use support::{raytracer, stderr};

use std::path::Path;

use raytracer::math::{Float, Vec3};
use raytracer::options::{Origin, PartialOptions, Projection, Sourced};
use raytracer::{BvhParams, Mode, RenderOptions, Scene, Tile, formats, render, render_tile};

/// Renders the Cornell box in path mode with `extra` flags to `out`.
fn render_cornell(out: &Path, extra: &[&str]) {
    let cornell = support::cornell_box();
    let mut args = vec![
        "render",
        cornell.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "-q",
        "--width",
        "40",
        "--height",
        "30",
        "--spp",
        "4",
        "--depth",
        "4",
    ];
    args.extend(support::CORNELL_CAMERA);
    args.extend(extra);
    let output = raytracer(&args);
    assert!(output.status.success(), "{}", stderr(&output));
}

/// Khronos PBR Neutral as its specification (KhronosGroup/ToneMapping,
/// PBR_Neutral/README.md) writes it, in f64: `f`, `p`, `p_n`, `g`.
fn pbr_neutral(c: [f64; 3]) -> [f64; 3] {
    let (f90, ks, kd) = (0.04, 0.8 - 0.04, 0.15);
    let x = c[0].min(c[1]).min(c[2]);
    let f = if x <= 2.0 * f90 {
        x - x * x / (4.0 * f90)
    } else {
        f90
    };
    let p = (c[0] - f).max(c[1] - f).max(c[2] - f);
    if p <= ks {
        return c.map(|v| v - f);
    }
    let pn = 1.0 - (1.0 - ks) * (1.0 - ks) / (p + 1.0 - 2.0 * ks);
    let g = 1.0 / (kd * (p - pn) + 1.0);
    c.map(|v| (v - f) * pn / p * g + pn * (1.0 - g))
}

/// The sRGB transfer curve (IEC 61966-2-1), in f64.
fn srgb(v: f64) -> f64 {
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// The PNG's bytes against `map` applied to the EXR's linear values times
/// `2^exposure`, each within 1; returns how many pixels reached the highlight range
/// (a channel above 0.76 after the exposure).
fn compare_png_with_exr(
    png: &Path,
    exr: &Path,
    exposure: f64,
    map: fn([f64; 3]) -> [f64; 3],
) -> usize {
    let (width, height, rgb) = support::read_png(png);
    let (w, h, channels) = support::read_exr(exr);
    assert_eq!((w, h), (width as usize, height as usize));
    let mut bright = 0;
    for (i, bytes) in rgb.chunks_exact(3).enumerate() {
        let linear =
            ["R", "G", "B"].map(|c| (f64::from(channels[c][i]) * exposure.exp2()).max(0.0));
        if linear.iter().any(|&v| v > 0.76) {
            bright += 1;
        }
        let expected = map(linear).map(|v| (srgb(v.clamp(0.0, 1.0)) * 255.0).round());
        for (got, want) in bytes.iter().zip(expected) {
            assert!(
                (f64::from(*got) - want).abs() <= 1.0,
                "pixel {i}: {bytes:?} against {expected:?} from {linear:?}"
            );
        }
    }
    bright
}

#[test]
fn khronos_neutral_png_is_the_reference_formula_applied_to_the_exr() {
    let dir = tempfile::tempdir().unwrap();
    let (png, exr) = (dir.path().join("out.png"), dir.path().join("out.exr"));
    let flags = [
        "--mode",
        "path",
        "--exposure",
        "1.5",
        "--tonemap",
        "khronos-neutral",
    ];
    render_cornell(&png, &flags);
    render_cornell(&exr, &flags);
    let bright = compare_png_with_exr(&png, &exr, 1.5, pbr_neutral);
    assert!(
        bright > 20,
        "only {bright} pixels test the highlight compression"
    );
    // khronos-neutral is path mode's default.
    let default = dir.path().join("default.png");
    render_cornell(&default, &["--mode", "path", "--exposure", "1.5"]);
    assert_eq!(support::read_png(&default), support::read_png(&png));
    // standard: the clamp and the sRGB curve of earlier versions.
    let standard = dir.path().join("standard.png");
    render_cornell(
        &standard,
        &[
            "--mode",
            "path",
            "--exposure",
            "1.5",
            "--tonemap",
            "standard",
        ],
    );
    compare_png_with_exr(&standard, &exr, 1.5, |c| c);
}

/// Full mode keeps SPEC's tone map: `--tonemap` changes nothing there (as
/// `--exposure` does not), so the reference images stay what they are.
#[test]
fn full_mode_ignores_the_tone_map() {
    let dir = tempfile::tempdir().unwrap();
    let (plain, aces) = (dir.path().join("a.png"), dir.path().join("b.png"));
    render_cornell(&plain, &["--mode", "full"]);
    render_cornell(&aces, &["--mode", "full", "--tonemap", "aces"]);
    assert_eq!(support::read_png(&plain), support::read_png(&aces));
}

/// A small emitting sphere at depth `z`, seen by a thin lens focused at `focus`, in
/// path mode: the linear film.
fn defocused_sphere(aperture_radius: Float, focus: Float, z: Float, radius: Float) -> Vec<Vec3> {
    let toml = format!(
        "[[sphere]]\ncenter = [0, 0, {}]\nradius = {radius}\nmaterial = \"glow\"\n\n\
         [materials.glow]\nKd = 0\nKs = 0\nKe = 1\n",
        -z
    );
    let loaded = formats::parse_toml(toml.as_bytes(), Path::new("lens.toml")).unwrap();
    let scene = Scene::build(loaded.description, &BvhParams::default());
    let options = RenderOptions {
        width: 41,
        height: 41,
        fov_degrees: 60.0,
        look_from: Vec3::ZERO,
        look_to: Vec3::NEG_Z,
        mode: Mode::Path,
        depth: 1,
        samples_per_pixel: 512,
        default_light: false,
        aperture_radius,
        focus_distance: Some(focus),
        ..RenderOptions::default()
    };
    options.validate().unwrap();
    render(&scene, &options).pixels
}

/// The radius of the image's disc from its second moment about the image centre (a
/// uniform disc of radius `r` blurred by the sphere's own disc of radius `a` has
/// `E[d^2] = (r^2 + a^2) / 2`; pixel centres lose `1/6` of a pixel squared), and the
/// mean value over the rings `d < 0.35 r` and `0.45 r < d < 0.7 r`.
fn disc_of(pixels: &[Vec3], a: f64) -> (f64, f64, f64) {
    let d2 = |i: usize| {
        let (x, y) = ((i % 41) as f64 - 20.0, (i / 41) as f64 - 20.0);
        x * x + y * y
    };
    let (mut weight, mut moment) = (0.0, 0.0);
    for (i, v) in pixels.iter().enumerate() {
        weight += f64::from(v.x);
        moment += f64::from(v.x) * d2(i);
    }
    let r = (2.0 * (moment / weight + 1.0 / 6.0) - a * a)
        .max(0.0)
        .sqrt();
    let ring = |from: f64, to: f64| {
        let values: Vec<f64> = (0..pixels.len())
            .filter(|&i| (from * r..to * r).contains(&d2(i).sqrt()))
            .map(|i| f64::from(pixels[i].x))
            .collect();
        values.iter().sum::<f64>() / values.len() as f64
    };
    (r, ring(0.0, 0.35), ring(0.45, 0.7))
}

/// A point at depth `z` seen through a lens of radius `R` focused at `f` is a uniform
/// disc of radius `R |z - f| / (z f)` on the image plane at distance 1, times the
/// focal length in pixels.
#[test]
fn a_defocused_point_is_a_uniform_disc_of_the_thin_lens_radius() {
    let (radius, focus, z, sphere): (f64, f64, f64, f64) = (1.35, 2.0, 4.0, 0.3);
    let focal_pixels = 41.0 / (2.0 * (30.0f64).to_radians().tan());
    let expected = radius * (z - focus).abs() / (z * focus) * focal_pixels;
    // The sphere's own disc, as the pinhole sees it.
    let a = (sphere / (z * z - sphere * sphere).sqrt()) * focal_pixels;
    let film = defocused_sphere(radius as Float, focus as Float, z as Float, sphere as Float);
    let (r, inner, middle) = disc_of(&film, a);
    assert!(
        (r - expected).abs() < 0.03 * expected,
        "disc radius {r:.3} pixels, expected {expected:.3}"
    );
    // Uniform: the inner and middle rings agree, at the value the covered fraction of
    // the lens gives, (a / r)^2.
    let coverage = (a / expected).powi(2);
    for ring in [inner, middle] {
        assert!(
            (ring - coverage).abs() < 0.1 * coverage,
            "rings {inner:.4} and {middle:.4} against {coverage:.4}"
        );
    }
    // In focus, and through a pinhole, the sphere is only its own disc.
    for (radius, focus) in [(1.35, z), (0.0, focus)] {
        let film = defocused_sphere(radius as Float, focus as Float, z as Float, sphere as Float);
        let (r, _, _) = disc_of(&film, a);
        assert!(r < 1.5, "{radius} at {focus}: disc of {r} pixels");
    }
}

/// `aperture_radius` 0 is the pinhole, bit for bit, whatever the focus distance.
#[test]
fn radius_zero_is_the_pinhole_bit_for_bit() {
    let scene = support::cornell_scene();
    let pinhole = support::cornell_options(12, 9, Mode::Path, 3);
    let zero = RenderOptions {
        aperture_radius: 0.0,
        focus_distance: Some(0.3),
        ..pinhole
    };
    let bits = |o: &RenderOptions| -> Vec<[u32; 3]> {
        render(&scene, o)
            .pixels
            .iter()
            .map(|v| v.to_array().map(f32::to_bits))
            .collect()
    };
    assert_eq!(bits(&pinhole), bits(&zero));
}

/// With a lens, as without: a tile is bit for bit the same pixels of the whole image
/// (the lens value is a pure function of pixel and sample), in full mode at one sample
/// per pixel (which then leaves the packet loop) and in path mode.
#[test]
fn lens_tiles_are_the_whole_images_pixels() {
    let scene = support::cornell_scene();
    for (mode, spp) in [(Mode::Full, 1), (Mode::Path, 2)] {
        let options = RenderOptions {
            aperture_radius: 0.05,
            focus_distance: Some(1.2),
            ..support::cornell_options(23, 17, mode, spp)
        };
        let whole = render(&scene, &options);
        let tile = Tile {
            x: 5,
            y: 3,
            width: 9,
            height: 11,
        };
        let part = render_tile(&scene, &options, tile).unwrap();
        for row in 0..tile.height {
            let start = ((tile.y + row) * options.width + tile.x) as usize;
            let got = &part.pixels[(row * tile.width) as usize..][..tile.width as usize];
            assert_eq!(
                got,
                &whole.pixels[start..][..tile.width as usize],
                "{mode:?}"
            );
        }
        // The lens changes the image.
        let pinhole = render(
            &scene,
            &RenderOptions {
                aperture_radius: 0.0,
                ..options
            },
        );
        assert_ne!(pinhole.pixels, whole.pixels, "{mode:?}");
    }
}

#[test]
fn bad_lens_values_name_the_flag_or_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.png");
    let cornell = support::cornell_box();
    for (flags, message) in [
        (
            ["--aperture-radius", "-0.5"],
            "invalid --aperture-radius: -0.5 is not a finite radius of 0 or more",
        ),
        (
            ["--focus-distance", "0"],
            "invalid --focus-distance: 0 is not a finite distance greater than 0",
        ),
        (["--tonemap", "filmic"], "--tonemap"),
    ] {
        let mut args = vec![
            "render",
            cornell.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ];
        args.extend(flags);
        let output = raytracer(&args);
        assert_eq!(output.status.code(), Some(2), "{flags:?}");
        assert!(stderr(&output).contains(message), "{}", stderr(&output));
    }
    assert!(!out.exists());
    for (toml, message) in [
        (
            "[camera]\naperture_radius = -1\n",
            "lens.toml:2: camera.aperture_radius: -1 is not a finite radius of 0 or more (0 is a pinhole)",
        ),
        (
            "[camera]\naperture_radius = 0.1\nfocus_distance = -2\n",
            "lens.toml:3: camera.focus_distance: -2 is not a finite distance greater than 0",
        ),
    ] {
        let loaded = formats::parse_toml(toml.as_bytes(), Path::new("lens.toml")).unwrap();
        let error = loaded.resolve(PartialOptions::default()).unwrap_err();
        assert_eq!(error.to_string(), message);
    }
    let loaded = formats::parse_toml(
        b"[camera]\naperture_radius = 0.25\nfocus_distance = 3\n\n[render]\ntonemap = \"agx\"\n",
        Path::new("lens.toml"),
    )
    .unwrap();
    let (_, options) = loaded.resolve(PartialOptions::default()).unwrap();
    assert_eq!(
        (
            options.aperture_radius,
            options.focus_distance,
            options.tonemap
        ),
        (0.25, Some(3.0), raytracer::options::ToneMap::Agx)
    );
}

/// A quad 2 x 1 at z = 0 and an orthographic camera at z = 5 with xmag 2, ymag 1.
const ORTHOGRAPHIC_GLTF: &str = r#"{"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0, 1]}], "nodes": [{"mesh": 0}, {"camera": 0, "translation": [0, 0, 5]}], "cameras": [{"type": "orthographic", "orthographic": {"xmag": 2, "ymag": 1, "znear": 0.01, "zfar": 100}}], "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}], "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-1, -0.5, 0], "max": [1, 0.5, 0]}, {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}], "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48}, {"buffer": 0, "byteOffset": 48, "byteLength": 12}], "buffers": [{"byteLength": 62, "uri": "data:application/octet-stream;base64,AACAvwAAAL8AAAAAAACAPwAAAL8AAAAAAACAPwAAAD8AAAAAAACAvwAAAD8AAAAAAAABAAIAAAACAAMAAAA="}]}"#;

/// An orthographic glTF camera sees the quad face-on at one distance everywhere,
/// covering exactly the middle half of the image's width and height (xmag and ymag are
/// half the view's extent).
#[test]
fn gltf_orthographic_cameras_project_in_parallel() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ortho.gltf");
    std::fs::write(&path, ORTHOGRAPHIC_GLTF).unwrap();
    let loaded = formats::load(&path).unwrap();
    let projection = loaded.options.projection.clone().unwrap();
    assert_eq!(
        projection.value,
        Projection::Orthographic { half_height: 1.0 }
    );
    let flags = PartialOptions {
        width: Some(Sourced::new(40, Origin::Flag("--width"))),
        mode: Some(Sourced::new(Mode::Depth, Origin::Flag("--mode"))),
        ..PartialOptions::default()
    };
    let (description, options) = loaded.resolve(flags).unwrap();
    // xmag / ymag = 2: the height keeps that aspect ratio.
    assert_eq!((options.width, options.height), (40, 20));
    let scene = Scene::build(description, &BvhParams::default());
    let film = render(&scene, &options);
    for (i, v) in film.pixels.iter().enumerate() {
        let (column, row) = (i % 40, i / 40);
        let inside = (10..30).contains(&column) && (5..15).contains(&row);
        if inside {
            assert!((v.x - 5.0).abs() < 1e-5, "pixel ({column}, {row}): {v}");
        } else {
            assert!(v.x.is_infinite(), "pixel ({column}, {row}): {v}");
        }
    }
    // A bad ymag is an error naming the key.
    let bad = ORTHOGRAPHIC_GLTF.replace("\"ymag\": 1", "\"ymag\": 0");
    std::fs::write(&path, bad).unwrap();
    let error = formats::load(&path)
        .unwrap()
        .resolve(PartialOptions::default())
        .unwrap_err()
        .to_string();
    assert!(error.contains("camera.ymag"), "{error}");
}

/// A lone `--look-from` (no target from flags or file) looks at the centre of the
/// scene's bounding box.
#[test]
fn a_lone_look_from_aims_at_the_scene_centre() {
    let loaded = formats::load(&support::cornell_box()).unwrap();
    let centre = loaded.description.bounds().center();
    let flags = PartialOptions {
        look_from: Some(Sourced::new(
            Vec3::new(3.0, 2.0, 4.0),
            Origin::Flag("--look-from"),
        )),
        ..PartialOptions::default()
    };
    let (_, options) = loaded.resolve(flags).unwrap();
    assert_eq!(options.look_from, Vec3::new(3.0, 2.0, 4.0));
    assert_eq!(options.look_to, centre);
    // From the command line: the same image as with the centre given as the target.
    let dir = tempfile::tempdir().unwrap();
    let cornell = support::cornell_box();
    let target = format!("{},{},{}", centre.x, centre.y, centre.z);
    let mut images = Vec::new();
    for (name, target) in [("alone.png", None), ("aimed.png", Some(target.as_str()))] {
        let out = dir.path().join(name);
        let mut args = vec![
            "render",
            cornell.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--width",
            "16",
            "--height",
            "12",
            "--mode",
            "normal",
            "--look-from",
            "3,2,4",
        ];
        if let Some(target) = target {
            args.extend(["--look-to", target]);
        }
        let output = raytracer(&args);
        assert!(output.status.success(), "{}", stderr(&output));
        images.push(support::read_png(&out));
    }
    assert_eq!(images[0], images[1]);
    // The default target is no target then: a position there is fine (the flags are
    // checked before the load without the pair of points).
    let out = dir.path().join("there.png");
    let output = raytracer(&[
        "render",
        cornell.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--width",
        "8",
        "--height",
        "6",
        "--look-from",
        "0,0,-1",
    ]);
    assert!(output.status.success(), "{}", stderr(&output));
}
