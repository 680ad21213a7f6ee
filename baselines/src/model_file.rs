//! Saved models: 8 magic bytes, a little-endian format version, then bincode
//! ([`artifact`]'s framing); written atomically, so an interrupted save never leaves a file
//! that looks valid.

use std::path::Path;

use artifact::ArtifactError;
use serde::Serialize;
use serde::de::DeserializeOwned;
use thiserror::Error;

/// A saved model is unusable.
#[derive(Debug, Error)]
pub enum ModelFileError {
    /// Reading or writing failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// Not a file of the expected kind and version, or damaged.
    #[error("{path}: not a FreeForm {what} file of format version {version} ({reason})")]
    Format {
        /// The file.
        path: String,
        /// What was expected ("MLP", "Simplicits model").
        what: &'static str,
        /// The version this build reads.
        version: u32,
        /// What did not match.
        reason: String,
    },
}

/// Writes `value` to `path` with `magic` and `version` ([`artifact::save_framed`]: unique
/// temporary file, fsync, rename).
pub(crate) fn save<T: Serialize>(
    path: &Path,
    magic: &[u8; 8],
    version: u32,
    value: &T,
) -> Result<(), ModelFileError> {
    artifact::save_framed(path, magic, version, value).map_err(|e| match e {
        ArtifactError::Io { path, source } => ModelFileError::Io {
            path: path.display().to_string(),
            source,
        },
        // A write reports only I/O errors.
        ArtifactError::Format { path, source } => ModelFileError::Io {
            path: path.display().to_string(),
            source: std::io::Error::other(source),
        },
    })
}

/// Reads what [`save`] wrote with the same `magic` and `version`.
pub(crate) fn load<T: DeserializeOwned>(
    path: &Path,
    magic: &[u8; 8],
    version: u32,
    what: &'static str,
) -> Result<T, ModelFileError> {
    let display = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|source| ModelFileError::Io {
        path: display.clone(),
        source,
    })?;
    artifact::decode_framed(&bytes, magic, version).map_err(|e| ModelFileError::Format {
        path: display,
        what,
        version,
        reason: e.to_string(),
    })
}
