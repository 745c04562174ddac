//! Scene files end to end: compressed inputs, TOML transforms against pre-transformed
//! OBJ files, flag-over-file precedence through the binary (a flag replaces a bad
//! value, one dimension keeps the aspect ratio), `raytracer info`, and the bundled
//! TOML scenes.

use crate::support;

use support::raytracer;

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};

use raytracer::formats::{self, LoadedScene};
use raytracer::math::{Ray, Vec3};
use raytracer::{BvhParams, Image, Mode, RenderOptions, Scene, render};

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(path)
}

fn write(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
    let path = dir.join(name);
    fs::create_dir_all(path.parent().unwrap()).unwrap();
    fs::write(&path, bytes).unwrap();
    path
}

fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    encoder.write_all(bytes).unwrap();
    encoder.finish().unwrap()
}

fn load(path: &Path) -> LoadedScene {
    formats::load(path).unwrap_or_else(|e| panic!("{e}"))
}

fn render_image(loaded: LoadedScene, options: &RenderOptions) -> Image {
    let scene = Scene::build(loaded.description, &BvhParams::default());
    render(&scene, options).to_image(options.mode)
}

const TRIANGLE_OBJ: &str = "mtllib tri.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\n";
const TRIANGLE_MTL: &str = "newmtl red\nKd 1 0 0\n";
const TRIANGLE_PLY: &str = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";

#[test]
fn compressed_obj_mtl_and_ply_read_like_plain_ones() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "tri.mtl", TRIANGLE_MTL);
    let plain = load(&write(d, "tri.obj", TRIANGLE_OBJ)).description;
    // `.obj.gz` with the plain `.mtl` beside it, and a compressed `.mtl.gz` when named.
    let gz = load(&write(d, "a.obj.gz", gzip(TRIANGLE_OBJ.as_bytes()))).description;
    write(d, "c.mtl.gz", gzip(TRIANGLE_MTL.as_bytes()));
    let obj = TRIANGLE_OBJ.replace("tri.mtl", "c.mtl.gz");
    let both = load(&write(d, "b.obj.gz", gzip(obj.as_bytes()))).description;
    // Found by the magic bytes whatever the name.
    let magic = load(&write(d, "disguised.obj", gzip(TRIANGLE_OBJ.as_bytes()))).description;
    for other in [&gz, &both, &magic] {
        assert_eq!(other.positions, plain.positions);
        assert_eq!(other.triangles, plain.triangles);
        assert_eq!(other.materials, plain.materials);
    }
    assert_eq!(plain.materials[0].diffuse, Vec3::X);

    let ply = load(&write(d, "tri.ply", TRIANGLE_PLY)).description;
    let ply_gz = load(&write(d, "tri.PLY.GZ", gzip(TRIANGLE_PLY.as_bytes()))).description;
    assert_eq!(ply.positions, plain.positions);
    assert_eq!(ply_gz.triangles, ply.triangles);

    let corrupt = gzip(TRIANGLE_PLY.as_bytes());
    let path = write(d, "cut.ply.gz", &corrupt[..corrupt.len() / 2]);
    let err = formats::load(&path).unwrap_err().to_string();
    assert!(err.starts_with(&format!("{}: ", path.display())), "{err}");
    let path = write(d, "fake.ply.gz", TRIANGLE_PLY);
    let err = formats::load(&path).unwrap_err().to_string();
    assert_eq!(err, format!("{}: invalid gzip header", path.display()));
}

/// Rotation by `degrees` about x, written out rather than taken from glam.
fn rotate_x(v: Vec3, degrees: f32) -> Vec3 {
    let (s, c) = degrees.to_radians().sin_cos();
    Vec3::new(v.x, c * v.y - s * v.z, s * v.y + c * v.z)
}

fn rotate_z(v: Vec3, degrees: f32) -> Vec3 {
    let (s, c) = degrees.to_radians().sin_cos();
    Vec3::new(c * v.x - s * v.y, s * v.x + c * v.y, v.z)
}

