//! Rotation-variant singular value decomposition, the basis of analytic eigensystems of
//! isotropic energies (Smith et al. 2019, "Analytic Eigensystems for Isotropic Distortion
//! Energies", Sec. 3).

use nalgebra::{Matrix3, Vector3};

/// `F = U diag(σ) Vᵀ` with U, V proper rotations (det = +1). The sign of det F is carried by
/// σ₃ (the smallest magnitude), so `σ₁σ₂σ₃ = det F`.
#[derive(Clone, Copy, Debug)]
pub struct SignedSvd {
    /// Left rotation U.
    pub u: Matrix3<f64>,
    /// Signed singular values σ.
    pub sigma: Vector3<f64>,
    /// Right rotation V.
    pub v: Matrix3<f64>,
}

impl SignedSvd {
    /// Decomposes F. Non-finite input gives non-finite output (callers check).
    pub fn new(f: &Matrix3<f64>) -> Self {
        let svd = f.svd(true, true);
        let mut u = svd.u.expect("requested U");
        let mut v = svd.v_t.expect("requested Vᵀ").transpose();
        let mut sigma = svd.singular_values;
        // Put the smallest singular value last so the sign flip lands on it.
        let smallest = sigma.imin();
        if smallest != 2 {
            sigma.swap_rows(smallest, 2);
            u.swap_columns(smallest, 2);
            v.swap_columns(smallest, 2);
        }
        if u.determinant() < 0.0 {
            u.column_mut(2).neg_mut();
            sigma[2] = -sigma[2];
        }
        if v.determinant() < 0.0 {
            v.column_mut(2).neg_mut();
            sigma[2] = -sigma[2];
        }
        SignedSvd { u, sigma, v }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reconstructs_inverted_matrices_with_rotations() {
        let f = Matrix3::new(0.3, 1.2, -0.4, 0.9, -0.1, 0.2, 0.5, 0.7, -1.1);
        let s = SignedSvd::new(&f);
        assert!((s.u * Matrix3::from_diagonal(&s.sigma) * s.v.transpose() - f).norm() < 1e-12);
        assert!((s.u.determinant() - 1.0).abs() < 1e-12 && (s.v.determinant() - 1.0).abs() < 1e-12);
        assert!((s.sigma.product() - f.determinant()).abs() < 1e-12);
    }
}
