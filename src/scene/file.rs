//! Reading scene files whole, refusing what is not a readable regular file before
//! reading a byte: a folder, a device such as `/dev/zero` (endless), a FIFO (may never
//! end), or a file too large to hold in memory.

use std::fs::File;
use std::io::{self, Read};
use std::path::Path;

use super::SceneError;

/// Reads a whole regular file, naming it in the error.
pub(crate) fn read_file(path: &Path) -> Result<Vec<u8>, SceneError> {
    read_regular_file(path).map_err(|error| SceneError::Io {
        path: path.to_path_buf(),
        error,
    })
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
    fn regular_files_are_read_whole() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.obj");
        std::fs::write(&path, b"v 1 2 3\n").unwrap();
        assert_eq!(read_file(&path).unwrap(), b"v 1 2 3\n");
    }
}
