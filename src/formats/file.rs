//! Reading scene files whole, refusing what is not a readable regular file before
//! reading a byte: a folder, a device such as `/dev/zero` (endless), a FIFO (may never
//! end), or a file too large to hold in memory. Gzip-compressed files are
//! decompressed here, so every reader (OBJ, MTL, PLY, TOML) takes them.

use std::fs::File;
use std::io::{self, Read};
use std::path::Path;

use super::SceneError;
use crate::memory;

/// Whether `path` ends in `.gz` (any case): a file to decompress whatever its bytes.
fn named_gz(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gz"))
}

/// The first two bytes of every gzip member (RFC 1952).
const GZIP_MAGIC: [u8; 2] = [0x1f, 0x8b];

/// Bytes decompressed per step; memory is reserved fallibly one step at a time.
const GUNZIP_STEP: usize = 1 << 20;

/// Reads a whole regular file, naming it in the error. A file named `.gz` or
/// starting with the gzip magic bytes is decompressed.
pub(crate) fn read_file(path: &Path) -> Result<Vec<u8>, SceneError> {
    let io_error = |error| SceneError::Io {
        path: path.to_path_buf(),
        error,
    };
    let bytes = read_regular_file(path).map_err(io_error)?;
    if named_gz(path) || bytes.starts_with(&GZIP_MAGIC) {
        gunzip(&bytes).map_err(io_error)
    } else {
        Ok(bytes)
    }
}

/// Decompresses all gzip members of `bytes`. Memory is reserved step by step with
/// `try_reserve`, so that a small file that expands beyond memory (a "zip bomb")
/// fails with a message instead of aborting the process; and the first step must look
/// like a scene file ([`looks_like_a_scene`]), so that a bomb of binary data (2 GiB of
/// NUL bytes in 2 MB, say) is refused after one step instead of inflated whole.
fn gunzip(bytes: &[u8]) -> io::Result<Vec<u8>> {
    let too_large = || {
        io::Error::new(
            io::ErrorKind::OutOfMemory,
            "decompresses to more than fits in memory",
        )
    };
    // The trailer's ISIZE is the size modulo 2^32: a first reservation, capped by
    // deflate's best ratio (about 1032:1) so that a forged one asks for little.
    let hint = match bytes.last_chunk::<4>() {
        Some(&isize) => (u32::from_le_bytes(isize) as usize).min(bytes.len().saturating_mul(1032)),
        None => 0,
    };
    let mut text = Vec::new();
    let mut decoder = flate2::read::MultiGzDecoder::new(bytes);
    loop {
        text.try_reserve(GUNZIP_STEP).map_err(|_| too_large())?;
        let read = (&mut decoder)
            .take(GUNZIP_STEP as u64)
            .read_to_end(&mut text)?;
        if read == 0 {
            return Ok(text);
        }
        if text.len() == read {
            // The first step: judge it before reserving for the rest.
            if !looks_like_a_scene(&text) {
                return Err(io::Error::new(
                    io::ErrorKind::InvalidData,
                    format!(
                        "decompresses to binary data, not a scene file (refused after the first {} MiB)",
                        GUNZIP_STEP >> 20
                    ),
                ));
            }
            text.try_reserve_exact(hint.saturating_sub(text.len()))
                .map_err(|_| too_large())?;
        }
    }
}

/// Whether the start of a decompressed file can be a scene file the readers take:
/// text (OBJ, MTL, TOML, glTF JSON) has no NUL byte; binary PLY and GLB files start
/// with their magic words (`ply`, `glTF`).
fn looks_like_a_scene(start: &[u8]) -> bool {
    start.starts_with(b"ply") || start.starts_with(b"glTF") || memchr::memchr(0, start).is_none()
}

