//! FreeForm experiments (DESIGN 4, 5), the paper layer on top of the `freeform` library: the
//! named scenes, the metrics against the FEM ground truth, the paper's tables with its numbers
//! beside ours, the error-vs-time benchmark, and the `freeform` CLI (`src/bin/freeform.rs`).
//! Scenes, scene files, the reduced-run loop and frame writers live in the library crate
//! `freeform`; this crate holds what reproduces the paper.
//!
//! The paper's experiments, one folder each:
//! - [`beam`]: the beam Bend and Twist of DESIGN 4.1 and Tables 1, 5, 6 (with the Simplicits
//!   baseline trained on the beam).
//! - [`ablation`]: Tables 3 and 4 (how the basis is trained, how points are sampled).
//! - [`shapes`]: Tables 2 and 7 on a folder of meshes.
//! - [`bench`](mod@bench): the error-vs-time study. [`stress`]: the numerical stress suite.
//! - [`report`]: the paper's numbers, rendered tables, plots.
//!
//! What they share: [`fem_reference`] (the FEM ground truth on any scene, cached, refused
//! when unconverged), [`reduced_run`] (one reduced run recorded at the FEM vertices),
//! [`metrics`] (DESIGN 4.3), [`model_cache`] (trained networks), [`progress`] (terminal bars).
//!
//! Caches (FEM trajectories, bases) live under one folder (default `freeform-cache/`, or
//! `$FREEFORM_CACHE`), keyed by content hash; deleting it only costs recomputation.

use std::path::Path;

use thiserror::Error;

pub mod ablation;
pub mod beam;
pub mod bench;
pub mod fem_reference;
pub mod metrics;
pub mod model_cache;
pub mod pins;
pub mod progress;
pub mod reduced_run;
pub mod report;
pub mod shapes;
pub mod stress;

