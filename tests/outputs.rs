//! The extra outputs rendered with the colour (`render_outputs`: depth, normal,
//! albedo, alpha, object and material ids), `--aovs` as OpenEXR layers and
//! `--background transparent`, each against an answer worked out apart from the
//! renderer: the closed-form depth of a plane, the projected rectangles of two
//! meshes, the covered area of a square's edges.

use crate::support;

use std::fs;
use std::path::Path;

use raytracer::math::{Float, Vec3};
use raytracer::{Aov, BvhParams, Mode, RenderOptions, Scene, render, render_outputs};

/// An OBJ file of one quad with corners `corners` (counter-clockwise seen from the
/// camera) and material `material` of `Kd` `kd`, with a point light at the origin.
fn quad_obj(dir: &Path, name: &str, corners: [[Float; 3]; 4], kd: [Float; 3]) -> String {
    let mtl = format!("{name}.mtl");
    fs::write(
        dir.join(&mtl),
        format!("newmtl m_{name}\nKd {} {} {}\n", kd[0], kd[1], kd[2]),
    )
    .unwrap();
    let mut obj = format!("mtllib {mtl}\nusemtl m_{name}\n");
    for [x, y, z] in corners {
        obj += &format!("v {x} {y} {z}\n");
    }
    obj += "f 1 2 3 4\nP 0 0 0 1 1 1\n";
    let file = format!("{name}.obj");
    fs::write(dir.join(&file), obj).unwrap();
    file
}

/// A 2 x 2 quad facing the camera of [`run_cli`] 4 units away, lit by a point
/// light at the camera.
fn front_quad(dir: &Path, name: &str, kd: [Float; 3]) -> String {
    let corners = [
        [-1.0, -1.0, -4.0],
        [1.0, -1.0, -4.0],
        [1.0, 1.0, -4.0],
        [-1.0, 1.0, -4.0],
    ];
    quad_obj(dir, name, corners, kd)
}

/// [`front_quad`] without its point light: an unlit model.
fn unlit_quad_obj(dir: &Path, name: &str, kd: [Float; 3]) -> String {
    let file = front_quad(dir, name, kd);
    let path = dir.join(&file);
    let obj = fs::read_to_string(&path)
        .unwrap()
        .replace("P 0 0 0 1 1 1\n", "");
    fs::write(&path, obj).unwrap();
    file
}

/// `raytracer render` of `scene` into `out` at 20x20 from the origin down -z, with
/// `extra` flags; it must succeed.
fn run_cli(scene: &Path, out: &Path, extra: &[&str]) {
    let mut args = vec![
        "render",
        scene.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--width",
        "20",
        "--height",
        "20",
        "--look-from",
        "0,0,0",
        "--look-to",
        "0,0,-1",
    ];
    args.extend(extra);
    let run = support::raytracer(&args);
    assert!(run.status.success(), "{}", support::stderr(&run));
}

