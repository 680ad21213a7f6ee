//! The polynomials RKPM shape functions reproduce: the basis `P` of paper Eq. 7 and its
//! shifted-and-scaled evaluation ([`crate::shape_functions`]).
//!
//! The paper reproduces linear fields, `P(X) = [1, x, y, z]ᵀ`. Quadratic reproduction adds the
//! six second-degree monomials, `P(X) = [1, x, y, z, x², y², z², xy, yz, zx]ᵀ`: every quadratic
//! field `q` is then interpolated exactly, `Σ_k ϕ_k(X) q(p_k) = q(X)`, and so are its
//! gradients. For smooth fields the interpolation error falls as `h³` instead of `h²` (h the
//! kernel spacing), at the price of a 10 × 10 moment matrix and at least 10 kernels, not all on
//! one quadric, reaching every point.

use nalgebra::{SVector, Vector3};
use serde::{Deserialize, Serialize};

/// The polynomial degree the shape functions reproduce exactly.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Reproduction {
    /// Constant and linear fields, `P = [1, x, y, z]` (paper Eq. 7; the default).
    #[default]
    Linear,
    /// Constant, linear and quadratic fields, `P = [1, x, y, z, x², y², z², xy, yz, zx]`
    /// (10 terms).
    Quadratic,
}

impl Reproduction {
    /// Whether this is [`Reproduction::Linear`], the default (for `skip_serializing_if`).
    pub fn is_linear(&self) -> bool {
        *self == Reproduction::Linear
    }

    /// The number of terms of `P`: 4 or 10. No fewer kernels may reach a point.
    pub fn terms(&self) -> usize {
        match self {
            Reproduction::Linear => LINEAR_TERMS,
            Reproduction::Quadratic => QUADRATIC_TERMS,
        }
    }
}

/// Terms of the linear basis.
pub(crate) const LINEAR_TERMS: usize = 4;
/// Terms of the quadratic basis.
pub(crate) const QUADRATIC_TERMS: usize = 10;

/// A polynomial basis `P` of `N` terms, evaluated at a scaled offset `ξ = (X − p_k)/s`, with
/// its derivatives along each axis of X (so each carries a factor `1/s`).
pub(crate) trait PolynomialBasis<const N: usize> {
    /// `P(ξ)` and `∂P(ξ)/∂X_d` for d = 0, 1, 2, at `ξ = d / s`.
    fn at(offset: &Vector3<f64>, s: f64) -> (SVector<f64, N>, [SVector<f64, N>; 3]);

    /// `φ (∂_d P · C)` for the kernel value `φ`, the derivative `∂_d P` along `axis` and the
    /// correction C.
    fn weighted_derivative(
        phi: f64,
        derivative: &SVector<f64, N>,
        correction: &SVector<f64, N>,
        axis: usize,
        s: f64,
    ) -> f64 {
        let _ = (axis, s);
        phi * derivative.dot(correction)
    }
}

/// `[1, ξ_x, ξ_y, ξ_z]`.
pub(crate) struct LinearBasis;

impl PolynomialBasis<LINEAR_TERMS> for LinearBasis {
    fn at(
        offset: &Vector3<f64>,
        s: f64,
    ) -> (SVector<f64, LINEAR_TERMS>, [SVector<f64, LINEAR_TERMS>; 3]) {
        let xi = offset / s;
        let value = SVector::<f64, LINEAR_TERMS>::new(1.0, xi.x, xi.y, xi.z);
        let gradient = std::array::from_fn(|d| SVector::<f64, LINEAR_TERMS>::ith(d + 1, 1.0 / s));
        (value, gradient)
    }

    /// `φ C[d + 1] / s`, in the order the linear functions have always been evaluated in (so
    /// they stay bit for bit what they were).
    fn weighted_derivative(
        phi: f64,
        _derivative: &SVector<f64, LINEAR_TERMS>,
        correction: &SVector<f64, LINEAR_TERMS>,
        axis: usize,
        s: f64,
    ) -> f64 {
        phi * correction[axis + 1] / s
    }
}

/// `[1, ξ_x, ξ_y, ξ_z, ξ_x², ξ_y², ξ_z², ξ_x ξ_y, ξ_y ξ_z, ξ_z ξ_x]`.
pub(crate) struct QuadraticBasis;

impl PolynomialBasis<QUADRATIC_TERMS> for QuadraticBasis {
    fn at(
        offset: &Vector3<f64>,
        s: f64,
    ) -> (
        SVector<f64, QUADRATIC_TERMS>,
        [SVector<f64, QUADRATIC_TERMS>; 3],
    ) {
        let xi = offset / s;
        let (x, y, z) = (xi.x, xi.y, xi.z);
        let value = SVector::<f64, QUADRATIC_TERMS>::from_column_slice(&[
            1.0,
            x,
            y,
            z,
            x * x,
            y * y,
            z * z,
            x * y,
            y * z,
            z * x,
        ]);
        let u = 1.0 / s;
        let gradient = [
            [0.0, u, 0.0, 0.0, 2.0 * x * u, 0.0, 0.0, y * u, 0.0, z * u],
            [0.0, 0.0, u, 0.0, 0.0, 2.0 * y * u, 0.0, x * u, z * u, 0.0],
            [0.0, 0.0, 0.0, u, 0.0, 0.0, 2.0 * z * u, 0.0, y * u, x * u],
        ]
        .map(|g| SVector::<f64, QUADRATIC_TERMS>::from_column_slice(&g));
        (value, gradient)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each basis's derivative columns against central differences of its values.
    fn check_gradient<const N: usize, B: PolynomialBasis<N>>() {
        let (offset, s, h) = (Vector3::new(0.3, -0.7, 0.45), 0.8, 1e-6);
        let (_, gradient) = B::at(&offset, s);
        for (d, column) in gradient.iter().enumerate() {
            let step = Vector3::ith(d, h);
            let (plus, _) = B::at(&(offset + step), s);
            let (minus, _) = B::at(&(offset - step), s);
            let difference = (plus - minus) / (2.0 * h);
            assert!(
                (difference - column).norm() < 1e-8,
                "axis {d}: {difference} against {column}"
            );
        }
    }

    #[test]
    fn basis_gradients_match_central_differences() {
        check_gradient::<LINEAR_TERMS, LinearBasis>();
        check_gradient::<QUADRATIC_TERMS, QuadraticBasis>();
    }

    #[test]
    fn the_terms_count_the_basis_entries() {
        assert_eq!(Reproduction::Linear.terms(), LINEAR_TERMS);
        assert_eq!(Reproduction::Quadratic.terms(), QUADRATIC_TERMS);
        assert!(Reproduction::default().is_linear());
    }
}
