//! Magic + version framing of bincode payloads: `magic ‖ version (u32 LE) ‖ bincode`.

use std::path::Path;

use serde::Serialize;
use serde::de::DeserializeOwned;
use thiserror::Error;

use crate::{ArtifactError, write_atomically};

/// Bytes that are not a framed artifact of the expected kind and version.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
pub enum FrameError {
    /// The file does not start with the expected magic bytes (another kind of file).
    #[error("not a {expected} file (missing magic bytes)")]
    WrongMagic {
        /// The expected magic, as text.
        expected: String,
    },
    /// The file is of another format version.
    #[error("format version {found}, this build reads version {expected}")]
    WrongVersion {
        /// The file's version.
        found: u32,
        /// The version this build reads.
        expected: u32,
    },
    /// The payload does not decode.
    #[error("corrupt payload: {0}")]
    Corrupt(String),
}

/// `magic ‖ version ‖ bincode(value)`.
///
/// # Panics
/// If `value` cannot be encoded by bincode (a type whose `Serialize` fails; none of the
/// workspace's artifact types do).
pub fn encode_framed<T: Serialize>(magic: &[u8], version: u32, value: &T) -> Vec<u8> {
    let mut bytes = magic.to_vec();
    bytes.extend(version.to_le_bytes());
    bytes.extend(
        bincode::serde::encode_to_vec(value, bincode::config::standard())
            .expect("artifact types always encode"),
    );
    bytes
}

/// Decodes what [`encode_framed`] wrote with the same `magic` and `version`.
///
/// # Errors
/// [`FrameError`] for another magic, another version or a corrupt payload.
pub fn decode_framed<T: DeserializeOwned>(
    bytes: &[u8],
    magic: &[u8],
    version: u32,
) -> Result<T, FrameError> {
    let header = magic.len() + 4;
    if bytes.len() < header || &bytes[..magic.len()] != magic {
        return Err(FrameError::WrongMagic {
            expected: String::from_utf8_lossy(magic).into_owned(),
        });
    }
    let found = u32::from_le_bytes(
        bytes[magic.len()..header]
            .try_into()
            .expect("four version bytes"),
    );
    if found != version {
        return Err(FrameError::WrongVersion {
            found,
            expected: version,
        });
    }
    let (value, _) =
        bincode::serde::decode_from_slice(&bytes[header..], bincode::config::standard())
            .map_err(|e| FrameError::Corrupt(e.to_string()))?;
    Ok(value)
}

/// Writes `value` framed to `path` with [`write_atomically`].
///
/// # Errors
/// [`ArtifactError::Io`].
pub fn save_framed<T: Serialize>(
    path: &Path,
    magic: &[u8],
    version: u32,
    value: &T,
) -> Result<(), ArtifactError> {
    write_atomically(path, &encode_framed(magic, version, value))
}

/// Reads a value [`save_framed`] wrote, or `None` when `path` does not exist.
///
/// # Errors
/// [`ArtifactError::Io`] for a file that exists but cannot be read, [`ArtifactError::Format`]
/// for another kind, version or a corrupt payload.
pub fn load_framed<T: DeserializeOwned>(
    path: &Path,
    magic: &[u8],
    version: u32,
) -> Result<Option<T>, ArtifactError> {
    let bytes = match std::fs::read(path) {
        Ok(bytes) => bytes,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(source) => {
            return Err(ArtifactError::Io {
                path: path.to_path_buf(),
                source,
            });
        }
    };
    decode_framed(&bytes, magic, version)
        .map(Some)
        .map_err(|source| ArtifactError::Format {
            path: path.to_path_buf(),
            source,
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_framed_value_round_trips_and_other_kinds_versions_and_damage_are_named() {
        let value = (vec![1.5f64, -2.0], String::from("beam"));
        let bytes = encode_framed(b"FFTEST01", 3, &value);
        assert_eq!(&bytes[..8], b"FFTEST01");
        assert_eq!(
            decode_framed::<(Vec<f64>, String)>(&bytes, b"FFTEST01", 3),
            Ok(value)
        );
        assert_eq!(
            decode_framed::<(Vec<f64>, String)>(&bytes, b"FFOTHER1", 3),
            Err(FrameError::WrongMagic {
                expected: "FFOTHER1".into()
            })
        );
        assert_eq!(
            decode_framed::<(Vec<f64>, String)>(&bytes, b"FFTEST01", 4),
            Err(FrameError::WrongVersion {
                found: 3,
                expected: 4
            })
        );
        assert!(matches!(
            decode_framed::<(Vec<f64>, String)>(&bytes[..14], b"FFTEST01", 3),
            Err(FrameError::Corrupt(_))
        ));
        assert!(matches!(
            decode_framed::<u8>(&bytes[..5], b"FFTEST01", 3),
            Err(FrameError::WrongMagic { .. })
        ));
    }

    #[test]
    fn a_missing_file_loads_as_none_and_a_saved_one_as_its_value() {
        let dir = std::env::temp_dir().join(format!("artifact-framing-{}", std::process::id()));
        let path = dir.join("value.bin");
        let _ = std::fs::remove_dir_all(&dir);
        assert_eq!(load_framed::<u32>(&path, b"FF", 1).unwrap(), None);
        save_framed(&path, b"FF", 1, &42u32).unwrap();
        assert_eq!(load_framed::<u32>(&path, b"FF", 1).unwrap(), Some(42));
        let err = load_framed::<u32>(&path, b"FF", 2).unwrap_err();
        assert!(matches!(err, ArtifactError::Format { .. }), "{err}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
