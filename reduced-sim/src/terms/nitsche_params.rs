//! The options, report and errors of a [`NitscheInterface`].

use thiserror::Error;

use crate::model::deformation_map::DeformationMapError;
#[cfg(doc)]
use crate::terms::nitsche_term::NitscheInterface;

/// Options of a [`NitscheInterface`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NitscheParams {
    /// s in `β = 2 s C` (dimensionless, default 2; the sum is coercive for s ≥ 1, and the
    /// solution is insensitive to s over a wide range when the basis resolves the interface).
    pub stabilization_factor: f64,
}

impl Default for NitscheParams {
    fn default() -> Self {
        NitscheParams {
            stabilization_factor: 2.0,
        }
    }
}

/// What [`NitscheInterface::new`] chose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NitscheReport {
    /// Interface samples.
    pub samples: usize,
    /// Total interface area Σ a_s (m²).
    pub area: f64,
    /// C, the reduced trace bound (Pa/m).
    pub bound: f64,
    /// β = 2 s C (Pa/m).
    pub stabilization: f64,
}

/// The interface could not be set up.
#[derive(Debug, Error)]
pub enum NitscheError {
    /// No interface sample was given.
    #[error("a Nitsche interface needs at least one sample")]
    NoSamples,
    /// Samples, areas and normals differ in number.
    #[error("{samples} interface samples, {areas} areas and {normals} normals: one each")]
    LengthMismatch {
        /// Samples given.
        samples: usize,
        /// Areas given.
        areas: usize,
        /// Normals given.
        normals: usize,
    },
    /// A sample's area is not finite and positive, or its normal not a finite unit vector.
    #[error("interface sample {index}: area {area} m² and normal {normal:?} (need a > 0, |N| = 1)")]
    BadSample {
        /// The sample's index.
        index: usize,
        /// Its area (m²).
        area: f64,
        /// Its normal.
        normal: [f64; 3],
    },
    /// The stabilization factor is not finite and positive.
    #[error("the Nitsche stabilization factor must be finite and positive, got {0}")]
    Params(f64),
    /// The rest stiffness is not square of the reduced coordinates' size.
    #[error("the rest stiffness is {rows} × {cols}, expected {expected} square")]
    StiffnessShape {
        /// Its rows.
        rows: usize,
        /// Its columns.
        cols: usize,
        /// 12(m + 1).
        expected: usize,
    },
    /// The rest stiffness has no positive eigenvalue (no deformable handle).
    #[error("the rest stiffness has no positive eigenvalue: nothing to bound the traction by")]
    NoStiffness,
    /// The basis cannot be evaluated at the samples.
    #[error("the basis at the interface samples: {0}")]
    Map(#[from] DeformationMapError),
    /// The pressure functions at the samples do not fit the model's projected dilatation (or
    /// the model has none, `expected` 0), or are not finite.
    #[error(
        "pressure values at the interface: {rows} × {functions}, expected one row per sample and {expected} functions"
    )]
    PressureValues {
        /// Rows given.
        rows: usize,
        /// Columns given.
        functions: usize,
        /// The model's pressure functions (0: it has no projected dilatation).
        expected: usize,
    },
}