/// The colour type and the bytes of a PNG file, as stored.
fn read_png(path: &Path) -> (png::ColorType, Vec<u8>) {
    let decoder = png::Decoder::new(std::io::BufReader::new(fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut pixels = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut pixels).unwrap();
    (info.color_type, pixels)
}

/// A camera at the origin looking down -z with a vertical field of view of 60
/// degrees, `width` x `height` pixels.
fn options(width: u32, height: u32, samples_per_pixel: u32) -> RenderOptions {
    RenderOptions {
        width,
        height,
        look_from: Vec3::ZERO,
        look_to: Vec3::new(0.0, 0.0, -1.0),
        fov_degrees: 60.0,
        samples_per_pixel,
        ..RenderOptions::default()
    }
}

/// Where the centre of pixel (`column`, `row`) looks, as `(sx, sy)` on the plane at
/// distance 1 in front of the camera of [`options`]: the camera ray is along
/// `(sx, sy, -1)`.
fn screen(column: u32, row: u32, width: u32, height: u32) -> (f64, f64) {
    let half_height = (30f64).to_radians().tan();
    let half_width = half_height * width as f64 / height as f64;
    let sx = (2.0 * (column as f64 + 0.5) / width as f64 - 1.0) * half_width;
    let sy = (1.0 - 2.0 * (row as f64 + 0.5) / height as f64) * half_height;
    (sx, sy)
}

fn build(path: &Path) -> Scene {
    let loaded = raytracer::formats::load(path).unwrap();
    Scene::build(loaded.description, &BvhParams::default())
}

/// A tilted plane through (0, 0, -5) with normal `n`: the point seen along
/// `u = (sx, sy, -1)` is `s u` with `s = n.p0 / n.u`, and its z-depth (distance along
/// the view axis -z) is `s` itself.
#[test]
fn depth_of_a_tilted_plane_is_its_analytic_z_depth() {
    let dir = tempfile::tempdir().unwrap();
    let n = [0.3f64, -0.4, 1.0];
    let p0 = [0.0f64, 0.0, -5.0];
    // A large quad in the plane: z = -5 - (0.3 x - 0.4 y) / 1.
    let z = |x: f64, y: f64| p0[2] - (n[0] * x + n[1] * y) / n[2];
    let corners = [(-20.0, -20.0), (20.0, -20.0), (20.0, 20.0), (-20.0, 20.0)]
        .map(|(x, y)| [x as Float, y as Float, z(x, y) as Float]);
    let file = quad_obj(dir.path(), "plane", corners, [0.5, 0.5, 0.5]);
    let scene = build(&dir.path().join(file));
    let (width, height) = (24, 16);
    let outputs = render_outputs(&scene, &options(width, height, 1), &[Aov::Depth]);
    let depth = outputs.aovs.depth.unwrap();
    let n_dot_p0 = n[0] * p0[0] + n[1] * p0[1] + n[2] * p0[2];
    for row in 0..height {
        for column in 0..width {
            let (sx, sy) = screen(column, row, width, height);
            let expected = n_dot_p0 / (n[0] * sx + n[1] * sy - n[2]);
            let got = depth[(row * width + column) as usize] as f64;
            assert!(
                (got - expected).abs() <= 1e-5 * expected,
                "pixel ({column}, {row}): depth {got}, expected {expected}"
            );
        }
    }
    // The distance along the ray differs: not what `depth` holds.
    let corner = render(
        &scene,
        &RenderOptions {
            mode: Mode::Depth,
            ..options(width, height, 1)
        },
    );
    assert!(corner.pixels[0].x > depth[0] * 1.1);
}

/// Two quads facing the camera at different depths, from two files placed by a
/// scene file: each pixel whose centre ray falls inside one quad's rectangle (and
/// not behind the nearer one) holds that mesh's object and material id, every other
/// pixel -1; the object names are the files'.
#[test]
fn object_ids_of_two_meshes_cover_exactly_their_projected_rectangles() {
    let dir = tempfile::tempdir().unwrap();
    let mut toml = String::new();
    for (i, &(x0, x1, y0, y1, z)) in RECTS.iter().enumerate() {
        let corners = [[x0, y0], [x1, y0], [x1, y1], [x0, y1]]
            .map(|[x, y]| [x as Float, y as Float, z as Float]);
        let kd = [0.2 + 0.3 * i as Float, 0.5, 0.5];
        let file = quad_obj(dir.path(), &format!("quad{i}"), corners, kd);
        toml += &format!("[[mesh]]\nfile = \"{file}\"\n\n");
    }
    let scene_file = dir.path().join("two.toml");
    fs::write(&scene_file, toml).unwrap();
    let scene = build(&scene_file);
    assert_eq!(scene.object_names(), ["quad0.obj", "quad1.obj"]);
    let outputs = assert_ids_cover_rects(&scene, &RECTS, ["m_quad0", "m_quad1"]);
    // Albedo inside the first quad is its Kd.
    let albedo = outputs.aovs.albedo.as_ref().unwrap();
    let centre = (30 / 2 * 40 + 40 / 2 - 5) as usize;
    assert_eq!(outputs.aovs.object_id.as_ref().unwrap()[centre], 0);
    assert!(
        (albedo[centre] - Vec3::new(0.2, 0.5, 0.5))
            .abs()
            .max_element()
            < 1e-6
    );
}

/// (x0, x1, y0, y1, z) of the two quads of the object id tests, facing the camera of
/// [`options`].
const RECTS: [(f64, f64, f64, f64, f64); 2] =
    [(-1.3, 0.4, -0.9, 0.7, -3.0), (-0.2, 2.1, -1.6, 0.1, -4.0)];

/// Renders `scene` (the two quads of `rects`, objects 0 and 1 with materials
/// `material_names`) with object and material ids and albedo, and checks that each
/// pixel whose centre ray meets a quad (not behind the nearer one) holds its ids,
/// every other pixel -1.
fn assert_ids_cover_rects(
    scene: &Scene,
    rects: &[(f64, f64, f64, f64, f64); 2],
    material_names: [&str; 2],
) -> raytracer::Outputs {
    let (width, height) = (40, 30);
    let outputs = render_outputs(
        scene,
        &options(width, height, 4),
        &[Aov::ObjectId, Aov::MaterialId, Aov::Albedo],
    );
    let objects = outputs.aovs.object_id.as_ref().unwrap();
    let materials = outputs.aovs.material_id.as_ref().unwrap();
    let (mut counted, mut near_edges) = ([0; 3], 0);
    for row in 0..height {
        for column in 0..width {
            let (sx, sy) = screen(column, row, width, height);
            // Where the centre ray meets each quad's plane, and how far inside it is.
            let inside = |&(x0, x1, y0, y1, z): &(f64, f64, f64, f64, f64)| {
                let (x, y) = (-sx * z, -sy * z);
                (x - x0).min(x1 - x).min(y - y0).min(y1 - y)
            };
            let margins = rects.map(|r| inside(&r));
            if margins.iter().any(|m| m.abs() < 1e-4) {
                near_edges += 1;
                continue;
            }
            let expected = margins
                .iter()
                .position(|&m| m > 0.0)
                .map_or(-1, |i| i as i32);
            let i = (row * width + column) as usize;
            assert_eq!(objects[i], expected, "pixel ({column}, {row})");
            let name = scene
                .materials
                .get(materials[i].max(0) as usize)
                .map(|m| m.name.as_str());
            match expected {
                -1 => assert_eq!(materials[i], -1, "pixel ({column}, {row})"),
                k => assert_eq!(name, Some(material_names[k as usize]), "({column}, {row})"),
            }
            counted[(expected + 1) as usize] += 1;
        }
    }
    assert!(near_edges < 5, "{near_edges} pixel centres on an edge");
    assert!(
        counted.iter().all(|&c| c > 50),
        "{counted:?}: every case seen"
    );
    outputs
}

/// A square whose edges cut pixels at known fractions: alpha is 1 inside, 0 outside
/// and, over the whole image, sums to the square's projected area in pixels (64
/// stratified samples a pixel: each edge pixel within 1/8 of its covered fraction).
/// The colour is the same film as without outputs.
#[test]
fn alpha_is_the_covered_fraction_of_each_pixel() {
    let dir = tempfile::tempdir().unwrap();
    let (width, height) = (32, 32);
    // At distance 1 the image spans 2 tan(30) vertically; a square from pixel 7.3 to
    // 23.6 horizontally and 5.8 to 20.25 vertically.
    let half = (30f64).to_radians().tan();
    let to_x = |px: f64| (2.0 * px / width as f64 - 1.0) * half;
    let to_y = |py: f64| (1.0 - 2.0 * py / height as f64) * half;
    let (left, right, top, bottom) = (7.3, 23.6, 5.8, 20.25);
    let z = 2.0;
    let corners = [
        [to_x(left), to_y(bottom)],
        [to_x(right), to_y(bottom)],
        [to_x(right), to_y(top)],
        [to_x(left), to_y(top)],
    ]
    .map(|[x, y]| [(x * z) as Float, (y * z) as Float, -z as Float]);
    let file = quad_obj(dir.path(), "square", corners, [0.8, 0.8, 0.8]);
    let scene = build(&dir.path().join(file));
    let options = options(width, height, 64);
    let outputs = render_outputs(&scene, &options, &[Aov::Alpha, Aov::Normal]);
    let alpha = outputs.aovs.alpha.unwrap();
    let covered = |a: f64, b: f64, p: u32| (b.min(p as f64 + 1.0) - a.max(p as f64)).max(0.0);
    let mut sum = 0.0;
    for row in 0..height {
        for column in 0..width {
            let expected = covered(left, right, column) * covered(top, bottom, row);
            let got = alpha[(row * width + column) as usize] as f64;
            sum += got;
            if expected == 0.0 || expected == 1.0 {
                assert_eq!(got, expected, "pixel ({column}, {row})");
            } else {
                assert!(
                    (got - expected).abs() <= 0.125,
                    "({column}, {row}): {got} {expected}"
                );
            }
        }
    }
    let area = (right - left) * (bottom - top);
    assert!(
        (sum - area).abs() < 0.01 * area,
        "alpha sums to {sum}, area {area}"
    );
    // The normal faces the camera, weighted by coverage.
    let normal = outputs.aovs.normal.unwrap();
    let i = (12 * width + 12) as usize;
    assert!((normal[i] - Vec3::Z).length() < 1e-5, "{}", normal[i]);
    assert_eq!(
        outputs.film,
        render(&scene, &options),
        "the colour is unchanged"
    );
}

#[test]
fn a_transparent_background_writes_rgba_png_with_alpha_zero_on_misses() {
    let dir = tempfile::tempdir().unwrap();
    let file = front_quad(dir.path(), "q", [0.9, 0.1, 0.1]);
    let scene = dir.path().join(file);
    for mode in ["full", "path"] {
        let out = dir.path().join(format!("{mode}.png"));
        let flags = ["--mode", mode, "--spp", "4", "--background", "transparent"];
        run_cli(&scene, &out, &flags);
        let (colour, pixels) = read_png(&out);
        assert_eq!(colour, png::ColorType::Rgba, "{mode}");
        let at = |x: usize, y: usize| &pixels[(y * 20 + x) * 4..][..4];
        assert_eq!(at(0, 0)[3], 0, "{mode}: a miss is transparent");
        assert_eq!(at(19, 19)[3], 0, "{mode}");
        assert_eq!(at(10, 10)[3], 255, "{mode}: a hit is opaque");
        assert!(at(10, 10)[0] > at(10, 10)[1], "{mode}: red where it hit");
    }
}

#[test]
fn aovs_are_layers_of_one_exr_file_with_their_names() {
    let dir = tempfile::tempdir().unwrap();
    let file = front_quad(dir.path(), "q", [0.9, 0.1, 0.1]);
    let scene = dir.path().join(file);
    let out = dir.path().join("out.exr");
    let aovs = "depth,normal,albedo,alpha,object_id,material_id";
    run_cli(
        &scene,
        &out,
        &["--aovs", aovs, "--background", "transparent"],
    );
    let image = exr::prelude::read_all_flat_layers_from_file(&out).unwrap();
    let layers: Vec<(String, Vec<String>)> = image
        .layer_data
        .iter()
        .map(|layer| {
            let name = layer
                .attributes
                .layer_name
                .as_ref()
                .map_or(String::new(), |n| n.to_string());
            let channels = layer
                .channel_data
                .list
                .iter()
                .map(|c| c.name.to_string())
                .collect();
            (name, channels)
        })
        .collect();
    let expected: Vec<(String, Vec<String>)> = [
        ("color", &["A", "B", "G", "R"][..]),
        ("depth", &["Z"]),
        ("normal", &["X", "Y", "Z"]),
        ("albedo", &["B", "G", "R"]),
        ("alpha", &["A"]),
        ("object_id", &["id"]),
        ("material_id", &["id"]),
    ]
    .iter()
    .map(|(n, c)| (n.to_string(), c.iter().map(|s| s.to_string()).collect()))
    .collect();
    assert_eq!(layers, expected);
    let samples = |layer: usize, channel: usize| match &image.layer_data[layer].channel_data.list
        [channel]
        .sample_data
    {
        exr::prelude::FlatSamples::F32(v) => v.clone(),
        other => panic!("{other:?}"),
    };
    let (corner, centre) = (0, 10 * 20 + 10);
    let depth = samples(1, 0);
    assert_eq!(depth[corner], f32::INFINITY);
    assert!((depth[centre] - 4.0).abs() < 1e-5, "{}", depth[centre]);
    let object = samples(5, 0);
    assert_eq!((object[corner], object[centre]), (-1.0, 0.0));
    let alpha = samples(0, 0);
    assert_eq!((alpha[corner], alpha[centre]), (0.0, 1.0));
}

#[test]
fn bad_aov_names_and_non_exr_outputs_are_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let scene = support::cornell_box();
    let out = dir.path().join("out.exr");
    let run = |aovs: &str, out: &Path| {
        support::raytracer(&[
            "render",
            scene.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--width",
            "8",
            "--height",
            "8",
            "--aovs",
            aovs,
        ])
    };
    for (aovs, named) in [
        ("depth,colour", "'colour'"),
        ("depth,depth", "'depth' is named twice"),
    ] {
        let outcome = run(aovs, &out);
        assert_eq!(outcome.status.code(), Some(2), "{aovs}");
        let message = support::stderr(&outcome);
        assert!(
            message.contains(named) && message.contains("object_id"),
            "{message}"
        );
    }
    let png = dir.path().join("out.png");
    let outcome = run("depth", &png);
    assert_eq!(outcome.status.code(), Some(2));
    assert!(
        support::stderr(&outcome).contains(".exr"),
        "{}",
        support::stderr(&outcome)
    );
    assert!(!png.exists() && !out.exists());
}

