//! The README and the docs against the program: the quick start's commands run as
//! written, every flag the docs' commands use exists, the install command uses the
//! lock file, and no page cites the specification file a clone does not have.
// The examples run from a folder of symbolic links to the repository's files.
#![cfg(unix)]

use std::path::{Path, PathBuf};
use std::process::Command;

/// The repository's root, where the README's commands are meant to run.
fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn read(relative: &str) -> String {
    std::fs::read_to_string(root().join(relative)).unwrap()
}

/// The lines of the first ```sh block after the heading `heading` of `markdown`.
fn first_sh_block<'a>(markdown: &'a str, heading: &str) -> Vec<&'a str> {
    let after = markdown
        .split_once(&format!("\n{heading}\n"))
        .unwrap_or_else(|| panic!("no heading {heading:?}"))
        .1;
    let block = after.split_once("```sh\n").expect("no sh block").1;
    let block = block.split_once("```").expect("unclosed block").0;
    block.lines().filter(|l| !l.trim().is_empty()).collect()
}

/// Every `raytracer ...` command in the ```sh blocks of `markdown`.
fn commands(markdown: &str) -> Vec<String> {
    let mut found = Vec::new();
    let mut in_sh = false;
    for line in markdown.lines() {
        match line.trim() {
            "```sh" => in_sh = true,
            "```" => in_sh = false,
            l if in_sh && l.starts_with("raytracer ") => found.push(l.to_string()),
            _ => {}
        }
    }
    found
}

/// Width and height of a PNG file, from its IHDR chunk.
fn png_size(path: &Path) -> (u32, u32) {
    let bytes = std::fs::read(path).unwrap();
    assert_eq!(
        &bytes[..8],
        b"\x89PNG\r\n\x1a\n",
        "{} is no PNG",
        path.display()
    );
    let be = |at: usize| u32::from_be_bytes(bytes[at..at + 4].try_into().unwrap());
    (be(16), be(20))
}

/// The quick start's commands, run exactly as written (split on spaces, as a shell
/// splits these quote-free lines) from a folder that sees the repository's
/// `examples/` and `tests/` where the README's paths expect them, so that their
/// images land in a temporary folder rather than in the checkout.
#[test]
fn quick_start_commands_run_as_written() {
    let readme = read("README.md");
    let lines = first_sh_block(&readme, "## Quick start");
    assert_eq!(
        lines.len(),
        3,
        "the quick start promises three commands: {lines:?}"
    );
    let dir = tempfile::tempdir().unwrap();
    for folder in ["examples", "tests"] {
        std::os::unix::fs::symlink(root().join(folder), dir.path().join(folder)).unwrap();
    }
    for line in lines {
        assert!(
            !line.contains(['"', '\'', '$', '|', '>']),
            "not a plain command: {line}"
        );
        let words: Vec<&str> = line.split_whitespace().collect();
        assert_eq!(words[0], "raytracer", "{line}");
        let output = Command::new(env!("CARGO_BIN_EXE_raytracer"))
            .args(&words[1..])
            .current_dir(dir.path())
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(output.status.success(), "{line}\n{stderr}");
        assert!(!stderr.contains("error"), "{line}\n{stderr}");
        let out = words
            .iter()
            .position(|w| *w == "-o")
            .map(|i| words[i + 1])
            .expect("each command writes an image with -o");
        // None of the three sets a size: the default, 640x480.
        assert_eq!(png_size(&dir.path().join(out)), (640, 480), "{line}");
    }
}

/// The flags of every `raytracer render` command in the README and docs/ exist:
/// `render --help` lists each one.
#[test]
fn every_documented_command_uses_flags_that_exist() {
    let help = Command::new(env!("CARGO_BIN_EXE_raytracer"))
        .args(["render", "--help"])
        .output()
        .unwrap();
    let help = String::from_utf8(help.stdout).unwrap();
    let mut pages = vec!["README.md".to_string()];
    for entry in std::fs::read_dir(root().join("docs")).unwrap() {
        let name = entry.unwrap().file_name().into_string().unwrap();
        if name.ends_with(".md") {
            pages.push(format!("docs/{name}"));
        }
    }
    let mut checked = 0;
    for page in &pages {
        for command in commands(&read(page)) {
            if !command.starts_with("raytracer render ") {
                continue;
            }
            for flag in command.split_whitespace().filter(|w| w.starts_with("--")) {
                let flag = flag.split('=').next().unwrap();
                assert!(
                    help.contains(&format!("{flag} ")) || help.contains(&format!("{flag}\n")),
                    "{page}: {flag} is no flag of render: {command}"
                );
                checked += 1;
            }
        }
    }
    assert!(
        checked > 20,
        "only {checked} flags found: the extraction broke"
    );
}

#[test]
fn install_uses_the_lock_file_and_no_page_cites_a_file_a_clone_lacks() {
    let readme = read("README.md");
    let install = first_sh_block(&readme, "## Install");
    assert_eq!(install[0], "cargo install --path . --locked");
    for page in [
        "README.md",
        "docs/cli.md",
        "docs/python.md",
        "docs/scene-format.md",
    ] {
        assert!(!read(page).contains("SPEC.md"), "{page} cites SPEC.md");
    }
    // The pages the README links to are there.
    for link in readme.split("](").skip(1) {
        let target = link.split([')', '#']).next().unwrap();
        if target.is_empty() || target.starts_with("http") {
            continue;
        }
        assert!(
            root().join(target).exists(),
            "README links to missing {target}"
        );
    }
}
