//! Committed experiment presets: each of the paper's studies described by a TOML file under
//! `eval/presets/` (compiled into the binary), chosen by name, read from a file
//! (`--config FILE`), and changed key by key (`--set key=value`) before it is turned into the
//! study's typed configuration ([`crate::beam_protocol::study_config::BeamStudyConfig`],
//! [`crate::ablation::study::AblationStudyConfig`], [`crate::shapes::config::ShapeStudyConfig`],
//! [`crate::bench::BenchConfig`], [`crate::pins::PinSweepConfig`],
//! [`crate::stress::StressConfig`]).
//!
//! A preset file names its study and holds that study's configuration, every field spelled
//! out except the run's folders (`cache_dir`, and the shapes' `meshes`), which the command line
//! supplies:
//!
//! ```toml
//! study = "beam"
//! [config]
//! modes = [6, 9, 16, 32]
//! # …
//! ```
//!
//! `--set settings.kernels=500` assigns a TOML value (`1e-3`, `true`, `[16]`, `"full"`,
//! `{ kind = "full" }`) at a dotted path inside `[config]`; a bare word is a string, and
//! `none` removes the key (an optional setting left out, e.g. `--set simplicits=none`).

use std::path::{Path, PathBuf};

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// The committed presets, by name: `(name, TOML text)`.
pub const PRESETS: &[(&str, &str)] = &[
    ("beam", include_str!("../presets/beam.toml")),
    ("beam-quick", include_str!("../presets/beam-quick.toml")),
    ("beam-library", include_str!("../presets/beam-library.toml")),
    (
        "beam-converging",
        include_str!("../presets/beam-converging.toml"),
    ),
    ("ablation", include_str!("../presets/ablation.toml")),
    (
        "ablation-quick",
        include_str!("../presets/ablation-quick.toml"),
    ),
    ("shapes", include_str!("../presets/shapes.toml")),
    ("shapes-quick", include_str!("../presets/shapes-quick.toml")),
    (
        "shapes-converging",
        include_str!("../presets/shapes-converging.toml"),
    ),
    (
        "shapes-quick-graded",
        include_str!("../presets/shapes-quick-graded.toml"),
    ),
    (
        "shapes-uniform",
        include_str!("../presets/shapes-uniform.toml"),
    ),
    ("bench", include_str!("../presets/bench.toml")),
    ("bench-quick", include_str!("../presets/bench-quick.toml")),
    ("pins", include_str!("../presets/pins.toml")),
    ("pins-quick", include_str!("../presets/pins-quick.toml")),
    ("convergence", include_str!("../presets/convergence.toml")),
    (
        "convergence-quick",
        include_str!("../presets/convergence-quick.toml"),
    ),
    ("stress", include_str!("../presets/stress.toml")),
    ("stress-quick", include_str!("../presets/stress-quick.toml")),
];

/// Which study a preset configures.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StudyKind {
    /// Tables 1, 5 and 6 ([`crate::beam_protocol::study_config::BeamStudyConfig`]).
    Beam,
    /// Tables 3 and 4 ([`crate::ablation::study::AblationStudyConfig`]).
    Ablation,
    /// Tables 2 and 7 ([`crate::shapes::config::ShapeStudyConfig`]).
    Shapes,
    /// The error-vs-time sweep ([`crate::bench::BenchConfig`]).
    Bench,
    /// The pin sweep ([`crate::pins::PinSweepConfig`]).
    Pins,
    /// The numerical stress suite ([`crate::stress::StressConfig`]).
    Stress,
    /// The convergence study ([`crate::convergence::ConvergenceConfig`]).
    Convergence,
}

impl StudyKind {
    /// "beam", "ablation", …: the word a preset's `study` key holds.
    pub fn name(self) -> &'static str {
        match self {
            StudyKind::Beam => "beam",
            StudyKind::Ablation => "ablation",
            StudyKind::Shapes => "shapes",
            StudyKind::Bench => "bench",
            StudyKind::Pins => "pins",
            StudyKind::Stress => "stress",
            StudyKind::Convergence => "convergence",
        }
    }
}

