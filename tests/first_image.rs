//! A first image without flags: with no camera from flags or scene file, the camera
//! frames the whole scene; a scene with no light and no emitter gets the default
//! lighting (a light rig at the camera in full mode, a studio environment in path mode) with one
//! warning, which `--no-default-light` turns off; under the rig, `Ka` reflects the
//! rig's ambient light by `Kd`, so that an exported model (`Ka 1 1 1`) is not washed
//! out, and SPEC's tone curve shows a dark model dark (its white point at least 1).

use crate::support;

use std::path::Path;

use assert_cmd::Command;
use raytracer::formats::LoadedScene;
use raytracer::material::Light;
use raytracer::math::{Aabb, Vec3};
use raytracer::options::{Origin, PartialOptions, Sourced};
use raytracer::{Material, Mode, RenderOptions, SceneDescription};

/// A box from `min` to `max` as 12 triangles, with one material.
fn box_obj(min: Vec3, max: Vec3) -> String {
    let mut text = String::new();
    for i in 0..8 {
        let pick = |bit: usize, lo: f32, hi: f32| if i & bit == 0 { lo } else { hi };
        text += &format!(
            "v {} {} {}\n",
            pick(1, min.x, max.x),
            pick(2, min.y, max.y),
            pick(4, min.z, max.z)
        );
    }
    // Counter-clockwise seen from outside.
    for f in [
        [1, 3, 4, 2],
        [5, 6, 8, 7],
        [1, 2, 6, 5],
        [3, 7, 8, 4],
        [1, 5, 7, 3],
        [2, 4, 8, 6],
    ] {
        text += &format!("f {} {} {} {}\n", f[0], f[1], f[2], f[3]);
    }
    text
}

/// Where the camera of `options` sees `p`: pixel coordinates (x right, y down).
fn project(options: &RenderOptions, p: Vec3) -> (f32, f32) {
    let forward = (options.look_to - options.look_from).normalize();
    let right = forward.cross(options.up).normalize();
    let up = right.cross(forward);
    let d = p - options.look_from;
    let depth = d.dot(forward);
    assert!(depth > 0.0, "{p} is behind the camera");
    let tan = (options.fov_degrees.to_radians() / 2.0).tan();
    let (w, h) = (options.width as f32, options.height as f32);
    let x = d.dot(right) / depth / (tan * w / h);
    let y = d.dot(up) / depth / tan;
    ((x + 1.0) * w / 2.0, (1.0 - y) * h / 2.0)
}

/// The 8 corners of a box.
fn corners(min: Vec3, max: Vec3) -> [Vec3; 8] {
    std::array::from_fn(|i| {
        Vec3::new(
            if i & 1 == 0 { min.x } else { max.x },
            if i & 2 == 0 { min.y } else { max.y },
            if i & 4 == 0 { min.z } else { max.z },
        )
    })
}

/// The extent of the projections of `points` as fractions of the image's width and
/// height, after checking that each lies inside the image.
fn fill(options: &RenderOptions, points: &[Vec3]) -> (f32, f32) {
    let (w, h) = (options.width as f32, options.height as f32);
    let (mut lo, mut hi) = ((f32::INFINITY, f32::INFINITY), (0.0f32, 0.0f32));
    for &p in points {
        let (x, y) = project(options, p);
        // A thousandth of a pixel of rounding.
        assert!(
            (-1e-3..=w + 1e-3).contains(&x) && (-1e-3..=h + 1e-3).contains(&y),
            "{p} at ({x}, {y}) in {w}x{h}"
        );
        (lo, hi) = ((lo.0.min(x), lo.1.min(y)), (hi.0.max(x), hi.1.max(y)));
    }
    ((hi.0 - lo.0) / w, (hi.1 - lo.1) / h)
}

/// The model viewer's framing: from the front (+z, as glTF's models face) and above,
/// to the right (+x) of straight ahead; the projection of every corner of the
/// scene's bounds inside the image, reaching at least 60% of its limiting dimension.
fn assert_framed_like_a_model_viewer(options: &RenderOptions, min: Vec3, max: Vec3) {
    let back = (options.look_from - options.look_to).normalize();
    let elevation = back.y.asin().to_degrees();
    assert!((15.0..=30.0).contains(&elevation), "{back}");
    let azimuth = back.x.atan2(back.z).to_degrees();
    assert!((15.0..=40.0).contains(&azimuth), "{back}");
    let (x, y) = fill(options, &corners(min, max));
    assert!(
        x.max(y) >= 0.6,
        "{min}..{max} fills {x} x {y} of {}x{}",
        options.width,
        options.height
    );
}