/// Reads a file as [`read_file`] does, but hands it over in pieces as they are
/// read, so that they can be parsed while the rest is read: the chunks that the
/// OBJ reader's `split_into_chunks(text, piece_bytes)` would cut, each to
/// `take_piece` with its index, in order. The pieces are slices of `buffer`, which
/// is made to hold the whole file at once: one fresh allocation on huge pages (see
/// [`memory`]) instead of one per piece, whose first writes, made by the kernel
/// while it copies the file in, took a page fault for every 4 KiB (about 8,000 for
/// the 33 MB dragon). A compressed file is decompressed whole and returned instead,
/// and so is a file that grows while it is read (read again from the start).
pub(crate) fn read_in_pieces<'a>(
    path: &Path,
    piece_bytes: usize,
    buffer: &'a mut Vec<u8>,
    mut take_piece: impl FnMut(usize, &'a [u8]),
) -> Result<Option<Vec<u8>>, SceneError> {
    let io_error = |error| SceneError::Io {
        path: path.to_path_buf(),
        error,
    };
    if named_gz(path) {
        return read_file(path).map(Some);
    }
    let (mut file, size) = open_regular_file(path).map_err(io_error)?;
    // As read_file, refuse up front what cannot be held.
    Vec::<u8>::new()
        .try_reserve_exact(size)
        .map_err(|_| io_error(too_large(size)))?;
    *buffer = memory::zeroed_vec(size);
    let mut rest: &'a mut [u8] = buffer.as_mut_slice();
    // `rest[..filled]` has been read; `rest[..searched]` holds no newline at or past
    // `piece_bytes`.
    let (mut filled, mut searched) = (0, 0);
    let mut index = 0;
    let mut checked_magic = false;
    loop {
        let read = if filled < rest.len() {
            let end = filled + READ_BYTES.max(piece_bytes).min(rest.len() - filled);
            read_some(&mut file, &mut rest[filled..end]).map_err(io_error)?
        } else {
            // Full: the file must end here, as its size said.
            match read_some(&mut file, &mut [0]).map_err(io_error)? {
                0 => 0,
                _ => return read_file(path).map(Some),
            }
        };
        filled += read;
        let at_end = read == 0;
        if !checked_magic && (filled >= GZIP_MAGIC.len() || at_end) {
            if rest[..filled].starts_with(&GZIP_MAGIC) {
                return read_file(path).map(Some);
            }
            checked_magic = true;
        }
        // Cut every piece whose end has been read, as `split_into_chunks` cuts.
        while checked_magic && filled > piece_bytes {
            let from = searched.max(piece_bytes);
            let Some(newline) = memchr::memchr(b'\n', &rest[from..filled]) else {
                searched = filled;
                break;
            };
            let (piece, tail) = std::mem::take(&mut rest).split_at_mut(from + newline + 1);
            filled -= piece.len();
            searched = 0;
            rest = tail;
            take_piece(index, piece);
            index += 1;
        }
        if at_end {
            take_piece(index, &rest[..filled]);
            return Ok(None);
        }
    }
}

/// Maps a regular, uncompressed file into memory, its pages read in up front (on all
/// threads, see [`populate`]): the
/// text stays in the kernel's page cache, where reading it into a buffer of our own
/// would write every byte again into fresh memory (on the virtual machines this is
/// measured on, 33 MB took 54-94 ms that way, 4-6 ms mapped). `None` for a file the
/// caller should read instead: compressed, empty, or one the system cannot map.
///
/// Like every reader that maps files (ripgrep, for one), this trusts the file not to
/// shrink while it is read: a file truncated under a running render ends it with
/// `SIGBUS`.
pub(crate) fn map_uncompressed(path: &Path) -> Result<Option<memmap2::Mmap>, SceneError> {
    let io_error = |error| SceneError::Io {
        path: path.to_path_buf(),
        error,
    };
    if named_gz(path) {
        return Ok(None);
    }
    let (file, size) = open_regular_file(path).map_err(io_error)?;
    if size == 0 {
        return Ok(None);
    }
    // SAFETY: the mapping is read-only and private; its bytes change only if another
    // process writes the file meanwhile, which the renderer cannot prevent (as
    // above), and a reader of `&[u8]` sees at worst other bytes, never unsound ones.
    let Ok(map) = (unsafe { memmap2::MmapOptions::new().map(&file) }) else {
        return Ok(None);
    };
    populate(&map);
    if map.starts_with(&GZIP_MAGIC) {
        return Ok(None);
    }
    Ok(Some(map))
}

/// Bytes of a mapping one thread reads in at a time.
const POPULATE_BYTES: usize = 4 << 20;

/// Reads the pages of `map` in now, on all threads: `MAP_POPULATE` would do it on
/// the calling thread alone while the others wait (4-8 ms of the dragon's 33 MB on
/// the machine measured). Where the system cannot (before Linux 5.14), the readers'
/// first touches fault the pages in instead.
fn populate(map: &memmap2::Mmap) {
    #[cfg(target_os = "linux")]
    {
        use rayon::prelude::*;
        (0..map.len().div_ceil(POPULATE_BYTES))
            .into_par_iter()
            .for_each(|piece| {
                let offset = piece * POPULATE_BYTES;
                let len = POPULATE_BYTES.min(map.len() - offset);
                // Only a hint: failure leaves the pages to be faulted in when read.
                let _ = map.advise_range(memmap2::Advice::PopulateRead, offset, len);
            });
    }
    #[cfg(not(target_os = "linux"))]
    let _ = map;
}

/// Bytes read at a time at least (more for bigger pieces): few system calls, and a
/// piece is handed over soon after its last byte is read.
const READ_BYTES: usize = 64 * 1024;

/// One `read` into `into`, retried if interrupted.
fn read_some(file: &mut File, into: &mut [u8]) -> io::Result<usize> {
    loop {
        match file.read(into) {
            Err(error) if error.kind() == io::ErrorKind::Interrupted => continue,
            result => return result,
        }
    }
}

