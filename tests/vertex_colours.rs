//! Vertex colours (glTF `COLOR_0`, PLY `red green blue`, OBJ `v x y z r g b`): the
//! albedo at a pixel is the barycentric mix of the corners' colours where the pixel's
//! ray meets the triangle (closed form), times the material's colour; full and path
//! mode render a uniformly coloured mesh exactly as the same mesh whose material has
//! that colour; instanced coloured meshes render as their flattened copies.

use crate::support;

use std::fmt::Write as _;
use std::fs;
use std::path::Path;

use raytracer::math::Vec3;
use raytracer::{Aov, BvhParams, Mode, RenderOptions, Scene, formats, render, render_outputs};

const WIDTH: u32 = 24;
const HEIGHT: u32 = 20;

/// A camera 2 above (0.4, 0.4, 0) looking down -z, up +y, 60 degrees.
fn options(mode: Mode) -> RenderOptions {
    RenderOptions {
        width: WIDTH,
        height: HEIGHT,
        look_from: Vec3::new(0.4, 0.4, 2.0),
        look_to: Vec3::new(0.4, 0.4, 0.0),
        up: Vec3::Y,
        fov_degrees: 60.0,
        mode,
        samples_per_pixel: 1,
        ..RenderOptions::default()
    }
}

/// Where the centre ray of pixel (`column`, `row`) meets the plane z = 0.
fn on_plane(column: u32, row: u32) -> (f64, f64) {
    let half_height = 30f64.to_radians().tan();
    let half_width = half_height * f64::from(WIDTH) / f64::from(HEIGHT);
    let sx = (2.0 * (f64::from(column) + 0.5) / f64::from(WIDTH) - 1.0) * half_width;
    let sy = (1.0 - 2.0 * (f64::from(row) + 0.5) / f64::from(HEIGHT)) * half_height;
    (0.4 + 2.0 * sx, 0.4 + 2.0 * sy)
}

fn albedo_of(path: &Path) -> Vec<Vec3> {
    let loaded = formats::load(path).unwrap();
    let scene = Scene::build(loaded.description, &BvhParams::default());
    let outputs = render_outputs(&scene, &options(Mode::Full), &[Aov::Albedo]);
    outputs.aovs.albedo.unwrap()
}

/// Checks that the albedo of the triangle (0, 0, 0), (1, 0, 0), (0, 1, 0) coloured
/// red, green, blue is `factor` times the barycentric mix at every pixel whose centre
/// ray meets it (away from its edges), and zero where it misses.
fn assert_barycentric(path: &Path, factor: f32) {
    let albedo = albedo_of(path);
    let mut inside = 0;
    for row in 0..HEIGHT {
        for column in 0..WIDTH {
            let (x, y) = on_plane(column, row);
            let weights = [1.0 - x - y, x, y];
            let got = albedo[(row * WIDTH + column) as usize];
            if weights.iter().any(|w| w.abs() < 1e-3) {
                continue;
            }
            let want = match weights.iter().all(|&w| w > 0.0) {
                true => Vec3::new(weights[0] as f32, weights[1] as f32, weights[2] as f32) * factor,
                false => Vec3::ZERO,
            };
            inside += usize::from(want != Vec3::ZERO);
            assert!(
                (got - want).abs().max_element() < 1e-4,
                "{}: pixel ({column}, {row}): {got} vs {want}",
                path.display()
            );
        }
    }
    assert!(inside > 20, "only {inside} pixels on the triangle");
}

const CORNERS: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];

#[test]
fn albedo_is_the_barycentric_mix_of_the_corner_colours_in_every_format() {
    let dir = tempfile::tempdir().unwrap();
    let dir = dir.path();
    // PLY, ASCII with 8-bit colours (and an alpha channel, read past).
    let mut ply = String::from(
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
         property uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\n\
         element face 1\nproperty list uchar int vertex_indices\nend_header\n",
    );
    for (k, [x, y, z]) in CORNERS.iter().enumerate() {
        let rgb = [0, 1, 2].map(|c| if c == k { 255 } else { 0 });
        writeln!(ply, "{x} {y} {z} {} {} {} 128", rgb[0], rgb[1], rgb[2]).unwrap();
    }
    ply.push_str("3 0 1 2\n");
    fs::write(dir.join("t.ply"), &ply).unwrap();
    assert_barycentric(&dir.join("t.ply"), 0.8);

    // PLY, binary with 16-bit colours.
    let mut binary = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n\
         property float y\nproperty float z\nproperty ushort red\nproperty ushort green\n\
         property ushort blue\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
        .as_bytes()
        .to_vec();
    for (k, corner) in CORNERS.iter().enumerate() {
        corner.iter().for_each(|v| binary.extend(v.to_le_bytes()));
        for c in 0..3 {
            binary.extend(if c == k { 65535u16 } else { 0 }.to_le_bytes());
        }
    }
    binary.push(3);
    for i in 0i32..3 {
        binary.extend(i.to_le_bytes());
    }
    fs::write(dir.join("b.ply"), &binary).unwrap();
    assert_barycentric(&dir.join("b.ply"), 0.8);

    // OBJ with Blender's and MeshLab's `v x y z r g b`, and a material.
    fs::write(dir.join("t.mtl"), "newmtl m\nKd 0.5 0.5 0.5\n").unwrap();
    fs::write(
        dir.join("t.obj"),
        "mtllib t.mtl\nusemtl m\nv 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nf 1 2 3\n",
    )
    .unwrap();
    assert_barycentric(&dir.join("t.obj"), 0.5);

    // glTF COLOR_0 (floats), without a material: the renderer's grey.
    assert_barycentric(&support::vertex_coloured_gltf(dir, false), 0.8);
}