#[test]
fn with_no_camera_the_model_is_framed_from_the_front_and_above_filling_the_frame() {
    let size = |w: i64, h: i64, fov: Option<f32>| PartialOptions {
        width: Some(Sourced::new(w, Origin::Default)),
        height: Some(Sourced::new(h, Origin::Default)),
        fov_degrees: fov.map(|fov| Sourced::new(fov, Origin::Flag("--fov"))),
        ..PartialOptions::default()
    };
    let boxes = [
        // A cube; far from the origin and behind the default camera.
        (Vec3::new(-1.0, -1.0, -1.0), Vec3::new(1.0, 1.0, 1.0)),
        (Vec3::new(10.0, 20.0, 40.0), Vec3::new(16.0, 23.0, 45.0)),
        // A tall thin figure, a wide flat one (a car, a table), a long one along z.
        (Vec3::new(-0.1, 0.0, -0.1), Vec3::new(0.1, 3.0, 0.1)),
        (Vec3::new(-2.0, 0.0, -1.0), Vec3::new(2.0, 0.3, 1.0)),
        (Vec3::new(-0.5, -0.5, -10.0), Vec3::new(0.5, 0.5, 10.0)),
        // Huge and tiny.
        (Vec3::splat(-1e6), Vec3::new(2e6, 1e6, 1e6)),
        (Vec3::new(1.0, 2.0, 3.0), Vec3::new(1.001, 2.002, 3.001)),
    ];
    // Wide and tall images, narrow and wide fields of view.
    for flags in [
        size(640, 480, None),
        size(480, 640, None),
        size(400, 40, Some(30.0)),
        size(40, 400, Some(120.0)),
        size(100, 100, Some(10.0)),
    ] {
        for (min, max) in boxes {
            let description =
                raytracer::formats::parse_obj(box_obj(min, max).as_bytes(), Path::new("box.obj"))
                    .unwrap();
            let bounds = description.bounds();
            assert_eq!((bounds.min, bounds.max), (min, max));
            let options = flags.clone().framed(bounds).resolve().unwrap();
            // The field of view as given, else a model viewer's narrow one.
            let fov = flags.fov_degrees.as_ref().map_or(40.0, |f| f.value);
            assert_eq!(options.fov_degrees, fov);
            assert_framed_like_a_model_viewer(&options, min, max);
        }
    }
}

#[test]
fn the_bundled_gltf_box_is_framed_and_fills_the_frame() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/gltf-box/BoxTextured.glb");
    let loaded = raytracer::formats::load(&path).unwrap();
    let bounds = loaded.description.bounds();
    let (_, options) = loaded.resolve(PartialOptions::default()).unwrap();
    assert_eq!(
        (options.width, options.height, options.fov_degrees),
        (640, 480, 40.0)
    );
    assert_framed_like_a_model_viewer(&options, bounds.min, bounds.max);
}

#[test]
fn the_model_itself_not_its_box_is_centred_and_fills_the_frame() {
    // Shapes whose boxes' corners are mostly empty: a corner of a cube (a
    // tetrahedron), and a long slanted wedge seen along its length, as a VR
    // controller is (its box's near bottom corner projected far below the model,
    // which the box's framing left in the image's top half).
    let shapes: [&[[f32; 3]]; 2] = [
        &[[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [0., 0., 1.]],
        &[
            [-0.3, 0.2, -3.0],
            [0.3, 0.2, -3.0],
            [0.0, 0.5, -3.0],
            [-0.3, -0.3, 3.0],
            [0.3, -0.3, 3.0],
            [0.0, 0.0, 3.0],
        ],
    ];
    let dir = tempfile::tempdir().unwrap();
    for (k, shape) in shapes.into_iter().enumerate() {
        let mut obj: String = shape
            .iter()
            .map(|v| format!("v {} {} {}\n", v[0], v[1], v[2]))
            .collect();
        // Every triple of vertices a face: the hull's faces among them.
        let n = shape.len();
        for a in 1..=n {
            for b in a + 1..=n {
                for c in b + 1..=n {
                    obj += &format!("f {a} {b} {c}\n");
                }
            }
        }
        let path = dir.path().join(format!("shape{k}.obj"));
        std::fs::write(&path, obj).unwrap();
        let (_, options) = raytracer::formats::load(&path)
            .unwrap()
            .resolve(PartialOptions::default())
            .unwrap();
        let (w, h) = (options.width as f32, options.height as f32);
        let (mut lo, mut hi) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
        for v in shape {
            let (x, y) = project(&options, Vec3::from(*v));
            (lo, hi) = ([lo[0].min(x), lo[1].min(y)], [hi[0].max(x), hi[1].max(y)]);
        }
        let centre = [(lo[0] + hi[0]) / 2.0 / w, (lo[1] + hi[1]) / 2.0 / h];
        let fill = [(hi[0] - lo[0]) / w, (hi[1] - lo[1]) / h];
        // The model's projection, not its box's, centred and filling 92% of the
        // limiting dimension; in the other, centred between the planes that would
        // touch it at that fill, so within a few pixels.
        let limiting = usize::from(fill[1] > fill[0]);
        let off = centre.map(|c| (c - 0.5).abs());
        assert!(
            off[limiting] < 1e-3 && off[1 - limiting] < 0.03,
            "shape {k}: centred at {centre:?}, filling {fill:?}"
        );
        assert!(
            (fill[0].max(fill[1]) - 0.92).abs() < 1e-3,
            "shape {k}: fills {fill:?}"
        );
    }
}

/// `raytracer render ARGS` run in `dir`.
fn render_in(dir: &Path, args: &[&str]) -> std::process::Output {
    Command::cargo_bin("raytracer")
        .unwrap()
        .current_dir(dir)
        .arg("render")
        .args(args)
        .output()
        .unwrap()
}

/// Renders `scene` (written as `name` in a temporary folder) in normal mode at
/// 160x120 with no camera, and returns the fractions of the columns and rows that
/// show the model, checking that it does not touch the image's border (is not cut).
fn covered_by_the_model(name: &str, scene: &str) -> (f32, f32) {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join(name), scene).unwrap();
    let out = dir.path().join("out.png");
    let out_arg = out.to_str().unwrap();
    let output = render_in(
        dir.path(),
        &[
            name, "--mode", "normal", "-o", out_arg, "--width", "160", "--height", "120",
        ],
    );
    assert!(output.status.success(), "{output:?}");
    let (w, h, rgb) = support::read_png(&out);
    // Normal mode shows misses black, and no normal is black.
    let hit = |x: u32, y: u32| rgb[3 * (y * w + x) as usize..][..3].iter().any(|&c| c > 0);
    for x in 0..w {
        assert!(!hit(x, 0) && !hit(x, h - 1), "{name}: cut at column {x}");
    }
    for y in 0..h {
        assert!(!hit(0, y) && !hit(w - 1, y), "{name}: cut at row {y}");
    }
    let columns = (0..w).filter(|&x| (0..h).any(|y| hit(x, y))).count();
    let rows = (0..h).filter(|&y| (0..w).any(|x| hit(x, y))).count();
    (columns as f32 / w as f32, rows as f32 / h as f32)
}

