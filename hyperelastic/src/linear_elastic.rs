//! Linear (small-strain) elasticity, used by the Simplicits baseline's loss ramp (design §3.9).

use nalgebra::Matrix3;

use crate::determinant::{Matrix9, vectorize};
use crate::lame_parameters::LameParameters;
use crate::material::HyperelasticMaterial;

/// Linear elasticity in terms of F:
///
/// ```text
/// ε = ½ (F + Fᵀ) - I,   Ψ = μ ε:ε + ½ λ tr(ε)²,   P = 2μ ε + λ tr(ε) I,
/// ∂P/∂F = μ (I₉ + T) + λ vec(I) vec(I)ᵀ,   T the transpose permutation (T vec(A) = vec(Aᵀ)).
/// ```
///
/// Not rotation invariant (Ψ(RF) ≠ Ψ(F)); isotropic. The tangent is constant and PSD for valid
/// parameters (eigenvalues 2μ, 0 and 2μ + 3λ = 3K > 0), so the projection is the identity.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinearElastic;

fn strain(f: &Matrix3<f64>) -> Matrix3<f64> {
    (f + f.transpose()) * 0.5 - Matrix3::identity()
}

impl HyperelasticMaterial for LinearElastic {
    fn name(&self) -> &'static str {
        "linear elasticity"
    }

    fn energy_density(&self, params: &LameParameters, f: &Matrix3<f64>) -> f64 {
        let e = strain(f);
        params.mu() * e.norm_squared() + 0.5 * params.lambda() * e.trace().powi(2)
    }

    fn first_piola_kirchhoff(&self, params: &LameParameters, f: &Matrix3<f64>) -> Matrix3<f64> {
        let e = strain(f);
        e * (2.0 * params.mu()) + Matrix3::identity() * (params.lambda() * e.trace())
    }

    fn stress_derivative(&self, params: &LameParameters, _f: &Matrix3<f64>) -> Matrix9 {
        let mut transpose = Matrix9::zeros();
        for r in 0..3 {
            for c in 0..3 {
                transpose[(3 * c + r, 3 * r + c)] = 1.0;
            }
        }
        let i = vectorize(&Matrix3::identity());
        (Matrix9::identity() + transpose) * params.mu() + i * i.transpose() * params.lambda()
    }

    fn projected_stress_derivative(&self, params: &LameParameters, f: &Matrix3<f64>) -> Matrix9 {
        self.stress_derivative(params, f)
    }

    fn absolute_stress_derivative(&self, params: &LameParameters, f: &Matrix3<f64>) -> Matrix9 {
        self.stress_derivative(params, f)
    }
}