#[test]
fn full_and_path_modes_multiply_the_diffuse_colour_by_the_vertex_colour() {
    // A quad over a floor, lit by a point light: coloured (0.9, 0.3, 0.1) at every
    // corner on a white material against a plain material of that colour. Same
    // images in both modes; a colour of (1, 1, 1) changes nothing.
    let dir = tempfile::tempdir().unwrap();
    let dir = dir.path();
    let scene = |colour: &str, kd: &str| {
        format!(
            "mtllib m.mtl\nP 0.4 0.6 1.5 2 2 2\nusemtl floor\n\
             v -3 -3 -0.5\nv 3 -3 -0.5\nv 3 3 -0.5\nv -3 3 -0.5\nf 1 2 3 4\nusemtl {kd}\n\
             v -0.3 -0.3 0{colour}\nv 1.2 -0.3 0{colour}\nv 1.2 1.2 0.2{colour}\nv -0.3 1.2 0.2{colour}\n\
             f 5 6 7 8\n"
        )
    };
    fs::write(
        dir.join("m.mtl"),
        "newmtl floor\nKd 0.6 0.6 0.6\nnewmtl white\nKd 1 1 1\nKs 0.2 0.2 0.2\nNs 10\n\
         newmtl orange\nKd 0.9 0.3 0.1\nKs 0.2 0.2 0.2\nNs 10\n\
         newmtl gold\nKd 1 1 1\nPr 0.4\nPm 0.3\n",
    )
    .unwrap();
    let cases = [
        (" 0.9 0.3 0.1", "white", "", "orange"),
        (" 1 1 1", "orange", "", "orange"),
    ];
    let build = |text: String, name: &str| {
        let path = dir.join(name);
        fs::write(&path, text).unwrap();
        Scene::build(formats::load_obj(&path).unwrap(), &BvhParams::default())
    };
    for (colour, kd, plain_colour, plain_kd) in cases {
        let coloured = build(scene(colour, kd), "c.obj");
        let plain = build(scene(plain_colour, plain_kd), "p.obj");
        for mode in [Mode::Full, Mode::Path] {
            let options = RenderOptions {
                samples_per_pixel: if mode == Mode::Path { 4 } else { 1 },
                depth: 4,
                ..options(mode)
            };
            let (a, b) = (render(&coloured, &options), render(&plain, &options));
            for (a, b) in a.pixels.iter().zip(&b.pixels) {
                let close = (*a - *b).abs().max_element() <= 1e-5 * b.max_element().max(1.0);
                assert!(close, "{colour} on {kd}, {mode:?}: {a} vs {b}");
            }
            assert!(
                a.pixels.iter().any(|p| p.x > 2.0 * p.y),
                "{mode:?}: no orange"
            );
        }
    }
    // A physically based material (MTL's Pr/Pm): the colour multiplies its base
    // colour, against the white one's render, which must differ.
    let coloured = build(scene(" 0.9 0.3 0.1", "gold"), "c.obj");
    let white = build(scene("", "gold"), "p.obj");
    let options = RenderOptions {
        samples_per_pixel: 4,
        ..options(Mode::Path)
    };
    assert!(render(&coloured, &options).pixels != render(&white, &options).pixels);
}

#[test]
fn instanced_coloured_meshes_render_as_their_flattened_copies() {
    let dir = tempfile::tempdir().unwrap();
    let path = support::vertex_coloured_gltf(dir.path(), false);
    // The triangle's mesh used by two nodes, the second moved and turned over.
    let gltf = fs::read_to_string(&path).unwrap().replace(
        r#""scenes": [{"nodes": [0]}],
  "nodes": [{"mesh": 0}],"#,
        r#""scenes": [{"nodes": [0, 1]}],
  "nodes": [{"mesh": 0}, {"mesh": 0, "translation": [0.9, 0.8, 0.1], "scale": [-1, -0.5, 1]}],"#,
    );
    fs::write(&path, gltf).unwrap();
    let instanced = formats::load(&path).unwrap().description;
    assert_eq!(instanced.instances.len(), 2, "the mesh is not instanced");
    let mut flat = instanced.clone();
    flat.flatten_instances().unwrap();
    let albedo = |description| {
        let scene = Scene::build(description, &BvhParams::default());
        render_outputs(&scene, &options(Mode::Full), &[Aov::Albedo])
            .aovs
            .albedo
            .unwrap()
    };
    let (a, b) = (albedo(instanced), albedo(flat));
    let coloured = b.iter().filter(|c| c.x != c.y || c.y != c.z).count();
    assert!(coloured > 40, "{coloured} coloured pixels");
    let differ = a
        .iter()
        .zip(&b)
        .filter(|(a, b)| (**a - **b).abs().max_element() > 1e-5)
        .count();
    assert_eq!(differ, 0);
}
