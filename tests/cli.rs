//! Drives the `raytracer` binary: successful renders, argument validation before any
//! work, error messages and exit codes, and atomic output.

use crate::support;

use support::{raytracer, stderr};

use std::path::PathBuf;

fn box_scene() -> PathBuf {
    support::reference_dir().join("scenes/box/cube.obj")
}

#[test]
fn renders_a_png_of_the_requested_size_with_negative_vectors_in_both_spellings() {
    let dir = tempfile::tempdir().unwrap();
    let scene = box_scene();
    for (i, look_from) in [
        ["--look-from", "-0.5,0.7,1.75"],
        ["--look-from=-0.5,0.7,1.75", "--mode=normal"],
    ]
    .iter()
    .enumerate()
    {
        let out = dir.path().join(format!("out{i}.png"));
        let output = raytracer(&[
            "render",
            scene.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--width",
            "64",
            "--height",
            "48",
            look_from[0],
            look_from[1],
            "--look-to=0,0.7,0",
        ]);
        assert!(output.status.success(), "{}", stderr(&output));
        let (w, h, rgb) = support::read_png(&out);
        assert_eq!((w, h), (64, 48));
        assert!(rgb.iter().any(|&c| c > 0), "image is not black");
    }
}

#[test]
fn invalid_values_are_refused_before_any_work_with_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.png");
    let scene = box_scene();
    let cases: &[(&[&str], &str)] = &[
        (&["--width", "0"], "invalid --width: 0 is not in 1..=65536"),
        (
            &["--height", "70000"],
            "invalid --height: 70000 is not in 1..=65536",
        ),
        (
            &["--width", "65536", "--height", "65536"],
            "invalid --width/--height",
        ),
        (&["--width", "-3"], "--width"),
        (
            &["--fov", "180"],
            "invalid --fov: 180 is not strictly between 0 and 180",
        ),
        (&["--fov", "0"], "--fov"),
        (&["--fov", "nan"], "--fov"),
        (&["--depth", "0"], "invalid --depth: 0 is not in 1..=64"),
        (
            &["--look-from", "1,2,3", "--look-to", "1,2,3"],
            "cannot look at its own position",
        ),
        (&["--look-from", "1,2"], "a vector is written X,Y,Z"),
        (
            &["--look-from", "0", "0.7", "1.75"],
            "write --look-from 0,0.7,1.75, not --look-from 0 0.7 1.75",
        ),
        (&["--look-to", "1,x,3"], "'x' is not a finite number"),
        (&["--mode", "fancy"], "invalid value 'fancy' for '--mode"),
    ];
    for (extra, expected) in cases {
        let mut args = vec![
            "render",
            scene.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let output = raytracer(&args);
        assert_eq!(output.status.code(), Some(2), "{extra:?}");
        assert!(
            stderr(&output).contains(expected),
            "{extra:?}: {}",
            stderr(&output)
        );
        assert!(!out.exists(), "{extra:?} wrote an output file");
    }
}

