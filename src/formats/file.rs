//! Reading scene files whole, refusing what is not a readable regular file before
//! reading a byte: a folder, a device such as `/dev/zero` (endless), a FIFO (may never
//! end), or a file too large to hold in memory. Gzip-compressed files are
//! decompressed here, so every reader (OBJ, MTL, PLY, TOML) takes them.

use std::fs::File;
use std::io::{self, Read};
use std::path::Path;

use super::SceneError;

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
    let gz_name = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gz"));
    if gz_name || bytes.starts_with(&GZIP_MAGIC) {
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
/// `take_piece` with its index, in order. A compressed file is decompressed whole
/// and returned instead.
pub(crate) fn read_in_pieces(
    path: &Path,
    piece_bytes: usize,
    mut take_piece: impl FnMut(usize, Vec<u8>),
) -> Result<Option<Vec<u8>>, SceneError> {
    let io_error = |error| SceneError::Io {
        path: path.to_path_buf(),
        error,
    };
    let gz_name = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gz"));
    if gz_name {
        return read_file(path).map(Some);
    }
    let (mut file, size) = open_regular_file(path).map_err(io_error)?;
    // As read_file, refuse up front what cannot be held.
    Vec::<u8>::new()
        .try_reserve_exact(size)
        .map_err(|_| io_error(too_large(size)))?;
    // Bytes read past a piece's end, which start the next piece.
    let mut pending = Vec::new();
    let mut index = 0;
    loop {
        // As `split_into_chunks` cuts text: a piece ends at the first `\n` from
        // its `piece_bytes`-th byte on, the last one at the end of the text.
        let mut piece = pending;
        let mut read_to = piece_bytes.saturating_add(1);
        let mut searched_to = piece_bytes;
        let end = loop {
            let wanted = read_to.saturating_sub(piece.len());
            // With room for the piece's last line: growing a full piece to read
            // it would copy the whole piece.
            piece
                .try_reserve(wanted.min(size) + LINE_SLACK_BYTES)
                .map_err(|_| io_error(too_large(size)))?;
            let read = (&mut file)
                .take(wanted as u64)
                .read_to_end(&mut piece)
                .map_err(io_error)?;
            if index == 0 && piece.starts_with(&GZIP_MAGIC) {
                file.read_to_end(&mut piece).map_err(io_error)?;
                return gunzip(&piece).map(Some).map_err(io_error);
            }
            if piece.len() > searched_to {
                if let Some(newline) = memchr::memchr(b'\n', &piece[searched_to..]) {
                    break Some(searched_to + newline + 1);
                }
                searched_to = piece.len();
            }
            if read < wanted {
                break None;
            }
            // The piece's last line goes on: read more of it, twice as much each
            // time for a line that is very long.
            read_to = piece.len() + LINE_READ_BYTES.max(piece.len() - piece_bytes);
        };
        match end {
            Some(end) => {
                pending = piece.split_off(end);
                take_piece(index, piece);
                index += 1;
            }
            None => {
                take_piece(index, piece);
                return Ok(None);
            }
        }
    }
}

/// Bytes read at a time to find the end of a piece's last line.
const LINE_READ_BYTES: usize = 256;

/// Room kept in a piece for its last line.
const LINE_SLACK_BYTES: usize = 4096;

/// Reads a whole regular file as it is (no decompression), refusing anything else
/// (a folder, a device, a FIFO) before reading a byte.
pub(crate) fn read_regular_file(path: &Path) -> io::Result<Vec<u8>> {
    let (mut file, size) = open_regular_file(path)?;
    let mut text = Vec::new();
    // Asked for up front, so that a file beyond memory fails here with a message
    // instead of aborting the process halfway through reading it.
    text.try_reserve_exact(size).map_err(|_| too_large(size))?;
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
            "is a folder, not a file",
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
            format!("{}: is a folder, not a file", dir.path().display())
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
}
