//! The shapes study spread over tasks: the plan a workflow engine schedules ([`TaskPlan`]),
//! the receipt a task leaves ([`Receipt`]), the raw rows a `row` task writes ([`Shard`]: the
//! results with the settings and provenance, not a rendered table) and [`merge_shards`], which
//! gathers any set of shards into the study Tables 2 and 7 render.
//!
//! Shards merge only when their settings agree (the settings key, a content key of every
//! setting that changes a row); one shape in two shards must agree outside its timing fields.
//! Shapes no shard holds stay unfinished, so the tables are headed **Partial** and name them.

use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

use artifact::ContentKeyBuilder;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use thiserror::Error;

use crate::shapes::boundary::ShapeBoundary;
use crate::shapes::catalog::{MaterialClass, catalog_entry};
use crate::shapes::config::ShapeStudyConfig;
use crate::shapes::result::{ShapeResult, ShapeStudy, mesh_name};
use crate::shapes::stage::ShapeStage;

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
        }
    }

    /// Reads a shard file.
    ///
    /// # Errors
    /// [`MergeError::Read`] or [`MergeError::Format`] naming the file.
    pub fn read(path: &Path) -> Result<Self, MergeError> {
        let bytes = std::fs::read(path).map_err(|source| MergeError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        let format = |problem: String| MergeError::Format {
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

/// Shards could not be merged.
#[derive(Debug, Error)]
pub enum MergeError {
    /// No shard was given.
    #[error("no shards to merge")]
    NoShards,
    /// A shard file could not be read.
    #[error("{path}: cannot read the shard")]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A file is not a shard of this format.
    #[error("{path}: {problem}")]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        problem: String,
    },
    /// Two shards come from studies with different settings.
    #[error(
        "{path}: its settings differ from {first}'s at `{field}` ({theirs} there, {ours} here)"
    )]
    SettingsDiffer {
        /// The shard that differs.
        path: PathBuf,
        /// The first shard.
        first: PathBuf,
        /// The first differing setting (a dotted path).
        field: String,
        /// Its value in the first shard.
        theirs: String,
        /// Its value in this one.
        ours: String,
    },
    /// Two shards hold the same shape with different results.
    #[error(
        "{shape} is in {first} and {path} with different results at `{field}` (timing fields \
         aside)"
    )]
    Conflict {
        /// The shape.
        shape: String,
        /// The shard that held it first.
        first: PathBuf,
        /// The shard that disagrees.
        path: PathBuf,
        /// The first differing field (a dotted path).
        field: String,
    },
}

/// The first dotted path where `a` and `b` differ, if any.
fn first_difference(a: &Value, b: &Value, path: &str) -> Option<(String, String, String)> {
    match (a, b) {
        (Value::Object(x), Value::Object(y)) => {
            let mut keys: Vec<&String> = x.keys().chain(y.keys()).collect();
            keys.sort();
            keys.dedup();
            keys.into_iter().find_map(|k| {
                let here = if path.is_empty() {
                    k.clone()
                } else {
                    format!("{path}.{k}")
                };
                first_difference(
                    x.get(k).unwrap_or(&Value::Null),
                    y.get(k).unwrap_or(&Value::Null),
                    &here,
                )
            })
        }
        (Value::Array(x), Value::Array(y)) if x.len() == y.len() => x
            .iter()
            .zip(y)
            .enumerate()
            .find_map(|(i, (p, q))| first_difference(p, q, &format!("{path}[{i}]"))),
        _ if a == b => None,
        _ => Some((path.to_string(), a.to_string(), b.to_string())),
    }
}

