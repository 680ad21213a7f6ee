//! Cauchy (true) stress, its principal values and the von Mises stress (the paper's stress
//! figure, Sec. 9.3).

use nalgebra::{Matrix3, SymmetricEigen, Vector3};

use crate::{HyperelasticMaterial, LameParameters};

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

/// The von Mises stress `σ_vm = sqrt(3/2 · s:s)` with `s = σ − tr(σ)/3 · I` the deviatoric part
/// (Pa): the uniaxial stress with the same distortion energy (σ_vm = |σ₁₁| under uniaxial
/// stress).
pub fn von_mises_stress(sigma: &Matrix3<f64>) -> f64 {
    let deviatoric = sigma - Matrix3::identity() * (sigma.trace() / 3.0);
    (1.5 * deviatoric.norm_squared()).sqrt()
}

/// The stress state at one point: Cauchy stress, principal stresses, von Mises stress (Pa).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StressSample {
    /// σ = J⁻¹ P Fᵀ ([`cauchy_stress`]).
    pub cauchy: Matrix3<f64>,
    /// σ₁ ≥ σ₂ ≥ σ₃ ([`principal_stresses`]).
    pub principal: Vector3<f64>,
    /// [`von_mises_stress`].
    pub von_mises: f64,
}

impl StressSample {
    /// The stress of `material` with Lamé parameters `lame` at deformation gradient `f`.
    ///
    /// # Errors
    /// [`CauchyStressError::NonPositiveDeterminant`] when `det F ≤ 0` (the Cauchy stress of an
    /// inverted point is not defined).
    pub fn new<M: HyperelasticMaterial>(
        material: &M,
        lame: &LameParameters,
        f: &Matrix3<f64>,
    ) -> Result<Self, CauchyStressError> {
        let cauchy = cauchy_stress(f, &material.first_piola_kirchhoff(lame, f))?;
        Ok(StressSample {
            cauchy,
            principal: principal_stresses(&cauchy),
            von_mises: von_mises_stress(&cauchy),
        })
    }
}
