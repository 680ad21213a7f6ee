//! The basis trait: what the simulator needs from any skinning basis (design §2, 3.7).

use nalgebra::Vector3;
use rkpm_core::ShapeFunctionError;
use skin_eigen::{SkinningBasis, SkinningWeights};

/// A skinning basis: m + 1 weight fields `W^j(X)` and their gradients, evaluated at any rest
/// points. The RKPM eigenbasis ([`SkinningBasis`]) and the neural baseline both implement it, so
/// both run through the same simulator.
///
/// Contract: column 0 of [`SkinningWeights::weights`] is the constant handle `W⁰ ≡ 1` (with
/// `∇W⁰ = 0`), so that the handle-0 transform moves the object rigidly; the simulator checks it.
pub trait SkinningField {
    /// Why an evaluation failed (a point outside the basis's domain, a non-finite input).
    type Error: std::error::Error + Send + Sync + 'static;

    /// Number of handles m + 1 (the constant handle included).
    fn handles(&self) -> usize;

    /// W (N × (m + 1), dimensionless) and ∇W (three N × (m + 1) matrices, 1/m) at `points`
    /// (rest positions, m).
    ///
    /// # Errors
    /// [`Self::Error`] when some point cannot be evaluated.
    fn evaluate(&self, points: &[Vector3<f64>]) -> Result<SkinningWeights, Self::Error>;
}

impl SkinningField for SkinningBasis {
    type Error = ShapeFunctionError;

    fn handles(&self) -> usize {
        SkinningBasis::handles(self)
    }

    fn evaluate(&self, points: &[Vector3<f64>]) -> Result<SkinningWeights, Self::Error> {
        SkinningBasis::evaluate(self, points)
    }
}
