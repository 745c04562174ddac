//! Helpers shared by the integration tests.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

/// Runs the `raytracer` binary with `args`, to its end.
pub fn raytracer(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_raytracer"))
        .args(args)
        .output()
        .unwrap()
}

/// What a finished run printed on stderr.
pub fn stderr(output: &std::process::Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

/// The folder of the copied reference suite.
pub fn reference_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/reference")
}

/// Writes an 8-bit PNG of `channels` channels (1 grey, 2 grey + alpha, 3 RGB,
/// 4 RGBA), rows top to bottom.
pub fn write_png(path: &Path, width: u32, height: u32, channels: u32, texels: &[u8]) {
    assert_eq!(texels.len(), (width * height * channels) as usize);
    let file = std::fs::File::create(path).unwrap();
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), width, height);
    encoder.set_color(match channels {
        1 => png::ColorType::Grayscale,
        2 => png::ColorType::GrayscaleAlpha,
        3 => png::ColorType::Rgb,
        _ => png::ColorType::Rgba,
    });
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().unwrap();
    writer.write_image_data(texels).unwrap();
}

/// Decodes a PNG into (width, height, RGB bytes), dropping alpha if present.
pub fn read_png(path: &Path) -> (u32, u32, Vec<u8>) {
    let file = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut decoder = png::Decoder::new(std::io::BufReader::new(file));
    decoder.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    let channels = info.color_type.samples();
    let rgb = buf[..info.buffer_size()]
        .chunks(channels)
        .flat_map(|px| match channels {
            1 | 2 => [px[0], px[0], px[0]],
            _ => [px[0], px[1], px[2]],
        })
        .collect();
    (info.width, info.height, rgb)
}

/// Decodes an OpenEXR file's first layer into (width, height, channels by name), every
/// sample as `f32`, row by row from the top.
pub fn read_exr(path: &Path) -> (usize, usize, std::collections::BTreeMap<String, Vec<f32>>) {
    let image = exr::prelude::read_first_flat_layer_from_file(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let layer = image.layer_data;
    let channels = layer
        .channel_data
        .list
        .iter()
        .map(|channel| {
            let name = channel.name.to_string();
            let values = match &channel.sample_data {
                exr::prelude::FlatSamples::F32(values) => values.clone(),
                other => panic!("{}: channel {name} is not f32: {other:?}", path.display()),
            };
            (name, values)
        })
        .collect();
    (layer.size.width(), layer.size.height(), channels)
}

/// The bundled Cornell box with the camera of the README's first command.
pub fn cornell_box() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/cornell-box/scene.obj")
}

/// [`cornell_box`], built.
pub fn cornell_scene() -> raytracer::Scene {
    let description = raytracer::formats::load_obj(&cornell_box()).unwrap();
    raytracer::Scene::build(description, &raytracer::BvhParams::default())
}

/// Options of the README's camera on [`cornell_box`], validated.
pub fn cornell_options(
    width: u32,
    height: u32,
    mode: raytracer::Mode,
    samples_per_pixel: u32,
) -> raytracer::RenderOptions {
    let options = raytracer::RenderOptions {
        width,
        height,
        fov_degrees: 60.0,
        look_from: raytracer::math::Vec3::new(0.0, 0.7, 1.75),
        look_to: raytracer::math::Vec3::new(0.0, 0.7, 0.0),
        mode,
        samples_per_pixel,
        ..raytracer::RenderOptions::default()
    };
    options.validate().unwrap();
    options
}

/// The README's camera for [`cornell_box`], as command-line flags.
pub const CORNELL_CAMERA: [&str; 6] = [
    "--fov",
    "60",
    "--look-from",
    "0,0.7,1.75",
    "--look-to",
    "0,0.7,0",
];

/// One case of `tests/data/reference/cases.toml`.
#[derive(serde::Deserialize)]
pub struct ReferenceCase {
    pub name: String,
    pub scene: String,
    pub expected: String,
    pub width: u32,
    pub height: u32,
    pub fov_degrees: f32,
    pub look_from: [f32; 3],
    pub look_to: [f32; 3],
    pub depth: u32,
    pub mode: String,
}

