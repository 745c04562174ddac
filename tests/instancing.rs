//! Instancing (issue 39): a scene that places meshes through `[[instance]]` and
//! `[[instances]]` renders the image of the same scene flattened (every copy written
//! out through `[[mesh]]` transforms, the one-level path), in full and path mode, with
//! vertex normals, a texture, emitters (path mode's area lights sampled on the
//! placed copies), non-uniform and mirroring scales; and bad placements are errors
//! naming the file and entry.

use crate::support;

use std::fmt::Write as _;
use std::fs;
use std::path::Path;

use support::{differences, raytracer, render, stderr, write_png};

/// A UV sphere of `rings` x `segments` quads split into triangles, with unit vertex
/// normals and texture coordinates, in material `skin`; and a lamp quad facing -y,
/// material `glow`.
fn write_meshes(dir: &Path) {
    let (rings, segments) = (6, 10);
    let mut obj = String::from("mtllib m.mtl\nusemtl skin\n");
    for r in 0..=rings {
        for s in 0..=segments {
            let theta = std::f32::consts::PI * r as f32 / rings as f32;
            let phi = 2.0 * std::f32::consts::PI * s as f32 / segments as f32;
            let (x, y, z) = (
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            );
            // Slightly squashed, so its normals are not its positions.
            writeln!(obj, "v {x} {} {z}\nvn {x} {y} {z}", 0.8 * y).unwrap();
            let (u, v) = (s as f32 / segments as f32, r as f32 / rings as f32);
            writeln!(obj, "vt {u} {v}").unwrap();
        }
    }
    let at = |r: usize, s: usize| r * (segments + 1) + s + 1;
    for r in 0..rings {
        for s in 0..segments {
            let (a, b, c, d) = (at(r, s), at(r, s + 1), at(r + 1, s + 1), at(r + 1, s));
            writeln!(obj, "f {a}/{a}/{a} {b}/{b}/{b} {c}/{c}/{c}").unwrap();
            writeln!(obj, "f {a}/{a}/{a} {c}/{c}/{c} {d}/{d}/{d}").unwrap();
        }
    }
    fs::write(dir.join("ball.obj"), obj).unwrap();
    fs::write(
        dir.join("m.mtl"),
        "newmtl skin\nKa 0.05 0.05 0.05\nKd 1 1 1\nKs 0.4 0.4 0.4\nNs 20\nmap_Kd checker.png\n\
         newmtl glow\nKd 0 0 0\nKe 6 5 4\n",
    )
    .unwrap();
    let texels: Vec<u8> = (0..16)
        .flat_map(|i| {
            if (i % 4 + i / 4) % 2 == 0 {
                [230, 40, 30]
            } else {
                [30, 60, 220]
            }
        })
        .collect();
    write_png(&dir.join("checker.png"), 4, 4, 3, &texels);
    fs::write(
        dir.join("lamp.obj"),
        "mtllib m.mtl\nusemtl glow\nv -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nf 1 2 3\nf 1 3 4\n",
    )
    .unwrap();
    fs::write(
        dir.join("floor.obj"),
        "v -6 -1 -6\nv 6 -1 -6\nv 6 -1 6\nv -6 -1 6\nf 1 3 2\nf 1 4 3\n",
    )
    .unwrap();
}

/// Placements of the ball: uniform, non-uniform, mirroring (with a turn), and one
/// from the `.npy` file; then the lamp, once as it is and once mirrored upside down
/// (a mirror in y keeps it facing down, its winding turned).
const BALLS: [&str; 3] = [
    "{ translate = [-2.2, 0, 0] }",
    "{ translate = [0, 0.2, -0.5], scale = [1.4, 0.7, 1], rotate = [0, 30, 10] }",
    "{ translate = [2.2, 0, 0], scale = [-1, 1, 1], rotate = [0, 60, 0] }",
];
const LAMPS: [&str; 2] = [
    "{ translate = [-1.5, 3, 1] , scale = 0.6 }",
    "{ translate = [1.5, 3.2, 0], scale = [0.5, -1, 0.5], rotate = [0, 20, 0] }",
];
/// The `.npy` ball: row-major world from object, a shear included (no TOML
/// transform has one) to check matrices in the file are read row by row.
const NPY_BALL: [f64; 16] = [
    0.6, 0.2, 0.0, 0.0, //
    0.0, 0.6, 0.0, -0.3, //
    0.0, 0.0, 0.6, 1.8, //
    0.0, 0.0, 0.0, 1.0,
];

