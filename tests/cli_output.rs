//! Drives the binary for what users see: --quiet, --version, output formats by
//! extension, and --spp determinism.

use crate::support;

use std::fs;
use std::path::Path;

use assert_cmd::Command;
use raytracer::{BvhParams, Mode, RenderOptions, Scene, formats, math::Vec3, render};

fn raytracer() -> Command {
    Command::new(env!("CARGO_BIN_EXE_raytracer"))
}

/// `raytracer render` of the bundled Cornell box at 64x48 into `output`, plus `extra`.
fn render_cornell(output: &Path, extra: &[&str]) -> Command {
    let mut cmd = raytracer();
    cmd.arg("render")
        .arg(support::cornell_box())
        .arg("-o")
        .arg(output)
        .args(["--width", "64", "--height", "48"])
        .args(support::CORNELL_CAMERA)
        .args(extra);
    cmd
}

/// A one-triangle scene that loads with a warning: the face comes before any `usemtl`.
fn scene_with_a_warning(dir: &Path) -> std::path::PathBuf {
    let path = dir.join("warns.obj");
    fs::write(
        &path,
        "v -1 -1 -3\nv 1 -1 -3\nv 0 1 -3\nl 1 2\nf 1 2 3\nP 0 0 0 1 1 1\n",
    )
    .unwrap();
    path
}

#[test]
fn quiet_prints_nothing_on_success_not_even_warnings() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene_with_a_warning(dir.path());
    let output = dir.path().join("out.png");
    let base = [
        "render",
        scene.to_str().unwrap(),
        "-o",
        output.to_str().unwrap(),
    ];
    let base = [&base[..], &["--width", "32", "--height", "24"]].concat();

    // Without --quiet the warning shows, so the quiet run below has something to hide.
    let loud = raytracer().args(&base).assert().success();
    let loud_err = String::from_utf8_lossy(&loud.get_output().stderr).into_owned();
    assert!(loud_err.contains("warning:"), "stderr: {loud_err}");
    fs::remove_file(&output).unwrap();

    for quiet in [["--quiet"], ["-q"]] {
        raytracer()
            .args(&base)
            .args(quiet)
            .assert()
            .success()
            .stdout("")
            .stderr("");
        assert!(output.is_file(), "the image is still written");
    }
    // The flag is global: it may also come before the subcommand.
    raytracer()
        .arg("--quiet")
        .args(&base)
        .assert()
        .success()
        .stderr("");
}

#[test]
fn quiet_still_reports_errors() {
    let dir = tempfile::tempdir().unwrap();
    raytracer()
        .args(["render", "missing.obj", "-o"])
        .arg(dir.path().join("out.png"))
        .arg("--quiet")
        .assert()
        .code(2)
        .stderr(predicates::str::contains("missing.obj"));
}

#[test]
fn version_names_the_crate_version() {
    raytracer()
        .arg("--version")
        .assert()
        .success()
        .stdout(format!("raytracer {}\n", env!("CARGO_PKG_VERSION")));
}

#[test]
fn an_unknown_extension_is_an_error_naming_it_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    for (name, shown) in [("out.jpg", "'.jpg'"), ("out", "no file extension")] {
        let output = dir.path().join(name);
        render_cornell(&output, &[])
            .assert()
            .code(2)
            .stderr(predicates::str::contains(shown))
            .stderr(predicates::str::contains(name));
        assert!(!output.exists());
    }
    assert_eq!(
        fs::read_dir(dir.path()).unwrap().count(),
        0,
        "no files left"
    );
}

#[test]
fn extensions_pick_the_format_in_any_letter_case() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("OUT.PNG");
    let exr = dir.path().join("out.Exr");
    render_cornell(&png, &[]).assert().success();
    render_cornell(&exr, &[]).assert().success();
    assert_eq!(&fs::read(&png).unwrap()[1..4], b"PNG");
    // The OpenEXR magic number.
    assert_eq!(&fs::read(&exr).unwrap()[..4], &[0x76, 0x2f, 0x31, 0x01]);
}

#[test]
fn anti_aliased_output_is_identical_across_runs_and_thread_counts() {
    let dir = tempfile::tempdir().unwrap();
    let mut files = Vec::new();
    for (run, threads) in [(0, "1"), (1, "2"), (2, "2")] {
        for extension in ["png", "exr"] {
            let output = dir.path().join(format!("run{run}-j{threads}.{extension}"));
            // 5 samples: not a square, so the uneven strata are covered too.
            render_cornell(&output, &["--spp", "5", "-j", threads])
                .assert()
                .success();
            files.push((output.clone(), fs::read(&output).unwrap()));
        }
    }
    for pair in files.chunks(2).skip(1) {
        for (i, (path, bytes)) in pair.iter().enumerate() {
            assert!(
                bytes == &files[i].1,
                "{} differs from {}",
                path.display(),
                files[i].0.display()
            );
        }
    }
    // And anti-aliasing did change the image.
    let one_sample = dir.path().join("spp1.png");
    render_cornell(&one_sample, &["--spp", "1"])
        .assert()
        .success();
    assert_ne!(fs::read(&one_sample).unwrap(), files[0].1);
}

#[test]
fn spp_1_is_the_default() {
    let dir = tempfile::tempdir().unwrap();
    let default = dir.path().join("default.png");
    let explicit = dir.path().join("spp1.png");
    render_cornell(&default, &[]).assert().success();
    render_cornell(&explicit, &["--spp", "1"])
        .assert()
        .success();
    assert_eq!(fs::read(default).unwrap(), fs::read(explicit).unwrap());
}

#[test]
fn spp_out_of_range_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    for spp in ["0", "65537"] {
        render_cornell(&dir.path().join("out.png"), &["--spp", spp])
            .assert()
            .code(2)
            .stderr(predicates::str::contains("--spp"));
    }
}

#[test]
fn exr_output_holds_the_linear_film_before_tone_mapping() {
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("cornell.exr");
    render_cornell(&output, &["--spp", "4"]).assert().success();

    let options = RenderOptions {
        width: 64,
        height: 48,
        fov_degrees: 60.0,
        look_from: Vec3::new(0.0, 0.7, 1.75),
        look_to: Vec3::new(0.0, 0.7, 0.0),
        samples_per_pixel: 4,
        ..RenderOptions::default()
    };
    let description = formats::load_obj(&support::cornell_box()).unwrap();
    let film = render(&Scene::build(description, &BvhParams::default()), &options);

    let (width, height, channels) = support::read_exr(&output);
    assert_eq!((width, height), (64, 48));
    let names: Vec<&str> = channels.keys().map(String::as_str).collect();
    assert_eq!(names, ["B", "G", "R"]);
    for (i, v) in film.pixels.iter().enumerate() {
        let got = Vec3::new(channels["R"][i], channels["G"][i], channels["B"][i]);
        assert_eq!(got, *v, "pixel {i}");
    }
    assert_eq!(options.mode, Mode::Full);
}