/// Reads a whole regular file as it is (no decompression), refusing anything else
/// (a folder, a device, a FIFO) before reading a byte.
pub(crate) fn read_regular_file(path: &Path) -> io::Result<Vec<u8>> {
    let (mut file, size) = open_regular_file(path)?;
    let mut text = Vec::new();
    // Asked for up front, so that a file beyond memory fails here with a message
    // instead of aborting the process halfway through reading it.
    text.try_reserve_exact(size).map_err(|_| too_large(size))?;
    // Written from end to end by the read: the dragon's 17 MB binary PLY took 4,000
    // small-page faults.
    crate::memory::advise_huge_pages(&text);
    file.read_to_end(&mut text)?;
    Ok(text)
}

/// Opens a regular file and checks that its size (returned) could be held in
/// memory.
fn open_regular_file(path: &Path) -> io::Result<(File, usize)> {
    let file = open_without_blocking(path)?;
    let metadata = file.metadata()?;
    if metadata.is_dir() {
        return Err(io::Error::new(
            io::ErrorKind::IsADirectory,
            "is a directory",
        ));
    }
    if !metadata.is_file() {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "is not a regular file",
        ));
    }
    let size = usize::try_from(metadata.len()).map_err(|_| too_large(metadata.len()))?;
    Ok((file, size))
}

/// Opens `path` for reading without waiting for a writer: opening a FIFO blocks until
/// one comes, which may be never, before its type can even be checked. (On a regular
/// file the flag changes nothing.)
pub(crate) fn open_without_blocking(path: &Path) -> io::Result<File> {
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.custom_flags(libc::O_NONBLOCK);
    }
    options.open(path)
}

fn too_large(size: impl std::fmt::Display) -> io::Error {
    io::Error::new(
        io::ErrorKind::OutOfMemory,
        format!("is too large to load ({size} bytes)"),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn folders_and_devices_are_refused_with_their_path() {
        let dir = tempfile::tempdir().unwrap();
        let err = read_file(dir.path()).unwrap_err();
        assert_eq!(
            err.to_string(),
            format!("{}: is a directory", dir.path().display())
        );
        #[cfg(unix)]
        {
            let err = read_file(Path::new("/dev/zero")).unwrap_err();
            assert_eq!(err.to_string(), "/dev/zero: is not a regular file");
        }
    }

    #[test]
    fn gzip_files_are_decompressed_by_name_or_magic() {
        use std::io::Write;
        let dir = tempfile::tempdir().unwrap();
        let text = b"v 1 2 3\n".repeat(300_000);
        let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        encoder.write_all(&text).unwrap();
        let gz = encoder.finish().unwrap();
        for name in ["a.obj.gz", "a.obj"] {
            let path = dir.path().join(name);
            std::fs::write(&path, &gz).unwrap();
            assert_eq!(read_file(&path).unwrap(), text, "{name}");
        }
        let path = dir.path().join("b.obj.gz");
        std::fs::write(&path, b"v 1 2 3\nv 4 5 6\n").unwrap();
        assert_eq!(
            read_file(&path).unwrap_err().to_string(),
            format!("{}: invalid gzip header", path.display())
        );
    }

    #[test]
    fn regular_files_are_read_whole() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.obj");
        std::fs::write(&path, b"v 1 2 3\n").unwrap();
        assert_eq!(read_file(&path).unwrap(), b"v 1 2 3\n");
    }

    #[test]
    fn uncompressed_regular_files_are_mapped() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.obj");
        std::fs::write(&path, b"v 1 2 3\n").unwrap();
        let map = map_uncompressed(&path).unwrap().expect("mapped");
        assert_eq!(&map[..], b"v 1 2 3\n");
        // Read instead: empty, compressed by name or by content.
        let empty = dir.path().join("empty.obj");
        std::fs::write(&empty, b"").unwrap();
        assert!(map_uncompressed(&empty).unwrap().is_none());
        let gz_name = dir.path().join("b.obj.gz");
        std::fs::write(&gz_name, b"v 1 2 3\n").unwrap();
        assert!(map_uncompressed(&gz_name).unwrap().is_none());
        let gz_magic = dir.path().join("c.obj");
        std::fs::write(&gz_magic, [0x1f, 0x8b, 8, 0]).unwrap();
        assert!(map_uncompressed(&gz_magic).unwrap().is_none());
        let err = map_uncompressed(dir.path()).unwrap_err();
        assert_eq!(
            err.to_string(),
            format!("{}: is a directory", dir.path().display())
        );
    }

    /// A mapped file's pages are all in the process's page tables before the reader
    /// touches them (read in on all threads), not faulted in as the text is read.
    #[cfg(target_os = "linux")]
    #[test]
    fn mapped_files_are_read_in_up_front() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("big.obj");
        let size = 3 * POPULATE_BYTES + 12_345;
        std::fs::write(&path, vec![b'#'; size]).unwrap();
        let map = map_uncompressed(&path).unwrap().expect("mapped");
        let rss = crate::memory::smaps_field(map.as_ptr() as usize, "Rss:");
        let rss_kib: usize = rss.trim().trim_end_matches("kB").trim().parse().unwrap();
        assert!(
            rss_kib * 1024 >= size,
            "{rss_kib} KiB of {size} bytes mapped in"
        );
    }
}
