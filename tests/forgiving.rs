//! What other tools write and read renders here too, with one warning per kind naming
//! the file and line: OBJ `l` and `p` elements and faces of fewer than 3 vertices are
//! skipped, an MTL `Ns` below 0 is read as 0, a missing `.mtl` leaves its materials at
//! the default, an unknown PLY header line is skipped. (Truly broken input stays an
//! error: `tests/malformed.rs`.) Scenes: `tests/data/forgiving/`.

use crate::support;

use std::path::{Path, PathBuf};

use assert_cmd::Command;

fn forgiving_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/forgiving")
}

/// Renders `scene` (in the forgiving folder) looking down -z from the origin; returns
/// the warnings printed, in order, and the image.
fn render(scene: &str) -> (Vec<String>, Vec<u8>) {
    let out_dir = tempfile::tempdir().unwrap();
    let out = out_dir.path().join("out.png");
    let output = Command::cargo_bin("raytracer")
        .unwrap()
        .current_dir(forgiving_dir())
        .args(["render", scene, "-o"])
        .arg(&out)
        .args(["--width", "32", "--height", "24", "-j", "1"])
        .args(["--look-from", "0,0,0", "--look-to", "0,0,-1"])
        .output()
        .unwrap();
    let stderr = String::from_utf8(output.stderr).unwrap();
    assert!(output.status.success(), "{scene}: {stderr}");
    let warnings = stderr
        .lines()
        .map(|line| {
            line.strip_prefix("warning: ")
                .unwrap_or_else(|| panic!("not a warning: {line}"))
                .to_string()
        })
        .collect();
    (warnings, support::read_png(&out).2)
}

/// The middle pixel's red, green and blue.
fn centre(rgb: &[u8]) -> [u8; 3] {
    let at = 3 * (12 * 32 + 16);
    [rgb[at], rgb[at + 1], rgb[at + 2]]
}

#[test]
fn lines_points_and_short_faces_are_skipped_with_one_warning_per_kind() {
    let (warnings, rgb) = render("skipped-elements.obj");
    // The reader's warnings in file order, then the summary of what it skipped.
    assert_eq!(
        warnings,
        [
            "skipped-elements.obj:11: shapes before any 'usemtl' get the default material",
            "skipped-elements.obj:6: skipped 2 line elements ('l'): lines have no area to render",
            "skipped-elements.obj:8: skipped 1 point element ('p'): points have no area to render",
            "skipped-elements.obj:9: skipped 2 faces of fewer than 3 vertices",
        ]
    );
    // The triangle still renders, lit, in the default grey.
    let [r, g, b] = centre(&rgb);
    assert!(r > 50 && r == g && g == b, "{r} {g} {b}");
}

#[test]
fn a_missing_material_library_leaves_the_default_material_with_one_warning() {
    let (warnings, rgb) = render("missing-mtl.obj");
    // One warning, not one per material name the library would have defined.
    assert_eq!(
        warnings,
        [
            "missing-mtl.obj:1: material library nowhere.mtl not found; its materials get the default material"
        ]
    );
    let [r, g, b] = centre(&rgb);
    assert!(r > 50 && r == g && g == b, "{r} {g} {b}");
}

#[test]
fn a_scene_file_can_still_give_a_mesh_with_a_missing_library_its_material() {
    let (warnings, rgb) = render("missing-mtl.toml");
    // The warning is about the mesh's own materials, which the scene file replaced.
    assert!(warnings.is_empty(), "{warnings:?}");
    let [r, g, b] = centre(&rgb);
    assert!(g > 50 && r == 0 && b == 0, "{r} {g} {b}");
}

#[test]
fn a_negative_phong_exponent_is_read_as_zero() {
    let (warnings, rgb) = render("negative-ns.obj");
    assert_eq!(
        warnings,
        ["negative-ns.mtl:4: 'Ns' below 0 read as 0 (1 line)"]
    );
    assert!(centre(&rgb)[0] > 50);
}

#[test]
fn an_unknown_ply_header_line_is_skipped() {
    let (warnings, rgb) = render("created-by.ply");
    assert_eq!(
        warnings,
        [
            "created-by.ply:3: skipped 1 header line of unknown keyword ('Created')",
            "the scene has no lights ('P' or 'Ke'): lit by a default light rig at the camera (--no-default-light turns it off)"
        ]
    );
    assert!(centre(&rgb)[0] > 50);
}