/// A `.npy` file of float64 matrices.
fn write_npy(path: &Path, matrices: &[[f64; 16]]) {
    let shape = format!("({}, 4, 4)", matrices.len());
    fs::write(path, npy_bytes("<f8", &shape, matrices)).unwrap();
}

/// The bytes of a `.npy` file whose header says `descr` and `shape`, followed by
/// `matrices` as float64 values whatever the header says.
fn npy_bytes(descr: &str, shape: &str, matrices: &[[f64; 16]]) -> Vec<u8> {
    let mut header = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
    while !(10 + header.len() + 1).is_multiple_of(64) {
        header.push(' ');
    }
    header.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend((header.len() as u16).to_le_bytes());
    bytes.extend(header.as_bytes());
    for m in matrices {
        for v in m {
            bytes.extend(v.to_le_bytes());
        }
    }
    bytes
}

const HEAD: &str = "[camera]\nlook_from = [0, 2.5, 7]\nlook_to = [0, 0.3, 0]\nfov = 50\n\
    [[light]]\nposition = [3, 6, 5]\nintensity = [1, 1, 1]\n\
    [[mesh]]\nfile = \"floor.obj\"\n";

fn instanced_toml() -> String {
    let mut toml = format!(
        "{HEAD}[[mesh]]\nfile = \"ball.obj\"\nid = \"ball\"\n[[mesh]]\nfile = \"lamp.obj\"\nid = \"lamp\"\n"
    );
    for t in BALLS {
        writeln!(toml, "[[instance]]\nmesh = \"ball\"\ntransform = {t}").unwrap();
    }
    toml += "[[instances]]\nmesh = \"ball\"\nfile = \"ball.npy\"\n";
    for t in LAMPS {
        writeln!(toml, "[[instance]]\nmesh = \"lamp\"\ntransform = {t}").unwrap();
    }
    toml
}

/// The same scene with every copy written out (the `.npy` ball as the same matrix
/// through `matrix`'s flattened equivalent: a TOML transform cannot shear, so the
/// flattened scene places it with an OBJ of its corners moved here).
fn flattened_toml(dir: &Path) -> String {
    let mut toml = HEAD.to_string();
    for t in BALLS {
        writeln!(toml, "[[mesh]]\nfile = \"ball.obj\"\ntransform = {t}").unwrap();
    }
    // The sheared ball, its positions and normals moved here in f64.
    let m = NPY_BALL;
    let ball = fs::read_to_string(dir.join("ball.obj")).unwrap();
    // Inverse transpose of the linear part [[a, b, 0], [0, d, 0], [0, 0, e]].
    let (a, b, d, e) = (m[0], m[1], m[5], m[10]);
    let moved: String = ball
        .lines()
        .map(|line| {
            let mut words = line.split(' ');
            let kind = words.next().unwrap_or("");
            let v: Vec<f64> = words.filter_map(|w| w.parse().ok()).collect();
            match kind {
                "v" => format!(
                    "v {} {} {}\n",
                    a * v[0] + b * v[1] + m[3],
                    d * v[1] + m[7],
                    e * v[2] + m[11]
                ),
                "vn" => format!(
                    "vn {} {} {}\n",
                    v[0] / a,
                    -b / (a * d) * v[0] + v[1] / d,
                    v[2] / e
                ),
                _ => format!("{line}\n"),
            }
        })
        .collect();
    fs::write(dir.join("sheared.obj"), moved).unwrap();
    toml += "[[mesh]]\nfile = \"sheared.obj\"\n";
    for t in LAMPS {
        writeln!(toml, "[[mesh]]\nfile = \"lamp.obj\"\ntransform = {t}").unwrap();
    }
    toml
}

fn scenes() -> (tempfile::TempDir, std::path::PathBuf, std::path::PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_meshes(d);
    write_npy(&d.join("ball.npy"), &[NPY_BALL]);
    let instanced = d.join("instanced.toml");
    fs::write(&instanced, instanced_toml()).unwrap();
    let flat = d.join("flat.toml");
    fs::write(&flat, flattened_toml(d)).unwrap();
    (dir, instanced, flat)
}

