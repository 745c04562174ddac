//! The folder a fuzz process gives its scene files: private to the process, made
//! once, left in the system's temporary folder when libFuzzer stops the process.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// An empty folder of this process's own.
pub fn private() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("raytracer-fuzz-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("cannot create the fuzz folder");
        dir
    })
}

/// The private folder with `m.mtl` holding the fixed materials.
#[allow(dead_code)]
pub fn with_fixed_mtl() -> &'static Path {
    static READY: OnceLock<()> = OnceLock::new();
    let dir = private();
    READY.get_or_init(|| {
        let mtl = dir.join(super::fuzz_checks::MTL_NAME);
        std::fs::write(mtl, super::fuzz_checks::FIXED_MTL).expect("cannot write the MTL");
    });
    dir
}

/// A rayon pool of one thread.
#[allow(dead_code)]
pub fn single_thread() -> &'static rayon::ThreadPool {
    static POOL: OnceLock<rayon::ThreadPool> = OnceLock::new();
    POOL.get_or_init(|| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .expect("cannot start a worker thread")
    })
}

/// The private folder with the meshes and materials of `fuzz_checks::TOML_MESHES`.
#[allow(dead_code)]
pub fn with_toml_meshes() -> &'static Path {
    static READY: OnceLock<()> = OnceLock::new();
    let dir = private();
    READY.get_or_init(|| super::fuzz_checks::write_toml_meshes(dir));
    dir
}
