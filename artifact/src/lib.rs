#![doc = include_str!("../README.md")]

pub mod atomic_write;
pub mod content_key;
pub mod framing;
pub mod key_lock;

pub use atomic_write::write_atomically;
pub use content_key::{ContentKey, ContentKeyBuilder};
pub use framing::{FrameError, decode_framed, encode_framed, load_framed, save_framed};
pub use key_lock::{KeyLock, KeyLockParams, host_name};

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