/// A square pyramid with one `vn` per face, written as OBJ after mapping points
/// with `point` and normals with `normal`.
fn pyramid_obj(point: impl Fn(Vec3) -> Vec3, normal: impl Fn(Vec3) -> Vec3) -> String {
    let corners = [
        Vec3::new(-1.0, 0.0, -1.0),
        Vec3::new(1.0, 0.0, -1.0),
        Vec3::new(1.0, 0.0, 1.0),
        Vec3::new(-1.0, 0.0, 1.0),
    ];
    let apex = Vec3::new(0.0, 1.5, 0.0);
    let mut faces = vec![
        [corners[0], corners[1], corners[2]],
        [corners[0], corners[2], corners[3]],
    ];
    for i in 0..4 {
        faces.push([corners[(i + 1) % 4], corners[i], apex]);
    }
    let mut obj = String::new();
    for (f, [a, b, c]) in faces.iter().enumerate() {
        let n = normal((*b - *a).cross(*c - *a));
        for p in [a, b, c].map(|&p| point(p)) {
            obj += &format!("v {} {} {}\n", p.x, p.y, p.z);
        }
        obj += &format!("vn {} {} {}\n", n.x, n.y, n.z);
        let v = 3 * f + 1;
        obj += &format!("f {}//{n} {}//{n} {}//{n}\n", v, v + 1, v + 2, n = f + 1);
    }
    obj
}

#[test]
fn a_transformed_mesh_renders_like_the_mesh_transformed_beforehand() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (scale, rotate, translate) = (
        Vec3::new(2.0, 0.5, 1.0),
        Vec3::new(30.0, 0.0, 45.0),
        Vec3::new(0.5, -1.0, -6.0),
    );
    write(d, "pyramid.obj", pyramid_obj(|p| p, |n| n));
    let toml = "[[mesh]]\nfile = \"pyramid.obj\"\ntransform = { scale = [2, 0.5, 1], rotate = [30, 0, 45], translate = [0.5, -1, -6] }\n";
    let moved = load(&write(d, "moved.toml", toml));
    // By hand: scale, then x, then z, then translate; normals by the inverse
    // transpose, which for R S is R S^-1.
    let by_hand = pyramid_obj(
        |p| rotate_z(rotate_x(p * scale, rotate.x), rotate.z) + translate,
        |n| rotate_z(rotate_x(n / scale, rotate.x), rotate.z),
    );
    let expected = load(&write(d, "expected.obj", by_hand));

    let options = RenderOptions {
        width: 96,
        height: 72,
        fov_degrees: 50.0,
        look_from: Vec3::new(1.0, 2.0, 0.0),
        look_to: translate,
        mode: Mode::Normal,
        ..RenderOptions::default()
    };
    let got = render_image(moved.clone(), &options);
    let want = render_image(expected.clone(), &options);
    let differing = got
        .rgb
        .chunks(3)
        .zip(want.rgb.chunks(3))
        .filter(|(a, b)| a.iter().zip(b.iter()).any(|(x, y)| x.abs_diff(*y) > 1))
        .count();
    // Edge pixels may flip between two faces under rounding; the pyramid covers
    // about a third of the image.
    let covered = want.rgb.chunks(3).filter(|p| p != &[0, 0, 0]).count();
    assert!(
        covered > 96 * 72 / 10,
        "the pyramid is in view ({covered} pixels)"
    );
    assert!(differing <= 8, "{differing} pixels differ");

    let (a, b) = (
        Scene::build(moved.description, &BvhParams::default()),
        Scene::build(expected.description, &BvhParams::default()),
    );
    let mut hits = 0;
    for i in 0..40 {
        for j in 0..40 {
            let target = translate + Vec3::new(i as f32 / 13.0 - 1.5, j as f32 / 13.0 - 1.5, 0.3);
            let ray = Ray::new(options.look_from, target - options.look_from);
            match (a.intersect(&ray), b.intersect(&ray)) {
                (Some(x), Some(y)) => {
                    hits += 1;
                    assert!((x.t - y.t).abs() < 1e-4, "t {} vs {}", x.t, y.t);
                    assert!((x.ns - y.ns).length() < 1e-4, "ns {} vs {}", x.ns, y.ns);
                }
                (None, None) => {}
                // A ray grazing an edge may hit one copy only.
                _ => {}
            }
        }
    }
    assert!(hits > 400, "{hits} hits");
}

