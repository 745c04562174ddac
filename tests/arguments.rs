//! Every invalid option value is refused before any work, with exit code 2 and a
//! message naming the option and what it allows; `--help` states the limits. (Values
//! of scene files, and flags replacing them: `tests/scene_files.rs`.)

use assert_cmd::Command;
use predicates::prelude::*;
use raytracer::options::{MAX_DIMENSION, MAX_PIXELS, MAX_RECURSION_DEPTH};

/// `raytracer render` on a scene that does not exist, so that only a refusal of the
/// options themselves can explain an error that names them: nothing was read.
fn render(args: &[&str]) -> Command {
    let mut cmd = Command::cargo_bin("raytracer").unwrap();
    cmd.args(["render", "no-such-scene.obj", "-o", "never-written.png"])
        .args(args);
    cmd
}

/// Asserts that `args` are refused with a first line of exactly `message`.
fn assert_refused(args: &[&str], message: &str) {
    let first_line = format!("error: {message}\n");
    render(args)
        .assert()
        .code(2)
        .stdout("")
        .stderr(predicate::str::starts_with(first_line));
}

#[test]
fn sizes_outside_their_range_are_refused_naming_the_flag() {
    let range = format!("1..={MAX_DIMENSION}");
    for (option, value) in [
        ("--width", "0"),
        ("--width", "65537"),
        ("--width", "-5"),
        ("--height", "0"),
    ] {
        assert_refused(
            &[option, value],
            &format!("invalid {option}: {value} is not in {range}"),
        );
    }
    for (option, value, problem) in [
        ("--width", "wide", "not a whole number"),
        ("--width", "1.5", "not a whole number"),
        ("--height", "", "not a whole number"),
        ("--width", "99999999999999999999", "too many digits"),
    ] {
        assert_refused(
            &[option, value],
            &format!("invalid value '{value}' for '{option} <PIXELS>': {problem}"),
        );
    }
    assert_refused(
        &["--width", "65536", "--height", "65536"],
        &format!("invalid --width/--height: 65536x65536 has more than {MAX_PIXELS} pixels"),
    );
}

#[test]
fn field_of_view_depth_samples_and_threads_outside_their_range_are_refused() {
    for value in ["0", "180", "-10", "NaN", "inf"] {
        assert_refused(
            &["--fov", value],
            &format!("invalid --fov: {value} is not strictly between 0 and 180"),
        );
    }
    assert_refused(
        &["--fov", "wide"],
        "invalid value 'wide' for '--fov <DEGREES>': not a number",
    );
    for value in ["0", "65", "-1"] {
        assert_refused(
            &["--depth", value],
            &format!("invalid --depth: {value} is not in 1..={MAX_RECURSION_DEPTH}"),
        );
    }
    assert_refused(
        &["--depth", "deep"],
        "invalid value 'deep' for '--depth <N>': not a whole number",
    );
    for value in ["0", "65537", "-2"] {
        assert_refused(
            &["--spp", value],
            &format!("invalid --spp: {value} is not in 1..=65536"),
        );
    }
    for value in ["1025", "-1"] {
        assert_refused(
            &["-j", value],
            &format!("invalid value '{value}' for '--threads <N>': not in 0..=1024"),
        );
    }
}

#[test]
fn bad_camera_vectors_and_modes_are_refused() {
    assert_refused(
        &["--look-from", "1,2"],
        "invalid value '1,2' for '--look-from <X,Y,Z>': a vector is written X,Y,Z, three numbers with commas and no spaces, as in --look-from 0,0.7,1.75",
    );
    assert_refused(
        &["--up", "0 1 0"],
        "invalid value '0 1 0' for '--up <X,Y,Z>': a vector is written X,Y,Z, three numbers with commas and no spaces, as in --up 0,1,0",
    );
    assert_refused(
        &["--look-to", "1,inf,2"],
        "invalid value '1,inf,2' for '--look-to <X,Y,Z>': 'inf' is not a finite number in '1,inf,2'",
    );
    assert_refused(
        &["--look-from", "1,2,3", "--look-to", "1,2,3"],
        "invalid --look-from/--look-to: the camera cannot look at its own position",
    );
    assert_refused(
        &["--look-from", "3e38,0,0", "--look-to", "-3e38,0,0"],
        "invalid --look-from/--look-to: the points are too far apart (their distance overflows)",
    );
    render(&["--mode", "fancy"])
        .assert()
        .code(2)
        .stderr(predicate::str::starts_with(
            "error: invalid value 'fancy' for '--mode <MODE>'",
        ))
        .stderr(predicate::str::contains(
            "[possible values: full, depth, normal, path]",
        ));
}

#[test]
fn a_vector_written_with_spaces_is_shown_with_commas() {
    // clap alone says "unexpected argument '0.7' found", which does not say why.
    let form = "takes a vector as one argument, X,Y,Z with commas and no spaces";
    for (args, message) in [
        (
            &["--look-from", "0", "0.7", "1.75"][..],
            format!("--look-from {form}: write --look-from 0,0.7,1.75, not --look-from 0 0.7 1.75"),
        ),
        (
            &["--look-to", "0,", "0.7,", "0"],
            format!("--look-to {form}: write --look-to 0,0.7,0, not --look-to 0, 0.7, 0"),
        ),
        (
            &["--up=0", "1", "0", "--width", "8"],
            format!("--up {form}: write --up 0,1,0, not --up 0 1 0"),
        ),
        (
            &["--look-from", "1", "2"],
            format!("--look-from {form}, as in --look-from 0,0.7,1.75 (not --look-from 1 2)"),
        ),
    ] {
        render(args)
            .assert()
            .code(2)
            .stdout("")
            .stderr(format!("error: {message}\n"));
    }
    // Before the scene, the numbers would be taken for it.
    Command::cargo_bin("raytracer")
        .unwrap()
        .args(["render", "--look-from", "0", "0.7", "1.75", "scene.obj"])
        .args(["-o", "x.png"])
        .assert()
        .code(2)
        .stderr(predicate::str::starts_with(
            "error: --look-from takes a vector as one argument",
        ));
    // A lone number is refused by the vector's parser, with the same advice.
    assert_refused(
        &["--look-from", "0"],
        "invalid value '0' for '--look-from <X,Y,Z>': a vector is written X,Y,Z, three numbers with commas and no spaces, as in --look-from 0,0.7,1.75",
    );
}

#[test]
fn valid_options_reach_the_scene() {
    // The same command with good values gets as far as reading the scene.
    render(&[
        "--width", "1", "--height", "65536", "--fov", "0.5", "--depth", "64", "-j", "0",
    ])
    .assert()
    .code(2)
    .stderr(predicate::str::starts_with("error: no-such-scene.obj: "));
}

#[test]
fn help_states_every_limit() {
    let assert = Command::cargo_bin("raytracer")
        .unwrap()
        .args(["render", "--help"])
        .assert()
        .success();
    let help = String::from_utf8_lossy(&assert.get_output().stdout).into_owned();
    let side = (MAX_PIXELS as f64).sqrt() as u64;
    for limit in [
        format!("(1..={MAX_DIMENSION})"),
        format!("at most {side}x{side} pixels"),
        "strictly between 0 and 180".to_string(),
        format!("(1..={MAX_RECURSION_DEPTH})"),
        "(0..=1024)".to_string(),
        "the height keeps the aspect ratio of the scene file's image size".to_string(),
        "the width keeps the aspect ratio of the scene file's image size".to_string(),
    ] {
        assert!(help.contains(&limit), "--help lacks '{limit}':\n{help}");
    }
}