/// At most 0.1% of pixels may differ, by at most 2/255: the rounding of the
/// placement (the flattened corners are moved in the reader, the instanced rays in
/// the scene), nothing more.
fn assert_same_image(a: &[u8], b: &[u8], what: &str) {
    let (count, most) = differences(a, b);
    let pixels = a.len() / 3;
    eprintln!("{what}: {count} of {pixels} pixels differ, by at most {most}");
    assert!(
        count * 1000 <= pixels && most <= 2 || count == 0,
        "{what}: {count} of {pixels} pixels differ, by at most {most}"
    );
}

#[test]
fn instanced_scene_renders_as_its_flattened_self_in_full_mode() {
    let (dir, instanced, flat) = scenes();
    let flags = ["--width", "160", "--height", "120"];
    let a = render(&instanced, &dir.path().join("a.png"), &flags);
    let b = render(&flat, &dir.path().join("b.png"), &flags);
    assert_same_image(&a, &b, "full");
    // Not trivially equal: the balls are in the picture (a scene without its
    // instances differs in many pixels).
    let bare = dir.path().join("bare.toml");
    fs::write(&bare, HEAD).unwrap();
    let c = render(&bare, &dir.path().join("c.png"), &flags);
    assert!(differences(&a, &c).0 > 1000);
}

#[test]
fn instanced_scene_renders_as_its_flattened_self_in_path_mode() {
    let (dir, instanced, flat) = scenes();
    let flags = [
        "--width", "128", "--height", "96", "--mode", "path", "--spp", "8", "--depth", "3",
    ];
    let a = render(&instanced, &dir.path().join("a.png"), &flags);
    let b = render(&flat, &dir.path().join("b.png"), &flags);
    assert_same_image(&a, &b, "path");
}

#[test]
fn normals_are_placed_with_the_inverse_transpose() {
    let (dir, instanced, flat) = scenes();
    let flags = ["--width", "96", "--height", "72", "--mode", "normal"];
    let a = render(&instanced, &dir.path().join("a.png"), &flags);
    let b = render(&flat, &dir.path().join("b.png"), &flags);
    assert_same_image(&a, &b, "normal");
}

/// The error loading `toml` (beside the meshes of [`write_meshes`]), with the
/// folder's path replaced by `DIR`.
fn load_error(dir: &Path, toml: &str) -> String {
    let path = dir.join("bad.toml");
    fs::write(&path, toml).unwrap();
    match raytracer::formats::load(&path) {
        Ok(_) => panic!("{toml}: loaded"),
        Err(e) => e.to_string().replace(&dir.display().to_string(), "DIR"),
    }
}

