//! Derivatives of J = det F, written without F⁻¹ so they stay finite for J ≤ 0.
//!
//! Conventions for the whole crate: `vec(F)` stacks the columns of F (nalgebra's storage
//! order), so `vec(F)[3c + r] = F[(r, c)]`, and a 9×9 tangent `H` has
//! `H[(a, b)] = ∂vec(P)_a / ∂vec(F)_b`.

use nalgebra::{Matrix3, SMatrix, Vector3};

/// A 9×9 matrix over `vec(F)` (column-major vectorization).
pub type Matrix9 = SMatrix<f64, 9, 9>;

/// The cofactor matrix `cof F = ∂J/∂F = J F⁻ᵀ`, columns `[f₁×f₂, f₂×f₀, f₀×f₁]` for the
/// columns f₀, f₁, f₂ of F. Defined for every F.
pub fn cofactor(f: &Matrix3<f64>) -> Matrix3<f64> {
    let (c0, c1, c2) = (f.column(0), f.column(1), f.column(2));
    Matrix3::from_columns(&[c1.cross(&c2), c2.cross(&c0), c0.cross(&c1)])
}

/// The cross-product matrix `[a]×` with `[a]× b = a × b`.
pub fn cross_matrix(a: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -a.z, a.y, a.z, 0.0, -a.x, -a.y, a.x, 0.0)
}

/// The Hessian `∂²J/∂vec(F)²` (9×9), in 3×3 column blocks
/// `[[0, -[f₂]×, [f₁]×], [[f₂]×, 0, -[f₀]×], [-[f₁]×, [f₀]×, 0]]`. Linear in F.
pub fn determinant_hessian(f: &Matrix3<f64>) -> Matrix9 {
    let x: [Matrix3<f64>; 3] = [0, 1, 2].map(|c| cross_matrix(&f.column(c).into_owned()));
    let mut h = Matrix9::zeros();
    let mut put =
        |r: usize, c: usize, m: Matrix3<f64>| h.fixed_view_mut::<3, 3>(3 * r, 3 * c).copy_from(&m);
    put(0, 1, -x[2]);
    put(0, 2, x[1]);
    put(1, 0, x[2]);
    put(1, 2, -x[0]);
    put(2, 0, -x[1]);
    put(2, 1, x[0]);
    h
}

/// `vec(A)` as a 9-vector (column-major).
pub fn vectorize(a: &Matrix3<f64>) -> SMatrix<f64, 9, 1> {
    SMatrix::<f64, 9, 1>::from_column_slice(a.as_slice())
}
