//! Drives the `raytracer` binary over malformed scenes: each must exit with code 2 and
//! print exactly one error naming the file and line (or exit 0 where the input is
//! valid after all, such as CRLF line ends and tabs). The small files live in
//! `tests/data/malformed/`; large or special ones are made in a temporary folder.

use crate::support;

use std::fs;
use std::path::{Path, PathBuf};

use assert_cmd::Command;
use predicates::prelude::*;

fn malformed_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/malformed")
}

/// `raytracer render SCENE -o OUT` run from `dir`, small and single-threaded.
fn render(dir: &Path, scene: &str, out: &Path) -> Command {
    let mut cmd = Command::cargo_bin("raytracer").unwrap();
    cmd.current_dir(dir)
        .args(["render", scene, "-o"])
        .arg(out)
        .args(["--width", "32", "--height", "24", "-j", "1"]);
    cmd
}

/// Asserts that rendering `scene` (in `dir`) fails with exit code 2, printing exactly
/// `error: {message}` and creating no output.
fn assert_refused(dir: &Path, scene: &str, message: &str) {
    let out_dir = tempfile::tempdir().unwrap();
    let out = out_dir.path().join("out.png");
    render(dir, scene, &out)
        .assert()
        .code(2)
        .stdout("")
        .stderr(format!("error: {message}\n"));
    assert!(!out.exists(), "{scene}: an image was written");
    assert_eq!(fs::read_dir(out_dir.path()).unwrap().count(), 0, "{scene}");
}

/// What the system says when a file does not exist, in this platform's words.
fn not_found() -> String {
    fs::File::open("/this/file/does/not/exist")
        .unwrap_err()
        .to_string()
}

#[test]
fn malformed_lines_are_refused_with_file_and_line() {
    let cases = [
        ("bad-number.obj", "bad-number.obj:2: invalid number 'x'"),
        (
            "bad-face-number.obj",
            "bad-face-number.obj:4: malformed face vertex 'three'",
        ),
        (
            "bad-face-vertex.obj",
            "bad-face-vertex.obj:4: malformed face vertex '1/1/1/1'",
        ),
        (
            "zero-index.obj",
            "zero-index.obj:4: face index 0 is invalid (indices start at 1)",
        ),
        (
            "zero-texcoord-index.obj",
            "zero-texcoord-index.obj:5: texture coordinate index 0 is invalid (indices start at 1)",
        ),
        (
            "index-out-of-range.obj",
            "index-out-of-range.obj:4: face index 9 out of range (3 vertices defined)",
        ),
        (
            "negative-index-out-of-range.obj",
            "negative-index-out-of-range.obj:4: face index -4 out of range (3 vertices defined)",
        ),
        (
            "normal-index-out-of-range.obj",
            "normal-index-out-of-range.obj:5: normal index 2 out of range (1 normal defined)",
        ),
        (
            // A face of 2 vertices is skipped (tests/forgiving.rs), but its indices are
            // checked as any face's.
            "short-face-bad-index.obj",
            "short-face-bad-index.obj:4: face index 9 out of range (3 vertices defined)",
        ),
        (
            "bad-smoothing-group.obj",
            "bad-smoothing-group.obj:2: smoothing group 'on' is not 'off' or a whole number",
        ),
        (
            "too-few-values.obj",
            "too-few-values.obj:1: 'v' needs 3 values, found 2",
        ),
        (
            "negative-radius.obj",
            "negative-radius.obj:1: sphere radius -1 is negative",
        ),
        (
            "short-light.obj",
            "short-light.obj:2: 'P' needs 6 values, found 5",
        ),
        (
            "mtllib-without-name.obj",
            "mtllib-without-name.obj:1: 'mtllib' needs a name",
        ),
        (
            "binary-garbage.obj",
            "binary-garbage.obj:5: not a text file: a NUL byte (binary data, or UTF-16 text)",
        ),
    ];
    for (scene, message) in cases {
        assert_refused(&malformed_dir(), scene, message);
    }
}

#[test]
fn malformed_material_files_are_refused_with_their_own_file_and_line() {
    let cases = [
        ("bad-mtl.obj", "bad-colour.mtl:3: invalid number 'x'"),
        (
            "property-before-newmtl.obj",
            "before-newmtl.mtl:1: 'Kd' before any 'newmtl'",
        ),
        (
            "utf16-mtl.obj",
            "utf16.mtl:1: not a text file: a NUL byte (binary data, or UTF-16 text)",
        ),
    ];
    for (scene, message) in cases {
        assert_refused(&malformed_dir(), scene, message);
    }
}

#[test]
fn a_missing_scene_or_a_folder_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    fs::create_dir(dir.path().join("scene.obj")).unwrap();
    fs::write(dir.path().join("lib.obj"), "mtllib scene.obj\n").unwrap();
    assert_refused(
        dir.path(),
        "nowhere.obj",
        &format!("nowhere.obj: {}", not_found()),
    );
    assert_refused(dir.path(), "scene.obj", "scene.obj: is a directory");
    assert_refused(
        dir.path(),
        "lib.obj",
        "lib.obj:1: cannot read material library scene.obj: is a directory",
    );
}

