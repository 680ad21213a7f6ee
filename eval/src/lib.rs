//! FreeForm experiments (DESIGN 4, 5): the named scenes translated into each solver's inputs,
//! the metrics against the FEM ground truth, the paper's tables with its numbers beside ours,
//! the error-vs-time benchmark, and the `freeform` CLI (`src/bin/freeform.rs`).
//!
//! - [`scene_spec`]: one solver-independent scene ([`SceneSpec`]) → reduced and FEM inputs.
//! - [`beam`]: the beam Bend and Twist of DESIGN 4.1.
//! - [`metrics`]: normalized MSE, max error, basis fitting residual (DESIGN 4.3).
//! - [`fem_reference`], [`reduced_run`]: the FEM reference and one reduced run on any scene;
//!   [`reduced_beam`]: the beam's basis and integration points.
//! - [`simplicits_beam`], [`coefficient_beam`]: the Simplicits baseline and the Table 3
//!   coefficient ablations trained on the beam, cached through [`model_cache`].
//! - [`beam_study`], [`ablation_study`], [`tables`]: Tables 1, 3, 4, 5, 6. [`bench`]: the
//!   error-vs-time study.
//! - [`scene_file`]: user scenes in TOML/JSON for `freeform simulate`.
//! - [`stress`]: the numerical stress suite (`freeform stress`).
//! - [`output`], [`plot`], [`progress`]: files, figures, progress bars.
//!
//! Caches (FEM trajectories, bases) live under one folder (default `freeform-cache/`, or
//! `$FREEFORM_CACHE`), keyed by content hash; deleting it only costs recomputation.

use std::path::Path;

use thiserror::Error;

pub mod ablation_study;
pub mod ablation_tables;
pub mod beam;
pub mod beam_study;
pub mod bench;
pub mod coefficient_beam;
pub mod fem_reference;
pub mod metrics;
pub mod model_cache;
pub mod output;
pub mod paper;
pub mod plot;
pub mod progress;
pub mod reduced_beam;
pub mod reduced_run;
pub mod scene_file;
pub mod scene_spec;
pub mod shape_boundary;
pub mod shape_catalog;
pub mod shape_study;
pub mod shape_tables;
pub mod simplicits_beam;
pub mod stress;
pub mod tables;

pub use scene_spec::SceneSpec;

/// An experiment failed.
#[derive(Debug, Error)]
pub enum EvalError {
    /// Building a mesh, model or solver failed.
    #[error("setup failed: {0}")]
    Setup(String),
    /// Building a basis failed.
    #[error("basis construction failed: {0}")]
    Basis(String),
    /// The FEM reference failed.
    #[error("FEM reference failed: {0}")]
    Fem(String),
    /// The reduced simulation failed.
    #[error("reduced simulation failed: {0}")]
    Reduced(String),
    /// A scene cannot be applied.
    #[error(transparent)]
    Scene(#[from] scene_spec::SceneSpecError),
    /// Metrics could not be computed.
    #[error(transparent)]
    Metrics(#[from] metrics::MetricsError),
    /// A scene file is unreadable or malformed.
    #[error(transparent)]
    SceneFile(#[from] scene_file::SceneFileError),
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// A FEM reference stopped unconverged at some step, so nothing is scored against it.
    #[error(transparent)]
    UnconvergedReference(#[from] fem_reference::UnconvergedReference),
    /// An output or cache file could not be written or read.
    #[error(transparent)]
    Artifact(#[from] artifact::ArtifactError),
    /// A plot could not be drawn.
    #[error("plot failed: {0}")]
    Plot(String),
}

impl EvalError {
    /// An I/O error on `path`.
    pub fn io(path: &Path, source: std::io::Error) -> Self {
        EvalError::Io {
            path: path.display().to_string(),
            source,
        }
    }
}

/// The cache folder: `$FREEFORM_CACHE` if set, else `freeform-cache` in the working directory.
pub fn default_cache_dir() -> std::path::PathBuf {
    std::env::var_os("FREEFORM_CACHE")
        .map(Into::into)
        .unwrap_or_else(|| "freeform-cache".into())
}
