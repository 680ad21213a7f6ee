//! Why a scene file could not be run to the end.

use artifact::ArtifactError;
use hyperelastic::MaterialParameterError;
use reduced_sim::{DeformationMapError, MultiBodyError, MultiBodyStepError};
use skin_eigen::BasisError;
use thiserror::Error;

use crate::geometry::GeometryError;
use crate::runner::RunError;
use crate::splats::SplatFileError;

/// A scene file could not be run to the end.
#[derive(Debug, Error)]
pub enum SimulateError {
    /// The geometry could not be read or sampled.
    #[error(transparent)]
    Geometry(#[from] GeometryError),
    /// E or ν is out of range.
    #[error("invalid material")]
    Material(#[source] MaterialParameterError),
    /// The basis could not be built.
    #[error("building the basis failed")]
    Basis(#[source] BasisError),
    /// The deformation map at the written points could not be built.
    #[error("the deformation map at the output points failed")]
    OutputMap(#[source] DeformationMapError),
    /// The simulation stopped (frames already written stay valid files).
    #[error(transparent)]
    Run(#[from] RunError),
    /// A file could not be written.
    #[error(transparent)]
    Write(#[from] ArtifactError),
    /// The 3DGS file could not be read or a deformed frame written.
    #[error(transparent)]
    Splats(#[from] SplatFileError),
    /// The stress at a frame could not be evaluated.
    #[error(transparent)]
    Stress(#[from] crate::StressFieldError),
    /// The objects of a scene do not fit together ([`crate::simulate_objects`]).
    #[error("the objects do not make a scene")]
    Objects(#[source] MultiBodyError),
    /// A step of several objects failed (frames already written stay valid files).
    #[error("step {step} failed")]
    ObjectStep {
        /// The step (1-based).
        step: usize,
        /// Why.
        #[source]
        source: MultiBodyStepError,
    },
}
