//! `docs/errors.md` against the program: every example in its ```console blocks is
//! run as written and must print exactly what the page shows, with the exit code it
//! shows; and the messages this page promises beyond the examples (the default light
//! turned off by a scene file) say what it says.
// The examples run from a folder of symbolic links to the repository's files.
#![cfg(unix)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// One example: the command's arguments (after `raytracer`), the lines shown under
/// it, and the exit code shown (`None`: no `[exit N]` line, as for `info`, whose
/// lines are part of its stdout).
struct Example {
    args: Vec<String>,
    shown: Vec<String>,
    exit: Option<i32>,
}

fn examples(page: &str) -> Vec<Example> {
    let mut found: Vec<Example> = Vec::new();
    let mut in_console = false;
    for line in page.lines() {
        if line.starts_with("```") {
            in_console = line == "```console";
            continue;
        }
        if !in_console {
            continue;
        }
        if let Some(command) = line.strip_prefix("$ raytracer ") {
            found.push(Example {
                args: command.split_whitespace().map(String::from).collect(),
                shown: Vec::new(),
                exit: None,
            });
        } else if let Some(code) = line.strip_prefix("[exit ") {
            let example = found.last_mut().expect("[exit] before any command");
            example.exit = Some(code.trim_end_matches(']').parse().unwrap());
        } else {
            let example = found.last_mut().expect("output before any command");
            example.shown.push(line.to_string());
        }
    }
    found
}

/// Runs `raytracer ARGS` in `dir`.
fn run(dir: &Path, args: &[String]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_raytracer"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap()
}

/// A folder where the page's relative paths (`examples/...`, `tests/...`) lead to the
/// repository's files, and the images the examples write land in a temporary folder.
fn workdir() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    for folder in ["examples", "tests"] {
        std::os::unix::fs::symlink(root().join(folder), dir.path().join(folder)).unwrap();
    }
    dir
}

#[test]
fn every_example_of_errors_md_prints_what_the_page_shows() {
    let page = std::fs::read_to_string(root().join("docs/errors.md")).unwrap();
    let examples = examples(&page);
    assert!(
        examples.len() >= 15,
        "only {} examples found",
        examples.len()
    );
    let mut kinds = (0, 0);
    for example in &examples {
        let dir = workdir();
        let output = run(dir.path(), &example.args);
        let command = format!("raytracer {}", example.args.join(" "));
        let stderr = String::from_utf8_lossy(&output.stderr);
        match example.exit {
            Some(code) => {
                let mut shown = example.shown.join("\n");
                shown.push('\n');
                assert_eq!(stderr, shown, "{command}: stderr differs from the page");
                assert_eq!(output.status.code(), Some(code), "{command}: exit code");
                if code == 0 {
                    kinds.1 += 1;
                } else {
                    kinds.0 += 1;
                    // An error leaves no image behind.
                    assert!(!dir.path().join("out.png").exists(), "{command}");
                }
            }
            None => {
                let stdout = String::from_utf8_lossy(&output.stdout);
                assert!(output.status.success(), "{command}: {stderr}");
                for line in &example.shown {
                    assert!(
                        stdout.lines().any(|l| l == line),
                        "{command}: no {line:?} in\n{stdout}"
                    );
                }
            }
        }
    }
    assert!(
        kinds.0 >= 10 && kinds.1 >= 5,
        "errors and warnings: {kinds:?}"
    );
}

/// When a scene file turns the default light off, the warning names its line and key,
/// so that a user who gave no flag finds what did.
#[test]
fn the_default_light_off_by_a_scene_file_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let obj = root().join("examples/gltf-box/BoxTextured.glb");
    let scene = dir.path().join("scene.toml");
    std::fs::write(
        &scene,
        format!(
            "[render]\nmode = \"path\"\nspp = 1\ndefault_light = false\n\n[[mesh]]\nfile = {:?}\n",
            obj.to_str().unwrap()
        ),
    )
    .unwrap();
    let args: Vec<String> = ["render", "scene.toml", "-o", "out.png", "--width", "16"]
        .map(String::from)
        .to_vec();
    let output = run(dir.path(), &args);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    let warning = "warning: the scene has no lights (no light sources, no emitting surfaces): path mode renders it black (the default light is off: scene.toml:4: render.default_light)";
    assert!(stderr.lines().any(|l| l == warning), "{stderr}");
}
