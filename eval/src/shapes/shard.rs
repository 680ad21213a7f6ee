//! The raw rows a `row` task writes ([`Shard`]: the results with the settings and provenance,
//! not a rendered table), the settings that make two runs' rows comparable ([`row_settings`],
//! [`settings_key`]) and the shapes a shard of a Slurm array runs ([`shard_meshes`]).
//! [`crate::shapes::merge`] gathers shards into the study Tables 2 and 7 render.

use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

use artifact::ContentKeyBuilder;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use thiserror::Error;

use crate::shapes::config::ShapeStudyConfig;
use crate::shapes::result::{ShapeResult, ShapeStudy};

/// The `format` of a shard file.
pub const SHARD_FORMAT: &str = "freeform-shapes-shard";
/// The shard format's version: a reader refuses others.
pub const SHARD_VERSION: u32 = 1;

/// The study's settings with what does not change a row left out (the mesh list, the cache
/// folder, the jobs, cached-only): what shards must share to merge.
pub fn row_settings(config: &ShapeStudyConfig) -> ShapeStudyConfig {
    ShapeStudyConfig {
        meshes: Vec::new(),
        cache_dir: PathBuf::new(),
        jobs: 1,
        cached_only: false,
        ..config.clone()
    }
}

/// A content key (32 hex digits) of [`row_settings`]: equal for two runs whose rows can be
/// merged.
pub fn settings_key(config: &ShapeStudyConfig) -> String {
    let canonical = serde_json::to_string(&row_settings(config)).unwrap_or_default();
    let mut key = ContentKeyBuilder::new(b"freeform shapes study settings", 1);
    key.str(&canonical);
    key.finish().hex()
}

/// Where and when a task ran.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Provenance {
    /// The machine's host name.
    pub host: String,
    /// Threads the task ran with (rayon's pool).
    pub threads: usize,
    /// Start and end (s since the Unix epoch).
    pub started: f64,
    /// End (s since the Unix epoch).
    pub finished: f64,
    /// The `eval` crate's version.
    pub version: String,
}

impl Provenance {
    /// This machine and thread pool, started at `started` (s since the epoch), finished now.
    pub fn since(started: f64) -> Self {
        Provenance {
            host: artifact::host_name(),
            threads: rayon::current_num_threads(),
            started,
            finished: unix_seconds(),
            version: env!("CARGO_PKG_VERSION").to_string(),
        }
    }
}

/// Seconds since the Unix epoch now.
pub fn unix_seconds() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

/// The raw rows of some shapes of one study.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Shard {
    /// [`SHARD_FORMAT`].
    pub format: String,
    /// [`SHARD_VERSION`].
    pub version: u32,
    /// [`settings_key`] of `settings`.
    pub settings_key: String,
    /// The study's [`row_settings`].
    pub settings: ShapeStudyConfig,
    /// Every shape of the study (file names, table order), this shard's or not.
    pub study_shapes: Vec<String>,
    /// Where and when the shard was written.
    pub provenance: Provenance,
    /// The shard's shapes.
    pub shapes: Vec<ShapeResult>,
    /// Set when the shard was made from a table an earlier version rendered, not by a `row`
    /// task ([`crate::shapes::rendered_import`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub imported_from: Option<ImportedTable>,
}

/// Where an imported shard's rows come from, and what its source did not keep.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ImportedTable {
    /// The rendered `table2.json` the rows were read from.
    pub file: PathBuf,
    /// Fields of the shard's results the rendered table does not hold, as dotted paths
    /// (`rows[].exact.ms_per_step`): each is zero or `None` in this shard and means nothing.
    /// No table prints them.
    pub unknown_fields: Vec<String>,
}

/// A shard file could not be read.
#[derive(Debug, Error)]
pub enum ShardReadError {
    /// The file could not be read.
    #[error("{path}: cannot read the shard")]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The file is not a shard of this format.
    #[error("{path}: {problem}")]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        problem: String,
    },
}

impl Shard {
    /// The shard of `study`, one part of the study over `study_shapes`, started at `started`.
    pub fn new(study: &ShapeStudy, study_shapes: Vec<String>, started: f64) -> Self {
        Shard {
            format: SHARD_FORMAT.into(),
            version: SHARD_VERSION,
            settings_key: settings_key(&study.config),
            settings: row_settings(&study.config),
            study_shapes,
            provenance: Provenance::since(started),
            shapes: study.shapes.clone(),
            imported_from: None,
        }
    }

    /// Reads a shard file.
    ///
    /// # Errors
    /// [`ShardReadError`] naming the file.
    pub fn read(path: &Path) -> Result<Self, ShardReadError> {
        let bytes = std::fs::read(path).map_err(|source| ShardReadError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        let format = |problem: String| ShardReadError::Format {
            path: path.to_path_buf(),
            problem,
        };
        let value: Value = serde_json::from_slice(&bytes).map_err(|e| format(e.to_string()))?;
        if value["format"] != SHARD_FORMAT {
            return Err(format(format!(
                "not a shard (no \"format\": \"{SHARD_FORMAT}\")"
            )));
        }
        if value["version"] != SHARD_VERSION {
            return Err(format(format!(
                "shard version {}, this build reads {SHARD_VERSION}",
                value["version"]
            )));
        }
        serde_json::from_value(value).map_err(|e| format(e.to_string()))
    }

    /// Writes the shard as JSON (atomically).
    ///
    /// # Errors
    /// [`artifact::ArtifactError`] naming the file.
    pub fn write(&self, path: &Path) -> Result<(), artifact::ArtifactError> {
        let json = serde_json::to_vec_pretty(self).unwrap_or_default();
        artifact::write_atomically(path, &json)
    }
}

/// The shapes of `meshes` a shard `index` of `count` runs: every `count`-th from `index` (so
/// that the slow shapes, wherever they sit, spread over the shards).
pub fn shard_meshes(meshes: &[PathBuf], index: usize, count: usize) -> Vec<PathBuf> {
    meshes
        .iter()
        .enumerate()
        .filter(|(i, _)| count > 0 && i % count == index)
        .map(|(_, p)| p.clone())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_by_index_cover_every_mesh_once() {
        let meshes: Vec<PathBuf> = (0..7).map(|i| PathBuf::from(format!("m{i}.obj"))).collect();
        let mut all: Vec<PathBuf> = (0..3).flat_map(|i| shard_meshes(&meshes, i, 3)).collect();
        all.sort();
        assert_eq!(all, meshes);
        assert_eq!(
            shard_meshes(&meshes, 1, 3),
            vec![meshes[1].clone(), meshes[4].clone()]
        );
    }
}
