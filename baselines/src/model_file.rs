//! Saved models: 8 magic bytes, a little-endian format version, then bincode; written to a
//! temporary name and renamed, so an interrupted save never leaves a file that looks valid.

use std::path::Path;

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

/// Writes `value` to `path` with `magic` and `version`.
pub(crate) fn save<T: Serialize>(
    path: &Path,
    magic: &[u8; 8],
    version: u32,
    value: &T,
) -> Result<(), ModelFileError> {
    let io = |source| ModelFileError::Io {
        path: path.display().to_string(),
        source,
    };
    let mut bytes = magic.to_vec();
    bytes.extend(version.to_le_bytes());
    bytes.extend(
        bincode::serde::encode_to_vec(value, bincode::config::standard())
            .map_err(|e| io(std::io::Error::other(e)))?,
    );
    if let Some(dir) = path.parent()
        && !dir.as_os_str().is_empty()
    {
        std::fs::create_dir_all(dir).map_err(io)?;
    }
    let tmp = path.with_extension("partial");
    std::fs::write(&tmp, bytes).map_err(io)?;
    std::fs::rename(&tmp, path).map_err(io)
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
    let format = |reason: String| ModelFileError::Format {
        path: display.clone(),
        what,
        version,
        reason,
    };
    if bytes.len() < 12 || &bytes[..8] != magic {
        return Err(format("missing magic".into()));
    }
    let found = u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]);
    if found != version {
        return Err(format(format!("file has version {found}")));
    }
    let (value, _): (T, usize) =
        bincode::serde::decode_from_slice(&bytes[12..], bincode::config::standard())
            .map_err(|e| format(e.to_string()))?;
    Ok(value)
}