#[test]
fn bad_placements_are_errors_naming_file_line_and_entry() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_meshes(d);
    fs::write(d.join("ball.obj.txt"), "").unwrap();
    let mesh = "[[mesh]]\nfile = \"ball.obj\"\nid = \"ball\"\n";
    let cases: Vec<(String, &str)> = vec![
        (
            format!("{mesh}[[instance]]\nmesh = \"cube\"\n"),
            "DIR/bad.toml:5: instance.mesh: unknown mesh 'cube' (no [[mesh]] has this id)",
        ),
        (
            format!(
                "{mesh}[[instance]]\nmesh = \"ball\"\nmatrix = [1,0,0,0, 0,1,0,0, 0,2,0,0, 0,0,0,1]\n"
            ),
            "DIR/bad.toml:6: instance.matrix: singular matrix (determinant 0): it flattens the mesh",
        ),
        (
            format!(
                "{mesh}[[instance]]\nmesh = \"ball\"\nmatrix = [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,1,1]\n"
            ),
            "DIR/bad.toml:6: instance.matrix: the last row is 0 0 1 1, not 0 0 0 1 (an affine placement)",
        ),
        (
            format!(
                "{mesh}[[instance]]\nmesh = \"ball\"\nmatrix = [1,0,0,0, 0,1,0,0, 0,0,1e300,0, 0,0,0,1]\n"
            ),
            "DIR/bad.toml:6: instance.matrix: non-finite value 1e300 in the matrix",
        ),
        (
            format!("{mesh}[[instance]]\nmesh = \"ball\"\nmatrix = [1,0,0,0]\n"),
            "DIR/bad.toml:6: instance.matrix: 4 numbers: a matrix is 16 numbers, row-major world from object",
        ),
        (
            format!(
                "{mesh}[[instance]]\nmesh = \"ball\"\ntransform = {{ scale = 2 }}\nmatrix = [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]\n"
            ),
            "DIR/bad.toml:7: instance.matrix: give either transform or matrix, not both",
        ),
        (
            format!("{mesh}[[instance]]\nmesh = \"ball\"\ntransform = {{ scale = [1, 0, 1] }}\n"),
            "DIR/bad.toml:6: instance.transform.scale: scale components must not be zero",
        ),
        (
            "[[mesh]]\nfile = \"ball.obj\"\nid = \"ball\"\ntransform = { scale = 2 }\n".into(),
            "DIR/bad.toml:3: mesh.transform: a mesh with an id is placed by its instances: give the transform to each [[instance]]",
        ),
        (
            format!("{mesh}[[mesh]]\nfile = \"lamp.obj\"\nid = \"ball\"\n"),
            "DIR/bad.toml:6: mesh.id: mesh id 'ball' is given twice",
        ),
        (
            format!("{mesh}[[instances]]\nmesh = \"ball\"\nfile = \"missing.npy\"\n"),
            "DIR/bad.toml:6: instances.file: DIR/missing.npy: No such file or directory (os error 2)",
        ),
    ];
    for (toml, expected) in cases {
        assert_eq!(load_error(d, &toml), expected, "for {toml}");
    }
    // A `.npy` file: its wrong shape, size, dtype or matrix, named with the line of
    // the TOML that names it.
    let npy_case = |bytes: Vec<u8>| {
        fs::write(d.join("p.npy"), bytes).unwrap();
        load_error(
            d,
            &format!("{mesh}[[instances]]\nmesh = \"ball\"\nfile = \"p.npy\"\n"),
        )
    };
    write_npy(&d.join("good.npy"), &[NPY_BALL, NPY_BALL]);
    let good = fs::read(d.join("good.npy")).unwrap();
    assert_eq!(
        npy_case(good[..good.len() - 8].to_vec()),
        "DIR/bad.toml:6: instances.file: DIR/p.npy:1: shape (2, 4, 4) of 8-byte values needs 256 bytes of data, the file has 248"
    );
    assert!(
        npy_case(npy_bytes("<f2", "(2, 4, 4)", &[NPY_BALL, NPY_BALL])).contains(
            "DIR/p.npy:1: dtype '<f2': the matrices must be little-endian float32 ('<f4') or float64 ('<f8')"
        )
    );
    let mut singular = NPY_BALL;
    singular[10] = 0.0;
    write_npy(&d.join("p2.npy"), &[NPY_BALL, singular]);
    assert_eq!(
        npy_case(fs::read(d.join("p2.npy")).unwrap()),
        "DIR/bad.toml:6: instances.file: DIR/p.npy: matrix 1: singular matrix (determinant 0): it flattens the mesh"
    );
    assert!(
        npy_case(npy_bytes("<f8", "(4, 4)", &[]))
            .contains("shape (4, 4): the placements must be an (N, 4, 4) array")
    );
}

#[test]
fn info_counts_unique_and_instanced_triangles() {
    let (dir, instanced, _) = scenes();
    let output = raytracer(&["info", instanced.to_str().unwrap()]);
    assert!(output.status.success(), "{}", stderr(&output));
    let text = String::from_utf8_lossy(&output.stdout);
    // Floor 2, ball 120, lamp 2 stored once; four balls and two lamps placed.
    // The ball's top ring meets at its pole: ten triangles without area.
    assert!(text.contains("triangles  124 (10 degenerate)\n"), "{text}");
    assert!(
        text.contains("instanced  486 triangles (6 instances of 2 meshes stored once)"),
        "{text}"
    );
    drop(dir);
}

/// A glTF file whose mesh (an octahedron with vertex normals) hangs from three nodes
/// (one mirrored, one stretched), written with the mesh once (`shared`) or once per
/// node (each node its own copy of the mesh, which the reader flattens).
fn write_gltf(dir: &Path, shared: bool) -> std::path::PathBuf {
    let positions: [[f32; 3]; 6] = [
        [1.0, 0.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.0, -1.0],
    ];
    let indices: [u16; 24] = [
        0, 2, 4, 2, 1, 4, 1, 3, 4, 3, 0, 4, 2, 0, 5, 1, 2, 5, 3, 1, 5, 0, 3, 5,
    ];
    let mut bin = Vec::new();
    for p in positions {
        bin.extend(p.iter().flat_map(|v| v.to_le_bytes()));
    }
    for p in positions {
        // Normals tilted off the faces', so that interpolation shows.
        let n = [p[0] * 0.9, p[1], p[2] * 1.1];
        bin.extend(n.iter().flat_map(|v| v.to_le_bytes()));
    }
    bin.extend(indices.iter().flat_map(|v| v.to_le_bytes()));
    fs::write(dir.join("octa.bin"), &bin).unwrap();
    let nodes = [
        r#""translation": [-2.5, 0, 0]"#,
        r#""translation": [0, 0, 0], "scale": [-1, 1.3, 0.8], "rotation": [0, 0.3826834, 0, 0.9238795]"#,
        r#""translation": [2.5, 0.2, 0], "scale": [1.5, 0.6, 1]"#,
    ];
    let meshes = if shared { 1 } else { 3 };
    let mesh = r#"{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 2}]}"#;
    let gltf = format!(
        r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0, 1, 2]}}],