#[test]
fn rendered_models_fill_most_of_the_frame_uncut() {
    let sphere = "[[sphere]]\ncenter = [3, -2, 7]\nradius = 2\n";
    let tall = box_obj(Vec3::new(0.0, 0.0, 0.0), Vec3::new(0.3, 4.0, 0.3));
    let wide = box_obj(Vec3::new(-3.0, 0.0, -1.0), Vec3::new(3.0, 0.5, 1.0));
    let cube = box_obj(Vec3::splat(-1.0), Vec3::splat(1.0));
    for (name, scene) in [
        ("sphere.toml", sphere),
        ("tall.obj", &tall),
        ("wide.obj", &wide),
        ("cube.obj", &cube),
    ] {
        let (columns, rows) = covered_by_the_model(name, scene);
        assert!(
            columns.max(rows) >= 0.6,
            "{name} covers {columns} of the columns and {rows} of the rows"
        );
    }
}

#[test]
fn a_flat_scene_is_framed_face_on() {
    // A square in the plane x = 2, as LightWave's concave test polygon lies: along -z
    // it would be edge-on, so the camera looks along -x; a floor (y = 1) is seen from
    // above.
    for (min, max, axis) in [
        (Vec3::new(2.0, 0.0, 0.0), Vec3::new(2.0, 1.0, 1.0), Vec3::X),
        (Vec3::new(0.0, 1.0, 0.0), Vec3::new(1.0, 1.0, 1.0), Vec3::Y),
        (Vec3::new(0.0, 0.0, 3.0), Vec3::new(1.0, 1.0, 3.0), Vec3::Z),
    ] {
        let options = PartialOptions::default()
            .framed(Aabb { min, max })
            .resolve()
            .unwrap();
        let back = (options.look_from - options.look_to).normalize();
        assert!((back - axis).length() < 1e-6, "{back} for {min}..{max}");
    }
}

