//! FEM trajectories on disk, keyed by a hash of every input that defines them (DESIGN 3.8).
//!
//! A trajectory is expensive (minutes) and fully determined by the mesh, element order, mass
//! kind, materials, scene, time step, Newton options and step count. [`TrajectoryKey`] hashes
//! all of them (plus a caller label for what cannot be hashed: the closures of moving Dirichlet
//! targets) with 128-bit FNV-1a; the file is `<dir>/fem-<key>.traj`. Deleting the folder is
//! always safe.

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Version of the trajectory file format and of the key derivation.
pub const TRAJECTORY_FORMAT_VERSION: u32 = 1;
const MAGIC: &[u8; 6] = b"FFTRAJ";

/// A 128-bit content hash naming a cached trajectory.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct TrajectoryKey(u128);

impl TrajectoryKey {
    /// The key as 32 hex digits.
    pub fn hex(&self) -> String {
        format!("{:032x}", self.0)
    }
}

/// Builds a [`TrajectoryKey`] from typed parts (FNV-1a 128 over tagged little-endian bytes).
#[derive(Clone, Debug)]
pub struct TrajectoryKeyBuilder(u128);

impl Default for TrajectoryKeyBuilder {
    fn default() -> Self {
        let mut b = TrajectoryKeyBuilder(0x6c62_272e_07bb_0142_62b8_2175_6295_c58d);
        b.bytes(MAGIC);
        b.u64(u64::from(TRAJECTORY_FORMAT_VERSION));
        b
    }
}

impl TrajectoryKeyBuilder {
    fn bytes(&mut self, bytes: &[u8]) {
        const PRIME: u128 = 0x0000_0000_0100_0000_0000_0000_0000_013b;
        for &b in bytes {
            self.0 ^= u128::from(b);
            self.0 = self.0.wrapping_mul(PRIME);
        }
    }

    /// Adds an integer.
    pub fn u64(&mut self, v: u64) -> &mut Self {
        self.bytes(&v.to_le_bytes());
        self
    }

    /// Adds floats by their exact bits.
    pub fn f64s(&mut self, values: &[f64]) -> &mut Self {
        self.u64(values.len() as u64);
        for v in values {
            self.bytes(&v.to_bits().to_le_bytes());
        }
        self
    }

    /// Adds a string (length-prefixed).
    pub fn str(&mut self, s: &str) -> &mut Self {
        self.u64(s.len() as u64);
        self.bytes(s.as_bytes());
        self
    }

    /// The key.
    pub fn finish(&self) -> TrajectoryKey {
        TrajectoryKey(self.0)
    }
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
        let path = self.path(key);
        let bytes = match fs::read(&path) {
            Ok(b) => b,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(source) => return Err(TrajectoryCacheError::Io { path, source }),
        };
        let format = |reason: &str| TrajectoryCacheError::Format {
            path: path.clone(),
            reason: reason.into(),
        };
        if bytes.len() < 10 || &bytes[..6] != MAGIC {
            return Err(format("missing magic bytes"));
        }
        let version = u32::from_le_bytes(bytes[6..10].try_into().expect("4 bytes"));
        if version != TRAJECTORY_FORMAT_VERSION {
            return Err(format(&format!("file has version {version}")));
        }
        let (trajectory, _) =
            bincode::serde::decode_from_slice(&bytes[10..], bincode::config::standard())
                .map_err(|e| format(&e.to_string()))?;
        Ok(Some(trajectory))
    }

    /// Stores a trajectory atomically (temporary file, then rename); returns its path.
    ///
    /// # Errors
    /// [`TrajectoryCacheError::Io`].
    pub fn store(
        &self,
        key: TrajectoryKey,
        trajectory: &Trajectory,
    ) -> Result<PathBuf, TrajectoryCacheError> {
        let io = |path: &Path| {
            let path = path.to_path_buf();
            move |source| TrajectoryCacheError::Io { path, source }
        };
        fs::create_dir_all(&self.dir).map_err(io(&self.dir))?;
        let path = self.path(key);
        let tmp = path.with_extension("partial");
        let mut bytes = MAGIC.to_vec();
        bytes.extend(TRAJECTORY_FORMAT_VERSION.to_le_bytes());
        bytes.extend(
            bincode::serde::encode_to_vec(trajectory, bincode::config::standard())
                .expect("a trajectory always encodes"),
        );
        let mut file = fs::File::create(&tmp).map_err(io(&tmp))?;
        file.write_all(&bytes).map_err(io(&tmp))?;
        file.sync_all().map_err(io(&tmp))?;
        fs::rename(&tmp, &path).map_err(io(&path))?;
        Ok(path)
    }
}