#[test]
fn a_failed_run_keeps_the_existing_output_and_leaves_no_temporary_file() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("keep.png");
    std::fs::write(&out, b"precious").unwrap();
    let bad = dir.path().join("bad.obj");
    std::fs::write(&bad, "v 0 0 0\nv 1 0 0\nf 1 2 3\n").unwrap();
    let output = raytracer(&["render", bad.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert_eq!(output.status.code(), Some(2));
    assert_eq!(
        stderr(&output).trim(),
        format!(
            "error: {}:3: face index 3 out of range (2 vertices defined)",
            bad.display()
        )
    );
    assert_eq!(std::fs::read(&out).unwrap(), b"precious");
    let leftovers: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert_eq!(leftovers.len(), 2, "only bad.obj and keep.png remain");
}

#[test]
fn missing_scene_and_unwritable_output_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.obj");
    let out = dir.path().join("out.png");
    let output = raytracer(&[
        "render",
        missing.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(output.status.code(), Some(2));
    assert!(
        stderr(&output).contains(&format!("{}: No such file", missing.display())),
        "{}",
        stderr(&output)
    );

    let nowhere = dir.path().join("no/such/folder/out.png");
    let scene = box_scene();
    let output = raytracer(&[
        "render",
        scene.to_str().unwrap(),
        "-o",
        nowhere.to_str().unwrap(),
        "--width",
        "8",
        "--height",
        "8",
    ]);
    assert_eq!(output.status.code(), Some(2));
    assert!(
        stderr(&output).contains(&format!("cannot write {}", nowhere.display())),
        "{}",
        stderr(&output)
    );
}

/// The `[default: ...]` notes of each flag in `help` (long help), by flag: the notes
/// of the lines from the flag's own line to the next flag's.
fn help_defaults(help: &str) -> std::collections::HashMap<String, Vec<String>> {
    let mut defaults = std::collections::HashMap::new();
    let mut flag = None;
    for line in help.lines() {
        let trimmed = line.trim_start();
        if line.starts_with("  ") && !line.starts_with("          ") && trimmed.starts_with('-') {
            // `-j, --threads <N>` or `--width <PIXELS>`: the long name.
            let long = trimmed.split(['<', ' ']).find(|w| w.starts_with("--"));
            flag = long.map(|l| l.trim_end_matches(',').to_string());
        }
        let Some(flag) = &flag else { continue };
        for note in line.split("[default: ").skip(1) {
            let value = note.split(']').next().unwrap().to_string();
            defaults
                .entry(flag.clone())
                .or_insert_with(Vec::new)
                .push(value);
        }
    }
    defaults
}

/// Every default `render --help` states is the value the program uses when the flag
/// is left out: what resolving no flags at all gives, in full and in path mode.
#[test]
fn help_states_the_defaults_the_program_uses() {
    use raytracer::Mode;
    use raytracer::options::{Origin, PartialOptions, Sourced};

    let output = raytracer(&["render", "--help"]);
    assert!(output.status.success());
    let help = String::from_utf8_lossy(&output.stdout);
    let defaults = help_defaults(&help);
    let full = PartialOptions::default().resolve().unwrap();
    let path = PartialOptions {
        mode: Some(Sourced::new(Mode::Path, Origin::Flag("--mode"))),
        ..PartialOptions::default()
    }
    .resolve()
    .unwrap();
    // A camera that frames a scene takes a field of view of its own.
    let cube = raytracer::math::Aabb {
        min: raytracer::math::Vec3::ZERO,
        max: raytracer::math::Vec3::ONE,
    };
    let framed_fov = PartialOptions::default()
        .framed(cube)
        .resolve()
        .unwrap()
        .fov_degrees;
    let vector = |v: raytracer::math::Vec3| format!("{},{},{}", v.x, v.y, v.z);
    let both = |full: u32, path: u32| format!("{full}; {path} in path mode");
    let expected = [
        ("--width", full.width.to_string()),
        ("--height", full.height.to_string()),
        (
            "--fov",
            format!(
                "{}; {framed_fov} when the camera frames the scene",
                full.fov_degrees
            ),
        ),
        // Left out, the camera frames the scene (tests/first_image.rs checks it).
        ("--look-from", "framed".to_string()),
        ("--look-to", "framed".to_string()),
        ("--up", vector(full.up)),
        ("--depth", both(full.depth, path.depth)),
        ("--mode", full.mode.name().to_string()),
        (
            "--spp",
            format!(
                "{}; {} in full mode under the default light rig; {} in path mode",
                full.samples_per_pixel,
                PartialOptions::default()
                    .resolve_for(true, false)
                    .unwrap()
                    .samples_per_pixel,
                path.samples_per_pixel
            ),
        ),
        ("--exposure", full.exposure.to_string()),
        ("--tonemap", path.tonemap.name().to_string()),
        ("--aperture-radius", full.aperture_radius.to_string()),
        // None: the distance to the target (tests/look.rs checks the lens).
        (
            "--focus-distance",
            "the distance from --look-from to --look-to".to_string(),
        ),
        ("--seed", full.seed.to_string()),
        ("--threads", "0".to_string()),
        // The environment is the scene's unless a flag sets it: strength 1 and no
        // turn when neither does (tests/environment.rs).
        ("--env", "the scene's; none".to_string()),
        ("--env-strength", "the scene's; 1".to_string()),
        ("--env-rotation", "the scene's; 0".to_string()),
        ("--background", "the environment".to_string()),
    ];
    for (flag, value) in &expected {
        assert_eq!(
            defaults.get(*flag),
            Some(&vec![value.clone()]),
            "{flag}: --help says {:?}, the program uses {value}",
            defaults.get(*flag)
        );
    }
    // Every flag that states a default is checked above.
    for flag in defaults.keys() {
        assert!(
            expected.iter().any(|(f, _)| f == flag),
            "{flag} is not checked"
        );
    }
    // The empty scene keeps the origin, as --help says of --look-from.
    assert_eq!(vector(full.look_from), "0,0,0");
    assert!(help.contains("An empty scene, or --look-to alone, keeps 0,0,0."));
    for flag in [
        "--output",
        "--stats",
        "--denoise",
        "--no-default-light",
        "--quiet",
    ] {
        assert!(help.contains(flag), "--help lacks {flag}");
    }
    let top = raytracer(&["--help"]);
    let top = String::from_utf8_lossy(&top.stdout);
    for said in ["OBJ/MTL, PLY, glTF 2.0 and TOML", "path"] {
        assert!(
            top.contains(said),
            "raytracer --help lacks {said:?}:\n{top}"
        );
    }
    let info = raytracer(&["info", "--help"]);
    assert!(String::from_utf8_lossy(&info.stdout).contains("glTF 2.0"));
}

/// The shell completions and the man page come from the same definitions as
/// `--help`: each names every flag of `render`.
#[test]
fn completions_and_man_page_are_generated_with_every_flag() {
    let flags = [
        "--look-from",
        "--no-default-light",
        "--denoise",
        "--spp",
        "--exposure",
    ];
    for shell in ["bash", "zsh", "fish", "elvish", "powershell"] {
        let output = raytracer(&["completions", shell]);
        assert!(output.status.success(), "{shell}: {}", stderr(&output));
        let script = String::from_utf8_lossy(&output.stdout);
        for flag in flags {
            // fish writes long flags without their dashes (`-l look-from`).
            assert!(
                script.contains(flag.trim_start_matches('-')),
                "{shell} lacks {flag}"
            );
        }
        assert!(
            script.contains("render"),
            "{shell} lacks the render subcommand"
        );
    }
    let output = raytracer(&["man"]);
    assert!(output.status.success(), "{}", stderr(&output));
    let page = String::from_utf8_lossy(&output.stdout);
    assert!(
        page.starts_with(".ie") && page.contains(".TH raytracer 1"),
        "{page}"
    );
    for section in [
        ".SH \"RAYTRACER RENDER\"",
        ".SH \"RAYTRACER BENCH\"",
        ".SH \"RAYTRACER INFO\"",
    ] {
        assert!(page.contains(section), "the man page lacks {section}");
    }
    for flag in flags {
        // roff escapes each hyphen: \-\-look\-from.
        let roff = flag.replace('-', "\\-");
        assert!(page.contains(&roff), "the man page lacks {flag}");
    }
    // Generating them is no subcommand to advertise: --help does not list them.
    let help = String::from_utf8_lossy(&raytracer(&["--help"]).stdout).into_owned();
    assert!(
        !help.contains("completions") && !help.contains(" man "),
        "{help}"
    );
    assert_eq!(raytracer(&["completions", "tcsh"]).status.code(), Some(2));
}

#[test]
fn images_are_identical_for_any_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let scene = box_scene();
    let render = |threads: &str| {
        let out = dir.path().join(format!("j{threads}.png"));
        let output = raytracer(&[
            "render",
            scene.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--width",
            "96",
            "--height",
            "64",
            "--look-from",
            "0,0.7,1.75",
            "--look-to",
            "0,0.7,0",
            "-j",
            threads,
        ]);
        assert!(output.status.success(), "{}", stderr(&output));
        std::fs::read(&out).unwrap()
    };
    assert_eq!(render("1"), render("2"));
    assert_eq!(render("1"), render("3"));
}

#[test]
fn a_file_of_no_scene_format_is_refused_naming_it_and_the_formats() {
    let dir = tempfile::tempdir().unwrap();
    let readme = dir.path().join("README.md");
    std::fs::write(&readme, "# not a scene\nv 0 0 0\n").unwrap();
    let out = dir.path().join("out.png");
    for command in [
        &[
            "render",
            readme.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ][..],
        &["info", readme.to_str().unwrap()],
    ] {
        let output = raytracer(command);
        assert_eq!(output.status.code(), Some(2), "{command:?}");
        let message = stderr(&output);
        assert!(message.contains(&readme.display().to_string()), "{message}");
        assert!(message.contains(".obj, .ply, .toml"), "{message}");
    }
    assert!(!out.exists(), "no output is written");
}

#[test]
fn scene_extensions_are_matched_in_any_case_and_under_gz() {
    use std::io::Write;
    let dir = tempfile::tempdir().unwrap();
    let text = b"v -1 -1 -2\nv 1 -1 -2\nv 0 1 -2\nf 1 2 3\nP 0 0 0 1 1 1\n";
    let plain = dir.path().join("tri.OBJ");
    std::fs::write(&plain, text).unwrap();
    let packed = dir.path().join("tri.Obj.GZ");
    let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    encoder.write_all(text).unwrap();
    std::fs::write(&packed, encoder.finish().unwrap()).unwrap();
    for scene in [plain, packed] {
        let out = dir.path().join("out.png");
        let output = raytracer(&[
            "render",
            scene.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--width",
            "8",
            "--height",
            "8",
        ]);
        assert!(
            output.status.success(),
            "{}: {}",
            scene.display(),
            stderr(&output)
        );
    }
}

/// What `--stats` prints for a 40x30 render of the box scene into `dir/file`, with
/// `extra` arguments.
fn stats_of_small_render(dir: &std::path::Path, file: &str, extra: &[&str]) -> String {
    let out = dir.join(file);
    let scene = box_scene();
    let mut args = vec![
        "render",
        scene.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--width",
        "40",
        "--height",
        "30",
        "--stats",
    ];
    args.extend_from_slice(extra);
    let output = raytracer(&args);
    assert!(output.status.success(), "{}", stderr(&output));
    stderr(&output)
}

/// `--stats` names every stage of the pipeline, each on its own line (their times are
/// not checked): in full mode the traced ray packets apart from the shading, in path
/// mode tracing and shading together; post-processing and PNG encoding (with the
/// file's size) apart; EXR encoding without post-processing.
#[test]
fn stats_show_every_stage() {
    let dir = tempfile::tempdir().unwrap();
    let stages = |mode: &str, file: &str| {
        let text = stats_of_small_render(dir.path(), file, &["--mode", mode, "--spp", "1"]);
        let starts: Vec<String> = text
            .lines()
            .map(|line| {
                let words: Vec<&str> = line.split_whitespace().collect();
                let end = words
                    .iter()
                    .position(|w| w.parse::<f64>().is_ok())
                    .unwrap_or(words.len());
                words[..end].join(" ")
            })
            .collect();
        (text, starts)
    };
    let (text, full) = stages("full", "full.png");
    for stage in [
        "parse",
        "BVH build",
        "binary tree",
        "8-wide collapse",
        "packets",
        "trace",
        "shading",
        "render total",
        "post-processing",
        "PNG encoding",
        "total",
    ] {
        assert!(
            full.iter().any(|s| s == stage),
            "no '{stage}' line in:\n{text}"
        );
    }
    assert!(text.contains("kB written"), "{text}");
    let (text, path) = stages("path", "path.png");
    for stage in [
        "parse",
        "BVH build",
        "trace + shading",
        "post-processing",
        "PNG encoding",
    ] {
        assert!(
            path.iter().any(|s| s == stage),
            "no '{stage}' line in:\n{text}"
        );
    }
    let (text, exr) = stages("full", "full.exr");
    assert!(exr.iter().any(|s| s == "EXR encoding"), "{text}");
    assert!(!exr.iter().any(|s| s == "post-processing"), "{text}");
}

/// Where the OS reports them, `--stats` gives each stage's CPU time (all threads)
/// and page faults beside its wall time: the stages of the pipeline and the steps
/// of the BVH build, and the whole run, whose counts are at least those of the
/// stages in it.
#[cfg(unix)]
#[test]
fn stats_show_cpu_time_and_page_faults_of_each_stage() {
    let dir = tempfile::tempdir().unwrap();
    let text = stats_of_small_render(dir.path(), "stats.png", &[]);
    // `name  <wall> ms  <cpu> ms CPU  <faults> faults ...` -> (cpu, faults)
    let usage = |stage: &str| -> (f64, u64) {
        let line = text
            .lines()
            .find(|line| {
                line.trim_start().starts_with(stage)
                    && line.trim_start()[stage.len()..].starts_with(' ')
            })
            .unwrap_or_else(|| panic!("no '{stage}' line in:\n{text}"));
        let words: Vec<&str> = line.split_whitespace().collect();
        let cpu_at = words
            .iter()
            .position(|&w| w == "CPU")
            .unwrap_or_else(|| panic!("no CPU time in '{line}'"));
        let faults_at = words
            .iter()
            .position(|&w| w == "faults")
            .unwrap_or_else(|| panic!("no faults in '{line}'"));
        assert_eq!(words[cpu_at - 1], "ms", "{line}");
        let cpu: f64 = words[cpu_at - 2].parse().expect("CPU time in ms");
        let faults: u64 = words[faults_at - 1].parse().expect("a count of faults");
        assert!(cpu >= 0.0, "{line}");
        (cpu, faults)
    };
    let stages = [
        "parse",
        "BVH build",
        "render total",
        "post-processing",
        "PNG encoding",
        "file write",
    ];
    let (total_cpu, total_faults) = usage("total");
    let (mut cpu, mut faults) = (0.0, 0);
    for stage in stages {
        let (c, f) = usage(stage);
        cpu += c;
        faults += f;
    }
    for step in ["binary tree", "8-wide collapse", "packets"] {
        usage(step);
    }
    // Each column is rounded to 0.1 ms.
    assert!(cpu <= total_cpu + 0.05 * stages.len() as f64, "{text}");
    assert!(faults <= total_faults, "{text}");
    // Loading a program and reading a scene touch fresh pages.
    assert!(total_faults > 0, "{text}");
}

/// `raytracer bench` reports incoherent bounce rays (one per primary hit, also through
/// the array query) and the primary and shadow rays in packets, with the same hit
/// counts as ray by ray; and
/// `--dump-rays` writes the triangles and every ray for the Embree benchmark.
#[test]
fn bench_reports_incoherent_rays_and_packets_and_dumps_the_rays() {
    let dir = tempfile::tempdir().unwrap();
    let rays = dir.path().join("rays.bin");
    let scene = box_scene();
    let output = raytracer(&[
        "bench",
        scene.to_str().unwrap(),
        "--width",
        "32",
        "--height",
        "24",
        "--look-from",
        "-0.5,0.7,1.75",
        "--look-to=0,0.7,0",
        "--repeat",
        "1",
        "--dump-rays",
        rays.to_str().unwrap(),
    ]);
    assert!(output.status.success(), "{}", stderr(&output));
    let json = String::from_utf8(output.stdout).unwrap();
    let number = |key: &str| -> f64 {
        let start = json
            .find(&format!("\"{key}\": "))
            .unwrap_or_else(|| panic!("no {key} in {json}"))
            + key.len()
            + 4;
        let end = json[start..].find([',', '}']).unwrap() + start;
        json[start..end].trim().parse().unwrap()
    };
    let hits = number("primary_hits");
    assert!(hits > 100.0, "{json}");
    assert_eq!(
        number("incoherent_rays"),
        hits,
        "one bounce per primary hit"
    );
    assert!(number("incoherent_hits") > 0.0, "{json}");
    for key in [
        "incoherent_mrays_per_s",
        "incoherent_stream_mrays_per_s",
        "shadow_stream_mrays_per_s",
        "occlusion_mrays_per_s",
        "occlusion_stream_mrays_per_s",
        "primary_packet_mrays_per_s",
        "shadow_packet_mrays_per_s",
        "primary_mrays_per_cpu_s",
    ] {
        assert!(number(key) > 0.0, "{key}: {json}");
    }
    // The file: header, vertices, triangles, then the primary rays (one per pixel).
    let bytes = std::fs::read(&rays).unwrap();
    assert_eq!(&bytes[..8], b"RTBENCH1");
    let u32_at = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
    let vertices = u32_at(8);
    let triangles = u32_at(12 + 12 * vertices);
    let primary = u32_at(16 + 12 * vertices + 12 * triangles);
    assert!(vertices > 0 && triangles > 0);
    assert_eq!(primary, 32 * 24);
}

#[test]
fn a_reader_that_stops_early_is_no_error() {
    // `raytracer info FILE | head -3`, `raytracer man | head`: the reader has gone
    // (here before the command writes, so its write fails for certain).
    let scene = support::cornell_box();
    for args in [
        &["info", scene.to_str().unwrap()][..],
        &["man"],
        &["completions", "bash"],
    ] {
        let (reader, writer) = std::io::pipe().unwrap();
        drop(reader);
        let output = std::process::Command::new(env!("CARGO_BIN_EXE_raytracer"))
            .args(args)
            .stdout(writer)
            .stderr(std::process::Stdio::piped())
            .output()
            .unwrap();
        assert!(output.status.success(), "{args:?}: {}", stderr(&output));
        assert!(stderr(&output).is_empty(), "{args:?}: {}", stderr(&output));
    }
}
