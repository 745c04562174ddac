//! The linear framebuffer, post-processing to 8 bits, and PNG output.

use std::fs;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use crate::math::{Float, Vec3};
use crate::options::Mode;

/// Linear per-pixel values, row 0 at the top: radiance in full mode, the distance in
/// every channel in depth mode (infinity on a miss), the unit normal in normal mode
/// (zero on a miss).
#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width * height` values, row by row.
    pub pixels: Vec<Vec3>,
}

/// An 8-bit RGB image, row 0 at the top.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `3 * width * height` bytes, RGB, row by row.
    pub rgb: Vec<u8>,
}

/// Why an image could not be written.
#[derive(Debug, thiserror::Error)]
#[error("cannot write {}: {error}", path.display())]
pub struct WriteError {
    /// The file we were asked to write.
    pub path: PathBuf,
    /// What failed (part of the message, so not also a `source`).
    pub error: io::Error,
}

impl Film {
    /// Post-processes the film for `mode` into 8 bits per channel:
    /// depth divides by the largest distance (misses white), normal maps `n` to
    /// `n / 2 + 1/2` (misses black), full applies SPEC's tone mapping and gamma.
    ///
    /// See also [`Film::write`], which also writes linear OpenEXR files.
    pub fn to_image(&self, mode: Mode) -> Image {
        // In parallel: the gamma curve's `powf` on every channel of a megapixel film
        // took 30-40 ms on one thread.
        const CHUNK: usize = 4096;
        let encoding = self.encoding(mode);
        let mut rgb = vec![0u8; self.pixels.len() * 3];
        rgb.par_chunks_mut(3 * CHUNK)
            .zip(self.pixels.par_chunks(CHUNK))
            .for_each(|(bytes, pixels)| {
                for (rgb, &v) in bytes.chunks_exact_mut(3).zip(pixels) {
                    rgb.copy_from_slice(&encoding.apply(v).to_array().map(to_byte));
                }
            });
        Image {
            width: self.width,
            height: self.height,
            rgb,
        }
    }

    /// The post-processed value of every pixel, row by row, before quantization to
    /// 8 bits: what [`Film::to_image`] encodes.
    pub fn display_values(&self, mode: Mode) -> impl Iterator<Item = Vec3> + '_ {
        let encoding = self.encoding(mode);
        self.pixels.iter().map(move |&v| encoding.apply(v))
    }

    /// How `mode` maps this film's values for display (which needs the film's
    /// largest value).
    fn encoding(&self, mode: Mode) -> Encoding {
        match mode {
            Mode::Depth => Encoding::Depth {
                farthest: self.max_channel(|v| v.x.is_finite()),
            },
            Mode::Normal => Encoding::Normal,
            Mode::Full => Encoding::Full {
                brightest: self.max_channel(|_| true),
            },
        }
    }

    /// The largest channel value over the pixels that `keep` accepts (0 if none).
    fn max_channel(&self, keep: impl Fn(Vec3) -> bool + Sync) -> Float {
        self.pixels
            .par_iter()
            .filter(|&&v| keep(v))
            .map(|v| v.max_element())
            .reduce(|| 0.0, Float::max)
    }
}

/// Post-processing of one mode, with the image-wide maximum it needs.
#[derive(Clone, Copy)]
enum Encoding {
    /// Distance over the farthest hit; misses white.
    Depth { farthest: Float },
    /// `n / 2 + 1/2`; misses (zero normal) black.
    Normal,
    /// Tone mapping by the brightest channel, then gamma 2.2.
    Full { brightest: Float },
}

impl Encoding {
    #[inline]
    fn apply(self, v: Vec3) -> Vec3 {
        match self {
            Encoding::Depth { farthest } => {
                if !v.x.is_finite() {
                    Vec3::ONE
                } else if farthest > 0.0 {
                    v / farthest
                } else {
                    Vec3::ZERO
                }
            }
            Encoding::Normal => {
                if v == Vec3::ZERO {
                    Vec3::ZERO
                } else {
                    v * 0.5 + Vec3::splat(0.5)
                }
            }
            Encoding::Full { brightest } => tone_map(v, brightest).powf(1.0 / 2.2),
        }
    }
}

/// SPEC's tone curve `v (1 + v / c^2) / (1 + v)` with `c` the image's largest
/// channel; an all-black image (`c = 0`) stays black.
///
/// Written as `(v + (v/c)^2) / (1 + v)`: with `0 <= v <= c` every term stays in
/// range, where `c * c` would overflow for large `c` or vanish for tiny ones.
/// Negative values (negative colours or lights in the scene) are black.
#[inline]
fn tone_map(v: Vec3, c: Float) -> Vec3 {
    if c <= 0.0 {
        return Vec3::ZERO;
    }
    let v = v.max(Vec3::ZERO);
    let r = v / c;
    (v + r * r) / (Vec3::ONE + v)
}

/// Scales 0..1 to 0..255, rounding to nearest; out-of-range values clamp.
#[inline]
fn to_byte(v: Float) -> u8 {
    (v * 255.0).round().clamp(0.0, 255.0) as u8
}

impl Image {
    /// Writes the image as an 8-bit RGB PNG, atomically: into a temporary file in the
    /// same folder, renamed over `path` only once complete. A failure leaves any
    /// existing file untouched and no temporary file behind; so does an interrupt, if
    /// its handler calls [`remove_temp_files`].
    ///
    /// # Errors
    /// As [`check_output`], or the disk is full.
    pub fn write_png(&self, path: &Path) -> Result<(), WriteError> {
        write_atomically(path, "png", |file| {
            let mut writer = BufWriter::new(file);
            let mut encoder = png::Encoder::new(&mut writer, self.width, self.height);
            encoder.set_color(png::ColorType::Rgb);
            // fdeflate: several times faster than zlib level 6 on renders, for files
            // a few percent larger.
            encoder.set_compression(png::Compression::Fast);
            encoder.set_depth(png::BitDepth::Eight);
            let mut png_writer = encoder.write_header().map_err(io::Error::other)?;
            png_writer
                .write_image_data(&self.rgb)
                .map_err(io::Error::other)?;
            png_writer.finish().map_err(io::Error::other)?;
            writer.flush()
        })
    }
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
            let message = "is a folder, not a file";
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
/// [`Image::write_png`]), and returns how many it removed. Meant for a Ctrl-C
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tone_map_keeps_the_brightest_channel_and_black() {
        let c = 4.0;
        assert!((tone_map(Vec3::splat(c), c).x - 1.0).abs() < 1e-6);
        assert_eq!(tone_map(Vec3::ZERO, c), Vec3::ZERO);
        assert_eq!(tone_map(Vec3::ZERO, 0.0), Vec3::ZERO);
    }

    #[test]
    fn depth_normalizes_by_farthest_hit_and_misses_are_white() {
        let film = Film {
            width: 3,
            height: 1,
            pixels: vec![
                Vec3::splat(2.0),
                Vec3::splat(4.0),
                Vec3::splat(Float::INFINITY),
            ],
        };
        let image = film.to_image(Mode::Depth);
        assert_eq!(image.rgb, vec![128, 128, 128, 255, 255, 255, 255, 255, 255]);
    }
}
