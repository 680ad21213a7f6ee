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
    /// Whether this is [`Reproduction::Linear`], the default (for `skip_serializing_if` in text
    /// settings).
    pub fn is_linear(&self) -> bool {
        *self == Reproduction::Linear
    }
}

/// Terms of the linear basis.
pub(crate) const LINEAR_TERMS: usize = 4;
/// Terms of the quadratic basis.
pub(crate) const QUADRATIC_TERMS: usize = 10;

/// A polynomial basis `P` of `N` terms, evaluated at a scaled offset `ξ = (X − p_k)/s`. Its
/// derivatives are not needed: in the shape functions' gradients only ∂P's constant part
/// enters, `e_{d+1}/s` for both bases ([`crate::shape_functions`]).
pub(crate) trait PolynomialBasis<const N: usize> {
    /// `P(ξ)` at `ξ = offset / s`.
    fn at(offset: &Vector3<f64>, s: f64) -> SVector<f64, N>;
}

/// `[1, ξ_x, ξ_y, ξ_z]`.
pub(crate) struct LinearBasis;

impl PolynomialBasis<LINEAR_TERMS> for LinearBasis {
    fn at(offset: &Vector3<f64>, s: f64) -> SVector<f64, LINEAR_TERMS> {
        let xi = offset / s;
        SVector::<f64, LINEAR_TERMS>::new(1.0, xi.x, xi.y, xi.z)
    }
}

/// `[1, ξ_x, ξ_y, ξ_z, ξ_x², ξ_y², ξ_z², ξ_x ξ_y, ξ_y ξ_z, ξ_z ξ_x]`.
pub(crate) struct QuadraticBasis;

impl PolynomialBasis<QUADRATIC_TERMS> for QuadraticBasis {
    fn at(offset: &Vector3<f64>, s: f64) -> SVector<f64, QUADRATIC_TERMS> {
        let xi = offset / s;
        let (x, y, z) = (xi.x, xi.y, xi.z);
        SVector::<f64, QUADRATIC_TERMS>::from_column_slice(&[
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
        ])
    }
}
