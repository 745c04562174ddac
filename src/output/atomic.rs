//! Replacing an output file only by a complete one: every encoder writes a temporary
//! file beside the output, renamed over it once complete, under a lock that an
//! interrupt handler takes too ([`lock_commits`]), so that what a handler reports
//! is what is on disk.

use std::fs;
use std::io;
use std::path::{Path, PathBuf};

/// Why an image could not be written.
#[derive(Debug, thiserror::Error)]
#[error("cannot write {}: {error}", path.display())]
pub struct WriteError {
    /// The file we were asked to write.
    pub path: PathBuf,
    /// What failed (part of the message, so not also a `source`).
    pub error: io::Error,
}

/// Writes `path` atomically: `encode` fills a temporary file in the same folder (named
/// `.raytracer-*.EXTENSION.tmp`), which is synced and renamed over `path` only once
/// complete, so readers never see half a file. A failure leaves any existing file
/// untouched and no temporary file behind.
///
/// # Errors
/// `path` is a folder, its folder is missing or not writable, the disk is full, or
/// `encode` failed.
pub(crate) fn write_atomically(
    path: &Path,
    extension: &str,
    encode: impl FnOnce(&mut fs::File) -> io::Result<()>,
) -> Result<(), WriteError> {
    let fail = |error| WriteError {
        path: path.to_path_buf(),
        error,
    };
    check_output(path)?;
    let suffix = format!(".{extension}.tmp");
    let mut temp = create_temp_file(output_folder(path), &suffix).map_err(fail)?;
    encode(temp.as_file_mut()).map_err(fail)?;
    temp.as_file().sync_all().map_err(fail)?;
    set_output_permissions(temp.path(), path).map_err(fail)?;
    test_pause("RAYTRACER_TEST_PAUSE_BEFORE_COMMIT");
    {
        // The rename and the record of it happen under the lock an interrupt handler
        // takes (`lock_commits`), so the handler sees either the old file and no
        // record, or the new file and its record: never a mix.
        let mut commits = lock_commits();
        temp.persist(path)
            .map_err(|e| fail(without_path(e.error)))?;
        commits.paths.push(path.to_path_buf());
    }
    test_pause("RAYTRACER_TEST_PAUSE_AFTER_COMMIT");
    Ok(())
}

/// The outputs this process has renamed into place, guarded by the lock that orders
/// each rename against an interrupt handler.
#[derive(Debug, Default)]
pub struct Commits {
    paths: Vec<PathBuf>,
}

impl Commits {
    /// Whether `path` (as given to the writer) was replaced by a complete new file.
    pub fn contains(&self, path: &Path) -> bool {
        self.paths.iter().any(|p| p == path)
    }
}

static COMMITS: std::sync::Mutex<Commits> = std::sync::Mutex::new(Commits { paths: Vec::new() });

/// Takes the lock every output's final rename takes. An interrupt handler holds it
/// until the process exits: a rename not yet started then never happens, and one that
/// happened is in [`Commits::contains`], so what the handler reports is what is on disk.
pub fn lock_commits() -> std::sync::MutexGuard<'static, Commits> {
    // A panic while the lock was held cannot leave `Commits` half-updated (one push).
    COMMITS
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Test hook: when the environment variable `name` holds a number of milliseconds,
/// says so on stderr and sleeps that long, so that a test can send a signal at an
/// exact step of the write instead of at a lucky moment.
fn test_pause(name: &str) {
    if let Some(ms) = std::env::var_os(name).and_then(|v| v.to_str()?.parse::<u64>().ok()) {
        eprintln!("{name}: pausing {ms} ms");
        std::thread::sleep(std::time::Duration::from_millis(ms));
    }
}