#[test]
fn flags_override_the_file_and_the_file_overrides_defaults() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "tri.obj", TRIANGLE_OBJ);
    write(d, "tri.mtl", TRIANGLE_MTL);
    let toml = "[camera]\nlook_from = [0.3, 0.3, 2]\nlook_to = [0.3, 0.3, 0]\nwidth = 24\nheight = 16\n[render]\nmode = \"depth\"\n[[mesh]]\nfile = \"tri.obj\"\n";
    let scene = write(d, "s.toml", toml);
    let out = d.join("out.png");
    let run = |extra: &[&str]| {
        let mut args = vec![
            "render",
            scene.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ];
        args.extend(extra);
        let output = raytracer(&args);
        assert!(
            output.status.success(),
            "{}",
            String::from_utf8_lossy(&output.stderr)
        );
        support::read_png(&out)
    };
    let file_only = run(&[]);
    assert_eq!((file_only.0, file_only.1), (24, 16));
    let options = |mode| RenderOptions {
        width: 24,
        height: 16,
        look_from: Vec3::new(0.3, 0.3, 2.0),
        look_to: Vec3::new(0.3, 0.3, 0.0),
        mode,
        ..RenderOptions::default()
    };
    let library = |mode| render_image(load(&scene), &options(mode)).rgb;
    assert_eq!(
        file_only.2,
        library(Mode::Depth),
        "the file's mode and camera are used"
    );
    assert_eq!(
        run(&["--mode", "normal"]).2,
        library(Mode::Normal),
        "--mode wins over the file"
    );
    let narrow = run(&["--width", "12", "--height", "16"]);
    assert_eq!((narrow.0, narrow.1), (12, 16), "--width and --height win");

    // Values neither the file nor the flags set keep their defaults: a bare OBJ
    // renders at 640x480.
    let obj = d.join("tri.obj");
    let output = raytracer(&["render", obj.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert!(output.status.success());
    assert_eq!(support::read_png(&out).0, 640);
}

/// `raytracer render SCENE -o DIR/out.png EXTRA...`: the exit code, stderr and, on
/// success, the image's size.
fn render_size(scene: &Path, extra: &[&str]) -> (Option<i32>, String, Option<(u32, u32)>) {
    let out = scene.with_file_name("out.png");
    let _ = fs::remove_file(&out);
    let mut args = vec![
        "render",
        scene.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ];
    args.extend(extra);
    let output = raytracer(&args);
    let size = output.status.success().then(|| {
        let (w, h, _) = support::read_png(&out);
        (w, h)
    });
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    (output.status.code(), stderr, size)
}

#[test]
fn a_valid_flag_replaces_a_bad_value_of_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "tri.obj", TRIANGLE_OBJ);
    write(d, "tri.mtl", TRIANGLE_MTL);
    let toml = "[camera]\nwidth = 65536\nheight = 65536\nfov = 180\n[render]\ndepth = 0\n[[mesh]]\nfile = \"tri.obj\"\n";
    let scene = write(d, "huge.toml", toml);
    let s = scene.display();
    // Alone, the file is refused at its first bad value, by file, line and key.
    assert_eq!(
        render_size(&scene, &[]),
        (
            Some(2),
            format!(
                "error: {s}:2: camera.width: 65536x65536 has more than 268435456 pixels (with {s}:3: camera.height)\n"
            ),
            None
        )
    );
    assert_eq!(
        render_size(&scene, &["--width", "64", "--height", "48"]).1,
        format!("error: {s}:4: camera.fov: 180 is not strictly between 0 and 180\n")
    );
    assert_eq!(
        render_size(&scene, &["--width", "64", "--height", "48", "--fov", "60"]).1,
        format!("error: {s}:6: render.depth: 0 is not in 1..=64\n")
    );
    let flags = [
        "--width", "64", "--height", "48", "--fov", "60", "--depth", "2",
    ];
    let (code, stderr, size) = render_size(&scene, &flags);
    assert_eq!((code, size), (Some(0), Some((64, 48))), "{stderr}");
    // A bad flag is named as a flag, whatever the file says.
    assert_eq!(
        render_size(&scene, &["--width", "64", "--height", "0"]).1,
        "error: invalid --height: 0 is not in 1..=65536\n"
    );
    // The same value from a flag and from the file: the flag is named, then the file.
    let camera = write(d, "camera.toml", "[camera]\n\nlook_to = [1, 2, 3]\n");
    assert_eq!(
        render_size(&camera, &["--look-from", "1,2,3"]).1,
        format!(
            "error: invalid --look-from: the camera cannot look at its own position (with {}:3: camera.look_to)\n",
            camera.display()
        )
    );
    // `info` has no flags to replace the file's values.
    let output = raytracer(&["info", scene.to_str().unwrap()]);
    assert_eq!(output.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&output.stderr)
            .starts_with(&format!("error: {s}:2: camera.width:")),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
}