"nodes": [{}],
"meshes": [{}],
"buffers": [{{"uri": "octa.bin", "byteLength": {}}}],
"bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": 144}}, {{"buffer": 0, "byteOffset": 144, "byteLength": 48}}],
"accessors": [
 {{"bufferView": 0, "byteOffset": 0, "componentType": 5126, "count": 6, "type": "VEC3", "min": [-1, -1, -1], "max": [1, 1, 1]}},
 {{"bufferView": 0, "byteOffset": 72, "componentType": 5126, "count": 6, "type": "VEC3"}},
 {{"bufferView": 1, "componentType": 5123, "count": 24, "type": "SCALAR"}}]}}"#,
        (0..3)
            .map(|i| format!(
                r#"{{"mesh": {}, {}}}"#,
                if shared { 0 } else { i },
                nodes[i]
            ))
            .collect::<Vec<_>>()
            .join(", "),
        vec![mesh; meshes].join(", "),
        bin.len()
    );
    let path = dir.join(if shared { "shared.gltf" } else { "copies.gltf" });
    fs::write(&path, gltf).unwrap();
    path
}

#[test]
fn a_gltf_mesh_of_several_nodes_is_stored_once_and_renders_as_its_copies() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let shared = write_gltf(d, true);
    let copies = write_gltf(d, false);
    let output = raytracer(&["info", shared.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&output.stdout);
    assert!(text.contains("triangles  8\n"), "{text}");
    assert!(
        text.contains("instanced  24 triangles (3 instances of 1 mesh"),
        "{text}"
    );
    for mode in ["full", "normal"] {
        let flags = [
            "--width",
            "120",
            "--height",
            "60",
            "--mode",
            mode,
            "--look-from",
            "0,2,7",
            "--look-to",
            "0,0,0",
        ];
        let a = render(&shared, &d.join("a.png"), &flags);
        let b = render(&copies, &d.join("b.png"), &flags);
        assert_same_image(&a, &b, mode);
    }
}

/// Under the default rig shadow rays at grazing light leave smooth meshes from the
/// surface their vertex normals describe (`Hit::lift`): a copy's lift is made in
/// world space from its placed corners and normals, as its flattened self's is, so
/// the two scenes still render alike (the stretched and sheared balls among them);
/// and the lift changes the picture, so the comparison is not of two unlifted ones.
#[test]
fn under_the_rig_instanced_copies_lift_their_shadow_rays_as_their_flattened_selves() {
    use raytracer::{BvhParams, RenderOptions, Scene, render};
    let (_dir, instanced, flat) = scenes();
    let options = RenderOptions {
        width: 160,
        height: 120,
        fov_degrees: 50.0,
        look_from: raytracer::math::Vec3::new(0.0, 2.5, 7.0),
        look_to: raytracer::math::Vec3::new(0.0, 0.3, 0.0),
        ..RenderOptions::default()
    };
    let film = |path: &Path, lit: bool| {
        let description = raytracer::formats::load(path).unwrap().description;
        let mut scene = Scene::build(description, &BvhParams::default());
        scene.set_lit_by_rig(lit);
        render(&scene, &options).pixels
    };
    let differing = |a: &[raytracer::math::Vec3], b: &[raytracer::math::Vec3]| {
        a.iter()
            .zip(b)
            .filter(|(a, b)| (**a - **b).abs().max_element() > 0.01)
            .count()
    };
    let lifted = film(&instanced, true);
    let pixels = lifted.len();
    let flat_lifted = film(&flat, true);
    let count = differing(&lifted, &flat_lifted);
    assert!(count * 1000 <= pixels, "{count} of {pixels} pixels differ");
    let unlifted = film(&instanced, false);
    assert!(
        differing(&lifted, &unlifted) > 10,
        "the lift changed nothing"
    );
}