/// All cases of the copied reference suite, in file order.
pub fn reference_cases() -> Vec<ReferenceCase> {
    #[derive(serde::Deserialize)]
    struct Cases {
        case: Vec<ReferenceCase>,
    }
    let text = std::fs::read_to_string(reference_dir().join("cases.toml")).unwrap();
    toml::from_str::<Cases>(&text).unwrap().case
}

/// A glTF file of one triangle (0, 0, 0), (1, 0, 0), (0, 1, 0) facing +z with
/// `COLOR_0` red, green, blue (as floats), in `dir`; no material, or one with the
/// fixtures' checker as its base colour texture.
pub fn vertex_coloured_gltf(dir: &Path, textured: bool) -> PathBuf {
    let mut bin = Vec::new();
    let floats: [f32; 18] = [
        0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, // positions
        1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, // colours
    ];
    for f in floats {
        bin.extend(f.to_le_bytes());
    }
    std::fs::write(dir.join("t.bin"), &bin).unwrap();
    let gltf = r#"{
  "asset": {"version": "2.0"},
  "scene": 0,
  "scenes": [{"nodes": [0]}],
  "nodes": [{"mesh": 0}],
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "COLOR_0": 1}}]}],
  "buffers": [{"uri": "t.bin", "byteLength": 72}],
  "bufferViews": [
    {"buffer": 0, "byteOffset": 0, "byteLength": 36},
    {"buffer": 0, "byteOffset": 36, "byteLength": 36}
  ],
  "accessors": [
    {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
    {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC3"}
  ]
}"#;
    let gltf = if textured {
        std::fs::copy(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/gltf/checker.png"),
            dir.join("checker.png"),
        )
        .unwrap();
        gltf.replace(r#""COLOR_0": 1}}"#, r#""COLOR_0": 1}, "material": 0}"#)
            .replace(
                r#""buffers""#,
                r#""materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
  "textures": [{"source": 0}],
  "images": [{"uri": "checker.png"}],
  "buffers""#,
            )
    } else {
        gltf.to_string()
    };
    let path = dir.join("t.gltf");
    std::fs::write(&path, gltf).unwrap();
    path
}

/// Renders `scene` with `flags` into `out` and returns its RGB bytes.
pub fn render(scene: &Path, out: &Path, flags: &[&str]) -> Vec<u8> {
    let mut args = vec![
        "render",
        scene.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "-q",
    ];
    args.extend(flags);
    let output = raytracer(&args);
    assert!(output.status.success(), "{}", stderr(&output));
    read_png(out).2
}

/// Pixels that differ, and by how much at most (over channels, in 8-bit steps).
pub fn differences(a: &[u8], b: &[u8]) -> (usize, u8) {
    differences_over(a, b, 0)
}

/// Pixels that differ by more than `levels` (over channels, in 8-bit steps), and by
/// how much the most different one does.
pub fn differences_over(a: &[u8], b: &[u8], levels: u8) -> (usize, u8) {
    assert_eq!(a.len(), b.len());
    let mut count = 0;
    let mut most = 0;
    for (p, q) in a.chunks(3).zip(b.chunks(3)) {
        let d = p
            .iter()
            .zip(q)
            .map(|(x, y)| x.abs_diff(*y))
            .max()
            .unwrap_or(0);
        if d > levels {
            count += 1;
        }
        most = most.max(d);
    }
    (count, most)
}

/// Checks a GGX distribution against a table of Mitsuba 3's `roughconductor` (a
/// perfect conductor, so `f = D G1(wo) G1(wi) / (4 |n.wo| |n.wi|)`) at fixed pairs of
/// directions, `tests/data/materials/NAME` as a `make_mitsuba*.py` script writes it:
/// each `[[pair]]`'s distribution made by `distribution`, its `D` with Mitsuba's
/// separable Smith term swapped in for glTF's height-correlated one, within 1e-4
/// relative. Returns how many pairs it checked.
pub fn check_against_mitsuba_table<
    D: raytracer::bxdfs::microfacet::Distribution + std::fmt::Debug,
>(
    name: &str,
    distribution: impl Fn(&toml::Table) -> D,
) -> usize {
    use raytracer::math::{Float, Vec3};
    let path = format!("{}/tests/data/materials/{name}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let table: toml::Table = text.parse().unwrap();
    let pairs = table["pair"].as_array().unwrap();
    let vector = |value: &toml::Value| {
        let v: Vec<f64> = (value.as_array().unwrap().iter())
            .map(|x| x.as_float().unwrap())
            .collect();
        Vec3::new(v[0] as Float, v[1] as Float, v[2] as Float)
    };
    for pair in pairs {
        let ggx = distribution(pair.as_table().unwrap());
        let (wi, wo) = (vector(&pair["wi"]), vector(&pair["wo"]));
        let expected = pair["f"].as_float().unwrap() as Float;
        let h = (wi + wo).normalize();
        let ours = ggx.d(h) * ggx.separable_visibility(wo, wi);
        assert!(
            (ours - expected).abs() <= 1e-4 * expected.max(1e-3),
            "{ggx:?}, wi {wi}, wo {wo}: ours {ours}, Mitsuba {expected}"
        );
    }
    pairs.len()
}

/// `integral f(l) cos(l) dl` over the hemisphere above z seen from the unit direction
/// `v`, by a midpoint quadrature over half vectors `h` (`dl = 4 |v.h| dh`), dense
/// where a microfacet distribution peaks: `theta_h = (pi / 2) s^power` for `s` in
/// `n_s` steps, `phi_h` in `n_phi` steps round the circle, or round half of it
/// (counted twice) where `f` is symmetric about the plane of `v` and z. `f(l, h,
/// v.h)` is the BRDF's value for each colour channel.
pub fn half_vector_albedo(
    v: [f64; 3],
    (n_s, n_phi): (usize, usize),
    power: i32,
    half_circle: bool,
    mut f: impl FnMut([f64; 3], [f64; 3], f64) -> [f64; 3],
) -> [f64; 3] {
    use std::f64::consts::PI;
    let circle = if half_circle { PI } else { 2.0 * PI };
    let mut sum = [0.0; 3];
    for i in 0..n_s {
        let s = (i as f64 + 0.5) / n_s as f64;
        let theta = PI / 2.0 * s.powi(power);
        let d_theta = PI / 2.0 * f64::from(power) * s.powi(power - 1) / n_s as f64;
        for j in 0..n_phi {
            let phi = circle * (j as f64 + 0.5) / n_phi as f64;
            let h = [
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            ];
            let v_h = v[0] * h[0] + v[1] * h[1] + v[2] * h[2];
            let l = [
                2.0 * v_h * h[0] - v[0],
                2.0 * v_h * h[1] - v[1],
                2.0 * v_h * h[2] - v[2],
            ];
            if v_h <= 0.0 || l[2] <= 0.0 {
                continue;
            }
            let value = f(l, h, v_h);
            let measure = l[2] * 4.0 * v_h * theta.sin() * d_theta * (2.0 * PI / n_phi as f64);
            for c in 0..3 {
                sum[c] += value[c] * measure;
            }
        }
    }
    sum
}

/// An octahedron of "radius" 1 as OBJ text, whose vertex normals point out from its
/// centre as a coarse sphere's do.
pub fn smooth_octahedron_obj() -> String {
    let mut obj = String::from("v 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\n");
    obj += "vn 1 0 0\nvn -1 0 0\nvn 0 1 0\nvn 0 -1 0\nvn 0 0 1\nvn 0 0 -1\n";
    for (x, y, z) in [
        (1, 3, 5),
        (1, 6, 3),
        (1, 5, 4),
        (1, 4, 6),
        (2, 5, 3),
        (2, 3, 6),
        (2, 4, 5),
        (2, 6, 4),
    ] {
        obj += &format!("f {x}//{x} {y}//{y} {z}//{z}\n");
    }
    obj
}