#[cfg(unix)]
#[test]
fn a_device_named_as_material_library_is_not_read() {
    // `/dev/zero` never ends: reading it would take all memory.
    let dir = tempfile::tempdir().unwrap();
    fs::write(dir.path().join("zero.obj"), "mtllib /dev/zero\n").unwrap();
    assert_refused(
        dir.path(),
        "zero.obj",
        "zero.obj:1: cannot read material library /dev/zero: is not a regular file",
    );
}

#[test]
fn crlf_line_ends_and_tabs_render_like_plain_lines() {
    let out_dir = tempfile::tempdir().unwrap();
    let mut images = Vec::new();
    for scene in ["crlf-tabs.obj", "lf.obj"] {
        let out = out_dir.path().join(format!("{scene}.png"));
        render(&malformed_dir(), scene, &out)
            .args(["--look-from", "0,2,0", "--look-to", "0,0,0"])
            .assert()
            .success()
            .stderr("");
        images.push(support::read_png(&out));
    }
    assert_eq!(images[0], images[1]);
    // The blue triangle is there: the material was found despite `\r` and tabs.
    let (_, _, rgb) = &images[0];
    assert!(rgb.chunks(3).any(|px| px[2] > 100 && px[0] == 0));
}

#[test]
fn an_empty_scene_renders_with_warnings() {
    let out_dir = tempfile::tempdir().unwrap();
    let out = out_dir.path().join("empty.png");
    render(&malformed_dir(), "empty.obj", &out)
        .assert()
        .success()
        .stderr(predicate::str::contains(
            "warning: the scene has no shapes left to render: every ray misses",
        ))
        .stderr(predicate::str::contains("warning: the scene has no lights"));
    let (_, _, rgb) = support::read_png(&out);
    assert!(rgb.iter().all(|&b| b == 0), "an empty scene is black");
}

/// A 10 MB line of `len` bytes: `prefix`, then `unit` repeated.
fn long_line(prefix: &str, unit: &str, len: usize) -> String {
    let mut line = String::with_capacity(len + 1);
    line.push_str(prefix);
    while line.len() + unit.len() <= len {
        line.push_str(unit);
    }
    line
}

const TEN_MB: usize = 10 << 20;

#[test]
fn ten_megabyte_lines_are_read_or_refused_with_a_short_message() {
    let dir = tempfile::tempdir().unwrap();
    let triangle = "v -1 -1 -2\nv 1 -1 -2\nv 0 1 -2\n";

    // A 10 MB comment, then a 10 MB fan of ~5 million triangles over one corner: all
    // zero-area, so skipped with one warning that counts them.
    let comment = long_line("#", "x", TEN_MB);
    let face = long_line("f 1", " 1 1", TEN_MB);
    let triangles = face.split(' ').count() - 3;
    fs::write(
        dir.path().join("long-face.obj"),
        format!("{comment}\n{triangle}{face}\nP 0 0 0 1 1 1\n"),
    )
    .unwrap();
    let out = dir.path().join("long-face.png");
    render(dir.path(), "long-face.obj", &out)
        .assert()
        .success()
        .stderr(format!(
            "warning: skipped {triangles} degenerate (zero-area) triangles\n\
             warning: the scene has no shapes left to render: every ray misses\n"
        ));
    assert!(out.exists());

    // One 10 MB number (in a sphere's radius: in a vertex it is a warning): the
    // message quotes it cut.
    let number = long_line("S 0 0 -3 ", "1", TEN_MB);
    fs::write(dir.path().join("long-number.obj"), format!("{number}\n")).unwrap();
    let shown = "1".repeat(40);
    assert_refused(
        dir.path(),
        "long-number.obj",
        &format!("long-number.obj:1: non-finite value '{shown}...'"),
    );

    // One 10 MB token of garbage in a face.
    let garbage = long_line("f 1 2 ", "z", TEN_MB);
    fs::write(
        dir.path().join("long-garbage.obj"),
        format!("{triangle}{garbage}\n"),
    )
    .unwrap();
    let shown = "z".repeat(40);
    assert_refused(
        dir.path(),
        "long-garbage.obj",
        &format!("long-garbage.obj:4: malformed face vertex '{shown}...'"),
    );
}

#[test]
fn a_huge_sphere_and_lights_inside_it_render() {
    // The camera sits inside a sphere of radius 1e30, lit from inside: nothing may
    // overflow into the image.
    let dir = tempfile::tempdir().unwrap();
    fs::write(
        dir.path().join("huge.obj"),
        "S 0 0 0 1e30\nS 0 0 -3 1\nP 0 0 1 1e30 1e30 1e30\nP 0 0 -3 1 1 1\n",
    )
    .unwrap();
    let out = dir.path().join("huge.png");
    for mode in ["full", "depth", "normal"] {
        render(dir.path(), "huge.obj", &out)
            .args([
                "--mode",
                mode,
                "--look-from",
                "0,0,0",
                "--look-to",
                "0,0,-1",
            ])
            .assert()
            .success();
        let (_, _, rgb) = support::read_png(&out);
        assert!(rgb.iter().any(|&b| b != 0), "{mode}: the image is black");
    }
}
