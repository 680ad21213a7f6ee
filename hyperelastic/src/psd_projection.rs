//! Projection of a symmetric 9×9 tangent onto the positive semi-definite cone, and its
//! absolute value (the other positive semi-definite filter of its eigenvalues).

use nalgebra::SymmetricEigen;

use crate::determinant::Matrix9;

/// `Σ max(λ_i, 0) q_i q_iᵀ` from a numeric symmetric eigendecomposition of `(H + Hᵀ)/2`: the
/// nearest PSD matrix in the Frobenius norm. The generic fallback for any material.
pub fn project_to_psd(h: &Matrix9) -> Matrix9 {
    let eigen = SymmetricEigen::new((h + h.transpose()) * 0.5);
    if eigen.eigenvalues.iter().all(|&l| l >= 0.0) {
        return (h + h.transpose()) * 0.5;
    }
    let clamped = eigen.eigenvalues.map(|l| l.max(0.0));
    eigen.eigenvectors * Matrix9::from_diagonal(&clamped) * eigen.eigenvectors.transpose()
}

/// `Σ |λ_i| q_i q_iᵀ` from a numeric symmetric eigendecomposition of `(H + Hᵀ)/2`: the
/// matrix absolute value, positive semi-definite, equal to `(H + Hᵀ)/2` where that is. The
/// generic fallback for any material ([`crate::Tangent::AbsoluteEigenvalues`]).
pub fn absolute_eigenvalues(h: &Matrix9) -> Matrix9 {
    let eigen = SymmetricEigen::new((h + h.transpose()) * 0.5);
    if eigen.eigenvalues.iter().all(|&l| l >= 0.0) {
        return (h + h.transpose()) * 0.5;
    }
    let mirrored = eigen.eigenvalues.map(f64::abs);
    eigen.eigenvectors * Matrix9::from_diagonal(&mirrored) * eigen.eigenvectors.transpose()
}
