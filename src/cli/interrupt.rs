//! Ctrl-C for the `raytracer` binary (not part of the library): nothing is lost.
//!
//! A signal ends the process without running destructors, so the temporary file of a
//! PNG being encoded would stay behind. The handler removes it and exits with 130
//! (128 + SIGINT), whichever of SIGINT, SIGTERM or SIGHUP arrived. The output file is
//! only ever replaced by an atomic rename, so it is either the previous file or the
//! complete new one.

use std::path::PathBuf;

use anyhow::Context;

/// Exit code after an interrupt: 128 + SIGINT, as shells report it.
const EXIT_INTERRUPTED: u8 = 130;

/// Installs the handler for a render writing `output`. The handler runs on its own
/// thread, never on the render's.
pub fn install(output: PathBuf) -> anyhow::Result<()> {
    ctrlc::set_handler(move || {
        if let Err(e) = raytracer::film::remove_temp_files(&output) {
            eprintln!("error: cannot remove the temporary file: {e}");
        }
        eprintln!("interrupted; {} left as it was", output.display());
        std::process::exit(EXIT_INTERRUPTED.into());
    })
    .context("cannot install the Ctrl-C handler")
}
