//! Which files a scene's readers may open, and which ones they tried.
//!
//! A scene file names other files (an OBJ file its MTL libraries, an MTL file its
//! textures, a TOML file its meshes, a glTF file its buffers and images). Locally the
//! readers open whatever path a file names, as every tool does. A scene shipped to
//! another machine (the Python package's Dask renderer) is read there from a private
//! folder, and must not make that machine read its own files on the scene's behalf:
//! [`FileAccess::confined_to`] refuses every path outside one folder, before it is
//! opened, and the readers report the refusal as they report any file they cannot
//! read (an error for geometry, a warning for a texture), naming the file and line
//! that named it. Every reader asks [`FileAccess::admit`] before it opens or looks
//! for a file, so the paths asked for are also the list of files a scene reads: what
//! to ship.

use std::io;
use std::path::{Component, Path, PathBuf};
use std::sync::Mutex;

/// The files a load may open, and the record of those it tried.
#[derive(Debug, Default)]
pub struct FileAccess {
    /// The folder every file must lie in (absolute, lexically normalised, and its
    /// canonical form, to catch symbolic links that leave it); `None`: anywhere.
    confined: Option<(PathBuf, PathBuf)>,
    /// Every path asked for, in order, each once (absolute, lexically normalised),
    /// and whether it was refused.
    asked: Mutex<Vec<(PathBuf, bool)>>,
}

impl FileAccess {
    /// Access to any path, as the command line reads scenes.
    pub fn anywhere() -> FileAccess {
        FileAccess::default()
    }

    /// Access to the files inside `folder` (and its subfolders) only.
    ///
    /// # Errors
    /// When `folder` cannot be resolved (it does not exist, or the current folder is
    /// unknown).
    pub fn confined_to(folder: &Path) -> io::Result<FileAccess> {
        let canonical = std::fs::canonicalize(folder)?;
        Ok(FileAccess {
            confined: Some((absolute(folder)?, canonical)),
            asked: Mutex::default(),
        })
    }

    /// The folder files must lie in, if confined.
    pub fn folder(&self) -> Option<&Path> {
        self.confined.as_ref().map(|(folder, _)| folder.as_path())
    }

    /// Records `path` as a file the scene reads and says whether it may be opened.
    /// Call it before opening `path` or asking whether it exists.
    ///
    /// # Errors
    /// [`io::ErrorKind::PermissionDenied`] when access is confined and `path` (as
    /// written, or once symbolic links are followed) lies outside the folder.
    pub fn admit(&self, path: &Path) -> io::Result<()> {
        let path = absolute(path)?;
        let inside = match &self.confined {
            None => true,
            Some((folder, canonical_folder)) => {
                path.starts_with(folder)
                    && match std::fs::canonicalize(&path) {
                        Ok(canonical) => canonical.starts_with(canonical_folder),
                        // Not there (yet): the lexical test is all there is; opening fails.
                        Err(_) => true,
                    }
            }
        };
        {
            let mut asked = self.lock();
            if !asked.iter().any(|(p, _)| *p == path) {
                asked.push((path.clone(), !inside));
            }
        }
        match &self.confined {
            Some((folder, _)) if !inside => Err(io::Error::new(
                io::ErrorKind::PermissionDenied,
                format!(
                    "{} lies outside the scene's folder {}, and a shipped scene reads only \
                     files inside its folder",
                    path.display(),
                    folder.display()
                ),
            )),
            _ => Ok(()),
        }
    }

    /// The paths asked for so far (allowed or refused), in the order first asked,
    /// each once: absolute and lexically normalised (`.` and `..` resolved, links
    /// not). Paths that do not exist are among them (a missing texture, a fallback
    /// looked for).
    pub fn asked(&self) -> Vec<PathBuf> {
        self.lock().iter().map(|(path, _)| path.clone()).collect()
    }

    /// The paths refused so far, as [`FileAccess::asked`] gives them.
    pub fn refused(&self) -> Vec<PathBuf> {
        let asked = self.lock();
        asked
            .iter()
            .filter(|(_, refused)| *refused)
            .map(|(path, _)| path.clone())
            .collect()
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Vec<(PathBuf, bool)>> {
        // A panic elsewhere cannot leave the list half-changed: it is pushed whole.
        self.asked
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }
}

/// `path` made absolute (against the current folder) with `.` and `..` resolved
/// lexically: `a/../../b` from `/x/y` is `/x/b`.
fn absolute(path: &Path) -> io::Result<PathBuf> {
    let joined = std::path::absolute(path)?;
    let mut normal = PathBuf::new();
    for component in joined.components() {
        match component {
            Component::ParentDir => {
                normal.pop();
            }
            Component::CurDir => {}
            other => normal.push(other),
        }
    }
    Ok(normal)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn confined_access_refuses_paths_that_leave_the_folder() {
        let dir = tempfile::tempdir().unwrap();
        let scene = dir.path().join("scene");
        std::fs::create_dir_all(scene.join("textures")).unwrap();
        std::fs::write(dir.path().join("secret.png"), b"x").unwrap();
        let access = FileAccess::confined_to(&scene).unwrap();
        assert!(access.admit(&scene.join("textures/wood.png")).is_ok());
        assert!(access.admit(&scene.join("textures/../a.mtl")).is_ok());
        for outside in [
            scene.join("../secret.png"),
            scene.join("textures/../../secret.png"),
            PathBuf::from("/etc/passwd"),
        ] {
            let error = access.admit(&outside).unwrap_err();
            assert_eq!(error.kind(), io::ErrorKind::PermissionDenied);
            assert!(error.to_string().contains("outside the scene's folder"));
        }
        // `../secret.png` and `textures/../../secret.png` are one file.
        assert_eq!(access.asked().len(), 4);
        assert_eq!(access.asked()[1], scene.join("a.mtl"));
        assert_eq!(
            access.refused(),
            [dir.path().join("secret.png"), PathBuf::from("/etc/passwd")]
        );
    }

    #[cfg(unix)]
    #[test]
    fn a_link_inside_the_folder_to_a_file_outside_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let scene = dir.path().join("scene");
        std::fs::create_dir(&scene).unwrap();
        std::fs::write(dir.path().join("secret.mtl"), b"x").unwrap();
        std::os::unix::fs::symlink(dir.path().join("secret.mtl"), scene.join("m.mtl")).unwrap();
        let access = FileAccess::confined_to(&scene).unwrap();
        assert!(access.admit(&scene.join("m.mtl")).is_err());
        assert!(FileAccess::anywhere().admit(&scene.join("m.mtl")).is_ok());
    }
}
