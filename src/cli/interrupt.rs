//! Ctrl-C for the `raytracer` binary (not part of the library): nothing is lost, and
//! nothing is said that is not true.
//!
//! A signal ends the process without running destructors, so the temporary file of an
//! image being encoded would stay behind. The handler takes the lock every output's
//! final rename takes ([`raytracer::output::lock_commits`]) and keeps it until the
//! process exits, so the rename either happened before (the output holds the complete
//! new image: exit 0, saying so) or never will (the previous file stays, the temporary
//! file is removed: exit 130, 128 + SIGINT, whichever of SIGINT, SIGTERM or SIGHUP
//! arrived).

use std::path::PathBuf;

use anyhow::Context;

/// Exit code after an interrupt that stopped the output: 128 + SIGINT, as shells
/// report it.
const EXIT_INTERRUPTED: u8 = 130;

/// Installs the handler for a render writing `output`. The handler runs on its own
/// thread, never on the render's.
pub fn install(output: PathBuf) -> anyhow::Result<()> {
    ctrlc::set_handler(move || {
        let commits = raytracer::output::lock_commits();
        if commits.contains(&output) {
            eprintln!(
                "interrupted after {} was written; it holds the complete new image",
                output.display()
            );
            std::process::exit(0);
        }
        if let Err(e) = raytracer::output::remove_temp_files(&output) {
            eprintln!("error: cannot remove the temporary file: {e}");
        }
        eprintln!("interrupted; {} left as it was", output.display());
        // Exits with the lock held: the render's rename can no longer happen.
        std::process::exit(EXIT_INTERRUPTED.into());
    })
    .context("cannot install the Ctrl-C handler")
}