/// [`run_cli`] at 4 samples per pixel, with `extra` flags: the PNG's bytes, as RGBA.
fn render_png(scene: &Path, out: &Path, extra: &[&str]) -> Vec<u8> {
    run_cli(scene, out, &[&["--spp", "4"], extra].concat());
    let (colour, pixels) = read_png(out);
    match colour {
        png::ColorType::Rgba => pixels,
        _ => pixels
            .chunks(3)
            .flat_map(|p| [p[0], p[1], p[2], 255])
            .collect(),
    }
}

/// Full mode's default light rig shows the studio's grey backdrop where camera rays
/// miss, composited after SPEC's tone map: a black model stands out, and its
/// pixels are those it has without a backdrop (a transparent render's colour). A
/// scene with a light of its own keeps black misses.
#[test]
fn an_unlit_model_in_full_mode_stands_out_against_a_grey_backdrop() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir
        .path()
        .join(unlit_quad_obj(dir.path(), "black", [0.0, 0.0, 0.0]));
    let out = dir.path().join("out.png");
    let grey = raytracer::postprocess::default_backdrop();
    assert!(grey.iter().all(|&c| (60..200).contains(&c)), "{grey:?}");
    let backdrop = render_png(&scene, &out, &[]);
    let transparent = render_png(&scene, &out, &["--background", "transparent"]);
    let at = |pixels: &[u8], x: usize, y: usize| -> [u8; 4] {
        pixels[(y * 20 + x) * 4..][..4].try_into().unwrap()
    };
    assert_eq!(at(&backdrop, 0, 0), [grey[0], grey[1], grey[2], 255]);
    assert_eq!(at(&backdrop, 10, 10), [0, 0, 0, 255], "the model is black");
    let (mut covered, mut edges) = (0, 0);
    for y in 0..20 {
        for x in 0..20 {
            let (b, t) = (at(&backdrop, x, y), at(&transparent, x, y));
            match t[3] {
                255 => {
                    assert_eq!(b, t, "({x}, {y}): the model's pixels are its own");
                    covered += 1;
                }
                0 => assert_eq!(b, [grey[0], grey[1], grey[2], 255], "({x}, {y})"),
                _ => edges += 1,
            }
        }
    }
    assert!(
        covered > 10 && edges > 4,
        "{covered} covered, {edges} on edges"
    );
    // With a light of its own, the scene is SPEC's: misses stay black.
    let lit = dir
        .path()
        .join(front_quad(dir.path(), "lit", [0.0, 0.0, 0.0]));
    assert_eq!(at(&render_png(&lit, &out, &[]), 0, 0), [0, 0, 0, 255]);
}

