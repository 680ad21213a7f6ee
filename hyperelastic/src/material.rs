//! The constitutive-model trait shared by every solver, with batch entry points.

use nalgebra::Matrix3;
use serde::{Deserialize, Serialize};

use crate::determinant::Matrix9;
use crate::lame_parameters::LameParameters;
use crate::psd_projection::{absolute_eigenvalues, project_to_psd};

/// Which tangent a batch call returns.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Tangent {
    /// The exact `∂P/∂F`.
    #[serde(alias = "Exact")]
    Exact,
    /// Its projection onto the positive semi-definite cone (negative eigenvalues clamped to 0),
    /// what Newton's method needs.
    #[serde(alias = "ProjectedPsd")]
    ProjectedPsd,
    /// Its absolute value `Σ |λ_i| q_i q_iᵀ` (negative eigenvalues mirrored, not clamped):
    /// positive semi-definite like the projection, but it keeps the curvature of a compressed or
    /// buckling point instead of dropping it. Chen et al., *Stabler Neo-Hookean Simulation:
    /// Absolute Eigenvalue Filtering for Projected Newton* (SIGGRAPH 2024).
    #[serde(alias = "AbsoluteEigenvalues")]
    AbsoluteEigenvalues,
}

/// The volumetric term of a material whose energy density splits as
/// `Ψ(F) = Ψ_rest(F) + ½ κ (J − γ)²`, J = det F: the term a projected dilatation replaces by
/// `½ κ (Π(J − γ))²`. Ψ_rest must be stable on its own (stress-free at F = I with a positive
/// semi-definite tangent there) and must not grow with κ: it is integrated pointwise while the
/// volumetric term is projected.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VolumetricPart {
    /// κ (Pa).
    pub modulus: f64,
    /// γ (dimensionless): the J at which the term vanishes.
    pub rest_ratio: f64,
}

/// A hyperelastic material: energy density Ψ(F) (J/m³ = Pa), first Piola-Kirchhoff stress
/// P = ∂Ψ/∂F (Pa) and the 9×9 tangent ∂P/∂F (Pa) over column-major `vec(F)`, with per-point
/// Lamé parameters (heterogeneous objects).
///
/// Implementations must be isotropic and frame-indifferent with Ψ(I) = 0, P(I) = 0, and plain
/// data (`Send + Sync`: objects are stepped on several threads).
pub trait HyperelasticMaterial: Send + Sync {
    /// A short name for reports ("stable Neo-Hookean").
    fn name(&self) -> &'static str;

    /// Energy density Ψ(F) (Pa).
    fn energy_density(&self, params: &LameParameters, f: &Matrix3<f64>) -> f64;

    /// The volumetric term `½ κ (J − γ)²` of Ψ at these parameters, if Ψ has one in that form
    /// (default `None`).
    fn volumetric_part(&self, params: &LameParameters) -> Option<VolumetricPart> {
        let _ = params;
        None
    }

    /// First Piola-Kirchhoff stress P(F) = ∂Ψ/∂F (Pa).
    fn first_piola_kirchhoff(&self, params: &LameParameters, f: &Matrix3<f64>) -> Matrix3<f64>;

    /// The exact tangent ∂vec(P)/∂vec(F) (9×9, symmetric, Pa).
    fn stress_derivative(&self, params: &LameParameters, f: &Matrix3<f64>) -> Matrix9;

    /// The tangent projected to be positive semi-definite. The default clamps the eigenvalues of
    /// a numeric 9×9 eigendecomposition; materials with an analytic eigensystem override it.
    fn projected_stress_derivative(&self, params: &LameParameters, f: &Matrix3<f64>) -> Matrix9 {
        project_to_psd(&self.stress_derivative(params, f))
    }

    /// The tangent with its eigenvalues replaced by their absolute values,
    /// `Σ |λ_i| q_i q_iᵀ` ([`Tangent::AbsoluteEigenvalues`]). The default mirrors the eigenvalues
    /// of a numeric 9×9 eigendecomposition; materials with an analytic eigensystem override it.
    fn absolute_stress_derivative(&self, params: &LameParameters, f: &Matrix3<f64>) -> Matrix9 {
        absolute_eigenvalues(&self.stress_derivative(params, f))
    }

    /// The tangent `tangent` asks for: [`HyperelasticMaterial::stress_derivative`],
    /// [`HyperelasticMaterial::projected_stress_derivative`] or
    /// [`HyperelasticMaterial::absolute_stress_derivative`] (9×9, Pa).
    fn tangent_stress_derivative(
        &self,
        params: &LameParameters,
        f: &Matrix3<f64>,
        tangent: Tangent,
    ) -> Matrix9 {
        match tangent {
            Tangent::Exact => self.stress_derivative(params, f),
            Tangent::ProjectedPsd => self.projected_stress_derivative(params, f),
            Tangent::AbsoluteEigenvalues => self.absolute_stress_derivative(params, f),
        }
    }

    /// Ψ at many points: `out[i] = Ψ(params[i], F[i])`.
    ///
    /// # Panics
    /// If the three slices differ in length.
    fn energy_densities(&self, params: &[LameParameters], f: &[Matrix3<f64>], out: &mut [f64]) {
        assert_batch_lengths(params.len(), f.len(), out.len());
        for ((o, p), f) in out.iter_mut().zip(params).zip(f) {
            *o = self.energy_density(p, f);
        }
    }

    /// P at many points: `out[i] = P(params[i], F[i])`.
    ///
    /// # Panics
    /// If the three slices differ in length.
    fn first_piola_kirchhoff_stresses(
        &self,
        params: &[LameParameters],
        f: &[Matrix3<f64>],
        out: &mut [Matrix3<f64>],
    ) {
        assert_batch_lengths(params.len(), f.len(), out.len());
        for ((o, p), f) in out.iter_mut().zip(params).zip(f) {
            *o = self.first_piola_kirchhoff(p, f);
        }
    }

    /// ∂P/∂F (exact, PSD-projected or with absolute eigenvalues) at many points.
    ///
    /// # Panics
    /// If the three slices differ in length.
    fn stress_derivatives(
        &self,
        params: &[LameParameters],
        f: &[Matrix3<f64>],
        tangent: Tangent,
        out: &mut [Matrix9],
    ) {
        assert_batch_lengths(params.len(), f.len(), out.len());
        for ((o, p), f) in out.iter_mut().zip(params).zip(f) {
            *o = self.tangent_stress_derivative(p, f, tangent);
        }
    }
}

fn assert_batch_lengths(params: usize, f: usize, out: usize) {
    assert!(
        params == f && f == out,
        "batch lengths differ: {params} parameter sets, {f} deformation gradients, {out} outputs"
    );
}