/// Checks, before any work, that an image can be written to `path`: its folder
/// exists and takes new files (tried by creating and removing a temporary file), and
/// `path` is neither a folder nor a read-only file.
///
/// # Errors
/// The first of those that fails, naming `path`.
pub fn check_output(path: &Path) -> Result<(), WriteError> {
    let fail = |error| WriteError {
        path: path.to_path_buf(),
        error,
    };
    let folder = output_folder(path);
    match fs::metadata(folder) {
        Ok(m) if m.is_dir() => {}
        Ok(_) => {
            let message = format!("{} is not a folder", folder.display());
            return Err(fail(io::Error::new(io::ErrorKind::NotADirectory, message)));
        }
        Err(e) if e.kind() == io::ErrorKind::NotFound => {
            let message = format!("folder {} does not exist", folder.display());
            return Err(fail(io::Error::new(io::ErrorKind::NotFound, message)));
        }
        Err(e) => return Err(fail(e)),
    }
    if let Ok(m) = fs::metadata(path) {
        if m.is_dir() {
            let message = "is a directory";
            return Err(fail(io::Error::new(io::ErrorKind::IsADirectory, message)));
        }
        // Renaming over a read-only file would work, but would not respect it.
        if m.permissions().readonly() {
            let message = "the file is read-only";
            return Err(fail(io::Error::new(
                io::ErrorKind::PermissionDenied,
                message,
            )));
        }
    }
    create_temp_file(folder, PROBE_SUFFIX)
        .map(drop)
        .map_err(fail)
}

/// Removes the temporary files this process has open for writing `output` (see
/// [`crate::Image::write_png`]), and returns how many it removed. Meant for a Ctrl-C
/// handler, since exiting from one skips the destructors that would remove them.
///
/// # Errors
/// The output's folder cannot be listed, or a file cannot be removed.
pub fn remove_temp_files(output: &Path) -> io::Result<usize> {
    let prefix = temp_prefix();
    let mut removed = 0;
    for entry in fs::read_dir(output_folder(output))? {
        let entry = entry?;
        let name = entry.file_name();
        let name = name.to_string_lossy();
        if name.starts_with(&prefix) {
            match fs::remove_file(entry.path()) {
                Ok(()) => removed += 1,
                // Renamed into place or removed meanwhile: nothing left to clean.
                Err(e) if e.kind() == io::ErrorKind::NotFound => {}
                Err(e) => return Err(e),
            }
        }
    }
    Ok(removed)
}

/// Temporary files are named `.raytracer-<pid>-<random><suffix>`: hidden, and
/// carrying the process id so that [`remove_temp_files`] takes only its own.
fn temp_prefix() -> String {
    format!(".raytracer-{}-", std::process::id())
}

/// Suffix of the empty file [`check_output`] creates to test the folder.
const PROBE_SUFFIX: &str = ".probe.tmp";

fn create_temp_file(folder: &Path, suffix: &str) -> io::Result<tempfile::NamedTempFile> {
    tempfile::Builder::new()
        .prefix(&temp_prefix())
        .suffix(suffix)
        .tempfile_in(folder)
        .map_err(without_path)
}

/// The folder `path` goes into (`.` for a bare file name).
fn output_folder(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// tempfile's errors end with ` at path "<temporary file>"`, a name that means
/// nothing to the user: keep only what the system said.
fn without_path(error: io::Error) -> io::Error {
    let message = error.to_string();
    match message.find(" at path ") {
        Some(end) => io::Error::new(error.kind(), &message[..end]),
        None => error,
    }
}

/// Gives the finished temporary file the permissions the output should have: an
/// existing file's, or the usual 0644 rather than the temporary file's private 0600.
#[cfg(unix)]
fn set_output_permissions(temp: &Path, output: &Path) -> io::Result<()> {
    use std::os::unix::fs::PermissionsExt;
    let permissions = match fs::metadata(output) {
        Ok(m) => m.permissions(),
        Err(_) => fs::Permissions::from_mode(0o644),
    };
    fs::set_permissions(temp, permissions)
}

#[cfg(not(unix))]
fn set_output_permissions(_temp: &Path, _output: &Path) -> io::Result<()> {
    Ok(())
}