/// `value` with every timing field (wall times, seconds, ms per step, whether it came from the
/// cache) left out: what must agree between two copies of one shape.
fn without_timing(value: &Value) -> Value {
    const TIMING: [&str; 3] = ["seconds", "ms_per_step", "cached"];
    match value {
        Value::Object(map) => Value::Object(
            map.iter()
                .filter(|(k, _)| !TIMING.iter().any(|t| k.contains(t)))
                .map(|(k, v)| (k.clone(), without_timing(v)))
                .collect(),
        ),
        Value::Array(items) => Value::Array(items.iter().map(without_timing).collect()),
        other => other.clone(),
    }
}

/// The study the `shards` (with their files) hold together: the first shard's settings over
/// its `study_shapes`, each shape once, in table order; shapes no shard holds are the study's
/// [`ShapeStudy::unfinished`]. Its `seconds` is the sum of the shards' wall times.
///
/// # Errors
/// [`MergeError`] for no shards, shards of different settings or shape lists (naming the first
/// differing setting), or one shape with two different results.
pub fn merge_shards(shards: &[(PathBuf, Shard)]) -> Result<ShapeStudy, MergeError> {
    let Some((first_path, first)) = shards.first() else {
        return Err(MergeError::NoShards);
    };
    let first_settings = serde_json::to_value(&first.settings).unwrap_or(Value::Null);
    let mut shapes: Vec<(&PathBuf, &ShapeResult)> = Vec::new();
    let mut seconds = 0.0;
    for (path, shard) in shards {
        let settings = serde_json::to_value(&shard.settings).unwrap_or(Value::Null);
        let differs = first_difference(&first_settings, &settings, "").or_else(|| {
            (shard.study_shapes != first.study_shapes).then(|| {
                (
                    "study_shapes".to_string(),
                    first.study_shapes.join(", "),
                    shard.study_shapes.join(", "),
                )
            })
        });
        if let Some((field, theirs, ours)) = differs {
            return Err(MergeError::SettingsDiffer {
                path: path.clone(),
                first: first_path.clone(),
                field,
                theirs,
                ours,
            });
        }
        seconds += shard.provenance.finished - shard.provenance.started;
        for shape in &shard.shapes {
            match shapes.iter().find(|(_, s)| s.name == shape.name) {
                Some((held_in, held)) => {
                    let a = without_timing(&serde_json::to_value(held).unwrap_or(Value::Null));
                    let b = without_timing(&serde_json::to_value(shape).unwrap_or(Value::Null));
                    if let Some((field, _, _)) = first_difference(&a, &b, "") {
                        return Err(MergeError::Conflict {
                            shape: shape.name.clone(),
                            first: (*held_in).clone(),
                            path: path.clone(),
                            field,
                        });
                    }
                }
                None => shapes.push((path, shape)),
            }
        }
    }
    let ordered = first
        .study_shapes
        .iter()
        .filter_map(|name| shapes.iter().find(|(_, s)| &s.name == name))
        .map(|(_, s)| (*s).clone())
        .collect();
    Ok(ShapeStudy {
        config: ShapeStudyConfig {
            meshes: first.study_shapes.iter().map(PathBuf::from).collect(),
            ..first.settings.clone()
        },
        shapes: ordered,
        seconds,
    })
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

/// One shape of the plan.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlannedShape {
    /// Its index in table order (`--shard i/n` takes the indices `i`, `i + n`, …).
    pub index: usize,
    /// File name (what `--only` takes).
    pub name: String,
    /// The file.
    pub file: PathBuf,
    /// Young's modulus (Pa) the study gives it.
    pub youngs_modulus: f64,
    /// Its material class, if catalogued.
    pub class: Option<MaterialClass>,
}

/// One task: one stage of one shape, and the stages it waits for.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlannedTask {
    /// The shape's file name.
    pub shape: String,
    /// The stage.
    pub stage: ShapeStage,
    /// Stages of the same shape that must finish first.
    pub after: Vec<ShapeStage>,
}

