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
/// fails with a message instead of aborting the process.
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
    text.try_reserve_exact(hint).map_err(|_| too_large())?;
    let mut decoder = flate2::read::MultiGzDecoder::new(bytes);
    loop {
        text.try_reserve(GUNZIP_STEP).map_err(|_| too_large())?;
        let read = (&mut decoder)
            .take(GUNZIP_STEP as u64)
            .read_to_end(&mut text)?;
        if read == 0 {
            return Ok(text);
        }
    }
}

fn read_regular_file(path: &Path) -> io::Result<Vec<u8>> {
    let mut file = File::open(path)?;
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
    let too_large = || {
        io::Error::new(
            io::ErrorKind::OutOfMemory,
            format!("is too large to load ({} bytes)", metadata.len()),
        )
    };
    let size = usize::try_from(metadata.len()).map_err(|_| too_large())?;
    let mut text = Vec::new();
    // Asked for up front, so that a file beyond memory fails here with a message
    // instead of aborting the process halfway through reading it.
    text.try_reserve_exact(size).map_err(|_| too_large())?;
    file.read_to_end(&mut text)?;
    Ok(text)
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