#[test]
fn a_flat_scene_in_a_tilted_plane_is_framed_face_on() {
    // A thin strip (8 by 1.5, as Assimp's regr_3429812.obj) in a plane tilted about
    // two axes, its coordinates rounded to 6 digits as an OBJ writes them: from the
    // usual direction it was seen nearly edge-on, a line across the image.
    let (u, v) = (
        Vec3::new(0.8, -0.3, 0.52).normalize(),
        Vec3::new(0.2, 0.9, 0.1).normalize(),
    );
    let v = (v - u * u.dot(v)).normalize();
    let normal = u.cross(v);
    let origin = Vec3::new(0.05, 0.96, 0.09);
    let corners = [(0.0, 0.0), (8.0, 0.0), (8.0, 1.5), (0.0, 1.5)]
        .map(|(a, b): (f32, f32)| origin + (u * a + v * b) * 1e-3);
    let mut obj = String::new();
    for c in corners {
        obj += &format!("v {:.6} {:.6} {:.6}\n", c.x, c.y, c.z);
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("strip.obj");
    // Seen from the side its face looks to (counter-clockwise corners), whichever
    // it is; a pair of faces that disagree, from the side the usual view (front,
    // above, so +z) looks at.
    assert!(normal.z > 0.0);
    for (faces, side) in [
        ("f 1 2 3 4\n", normal),
        ("f 4 3 2 1\n", -normal),
        ("f 1 2 3\nf 1 4 3\n", normal),
    ] {
        std::fs::write(&path, format!("{obj}{faces}")).unwrap();
        let loaded = raytracer::formats::load(&path).unwrap();
        let (_, options) = loaded.resolve(PartialOptions::default()).unwrap();
        let back = (options.look_from - options.look_to).normalize();
        assert!(back.dot(side) > 0.999, "{faces:?}: {back} against {side}");
    }
    // Not from well below, whichever way the face looks: Assimp's
    // multiple_spaces.obj, one triangle facing down, showed dark in path mode.
    for faces in ["f 1 2 3\n", "f 3 2 1\n"] {
        let path = dir.path().join("triangle.obj");
        std::fs::write(&path, format!("v 1 2 3\nv 2 3 1\nv 3 1 2\n{faces}")).unwrap();
        let loaded = raytracer::formats::load(&path).unwrap();
        let (_, options) = loaded.resolve(PartialOptions::default()).unwrap();
        let back = (options.look_from - options.look_to).normalize();
        let normal = Vec3::ONE.normalize();
        assert!(back.dot(normal) > 0.999, "{faces:?}: {back}");
    }
    // A box's corners, or a sphere, are not flat: the usual direction stays.
    let cube = LoadedScene {
        description: raytracer::formats::parse_obj(
            box_obj(Vec3::ZERO, Vec3::ONE).as_bytes(),
            Path::new("cube.obj"),
        )
        .unwrap(),
        options: PartialOptions::default(),
    };
    let (_, options) = cube.resolve(PartialOptions::default()).unwrap();
    let back = (options.look_from - options.look_to).normalize();
    assert!(back.x > 0.1 && back.y > 0.1 && back.z > 0.5, "{back}");
}

#[test]
fn a_camera_from_flags_or_file_is_not_framed_and_a_lone_position_aims_at_the_centre() {
    let bounds = Aabb {
        min: Vec3::splat(5.0),
        max: Vec3::splat(6.0),
    };
    let flags = PartialOptions {
        look_from: Some(Sourced::new(Vec3::ONE, Origin::Flag("--look-from"))),
        ..PartialOptions::default()
    };
    let options = flags.framed(bounds).resolve().unwrap();
    assert_eq!(options.look_from, Vec3::ONE);
    // A lone position looks at the scene's centre.
    assert_eq!(options.look_to, Vec3::splat(5.5));
    let target = PartialOptions {
        look_to: Some(Sourced::new(Vec3::ONE, Origin::Flag("--look-to"))),
        ..PartialOptions::default()
    };
    let options = target.framed(bounds).resolve().unwrap();
    assert_eq!(options.look_to, Vec3::ONE);
    assert_eq!(options.look_from, RenderOptions::default().look_from);
    // An empty scene keeps the defaults.
    let options = PartialOptions::default()
        .framed(Aabb::EMPTY)
        .resolve()
        .unwrap();
    assert_eq!(options, RenderOptions::default());
}

/// An exported model's material: Blender's `Ka 1 1 1`, a red diffuse colour.
const RED: &str = "newmtl red\nNs 225\nKa 1 1 1\nKd 0.8 0.1 0.1\nKs 0.5 0.5 0.5\nKe 0 0 0\nNi 1.45\nd 1\nillum 2\n";

/// A box with the material `red` of `mtl`, and no lights. It sits off-centre and
/// behind the default camera, so only framing shows it.
fn write_scene(dir: &Path, mtl: &str) {
    std::fs::write(
        dir.join("model.obj"),
        format!(
            "mtllib model.mtl\nusemtl red\n{}",
            box_obj(Vec3::new(3.0, 1.0, 4.0), Vec3::new(5.0, 2.0, 6.0))
        ),
    )
    .unwrap();
    std::fs::write(dir.join("model.mtl"), mtl).unwrap();
}

/// `raytracer render model.obj -o out.png` with `args`: the warnings and the image.
fn render_model(args: &[&str]) -> (String, Vec<u8>) {
    render_model_in(RED, args)
}

/// [`render_model`] with the box's material `red` as `mtl` says.
fn render_model_in(mtl: &str, args: &[&str]) -> (String, Vec<u8>) {
    let dir = tempfile::tempdir().unwrap();
    write_scene(dir.path(), mtl);
    let out = dir.path().join("out.png");
    let size = [
        "-o",
        out.to_str().unwrap(),
        "--width",
        "80",
        "--height",
        "60",
    ];
    let output = render_in(dir.path(), &[&["model.obj"], &size[..], args].concat());
    let stderr = String::from_utf8(output.stderr).unwrap();
    assert!(output.status.success(), "{stderr}");
    (stderr, support::read_png(&out).2)
}

/// The brightest pixel's channels.
fn brightest(rgb: &[u8]) -> [u8; 3] {
    let px = rgb
        .chunks(3)
        .max_by_key(|p| p.iter().map(|&c| u32::from(c)).sum::<u32>())
        .unwrap();
    [px[0], px[1], px[2]]
}

#[test]
fn an_unlit_model_gets_the_default_light_rig_with_one_warning() {
    // One sample a pixel (the rig's default is four, whose silhouette blends the
    // model's colours with the backdrop's).
    let (stderr, rgb) = render_model(&["--spp", "1"]);
    assert_eq!(
        stderr,
        "warning: the scene has no lights (no light sources, no emitting surfaces): lit by a default light rig at the camera (--no-default-light turns it off)\n"
    );
    // The model's pixels: where camera rays missed, the grey backdrop shows (one
    // sample per pixel: each pixel is the model's or the backdrop's).
    let grey = raytracer::postprocess::default_backdrop();
    let backdrop = rgb.chunks(3).filter(|p| *p == grey).count();
    assert!(backdrop > 1000, "{backdrop} backdrop pixels");
    let rgb: Vec<u8> = rgb
        .chunks(3)
        .filter(|p| *p != grey)
        .flatten()
        .copied()
        .collect();
    // Framed, lit, and red: not a white silhouette. (Added in full, `Ka 1 1 1` made
    // every lit pixel nearly white; as a fraction of the rig's ambient light, the
    // diffuse red shows.)
    let lit = rgb.chunks(3).filter(|p| p[0] > 40).count();
    assert!(lit > 200, "{lit} lit pixels");
    // Kd 0.8 0.1 0.1 shows as green/red about 0.5 after SPEC's gamma (0.39 in sRGB, as
    // a modeller's viewport shows it); with `Ka 1 1 1` added in full it was 0.77.
    // Seen from above and to the right, the faces away from the key light show the
    // rig's grey ambient light more: still red, none white.
    let red =
        |p: &&[u8], percent: u32| p[0] > 40 && u32::from(p[1]) * 100 < u32::from(p[0]) * percent;
    let reds = rgb.chunks(3).filter(|p| red(p, 60)).count();
    assert!(reds * 4 > lit * 3, "{reds} of {lit} lit pixels are red");
    let reddish = rgb.chunks(3).filter(|p| red(p, 90)).count();
    assert_eq!(reddish, lit, "lit pixels with green near red");
    // Shaded: the faces in view differ in brightness.
    let mut levels: Vec<u8> = rgb.chunks(3).map(|p| p[0]).filter(|&r| r > 40).collect();
    levels.sort_unstable();
    levels.dedup();
    assert!(levels.len() > 3, "{levels:?}");
}

/// Under the rig, full mode's first picture takes four samples a pixel unless told
/// otherwise, as a model viewer multisamples: the same bytes as `--spp 4`, not those
/// of one ray through each pixel centre; the silhouette's pixels are blends of the
/// model and the backdrop (a one-sample image has none: each of its pixels is one or
/// the other). `--spp 1` (or `render.spp` in a scene file) still renders pixel
/// centres, and so do a render with extra outputs (`--aovs`) and a scene with a light
/// of its own (SPEC's one sample).
#[test]
fn under_the_rig_full_mode_takes_four_samples_a_pixel_unless_told() {
    let (_, default) = render_model(&[]);
    let (_, four) = render_model(&["--spp", "4"]);
    let (_, one) = render_model(&["--spp", "1"]);
    assert!(default == four, "the default is not --spp 4");
    assert!(default != one, "the default is --spp 1");
    // The silhouette's pixels, partly covered, are no longer the backdrop's grey.
    let backdrop = |rgb: &[u8]| model_pixels(rgb).1;
    assert!(
        backdrop(&default) + 20 < backdrop(&one),
        "backdrop pixels: {} at four samples, {} at one",
        backdrop(&default),
        backdrop(&one)
    );

    // Extra outputs are data, wanted at the pixel centre: one sample, as --spp 1.
    let exr = |extra: &[&str]| {
        let dir = tempfile::tempdir().unwrap();
        write_scene(dir.path(), RED);
        render_file(
            dir.path(),
            "out.exr",
            &[&["--aovs", "depth"], extra].concat(),
        )
    };
    assert!(
        exr(&[]) == exr(&["--spp", "1"]),
        "with --aovs, the default is not --spp 1"
    );
    assert!(
        exr(&[]) != exr(&["--spp", "4"]),
        "--spp 4 with --aovs is not another image"
    );

    // A light of its own: one sample, the same bytes as --spp 1.
    let dir = tempfile::tempdir().unwrap();
    write_scene(dir.path(), RED);
    let obj = dir.path().join("model.obj");
    let text = std::fs::read_to_string(&obj).unwrap();
    std::fs::write(&obj, format!("P 6 6 10 1 1 1\n{text}")).unwrap();
    let render = |extra: &[&str]| render_file(dir.path(), "lit.png", extra);
    assert!(
        render(&[]) == render(&["--spp", "1"]),
        "a lit scene's default is not --spp 1"
    );
}

/// The bytes of `out` (in `dir`) that `raytracer render model.obj` writes there at
/// 40x30 with `args`, which must succeed.
fn render_file(dir: &Path, out: &str, args: &[&str]) -> Vec<u8> {
    let out = dir.join(out);
    let size = [
        "-o",
        out.to_str().unwrap(),
        "--width",
        "40",
        "--height",
        "30",
    ];
    let output = render_in(dir, &[&["model.obj"], &size[..], args].concat());
    assert!(output.status.success(), "{}", support::stderr(&output));
    std::fs::read(&out).unwrap()
}

/// The image's pixels other than the default backdrop's grey, and how many of those
/// there were.
fn model_pixels(rgb: &[u8]) -> (Vec<[u8; 3]>, usize) {
    let grey = raytracer::postprocess::default_backdrop();
    let backdrop = rgb.chunks(3).filter(|p| *p == grey).count();
    let model = rgb.chunks(3).filter(|p| *p != grey);
    (model.map(|p| [p[0], p[1], p[2]]).collect(), backdrop)
}

#[test]
fn a_black_plastic_under_the_rig_stands_out_from_the_grey_backdrop() {
    // robosuite's Baxter pedestal as Blender exported it: near-black diffuse, a
    // tight highlight, and `Ka 1 1 1`. With the rig's grey ambient light added as
    // `Ka * 0.1`, the body showed as grey as the backdrop (the highlights set
    // SPEC's white point); a model viewer shows it black. A sphere, so that the
    // highlights are in view.
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("black.toml"),
        "[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"black\"\n\n\
         [materials.black]\nKa = 1\nKd = 0.013\nKs = 0.5\nNs = 225\n",
    )
    .unwrap();
    let out = dir.path().join("out.png");
    let out_arg = out.to_str().unwrap();
    let output = render_in(
        dir.path(),
        &[
            "black.toml",
            "--width",
            "80",
            "--height",
            "60",
            "-o",
            out_arg,
        ],
    );
    assert!(output.status.success(), "{}", support::stderr(&output));
    let (model, backdrop) = model_pixels(&support::read_png(&out).2);
    assert!(
        backdrop > 1000 && model.len() > 500,
        "{backdrop} {}",
        model.len()
    );
    let grey = raytracer::postprocess::default_backdrop()[0];
    let mut levels: Vec<u8> = model.iter().map(|p| p[0]).collect();
    levels.sort_unstable();
    let median = levels[levels.len() / 2];
    assert!(
        u32::from(median) * 2 < u32::from(grey),
        "the model's median {median} against the backdrop's {grey}"
    );
    // The highlights still show, brighter than the backdrop.
    assert!(levels[levels.len() - 1] > grey, "{levels:?}");
}