/// What a workflow engine schedules for a shapes study.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TaskPlan {
    /// [`settings_key`] of the study.
    pub settings_key: String,
    /// The shapes, in table order.
    pub shapes: Vec<PlannedShape>,
    /// The boundary conditions every shape runs.
    pub boundaries: Vec<ShapeBoundary>,
    /// The stages each shape needs (`check` only when the study checks convergence, `train`
    /// only with the baseline).
    pub stages: Vec<ShapeStage>,
    /// Every (shape, stage) task with what it waits for.
    pub tasks: Vec<PlannedTask>,
    /// The study's [`row_settings`].
    pub settings: ShapeStudyConfig,
}

impl TaskPlan {
    /// The plan of `config` (its `meshes` are the study's shapes).
    pub fn new(config: &ShapeStudyConfig) -> Self {
        let stages: Vec<ShapeStage> = ShapeStage::ALL
            .into_iter()
            .filter(|s| match s {
                ShapeStage::Train => config.simplicits.is_some(),
                ShapeStage::Check => config.check_convergence,
                _ => true,
            })
            .collect();
        let shapes: Vec<PlannedShape> = config
            .meshes
            .iter()
            .enumerate()
            .map(|(index, file)| {
                let name = mesh_name(file);
                let entry = catalog_entry(&name);
                PlannedShape {
                    index,
                    youngs_modulus: entry
                        .map_or(config.default_youngs_modulus, |e| e.class.youngs_modulus()),
                    class: entry.map(|e| e.class),
                    name,
                    file: file.clone(),
                }
            })
            .collect();
        let tasks = shapes
            .iter()
            .flat_map(|shape| {
                stages.iter().map(|&stage| PlannedTask {
                    shape: shape.name.clone(),
                    stage,
                    after: match stage {
                        ShapeStage::Check => vec![ShapeStage::Reference],
                        ShapeStage::Row => stages
                            .iter()
                            .copied()
                            .filter(|&s| s != ShapeStage::Row)
                            .collect(),
                        _ => Vec::new(),
                    },
                })
            })
            .collect();
        TaskPlan {
            settings_key: settings_key(config),
            shapes,
            boundaries: config.boundaries.clone(),
            stages,
            tasks,
            settings: row_settings(config),
        }
    }
}

/// What a task leaves when it has finished (written last, so its presence means the task's
/// outputs are complete).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Receipt {
    /// The shapes the task ran (file names).
    pub shapes: Vec<String>,
    /// Its stage, or `None` for every stage at once.
    pub stage: Option<ShapeStage>,
    /// The boundary conditions it ran.
    pub boundaries: Vec<ShapeBoundary>,
    /// Files it wrote besides the cache (a shard).
    pub wrote: Vec<PathBuf>,
    /// The cache it filled or read.
    pub cache_dir: PathBuf,
    /// [`settings_key`] of the study.
    pub settings_key: String,
    /// Where and when it ran.
    pub provenance: Provenance,
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn the_first_difference_is_named_by_its_dotted_path() {
        let a = json!({"settings": {"modes": 32, "kernels": 1000}, "list": [1, 2]});
        let b = json!({"settings": {"modes": 16, "kernels": 1000}, "list": [1, 2]});
        let (field, x, y) = first_difference(&a, &b, "").unwrap();
        assert_eq!(
            (field.as_str(), x.as_str(), y.as_str()),
            ("settings.modes", "32", "16")
        );
        assert!(first_difference(&a, &a, "").is_none());
        let c = json!({"list": [1, 3]});
        assert_eq!(
            first_difference(&json!({"list": [1, 2]}), &c, "")
                .unwrap()
                .0,
            "list[1]"
        );
    }

    #[test]
    fn timing_fields_are_left_out_at_every_depth() {
        let v = json!({"basis_seconds": 1.0, "rows": [{"ours": {"mse": 1e-3, "ms_per_step": 4.0}, "fem": {"cached": true, "dofs": 10}}]});
        assert_eq!(
            without_timing(&v),
            json!({"rows": [{"ours": {"mse": 1e-3}, "fem": {"dofs": 10}}]})
        );
    }

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