/// A preset could not be found, read, changed or turned into its study's configuration.
#[derive(Debug, Error)]
pub enum PresetError {
    /// No committed preset has this name.
    #[error("there is no preset `{name}`; the presets are: {known}")]
    Unknown {
        /// The name asked for.
        name: String,
        /// The committed names, comma-separated.
        known: String,
    },
    /// A `--config` file could not be read.
    #[error("{path}: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The text is not TOML, has no `study` or `[config]`, or a value does not fit its
    /// setting (the message names the field).
    #[error("{origin}: {message}")]
    Invalid {
        /// The preset's name or file.
        origin: String,
        /// What is wrong.
        message: String,
    },
    /// The preset configures another study than the command runs.
    #[error("{origin} configures the {found} study; this command needs a {expected} preset")]
    WrongStudy {
        /// The preset's name or file.
        origin: String,
        /// Its `study`.
        found: &'static str,
        /// The study the command runs.
        expected: &'static str,
    },
    /// A `--set` is not `key=value` or its path runs through a value that is not a table.
    #[error("--set {assignment}: {problem}")]
    Override {
        /// The `key=value` given.
        assignment: String,
        /// What is wrong.
        problem: String,
    },
}

/// A preset's TOML with where it came from.
#[derive(Clone, Debug, PartialEq)]
pub struct Preset {
    /// `preset beam` or the file's path, for messages.
    pub origin: String,
    /// The study it configures.
    pub study: StudyKind,
    /// Its `[config]` table.
    pub config: toml::Table,
}

/// The file `freeform-paper` reads for a preset: the committed one, or `--config FILE`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum PresetChoice {
    /// A committed preset by name ([`PRESETS`]).
    Named(String),
    /// A TOML file of the same form.
    File(PathBuf),
}