#[test]
fn a_dark_model_under_the_rig_is_shown_as_dark_as_it_is() {
    // SPEC's tone curve takes the image's brightest channel as white: a model of
    // `Kd 0.05` (Kinova's Jaco arm) showed its brightest face white where path mode
    // shows it dark grey. Under the rig the white point is at least 1, below which
    // the curve is the identity: no face can be brighter than `Kd` lit by both rig
    // lights head-on plus the ambient light, `0.05 * (0.8 + 0.4 + 0.1)`.
    let dark = "newmtl red\nKa 1 1 1\nKd 0.05 0.05 0.05\nKs 0 0 0\n";
    // One sample a pixel: the silhouette's blends with the grey backdrop are not
    // the model's.
    let (_, rgb) = render_model_in(dark, &["--spp", "1"]);
    let (model, _) = model_pixels(&rgb);
    let most = (0.05f32 * 1.3).powf(1.0 / 2.2) * 255.0;
    let brightest = model.iter().map(|p| p[0]).max().unwrap();
    assert!(
        f32::from(brightest) <= most.ceil() && f32::from(brightest) > most * 0.5,
        "brightest {brightest}, at most {most}"
    );
}

#[test]
fn a_scene_whose_every_surface_emits_gets_the_default_light() {
    // Some exporters write `Ke 0.1` into every material (robosuite's gripper
    // plates): the model glows, but its emitters light nothing else, and it
    // rendered as a flat white (full) or dim grey (path) shape on black.
    let glowing =
        "newmtl red\nNs 10\nKa 1 1 1\nKd 0.8 0.1 0.1\nKs 0.1 0.1 0.1\nKe 0.1 0.1 0.1\nillum 2\n";
    let reason = "warning: every surface of the scene emits ('Ke'), lighting nothing else";
    let (stderr, rgb) = render_model_in(glowing, &[]);
    assert_eq!(
        stderr,
        format!(
            "{reason}: lit by a default light rig at the camera (--no-default-light turns it off)\n"
        )
    );
    let (model, backdrop) = model_pixels(&rgb);
    assert!(backdrop > 1000, "{backdrop} backdrop pixels");
    // Lit and shaded by the rig: red, and the faces in view differ.
    assert!(model.iter().all(|p| p[0] > p[1]), "{model:?}");
    let mut levels: Vec<u8> = model.iter().map(|p| p[0]).collect();
    levels.sort_unstable();
    levels.dedup();
    assert!(levels.len() > 3, "{levels:?}");
    let (stderr, rgb) = render_model_in(glowing, &["--mode", "path", "--spp", "4"]);
    assert!(
        stderr.starts_with(&format!(
            "{reason}: path mode lights it with a studio environment"
        )),
        "{stderr}"
    );
    assert!(model_pixels(&rgb).1 > 1000);
    // A scene with a surface that does not emit is lit by its emitters as before.
    let lit = "newmtl red\nKd 0.8 0.1 0.1\nKe 0.1 0.1 0.1\n";
    let dir = tempfile::tempdir().unwrap();
    write_scene(dir.path(), lit);
    let floor = "v 1 0 2\nv 7 0 2\nv 7 0 8\nv 1 0 8\nusemtl grey\nf -4 -3 -2 -1\n";
    let model = std::fs::read_to_string(dir.path().join("model.obj")).unwrap();
    std::fs::write(dir.path().join("model.obj"), model + floor).unwrap();
    std::fs::write(
        dir.path().join("model.mtl"),
        format!("{lit}newmtl grey\nKd 0.5 0.5 0.5\n"),
    )
    .unwrap();
    let output = render_in(
        dir.path(),
        &[
            "model.obj",
            "-o",
            "out.png",
            "--width",
            "40",
            "--height",
            "30",
        ],
    );
    assert!(output.status.success());
    assert_eq!(String::from_utf8(output.stderr).unwrap(), "");
}

