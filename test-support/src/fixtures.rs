//! Locations of the test data.
//!
//! The data lives in the repository's `data/` folder (the 24 closed meshes and the 3DGS donut,
//! with their licences and provenance in `data/README.md`), so a fresh clone tests on its own.
//! `FREEFORM_SHARED_DATA` points the tests at another copy with the same layout.

use std::path::{Path, PathBuf};

/// The test data folder (`<workspace>/data`, or `$FREEFORM_SHARED_DATA`).
///
/// # Panics
/// If the folder does not exist: the tests that call this need the real data and must not pass
/// without it.
pub fn shared_data_dir() -> PathBuf {
    let dir = match std::env::var_os("FREEFORM_SHARED_DATA") {
        Some(dir) => PathBuf::from(dir),
        None => Path::new(env!("CARGO_MANIFEST_DIR")).join("../data"),
    };
    assert!(
        dir.is_dir(),
        "test data not found at {} (the repository's `data/` folder, or set \
         FREEFORM_SHARED_DATA)",
        dir.display()
    );
    dir
}

/// Path of one shared mesh, e.g. `shared_mesh("bunny.obj")`.
pub fn shared_mesh(name: &str) -> PathBuf {
    shared_data_dir().join("meshes").join(name)
}

/// All closed meshes in the shared data (OBJ, STL, PLY), sorted by file name.
pub fn shared_meshes() -> Vec<PathBuf> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(shared_data_dir().join("meshes"))
        .expect("shared meshes folder is readable")
        .map(|entry| entry.expect("readable directory entry").path())
        .filter(|path| {
            matches!(
                path.extension()
                    .and_then(|e| e.to_str())
                    .map(str::to_ascii_lowercase)
                    .as_deref(),
                Some("obj" | "stl" | "ply")
            )
        })
        .collect();
    paths.sort();
    assert!(!paths.is_empty(), "no meshes in the shared data folder");
    paths
}

/// Path of the shared 3D Gaussian Splatting file.
pub fn shared_splat() -> PathBuf {
    shared_data_dir()
        .join("splats")
        .join("donut_mipsplatting_fused.ply")
}

/// A fresh, empty scratch folder under the target directory, unique to `name`.
pub fn scratch_dir(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../target/test-scratch")
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch folder can be created");
    dir
}