/// Two instances of one unit quad, placed where the two quads of
/// [`object_ids_of_two_meshes_cover_exactly_their_projected_rectangles`] are: each
/// copy is an object of its own, numbered as the instances are listed.
#[test]
fn object_ids_of_two_instances_cover_exactly_their_projected_rectangles() {
    let dir = tempfile::tempdir().unwrap();
    let unit = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ];
    let file = quad_obj(dir.path(), "unit", unit, [0.5, 0.5, 0.5]);
    let mut toml = format!("[[mesh]]\nfile = \"{file}\"\nid = \"quad\"\n\n");
    for &(x0, x1, y0, y1, z) in &RECTS {
        toml += &format!(
            "[[instance]]\nmesh = \"quad\"\nmatrix = [{}, 0, 0, {x0}, 0, {}, 0, {y0}, 0, 0, 1, {z}, 0, 0, 0, 1]\n\n",
            x1 - x0,
            y1 - y0
        );
    }
    let scene_file = dir.path().join("instances.toml");
    fs::write(&scene_file, toml).unwrap();
    let scene = build(&scene_file);
    assert_eq!(scene.instance_count(), 2);
    assert_eq!(
        scene.object_names(),
        ["instance 0 of mesh 0", "instance 1 of mesh 0"]
    );
    assert_ids_cover_rects(&scene, &RECTS, ["m_unit", "m_unit"]);
}