#[test]
fn no_default_light_renders_the_unlit_scene_as_it_is() {
    let (stderr, rgb) = render_model(&["--no-default-light"]);
    assert_eq!(
        stderr,
        "warning: the scene has no lights (no light sources, no emitting surfaces): full mode shows only its ambient colour (Ka) (the default light is off: --no-default-light)\n"
    );
    // SPEC's formula: Ka alone, white, flat.
    assert_eq!(brightest(&rgb), [255, 255, 255]);
    let mut levels: Vec<&[u8]> = rgb.chunks(3).collect();
    levels.sort_unstable();
    levels.dedup();
    assert_eq!(levels.len(), 2, "black and white only");
}

#[test]
fn path_mode_lights_an_unlit_scene_with_a_white_sky_unless_told_not_to() {
    let (stderr, rgb) = render_model(&["--mode", "path", "--spp", "4", "--depth", "4"]);
    // The model's `red` has Kd + Ks above 1, which path mode scales down, saying so.
    const SCALED: &str =
        "warning: material 'red': Kd + Ks exceeds 1, scaled down in path mode to conserve energy\n";
    assert_eq!(
        stderr,
        format!(
            "warning: the scene has no lights (no light sources, no emitting surfaces): path mode lights it with a studio environment (--no-default-light turns it off)\n{SCALED}"
        )
    );
    assert!(rgb.iter().any(|&c| c > 0));
    let (stderr, rgb) = render_model(&["--mode", "path", "--spp", "4", "--no-default-light"]);
    assert_eq!(
        stderr,
        format!(
            "warning: the scene has no lights (no light sources, no emitting surfaces): path mode renders it black (the default light is off: --no-default-light)\n{SCALED}{BLACK}"
        )
    );
    assert!(rgb.iter().all(|&c| c == 0));
}

/// What `render` says of a path mode image that is nearly black.
const BLACK: &str = "warning: the image is nearly black (100.0% of its pixels below 8/255): try --exposure 2 (or more), --env R,G,B or --env FILE.hdr (an environment lighting the scene), or lights in the scene\n";

