//! Atomic file writes: a unique temporary file beside the target, fsync, rename.

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::ArtifactError;

/// Temporary files written by this process so far (makes every temporary name unique).
static TEMPORARY_FILES: AtomicU64 = AtomicU64::new(0);

/// The temporary file for `path`: `.<file name>.<pid>-<n>.tmp` in the same folder (same file
/// system, so the rename is atomic).
fn temporary_path(path: &Path) -> PathBuf {
    let n = TEMPORARY_FILES.fetch_add(1, Ordering::Relaxed);
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.{}-{n}.tmp", std::process::id()))
}

/// Writes `bytes` to `path` atomically: creates the parent folder, writes a temporary file with
/// a name unique to this process and call, flushes it to disk, and renames it over `path`.
/// Postcondition: `path` holds either its old content or all of `bytes`, never a part.
///
/// # Errors
/// [`ArtifactError::Io`] naming the file or folder that failed; the temporary file is removed.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), ArtifactError> {
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| ArtifactError::Io { path, source }
    };
    if let Some(dir) = path.parent()
        && !dir.as_os_str().is_empty()
    {
        fs::create_dir_all(dir).map_err(io(dir))?;
    }
    let tmp = temporary_path(path);
    let written = (|| {
        let mut file = fs::File::create(&tmp)?;
        file.write_all(bytes)?;
        file.sync_all()
    })();
    if let Err(source) = written {
        let _ = fs::remove_file(&tmp);
        return Err(io(&tmp)(source));
    }
    fs::rename(&tmp, path).map_err(|source| {
        let _ = fs::remove_file(&tmp);
        io(path)(source)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("artifact-{name}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        dir
    }

    #[test]
    fn files_of_the_same_stem_get_distinct_temporary_names() {
        let a = temporary_path(Path::new("out/frame_00001.ply"));
        let b = temporary_path(Path::new("out/frame_00001.vtk"));
        let c = temporary_path(Path::new("out/frame_00001.ply"));
        assert_ne!(a, b);
        assert_ne!(a, c, "two writes of one file never share a temporary file");
        assert_eq!(a.parent(), Some(Path::new("out")));
    }

    #[test]
    fn a_write_creates_the_folder_replaces_the_file_and_leaves_no_temporary_file() {
        let dir = scratch("write");
        let path = dir.join("nested/table.md");
        write_atomically(&path, b"first").unwrap();
        write_atomically(&path, b"second").unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"second");
        let names: Vec<_> = fs::read_dir(path.parent().unwrap())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("table.md")]);
        let _ = fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_write_into_an_unwritable_place_is_an_io_error_naming_it() {
        let dir = scratch("blocked");
        fs::create_dir_all(&dir).unwrap();
        // A file where a folder should be.
        let blocker = dir.join("blocker");
        fs::write(&blocker, b"x").unwrap();
        let err = write_atomically(&blocker.join("table.md"), b"y").unwrap_err();
        assert!(
            matches!(&err, ArtifactError::Io { path, .. } if path == &blocker),
            "{err}"
        );
        let _ = fs::remove_dir_all(&dir);
    }
}
