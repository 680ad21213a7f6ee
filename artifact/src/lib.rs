//! Files FreeForm writes and reads back, written one way everywhere (bases, FEM trajectory
//! caches, trained networks, result frames and tables):
//!
//! - [`write_atomically`]: the bytes go to a temporary file with a name unique to this
//!   process and write (so `frame_00001.ply` and `frame_00001.vtk`, or two threads, never share
//!   one), are flushed to disk (fsync), then renamed over the target: an interrupted run never
//!   leaves a half-written file that looks valid.
//! - [`save_framed`] / [`load_framed`]: `magic ‖ format version (u32 LE) ‖ bincode payload`, so
//!   a file of another kind or version is a named error, never a garbled value.
//! - [`ContentKeyBuilder`]: a 128-bit FNV-1a hash of typed parts naming a cached result by
//!   everything that determines it.

pub mod atomic_write;
pub mod content_key;
pub mod framing;

pub use atomic_write::write_atomically;
pub use content_key::{ContentKey, ContentKeyBuilder};
pub use framing::{FrameError, decode_framed, encode_framed, load_framed, save_framed};

use std::path::PathBuf;

use thiserror::Error;

/// Reading or writing an artifact failed.
#[derive(Debug, Error)]
pub enum ArtifactError {
    /// The file system refused (missing folder, permissions, disk full, …).
    #[error("{path}: {source}")]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The file exists but is not a valid artifact of the expected kind and version.
    #[error("{path}: {source}")]
    Format {
        /// The file.
        path: PathBuf,
        /// What did not match.
        #[source]
        source: FrameError,
    },
}