#[test]
fn render_warns_when_the_image_is_nearly_black_and_only_then() {
    // Path mode without light: black, with what to try.
    let (stderr, _) = render_model(&["--mode", "path", "--spp", "1", "--no-default-light"]);
    assert!(stderr.ends_with(BLACK), "{stderr}");
    assert_eq!(stderr.matches("nearly black").count(), 1, "{stderr}");
    // Also for OpenEXR output (what its PNG would show).
    let dir = tempfile::tempdir().unwrap();
    write_scene(dir.path(), RED);
    let small = ["model.obj", "--width", "16", "--height", "12"];
    let path = ["--mode", "path", "--spp", "1", "--no-default-light"];
    let output = render_in(
        dir.path(),
        &[&small[..], &["-o", "out.exr"], &path].concat(),
    );
    assert!(String::from_utf8_lossy(&output.stderr).ends_with(BLACK));
    // Full mode with only ambient black: `Ka 0` and no default light.
    std::fs::write(
        dir.path().join("model.mtl"),
        "newmtl red\nKa 0 0 0\nKd 0.8 0.1 0.1\n",
    )
    .unwrap();
    let output = render_in(
        dir.path(),
        &[&small[..], &["-o", "out.png", "--no-default-light"]].concat(),
    );
    let stderr = String::from_utf8(output.stderr).unwrap();
    assert!(
        stderr.ends_with("warning: the image is nearly black (100.0% of its pixels below 8/255): try --mode path (lit by --env, or by the studio environment when the scene has no lights), or lights in the scene\n"),
        "{stderr}"
    );
    // Lit renders, in both modes, and normal mode: no such warning.
    for args in [
        &[][..],
        &["--mode", "path", "--spp", "4"],
        &["--mode", "normal"],
    ] {
        let (stderr, _) = render_model(args);
        assert!(!stderr.contains("nearly black"), "{args:?}: {stderr}");
    }
}

#[test]
fn a_scene_with_lights_keeps_the_spec_formula_exactly() {
    let material = Material {
        ambient: Vec3::ONE,
        diffuse: Vec3::new(0.8, 0.1, 0.1),
        ..Material::named("red")
    };
    let light = Light::point(Vec3::ONE, Vec3::ONE);
    let lit = SceneDescription {
        lights: vec![light],
        materials: vec![material.clone()],
        ..SceneDescription::default()
    };
    let mut after = lit.clone();
    after.add_default_light(&RenderOptions::default());
    assert_eq!(after.lights, [light]);
    assert_eq!(after.materials, std::slice::from_ref(&material));
    assert!(after.warnings.is_empty());
    // An emitter lights the scene too (path mode's area light): a triangle that
    // emits beside one that does not.
    let emitting = Material {
        emission: Vec3::ONE,
        ..material.clone()
    };
    let loaded = LoadedScene {
        description: raytracer::formats::parse_obj(
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\n",
            Path::new("t.obj"),
        )
        .map(|mut d| {
            d.materials = vec![emitting, material];
            d.triangles[1].material = raytracer::material::MaterialId(1);
            d
        })
        .unwrap(),
        options: PartialOptions::default(),
    };
    let (description, options) = loaded.resolve(PartialOptions::default()).unwrap();
    assert_eq!(options.mode, Mode::Full);
    assert!(description.lights.is_empty());
    assert!(
        description.warnings.iter().all(|w| !w.contains("lights")),
        "{:?}",
        description.warnings
    );
}

#[test]
fn a_scene_file_can_turn_the_default_light_off() {
    let dir = tempfile::tempdir().unwrap();
    write_scene(dir.path(), RED);
    let toml = dir.path().join("scene.toml");
    std::fs::write(
        &toml,
        "[render]\ndefault_light = false\n\n[[mesh]]\nfile = \"model.obj\"\n",
    )
    .unwrap();
    let loaded = raytracer::formats::load(&toml).unwrap();
    let (description, options) = loaded.resolve(PartialOptions::default()).unwrap();
    assert!(!options.default_light);
    assert!(description.lights.is_empty());
    // The warning names the file's key that turned the light off.
    assert_eq!(
        description.warnings,
        [format!(
            "the scene has no lights (no light sources, no emitting surfaces): full mode shows only its ambient colour (Ka) (the default light is off: {}:2: render.default_light)",
            toml.display()
        )]
    );
    // The flag's default (unset) does not override the file; the file's camera is
    // unset, so the scene is framed.
    assert!(options.look_from.z > 6.0, "{}", options.look_from);
}

#[test]
fn a_z_up_scene_is_framed_from_its_front_minus_y_and_above() {
    // Blender's convention: +z up, the front view looks from -y.
    let (min, max) = (Vec3::new(-1.0, -0.5, 0.0), Vec3::new(1.0, 0.5, 3.0));
    let flags = PartialOptions {
        up: Some(Sourced::new(Vec3::Z, Origin::Flag("--up"))),
        ..PartialOptions::default()
    };
    let options = flags.framed(Aabb { min, max }).resolve().unwrap();
    let back = (options.look_from - options.look_to).normalize();
    let elevation = back.z.asin().to_degrees();
    assert!((15.0..=30.0).contains(&elevation), "{back}");
    // In front (-y), turned to the right (+x).
    assert!(back.y < -0.5 && back.x > 0.2, "{back}");
    let (x, y) = fill(&options, &corners(min, max));
    assert!(x.max(y) >= 0.6, "{x} x {y}");
}