#[test]
fn a_width_or_height_alone_keeps_the_aspect_ratio() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let obj = write(d, "tri.obj", TRIANGLE_OBJ);
    write(d, "tri.mtl", TRIANGLE_MTL);
    let mesh = "[[mesh]]\nfile = \"tri.obj\"\n";
    let vga = write(
        d,
        "vga.toml",
        format!("[camera]\nwidth = 640\nheight = 480\n{mesh}"),
    );
    let size = |scene: &Path, extra: &[&str]| {
        let (code, stderr, size) = render_size(scene, extra);
        assert_eq!(code, Some(0), "{extra:?}: {stderr}");
        size.unwrap()
    };
    assert_eq!(size(&vga, &["--width", "320"]), (320, 240));
    assert_eq!(size(&vga, &["--height", "100"]), (133, 100));
    assert_eq!(size(&obj, &["--height", "240"]), (320, 240));
    assert_eq!(size(&obj, &["--width", "320"]), (320, 240));
    let tall = write(
        d,
        "tall.toml",
        format!("[camera]\nwidth = 30\nheight = 90\n{mesh}"),
    );
    assert_eq!(size(&tall, &["--width", "20"]), (20, 60));
    // The file's size need not be valid: it gives only the ratio.
    let huge = write(
        d,
        "huge.toml",
        format!("[camera]\nwidth = 65536\nheight = 65536\n{mesh}"),
    );
    assert_eq!(size(&huge, &["--width", "64"]), (64, 64));
    // A file that sets only one dimension has the other at the default ratio.
    let wide = write(d, "wide.toml", format!("[camera]\nwidth = 400\n{mesh}"));
    assert_eq!(size(&wide, &[]), (400, 300));
    assert_eq!(size(&wide, &["--height", "30"]), (40, 30));
    // A computed dimension out of range names the flag that was given.
    assert_eq!(
        render_size(&obj, &["--height", "65536"]).1,
        "error: invalid --height: keeping the aspect ratio makes the width 87381, which is not in 1..=65536; set the width too\n"
    );
}

#[test]
fn bad_scene_files_exit_2_naming_file_line_and_key() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(
        dir.path(),
        "s.toml",
        "[camera]\nwidth = 10\n\n[[mesh]]\nfile = \"gone.ply\"\n",
    );
    let out = dir.path().join("out.png");
    let output = raytracer(&[
        "render",
        scene.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(output.status.code(), Some(2));
    let gone = dir.path().join("gone.ply");
    assert_eq!(
        String::from_utf8_lossy(&output.stderr),
        format!(
            "error: {}:5: mesh.file: {}: No such file or directory (os error 2)\n",
            scene.display(),
            gone.display()
        )
    );
    assert!(!out.exists());
    // A flag out of range is still named as a flag.
    let scene = write(dir.path(), "ok.toml", "");
    let output = raytracer(&[
        "render",
        scene.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--up",
        "0,0,0",
    ]);
    assert_eq!(output.status.code(), Some(2));
    assert_eq!(
        String::from_utf8_lossy(&output.stderr),
        "error: invalid --up: components must be finite and not all zero\n"
    );
}

#[test]
fn info_counts_bounds_materials_memory_and_warnings() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "tri.ply", TRIANGLE_PLY);
    let toml = "[camera]\nwidth = 100\nheight = 50\n[[mesh]]\nfile = \"tri.ply\"\nmaterial = \"red\"\n[[mesh]]\nfile = \"flat.obj\"\n[[sphere]]\ncenter = [0, 0, 5]\nradius = 1\nmaterial = \"red\"\n[materials.red]\nKd = [1, 0, 0]\n[materials.unused]\n";
    write(d, "flat.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\nl 1 2\n");
    let scene = write(d, "s.toml", toml);
    let output = raytracer(&["info", scene.to_str().unwrap()]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let text = String::from_utf8(output.stdout).unwrap();
    let expected_lines = [
        "vertices   6",
        "triangles  2 (1 degenerate)",
        "spheres    1",
        "lights     0",
        "materials  3",
        "  red                      1 triangles, 1 spheres",
        "  unused                   0 triangles, 0 spheres",
        "  default                  0 triangles, 0 spheres",
        "bounds     min (-1.0000, -1.0000, 0.0000) max (1.0000, 1.0000, 6.0000) size (2.0000, 2.0000, 6.0000)",
        // Two unused materials: one line, with a count.
        "warning: material 'unused' is not used (and 1 more like it)",
        "warning: 1 degenerate (zero-area) triangle will be skipped",
        "warning: no lights (no light sources, no emitting surfaces): render adds a default light rig at the camera (a studio environment in path mode) unless --no-default-light",
    ];
    for line in expected_lines {
        assert!(
            text.lines().any(|l| l == line),
            "missing {line:?} in:\n{text}"
        );
    }
    assert!(text.contains("film 0.1 MiB"), "{text}");
    assert!(
        text.lines().any(|l| l.starts_with("warning: ")
            && l.ends_with(
                "flat.obj:5: skipped 1 line element ('l'): lines have no area to render"
            )),
        "{text}"
    );
}

