//! Central finite differences for checking analytic derivatives.
//!
//! Central differences have truncation error O(h²) and round-off error O(ε/h); with h ≈ 1e-6
//! relative to the scale of the input both are around 1e-10 relative for smooth f64 functions.

use nalgebra::{DMatrix, DVector};

/// Gradient of a scalar function by central differences: `g_i ≈ (f(x + h e_i) - f(x - h e_i)) / 2h`.
pub fn gradient(f: impl Fn(&[f64]) -> f64, x: &[f64], h: f64) -> DVector<f64> {
    let mut probe = x.to_vec();
    DVector::from_iterator(
        x.len(),
        (0..x.len()).map(|i| {
            probe[i] = x[i] + h;
            let plus = f(&probe);
            probe[i] = x[i] - h;
            let minus = f(&probe);
            probe[i] = x[i];
            (plus - minus) / (2.0 * h)
        }),
    )
}

/// Jacobian (`rows × x.len()`) of a vector function by central differences:
/// column j is `(f(x + h e_j) - f(x - h e_j)) / 2h`.
pub fn jacobian(f: impl Fn(&[f64]) -> Vec<f64>, x: &[f64], h: f64) -> DMatrix<f64> {
    let rows = f(x).len();
    let mut probe = x.to_vec();
    let mut out = DMatrix::zeros(rows, x.len());
    for j in 0..x.len() {
        probe[j] = x[j] + h;
        let plus = f(&probe);
        probe[j] = x[j] - h;
        let minus = f(&probe);
        probe[j] = x[j];
        for i in 0..rows {
            out[(i, j)] = (plus[i] - minus[i]) / (2.0 * h);
        }
    }
    out
}

/// Relative error `|a - b| / max(|b|, floor)` in the Frobenius norm; `floor` keeps the measure
/// meaningful when the reference is near zero.
pub fn relative_error(a: &DMatrix<f64>, b: &DMatrix<f64>, floor: f64) -> f64 {
    (a - b).norm() / b.norm().max(floor)
}