/// A mirror sphere of `base_color` 1, `metallic` 1, `roughness` 0 at the origin (and,
/// with `light`, the point light of the TOML line), seen from (0, 0, 4) in full
/// mode: the linear film, the lights the render had, and per pixel the unit
/// direction of its camera ray by SPEC's camera (focal length 1, pixel centres, row
/// 0 at the top), derived here from the options alone.
fn chrome_sphere(light: &str) -> (Vec<Vec3>, Vec<Light>, Vec<Option<Vec3>>) {
    use raytracer::{BvhParams, Scene, render};
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("chrome.toml");
    std::fs::write(
        &path,
        format!(
            "[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"chrome\"\n\n\
             [materials.chrome]\nbase_color = 1\nmetallic = 1\nroughness = 0\n\n{light}"
        ),
    )
    .unwrap();
    let options = RenderOptions {
        width: 48,
        height: 48,
        fov_degrees: 36.0,
        look_from: Vec3::new(0.0, 0.0, 4.0),
        look_to: Vec3::ZERO,
        ..RenderOptions::default()
    };
    let mut description = raytracer::formats::load(&path).unwrap().description;
    description.add_default_light(&options);
    let lights = description.lights.clone();
    let scene = Scene::build(description, &BvhParams::default());
    let film = render(&scene, &options);
    let half = (options.fov_degrees.to_radians() * 0.5).tan();
    let rays = (0..options.height)
        .flat_map(|row| (0..options.width).map(move |column| (column, row)))
        .map(|(column, row)| {
            let x = (2.0 * (column as f32 + 0.5) / options.width as f32 - 1.0) * half;
            let y = (1.0 - 2.0 * (row as f32 + 0.5) / options.height as f32) * half;
            Some(Vec3::new(x, y, -1.0).normalize())
        })
        .collect();
    (film.pixels, lights, rays)
}

/// Where a camera ray from (0, 0, 4) along `dir` meets the unit sphere at the origin
/// well inside its outline: the point (its normal).
fn on_unit_sphere(dir: Vec3) -> Option<Vec3> {
    let eye = Vec3::new(0.0, 0.0, 4.0);
    let b = eye.dot(dir);
    let disc = b * b - (eye.length_squared() - 1.0);
    let p = eye + (-b - disc.max(0.0).sqrt()) * dir;
    (disc > 0.0 && -dir.dot(p) > 0.2).then_some(p)
}

/// The pixels of the sphere well inside its outline and away from the highlights of
/// `lights` (Ns 10000: nothing beyond 3 degrees): each pixel's value, its point on
/// the sphere and its camera ray's mirror direction there.
fn off_highlights(
    pixels: &[Vec3],
    lights: &[Light],
    rays: &[Option<Vec3>],
) -> Vec<(Vec3, Vec3, Vec3)> {
    let cone = 3f32.to_radians().cos();
    (pixels.iter().zip(rays))
        .filter_map(|(pixel, dir)| {
            let dir = (*dir)?;
            let p = on_unit_sphere(dir)?;
            let mirrored = dir - 2.0 * dir.dot(p) * p;
            let near = (lights.iter()).any(|l| mirrored.dot((l.position - p).normalize()) > cone);
            (!near).then_some((*pixel, p, mirrored))
        })
        .collect()
}

#[test]
fn a_chrome_sphere_under_the_rig_mirrors_the_studio() {
    // A polished metal showed black in full mode but for the rig's two highlights:
    // the rig has no surroundings for it to mirror (a model viewer lights it with an
    // environment). Under the rig, physically based surfaces reflect path mode's
    // studio; a white mirror (f0 = 1) shows it as it is in the mirror direction,
    // clamped at full mode's white, 1.
    use raytracer::lights::environment::studio_radiance;
    let (pixels, lights, rays) = chrome_sphere("");
    assert_eq!(lights.len(), 2, "the rig's key and fill lights");
    let checked = off_highlights(&pixels, &lights, &rays);
    assert!(checked.len() > 400, "{} pixels checked", checked.len());
    for (pixel, p, mirrored) in &checked {
        let expected = studio_radiance(*mirrored, 0.0).min(1.0);
        assert!(
            (*pixel - Vec3::splat(expected)).abs().max_element() < 2e-3,
            "at {p}: {pixel} against the studio's {expected}"
        );
    }
    // Not a flat grey: the soft key light shows, and the dim dome around it.
    let on_sphere: Vec<f32> = (pixels.iter().zip(&rays))
        .filter(|(_, dir)| dir.and_then(on_unit_sphere).is_some())
        .map(|(pixel, _)| pixel.x)
        .collect();
    let brightest = on_sphere.iter().copied().fold(0.0, f32::max);
    let darkest = on_sphere.iter().copied().fold(1.0, f32::min);
    assert!(brightest > 0.9 && darkest < 0.3, "{darkest}..{brightest}");
}

#[test]
fn a_chrome_sphere_in_a_scene_with_lights_mirrors_only_the_scene() {
    // A scene with a light of its own keeps SPEC's shading (as the reference scenes
    // do): nothing around the sphere to mirror, so it is black but for the light's
    // highlight.
    let (pixels, lights, rays) = chrome_sphere("[[light]]\nposition = [3, 3, 3]\nintensity = 1\n");
    assert_eq!(lights.len(), 1);
    let checked = off_highlights(&pixels, &lights, &rays);
    assert!(checked.len() > 400, "{} pixels checked", checked.len());
    for (pixel, p, _) in &checked {
        assert!(pixel.max_element() < 1e-4, "at {p}: {pixel}");
    }
}