/// An experiment failed. Every variant that wraps another error keeps it as its `source`.
#[derive(Debug, Error)]
pub enum EvalError {
    /// The experiment was asked for something it cannot run (an empty folder, no such mesh,
    /// zero jobs); the message says what.
    #[error("{0}")]
    InvalidInput(String),
    /// A mesh file could not be read.
    #[error(transparent)]
    MeshFile(#[from] rkpm_core::GeometryReadError),
    /// Integration points could not be sampled.
    #[error("sampling the {what} failed")]
    Sampling {
        /// Which points ("basis points", "simulation points", ...).
        what: &'static str,
        /// Why.
        #[source]
        source: rkpm_core::SamplingError,
    },
    /// E or ν is out of range.
    #[error("invalid material")]
    Material(#[source] hyperelastic::MaterialParameterError),
    /// Building a basis failed.
    #[error("building the basis failed")]
    Basis(#[source] skin_eigen::BasisError),
    /// Training the Simplicits network failed.
    #[error("training {what} failed")]
    Simplicits {
        /// Which network.
        what: String,
        /// Why.
        #[source]
        source: baselines::simplicits::SimplicitsError,
    },
    /// Training a Table 3 coefficient ablation failed.
    #[error("training {what} failed")]
    Coefficients {
        /// Which ablation.
        what: String,
        /// Why.
        #[source]
        source: baselines::coefficient_training::CoefficientTrainingError,
    },
    /// The FEM reference's box mesh could not be built.
    #[error("building the FEM box mesh failed")]
    FemBox(#[source] fem_ref::TetMeshError),
    /// A surface could not be tetrahedralized for the FEM reference.
    #[error("tetrahedralizing for the FEM reference failed")]
    FemMesh(#[source] fem_ref::LatticeMesherError),
    /// The FEM model could not be built.
    #[error("building the FEM model failed")]
    FemModel(#[source] fem_ref::FemModelError),
    /// The FEM simulator refused the scene.
    #[error("setting up the FEM simulator failed")]
    FemSetup(#[source] fem_ref::FemSetupError),
    /// The MPM baseline refused its options or its run failed.
    #[error("the MPM baseline failed")]
    Mpm(#[from] baselines::mpm::MpmError),
    /// The SPH baseline refused its options or its setup failed.
    #[error("the SPH baseline failed")]
    Sph(#[from] baselines::sph::SphError),
    /// The FEM reference failed to run or to use its cache.
    #[error("the FEM reference failed")]
    Fem(#[source] fem_ref::FemRunError),
    /// Points to read the FEM solution at lie outside its mesh.
    #[error(transparent)]
    PointLocation(#[from] fem_ref::PointLocationError),
    /// A skinning field cannot be evaluated at the output points.
    #[error("evaluating the skinning field at the output points failed")]
    OutputMap(#[source] reduced_sim::DeformationMapError),
    /// A scene cannot be applied.
    #[error(transparent)]
    Scene(#[from] freeform::SceneSpecError),
    /// A reduced run could not start or stopped.
    #[error(transparent)]
    Run(#[from] freeform::RunError),
    /// Metrics could not be computed.
    #[error(transparent)]
    Metrics(#[from] metrics::MetricsError),
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// A cached-only run ([`shapes::study::ShapeStudyConfig::cached_only`]) needed something
    /// the cache does not hold; nothing was computed for it.
    #[error("{what} is not in the cache (a cached-only run computes nothing)")]
    NotCached {
        /// What was missing ("FEM bunny.obj Fix side finer", "Simplicits m = 32").
        what: String,
    },
    /// A FEM reference stopped unconverged at some step, so nothing is scored against it.
    #[error(transparent)]
    UnconvergedReference(#[from] fem_reference::UnconvergedReference),
    /// An output or cache file could not be written or read.
    #[error(transparent)]
    Artifact(#[from] artifact::ArtifactError),
    /// A plot could not be drawn (plotters' errors are generic over the backend, so only
    /// their text is kept).
    #[error("{path}: plot failed: {message}")]
    Plot {
        /// The figure file.
        path: std::path::PathBuf,
        /// The drawing backend's message.
        message: String,
    },
}

impl From<freeform::HeldBasisError> for EvalError {
    fn from(error: freeform::HeldBasisError) -> Self {
        match error {
            freeform::HeldBasisError::Scene(e) => EvalError::Scene(e),
            freeform::HeldBasisError::Basis(e) => EvalError::Basis(e),
        }
    }
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

/// An error and its sources on one line ("building the basis failed: …: …"): what a table row,
/// a log line or the CLI's last line records, where `to_string` alone would drop the cause. A
/// cause whose text the line already shows (our error enums print their source inside their
/// own message) is not repeated.
pub fn failure_chain(error: &dyn std::error::Error) -> String {
    let mut line = error.to_string();
    let mut source = error.source();
    while let Some(cause) = source {
        let text = cause.to_string();
        if !line.contains(&text) {
            line += ": ";
            line += &text;
        }
        source = cause.source();
    }
    line
}

/// The cache folder: `$FREEFORM_CACHE` if set, else `freeform-cache` in the working directory.
pub fn default_cache_dir() -> std::path::PathBuf {
    std::env::var_os("FREEFORM_CACHE")
        .map(Into::into)
        .unwrap_or_else(|| "freeform-cache".into())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, Error)]
    #[error("building the thing failed")]
    struct Outer(#[source] Inner);

    #[derive(Debug, Error)]
    #[error("the inner cause")]
    struct Inner;

    #[test]
    fn failure_chain_names_every_cause_after_the_error_once() {
        assert_eq!(
            failure_chain(&Outer(Inner)),
            "building the thing failed: the inner cause"
        );
        // `Io` prints its source itself: the chain does not repeat it.
        let error = EvalError::io(
            Path::new("mesh.obj"),
            std::io::Error::new(std::io::ErrorKind::NotFound, "no such file"),
        );
        assert_eq!(failure_chain(&error), "mesh.obj: no such file");
    }
}
