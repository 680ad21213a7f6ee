//! FEM trajectories on disk, keyed by a hash of every input that defines them (design §3.8).
//!
//! A trajectory is expensive (minutes) and fully determined by the mesh, element order, mass
//! kind, materials, scene, time step, Newton options and step count. [`TrajectoryKey`] hashes
//! all of them (plus a caller label for what cannot be hashed: the closures of moving Dirichlet
//! targets) with 128-bit FNV-1a; the file is `<dir>/fem-<key>.traj`. Deleting the folder is
//! always safe.

use std::path::{Path, PathBuf};

use artifact::{ArtifactError, ContentKey, ContentKeyBuilder, load_framed, save_framed};
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Version of the trajectory file format and of the key derivation.
pub const TRAJECTORY_FORMAT_VERSION: u32 = 1;
const MAGIC: &[u8; 6] = b"FFTRAJ";

/// The content hash naming a cached trajectory.
pub type TrajectoryKey = ContentKey;

/// A builder for [`TrajectoryKey`]s: a [`ContentKeyBuilder`] in the trajectory domain (the file
/// magic and [`TRAJECTORY_FORMAT_VERSION`]).
pub fn trajectory_key_builder() -> ContentKeyBuilder {
    ContentKeyBuilder::new(MAGIC, u64::from(TRAJECTORY_FORMAT_VERSION))
}

/// Node positions per frame and what each step reported.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Trajectory {
    /// Time of each frame (s); frame 0 is the rest state at t = 0.
    pub times: Vec<f64>,
    /// Node positions per frame (m), `frames[f][node]`.
    pub frames: Vec<Vec<[f64; 3]>>,
    /// Newton iterations of each step.
    pub iterations: Vec<usize>,
    /// Whether each step converged.
    pub converged: Vec<bool>,
    /// Wall time of the run that produced it (s).
    pub seconds: f64,
}

/// Reading or writing the cache failed.
#[derive(Debug, Error)]
pub enum TrajectoryCacheError {
    /// File system error.
    #[error("trajectory cache {path}: {source}")]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The error.
        #[source]
        source: std::io::Error,
    },
    /// The file is not a trajectory of this format version.
    #[error("{path} is not a version-{TRAJECTORY_FORMAT_VERSION} trajectory file: {reason}")]
    Format {
        /// The file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
}

/// A folder of cached trajectories.
#[derive(Clone, Debug)]
pub struct TrajectoryCache {
    dir: PathBuf,
}

impl TrajectoryCache {
    /// A cache in `dir` (created on first store).
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        TrajectoryCache { dir: dir.into() }
    }

    /// The folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The file a key maps to.
    pub fn path(&self, key: TrajectoryKey) -> PathBuf {
        self.dir.join(format!("fem-{}.traj", key.hex()))
    }

    /// The cached trajectory, or `None` when there is none.
    ///
    /// # Errors
    /// [`TrajectoryCacheError`] when the file exists but cannot be read or decoded.
    pub fn load(&self, key: TrajectoryKey) -> Result<Option<Trajectory>, TrajectoryCacheError> {
        load_framed(&self.path(key), MAGIC, TRAJECTORY_FORMAT_VERSION).map_err(Into::into)
    }

    /// Stores a trajectory atomically ([`artifact::write_atomically`]: unique temporary file,
    /// fsync, rename); returns its path.
    ///
    /// # Errors
    /// [`TrajectoryCacheError::Io`].
    pub fn store(
        &self,
        key: TrajectoryKey,
        trajectory: &Trajectory,
    ) -> Result<PathBuf, TrajectoryCacheError> {
        let path = self.path(key);
        save_framed(&path, MAGIC, TRAJECTORY_FORMAT_VERSION, trajectory)?;
        Ok(path)
    }
}

impl From<ArtifactError> for TrajectoryCacheError {
    fn from(e: ArtifactError) -> Self {
        match e {
            ArtifactError::Io { path, source } => TrajectoryCacheError::Io { path, source },
            ArtifactError::Format { path, source } => TrajectoryCacheError::Format {
                path,
                reason: source.to_string(),
            },
        }
    }
}