impl Preset {
    /// The committed preset `name`.
    ///
    /// # Errors
    /// [`PresetError::Unknown`] naming the presets there are; [`PresetError::Invalid`] for a
    /// committed file that does not parse (a test keeps them parsing).
    pub fn named(name: &str) -> Result<Self, PresetError> {
        let text = PRESETS
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, text)| *text)
            .ok_or_else(|| PresetError::Unknown {
                name: name.to_string(),
                known: PRESETS
                    .iter()
                    .map(|(n, _)| *n)
                    .collect::<Vec<_>>()
                    .join(", "),
            })?;
        Self::parse(&format!("preset `{name}`"), text)
    }

    /// A preset file (`--config FILE`).
    ///
    /// # Errors
    /// [`PresetError::Read`], or [`PresetError::Invalid`] naming the file.
    pub fn file(path: &Path) -> Result<Self, PresetError> {
        let text = std::fs::read_to_string(path).map_err(|source| PresetError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(&path.display().to_string(), &text)
    }

    /// The preset `choice` names.
    ///
    /// # Errors
    /// As [`Preset::named`] and [`Preset::file`].
    pub fn load(choice: &PresetChoice) -> Result<Self, PresetError> {
        match choice {
            PresetChoice::Named(name) => Self::named(name),
            PresetChoice::File(path) => Self::file(path),
        }
    }

    /// Parses a preset's text: `study = "…"` and a `[config]` table.
    ///
    /// # Errors
    /// [`PresetError::Invalid`] naming `origin` and the problem.
    pub fn parse(origin: &str, text: &str) -> Result<Self, PresetError> {
        let invalid = |message: String| PresetError::Invalid {
            origin: origin.to_string(),
            message,
        };
        let mut table: toml::Table = text
            .parse()
            .map_err(|e: toml::de::Error| invalid(e.message().to_string()))?;
        let study = table.remove("study").ok_or_else(|| {
            invalid("no `study` key (beam, ablation, shapes, bench, pins or stress)".into())
        })?;
        let study = StudyKind::deserialize(study).map_err(|e| invalid(format!("study: {e}")))?;
        let config = match table.remove("config") {
            Some(toml::Value::Table(config)) => config,
            Some(_) => return Err(invalid("`config` is not a table".into())),
            None => return Err(invalid("no `[config]` table".into())),
        };
        if let Some(key) = table.keys().next() {
            return Err(invalid(format!(
                "unknown key `{key}` (a preset holds `study` and `[config]`)"
            )));
        }
        Ok(Preset {
            origin: origin.to_string(),
            study,
            config,
        })
    }

    /// Applies `--set key=value` assignments to `[config]`, in order.
    ///
    /// # Errors
    /// [`PresetError::Override`] naming the assignment.
    pub fn with_overrides(mut self, assignments: &[String]) -> Result<Self, PresetError> {
        for assignment in assignments {
            apply_override(&mut self.config, assignment)?;
        }
        Ok(self)
    }

    /// The configuration of `expected` study, with `folders` adding what the command line
    /// supplies (cache folder, meshes) to the `[config]` table first.
    ///
    /// # Errors
    /// [`PresetError::WrongStudy`] for a preset of another study, [`PresetError::Invalid`]
    /// naming the field that does not fit.
    pub fn config<T: DeserializeOwned>(
        &self,
        expected: StudyKind,
        folders: impl FnOnce(&mut toml::Table),
    ) -> Result<T, PresetError> {
        if self.study != expected {
            return Err(PresetError::WrongStudy {
                origin: self.origin.clone(),
                found: self.study.name(),
                expected: expected.name(),
            });
        }
        let mut config = self.config.clone();
        folders(&mut config);
        serde_path_to_error::deserialize(toml::Value::Table(config)).map_err(
            |e: serde_path_to_error::Error<toml::de::Error>| PresetError::Invalid {
                origin: self.origin.clone(),
                message: format!("{}: {}", e.path(), e.inner().message().trim()),
            },
        )
    }
}

/// Sets `config`'s entry at `key` (dotted) to `value`, one assignment `key=value`.
fn apply_override(config: &mut toml::Table, assignment: &str) -> Result<(), PresetError> {
    let problem = |problem: String| PresetError::Override {
        assignment: assignment.to_string(),
        problem,
    };
    let (key, value) = assignment
        .split_once('=')
        .ok_or_else(|| problem("expected key=value".into()))?;
    let path: Vec<&str> = key.trim().split('.').collect();
    if path.iter().any(|part| part.is_empty()) {
        return Err(problem("empty key".into()));
    }
    let value = value.trim();
    let (last, parents) = path.split_last().expect("a split has one part");
    let mut table = config;
    for part in parents {
        let entry = table
            .entry(part.to_string())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        table = entry
            .as_table_mut()
            .ok_or_else(|| problem(format!("`{part}` is not a table")))?;
    }
    if value == "none" {
        table.remove(*last);
    } else {
        table.insert(last.to_string(), parse_value(value));
    }
    Ok(())
}

/// A TOML value (`1e-3`, `true`, `[16]`, `{ kind = "full" }`, `"text"`), or a bare word as a
/// string.
fn parse_value(text: &str) -> toml::Value {
    format!("value = {text}")
        .parse::<toml::Table>()
        .ok()
        .and_then(|mut t| t.remove("value"))
        .unwrap_or_else(|| toml::Value::String(text.to_string()))
}

/// Puts `cache_dir` at `key`'s path in `config` (dotted, e.g. `base.cache_dir` for the
/// ablation's).
pub fn set_folder(config: &mut toml::Table, key: &str, folder: &Path) {
    let mut table = config;
    let path: Vec<&str> = key.split('.').collect();
    let (last, parents) = path.split_last().expect("a key has one part");
    for part in parents {
        table = table
            .entry(part.to_string())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()))
            .as_table_mut()
            .expect("the folders' parents are tables");
    }
    table.insert(
        last.to_string(),
        toml::Value::String(folder.display().to_string()),
    );
}