#[test]
fn the_bundled_toml_example_is_the_readme_command() {
    let toml = load(&repo("examples/cornell-box/scene.toml"));
    let readme = RenderOptions {
        fov_degrees: 60.0,
        look_from: Vec3::new(0.0, 0.7, 1.75),
        look_to: Vec3::new(0.0, 0.7, 0.0),
        ..RenderOptions::default()
    };
    assert_eq!(toml.options.resolve(), Ok(readme));
    let small = |o: RenderOptions| RenderOptions {
        width: 160,
        height: 120,
        ..o
    };
    let obj = load(&repo("examples/cornell-box/scene.obj"));
    assert_eq!(
        render_image(toml, &small(readme)),
        render_image(obj, &small(readme))
    );
}

#[test]
fn the_dragon_bench_scene_matches_the_bench_readme() {
    // The real dragon is not in the repository: stand a small PLY in for it.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let toml = write(
        d,
        "dragon.toml",
        fs::read(repo("bench/dragon.toml")).unwrap(),
    );
    write(d, "floor.obj", fs::read(repo("bench/floor.obj")).unwrap());
    write(
        d,
        "work/package/models/dragon_vrip.ply.gz",
        gzip(TRIANGLE_PLY.as_bytes()),
    );
    let loaded = load(&toml);
    let o = loaded.options.resolve().unwrap();
    assert_eq!(
        (o.width, o.height, o.fov_degrees, o.depth, o.mode),
        (1024, 768, 45.0, 8, Mode::Full)
    );
    assert_eq!(o.look_from, Vec3::new(0.09, 0.21, 0.27));
    assert_eq!(o.look_to, Vec3::new(-0.005, 0.12, -0.005));

    let d = loaded.description;
    let [dragon, floor] = &d.materials[..] else {
        panic!("{:?}", d.materials)
    };
    assert_eq!(
        (dragon.name.as_str(), floor.name.as_str()),
        ("dragon", "floor")
    );
    assert_eq!(dragon.ambient, Vec3::splat(0.01));
    assert_eq!(dragon.diffuse, Vec3::new(0.8, 0.2, 0.2));
    assert_eq!(dragon.specular, Vec3::splat(0.3));
    assert_eq!(dragon.shininess, 64.0);
    assert_eq!(
        (
            floor.ambient,
            floor.diffuse,
            floor.specular,
            floor.shininess
        ),
        (Vec3::splat(0.01), Vec3::splat(0.6), Vec3::ZERO, 1.0)
    );
    let lights: Vec<(Vec3, Vec3)> = d.lights.iter().map(|l| (l.position, l.intensity)).collect();
    assert_eq!(
        lights,
        [
            (Vec3::new(0.5, 0.9, 0.6), Vec3::ONE),
            (Vec3::new(-0.6, 0.5, 0.5), Vec3::splat(0.3))
        ]
    );
    // The stand-in's triangle, untransformed, then the floor facing +y.
    assert_eq!(d.triangles.len(), 3);
    assert_eq!(d.triangles[0].material.0, 0);
    for t in &d.triangles[1..] {
        let [a, b, c] = t.positions.map(|i| d.positions[i as usize]);
        assert_eq!(t.material.0, 1);
        assert!((b - a).cross(c - a).normalize().abs_diff_eq(Vec3::Y, 1e-6));
        assert!(
            [a, b, c]
                .iter()
                .all(|p| p.y == 0.0525 && p.x.abs() == 1.0 || p.z.abs() == 1.0)
        );
    }
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
}

#[test]
fn the_documented_complete_example_loads() {
    let doc = fs::read_to_string(repo("docs/scene-format.md")).unwrap();
    let example = doc.split("### A complete example").nth(1).unwrap();
    let toml = example
        .split("```toml\n")
        .nth(1)
        .unwrap()
        .split("```")
        .next()
        .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(
        d,
        "work/package/models/dragon_vrip.ply.gz",
        gzip(TRIANGLE_PLY.as_bytes()),
    );
    write(d, "floor.obj", fs::read(repo("bench/floor.obj")).unwrap());
    let loaded = load(&write(d, "dragon.toml", toml));
    assert_eq!(loaded.options.up.map(|up| up.value), Some(Vec3::Y));
    let d = loaded.description;
    let names: Vec<&str> = d.materials.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(names, ["dragon", "floor", "mirror"]);
    assert_eq!(d.spheres[0].material.0, 2);
    assert_eq!(d.materials[2].albedo, [0.2, 0.8, 0.0]);
    assert_eq!(d.lights[1].intensity, Vec3::splat(0.3));
    assert_eq!(d.triangles.len(), 3);
}
