#![doc = include_str!("../README.md")]

use std::path::Path;

use thiserror::Error;

pub mod ablation;
pub mod beam;
pub mod beam_protocol;
pub mod beam_scenario;
pub mod bench;
pub mod convergence;
pub mod fem_reference;
pub mod model_cache;
pub mod particle_baselines;
pub mod pins;
pub mod presets;
pub mod reduced_run;
pub mod reduced_settings;
pub mod report;
pub mod shapes;
pub mod simplicits_cache;
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
    /// A reduced run of the beam (a row of Tables 1, 5 and 6 or of the ablation) failed;
    /// `source` says why.
    #[error("the beam {test} at m = {modes}")]
    BeamRun {
        /// The test ("bend", "twist").
        test: &'static str,
        /// m.
        modes: usize,
        /// Why it failed.
        #[source]
        source: Box<EvalError>,
    },
    /// Metrics could not be computed.
    #[error(transparent)]
    Metrics(#[from] freeform::metrics::MetricsError),
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// A cached-only run ([`shapes::config::ShapeStudyConfig::cached_only`]) needed something
    /// the cache does not hold; nothing was computed for it.
    #[error("{what} is not in the cache (a cached-only run computes nothing)")]
    NotCached {
        /// What was missing ("FEM bunny.obj Fix side finer", "Simplicits m = 32").
        what: String,
    },
    /// A FEM reference stopped unconverged at some step, so nothing is scored against it.
    #[error(transparent)]
    UnconvergedReference(#[from] freeform::fem_reference::UnconvergedReference),
    /// An output or cache file could not be written or read.
    #[error(transparent)]
    Artifact(#[from] artifact::ArtifactError),
    /// The static FEM reference of the convergence study did not converge.
    #[error("the static FEM reference did not converge in {iterations} Newton iterations")]
    StaticReferenceNotConverged {
        /// Iterations run.
        iterations: usize,
    },
    /// A Nitsche interface of the convergence study could not be set up.
    #[error("the Nitsche interface")]
    Nitsche(#[from] reduced_sim::NitscheError),
    /// The convergence study's Nitsche rows hold half-space regions only.
    #[error("the convergence study holds half-space regions by Nitsche, not {0}")]
    NitscheRegion(String),
    /// A best-approximation projection of the convergence study could not be solved.
    #[error("projection onto the subspace: {0}")]
    Projection(&'static str),
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

impl From<freeform::fem_reference::FemReferenceError> for EvalError {
    fn from(error: freeform::fem_reference::FemReferenceError) -> Self {
        use freeform::fem_reference::FemReferenceError as E;
        match error {
            E::Model(e) => EvalError::FemModel(e),
            E::Setup(e) => EvalError::FemSetup(e),
            E::Run(e) => EvalError::Fem(e),
            E::Scene(e) => EvalError::Scene(e),
            E::PointLocation(e) => EvalError::PointLocation(e),
            E::OutputMap(e) => EvalError::OutputMap(e),
            E::Metrics(e) => EvalError::Metrics(e),
        }
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_io_error_in_a_failure_chain_names_its_source_once() {
        // `Io` prints its source itself: the chain does not repeat it.
        let error = EvalError::io(
            Path::new("mesh.obj"),
            std::io::Error::new(std::io::ErrorKind::NotFound, "no such file"),
        );
        assert_eq!(freeform::failure_chain(&error), "mesh.obj: no such file");
    }
}
