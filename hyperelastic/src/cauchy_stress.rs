//! Cauchy (true) stress and its principal values (the paper's stress figure, Sec. 9.3).

use nalgebra::{Matrix3, SymmetricEigen, Vector3};

/// The Cauchy stress is undefined for a collapsed or inverted element.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum CauchyStressError {
    /// `J = det F` is not positive.
    #[error("Cauchy stress needs det F > 0, got J = {determinant}")]
    NonPositiveDeterminant {
        /// det F.
        determinant: f64,
    },
}

/// `σ = J⁻¹ P Fᵀ` (Pa), symmetrized to remove round-off (exactly symmetric for an isotropic,
/// frame-indifferent material).
///
/// # Errors
/// [`CauchyStressError::NonPositiveDeterminant`] when `det F ≤ 0` or is not finite.
pub fn cauchy_stress(
    f: &Matrix3<f64>,
    first_piola_kirchhoff: &Matrix3<f64>,
) -> Result<Matrix3<f64>, CauchyStressError> {
    let determinant = f.determinant();
    if !(determinant > 0.0 && determinant.is_finite()) {
        return Err(CauchyStressError::NonPositiveDeterminant { determinant });
    }
    let sigma = first_piola_kirchhoff * f.transpose() / determinant;
    Ok((sigma + sigma.transpose()) * 0.5)
}

/// Principal stresses: eigenvalues of a symmetric stress tensor, descending (σ₁ ≥ σ₂ ≥ σ₃, Pa).
pub fn principal_stresses(sigma: &Matrix3<f64>) -> Vector3<f64> {
    let mut values = SymmetricEigen::new(*sigma).eigenvalues;
    values.as_mut_slice().sort_by(|a, b| b.total_cmp(a));
    values
}