/// A preset's text for `config` of `study`, `description` as its leading comment, the run's
/// folders (`cache_dir`, `meshes` at any depth) left out: how the committed presets are made.
///
/// # Errors
/// [`PresetError::Invalid`] when `config` cannot be written as TOML.
pub fn render_preset<T: Serialize>(
    study: StudyKind,
    description: &str,
    config: &T,
) -> Result<String, PresetError> {
    let invalid = |message: String| PresetError::Invalid {
        origin: format!("the {} configuration", study.name()),
        message,
    };
    let mut table = toml::Table::try_from(config).map_err(|e| invalid(e.to_string()))?;
    remove_folders(&mut table);
    let mut preset = toml::Table::new();
    preset.insert("study".into(), toml::Value::String(study.name().into()));
    preset.insert("config".into(), toml::Value::Table(table));
    let body = toml::to_string(&preset).map_err(|e| invalid(e.to_string()))?;
    let comment: String = description
        .lines()
        .map(|line| format!("# {line}\n").replace("# \n", "#\n"))
        .collect();
    Ok(format!("{comment}\n{body}"))
}

fn remove_folders(table: &mut toml::Table) {
    table.remove("cache_dir");
    table.remove("meshes");
    for (_, value) in table.iter_mut() {
        if let toml::Value::Table(inner) = value {
            remove_folders(inner);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::beam_protocol::study_config::BeamStudyConfig;
    use crate::shapes::config::ShapeStudyConfig;

    #[test]
    fn a_set_assigns_typed_values_at_dotted_paths_and_none_removes_a_key() {
        let mut config: toml::Table =
            "modes = [6]\n[settings]\nkernels = 1000\n[simplicits]\nsteps = 10\n"
                .parse()
                .unwrap();
        for set in [
            "settings.kernels=500",
            "modes = [16, 32]",
            "settings.quadrature={ kind = \"full\" }",
            "label=bend",
            "simplicits=none",
        ] {
            apply_override(&mut config, set).unwrap();
        }
        assert_eq!(config["settings"]["kernels"].as_integer(), Some(500));
        assert_eq!(config["modes"].as_array().unwrap().len(), 2);
        assert_eq!(
            config["settings"]["quadrature"]["kind"].as_str(),
            Some("full")
        );
        assert_eq!(config["label"].as_str(), Some("bend"));
        assert!(!config.contains_key("simplicits"));
        let error = apply_override(&mut config, "modes.x=1").unwrap_err();
        assert!(
            error.to_string().contains("`modes` is not a table"),
            "{error}"
        );
        assert!(apply_override(&mut config, "no equals sign").is_err());
    }

    #[test]
    fn an_unknown_preset_lists_the_committed_ones_and_a_wrong_study_is_named() {
        let error = Preset::named("bogus").unwrap_err().to_string();
        assert!(
            error.contains("`bogus`") && error.contains("shapes-quick"),
            "{error}"
        );
        let beam = Preset::named("beam").unwrap();
        let error = beam
            .config::<ShapeStudyConfig>(StudyKind::Shapes, |_| {})
            .unwrap_err()
            .to_string();
        assert!(
            error.contains("beam study") && error.contains("shapes preset"),
            "{error}"
        );
    }

    #[test]
    fn a_value_of_the_wrong_type_is_an_error_naming_the_field() {
        let preset = Preset::named("beam")
            .unwrap()
            .with_overrides(&["settings.kernels=\"many\"".to_string()])
            .unwrap();
        let error = preset
            .config::<BeamStudyConfig>(StudyKind::Beam, |c| {
                set_folder(c, "cache_dir", Path::new("cache"))
            })
            .unwrap_err()
            .to_string();
        assert!(error.contains("kernels"), "{error}");
    }
}
