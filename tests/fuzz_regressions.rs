//! Replays, under `cargo test`, every input a fuzz target ever failed on
//! (`tests/data/fuzz-regressions/<target>/`, one file per bug, named after it) and
//! the committed fuzz corpus (`fuzz/corpus/<target>/`), through the same checks
//! the fuzz targets run (`tests/support/fuzz_checks.rs`).

use crate::fuzz_checks;

use std::fs;
use std::path::{Path, PathBuf};

use fuzz_checks::{FIXED_MTL, MTL_NAME};

/// The files of `dir` relative to the crate root, sorted; none if it is missing.
fn inputs(dir: &str) -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join(dir);
    let mut files: Vec<PathBuf> = match fs::read_dir(&dir) {
        Ok(entries) => entries.map(|e| e.unwrap().path()).collect(),
        Err(_) => Vec::new(),
    };
    files.sort();
    files
}

/// Runs `check` on each input of the target, naming the input that fails.
fn replay(target: &str, check: impl Fn(&[u8])) -> usize {
    let mut count = 0;
    for dir in [
        format!("tests/data/fuzz-regressions/{target}"),
        format!("fuzz/corpus/{target}"),
    ] {
        for path in inputs(&dir) {
            let data = fs::read(&path).unwrap();
            let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| check(&data)));
            assert!(
                outcome.is_ok(),
                "{} fails the {target} check",
                path.display()
            );
            count += 1;
        }
    }
    count
}

#[test]
fn obj_regressions_and_corpus_pass() {
    let dir = tempfile::tempdir().unwrap();
    fs::write(dir.path().join(MTL_NAME), FIXED_MTL).unwrap();
    let count = replay("obj", |data| fuzz_checks::check_obj(data, dir.path()));
    assert!(count > 0, "no obj inputs found");
}

#[test]
fn mtl_regressions_and_corpus_pass() {
    let count = replay("mtl", fuzz_checks::check_mtl);
    assert!(count > 0, "no mtl inputs found");
}

#[test]
fn pipeline_regressions_and_corpus_pass() {
    let dir = tempfile::tempdir().unwrap();
    let count = replay("pipeline", |data| {
        fuzz_checks::check_pipeline(data, dir.path())
    });
    assert!(count > 0, "no pipeline inputs found");
}

#[test]
fn ply_regressions_and_corpus_pass() {
    let count = replay("ply", fuzz_checks::check_ply);
    assert!(count > 0, "no ply inputs found");
}

#[test]
fn toml_regressions_and_corpus_pass() {
    let dir = tempfile::tempdir().unwrap();
    fuzz_checks::write_toml_meshes(dir.path());
    let count = replay("toml", |data| fuzz_checks::check_toml(data, dir.path()));
    assert!(count > 0, "no toml inputs found");
}

#[test]
fn gltf_regressions_and_corpus_pass() {
    let dir = tempfile::tempdir().unwrap();
    let count = replay("gltf", |data| fuzz_checks::check_gltf(data, dir.path()));
    assert!(count > 0, "no gltf inputs found");
}

#[test]
fn textures_regressions_and_corpus_pass() {
    let dir = tempfile::tempdir().unwrap();
    let count = replay("textures", |data| {
        fuzz_checks::check_textures(data, dir.path())
    });
    assert!(count > 0, "no textures inputs found");
}
