//! Checks any [`HyperelasticMaterial`] (a user's own included) against ground truth before it
//! is simulated: P against central differences of Ψ, ∂P/∂F against central differences of P,
//! a stress-free rest state, frame indifference and isotropy, and a PSD projected tangent.
//! Behind the `checks` feature (`hyperelastic = { features = ["checks"] }`).

use nalgebra::{DMatrix, Matrix3, Rotation3, SymmetricEigen, Vector3};
use thiserror::Error;

use crate::lame_parameters::LameParameters;
use crate::material::HyperelasticMaterial;

/// Options of [`check_material`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MaterialCheckParams {
    /// Random deformation gradients F = I + amplitude · U[−1, 1]³ˣ³ to probe (default 64).
    pub samples: usize,
    /// Their amplitude (default 1.0; above about 0.6 some F are inverted, J < 0).
    pub amplitude: f64,
    /// Central-difference step on the entries of F (default 1e-6).
    pub step: f64,
    /// Largest accepted relative error of every check (default 1e-6).
    pub tolerance: f64,
    /// Seed of the samples (default 0).
    pub seed: u64,
    /// Require Ψ(RF) = Ψ(F) (default true; false for linear elasticity, which is not frame
    /// indifferent).
    pub frame_indifference: bool,
}

impl Default for MaterialCheckParams {
    fn default() -> Self {
        MaterialCheckParams {
            samples: 64,
            amplitude: 1.0,
            step: 1e-6,
            tolerance: 1e-6,
            seed: 0,
            frame_indifference: true,
        }
    }
}

/// The largest relative error of each check over the samples.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MaterialCheckReport {
    /// `|P − FD(Ψ)| / max(|P|, μ)`.
    pub stress_error: f64,
    /// `|∂P/∂F − FD(P)| / max(|∂P/∂F|, μ)` (Frobenius).
    pub tangent_error: f64,
    /// `(|Ψ(I)| + |P(I)|) / μ`.
    pub rest_error: f64,
    /// Isotropy: `|Ψ(RFRᵀ) − Ψ(F)| / (|Ψ(F)| + μ)`, R random rotations.
    pub isotropy_error: f64,
    /// Frame indifference: `|Ψ(RF) − Ψ(F)| / (|Ψ(F)| + μ)` (checked when asked).
    pub frame_indifference_error: f64,
    /// The most negative eigenvalue of the projected tangent over its norm (≥ −tolerance).
    pub projected_min_eigenvalue: f64,
    /// Deformation gradients probed.
    pub samples: usize,
}

/// A check failed: the material is not what the simulator assumes.
#[derive(Debug, Error, PartialEq)]
pub enum MaterialCheckError {
    /// One of the checks exceeded the tolerance; `report` holds every measured error.
    #[error("{material}: {check} error {error:.3e} exceeds {tolerance:.1e} (at F = {f})")]
    Failed {
        /// The material's name.
        material: &'static str,
        /// "P vs FD of Ψ", "∂P/∂F vs FD of P", "rest state", "isotropy", "frame indifference"
        /// or "PSD projection".
        check: &'static str,
        /// The error measured.
        error: f64,
        /// The tolerance.
        tolerance: f64,
        /// The deformation gradient where it was largest.
        f: Box<Matrix3<f64>>,
        /// All measured errors.
        report: Box<MaterialCheckReport>,
    },
}

/// Runs every check of the module on `material` with `params`' Lamé parameters.
///
/// # Errors
/// [`MaterialCheckError::Failed`] naming the first check over the tolerance and where.
pub fn check_material<M: HyperelasticMaterial + ?Sized>(
    material: &M,
    params: &LameParameters,
    check: &MaterialCheckParams,
) -> Result<MaterialCheckReport, MaterialCheckError> {
    let mu = params.mu();
    let mut rng = SplitMix64(check.seed);
    let mut report = MaterialCheckReport {
        samples: check.samples,
        ..Default::default()
    };
    let mut worst = [[0.0; 9]; 6];
    let identity = Matrix3::identity();
    report.rest_error = (material.energy_density(params, &identity).abs()
        + material.first_piola_kirchhoff(params, &identity).norm())
        / mu;
    worst[2] = identity.as_slice().try_into().unwrap_or([0.0; 9]);
    for _ in 0..check.samples {
        let f = identity + Matrix3::from_fn(|_, _| check.amplitude * rng.symmetric());
        let at = f.as_slice().try_into().unwrap_or([0.0; 9]);
        let h = check.step;
        let perturbed = |k: usize, s: f64| {
            let mut g = f;
            g[k] += s * h;
            g
        };
        let fd_p = Matrix3::from_fn(|i, j| {
            let k = i + 3 * j;
            (material.energy_density(params, &perturbed(k, 1.0))
                - material.energy_density(params, &perturbed(k, -1.0)))
                / (2.0 * h)
        });
        let p = material.first_piola_kirchhoff(params, &f);
        let error = (p - fd_p).norm() / p.norm().max(mu);
        if error > report.stress_error {
            (report.stress_error, worst[0]) = (error, at);
        }
        let tangent = material.stress_derivative(params, &f);
        let fd_tangent = DMatrix::from_fn(9, 9, |row, k| {
            (material.first_piola_kirchhoff(params, &perturbed(k, 1.0))[row]
                - material.first_piola_kirchhoff(params, &perturbed(k, -1.0))[row])
                / (2.0 * h)
        });
        let exact = DMatrix::from_column_slice(9, 9, tangent.as_slice());
        let error = (&exact - fd_tangent).norm() / exact.norm().max(mu);
        if error > report.tangent_error {
            (report.tangent_error, worst[1]) = (error, at);
        }
        let r = Rotation3::from_scaled_axis(
            Vector3::new(rng.symmetric(), rng.symmetric(), rng.symmetric()) * 3.0,
        )
        .into_inner();
        let psi = material.energy_density(params, &f);
        let error = (material.energy_density(params, &(r * f * r.transpose())) - psi).abs()
            / (psi.abs() + mu);
        if error > report.isotropy_error {
            (report.isotropy_error, worst[3]) = (error, at);
        }
        let error = (material.energy_density(params, &(r * f)) - psi).abs() / (psi.abs() + mu);
        if error > report.frame_indifference_error {
            (report.frame_indifference_error, worst[4]) = (error, at);
        }
        let projected = material.projected_stress_derivative(params, &f);
        let scale = projected.norm().max(mu);
        let lowest = SymmetricEigen::new(projected).eigenvalues.min() / scale;
        if lowest < report.projected_min_eigenvalue {
            (report.projected_min_eigenvalue, worst[5]) = (lowest, at);
        }
    }
    let checks = [
        ("P vs FD of Ψ", report.stress_error),
        ("∂P/∂F vs FD of P", report.tangent_error),
        ("rest state", report.rest_error),
        ("isotropy", report.isotropy_error),
        (
            "frame indifference",
            if check.frame_indifference {
                report.frame_indifference_error
            } else {
                0.0
            },
        ),
        ("PSD projection", -report.projected_min_eigenvalue),
    ];
    for (k, (name, error)) in checks.into_iter().enumerate() {
        if !(error <= check.tolerance) {
            return Err(MaterialCheckError::Failed {
                material: material.name(),
                check: name,
                error,
                tolerance: check.tolerance,
                f: Box::new(Matrix3::from_column_slice(&worst[k])),
                report: Box::new(report),
            });
        }
    }
    Ok(report)
}

/// A small deterministic generator (SplitMix64), so the checks need no RNG crate.
struct SplitMix64(u64);

impl SplitMix64 {
    /// Uniform in [−1, 1).
    fn symmetric(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        2.0 * ((z >> 11) as f64 / (1u64 << 53) as f64) - 1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{LinearElastic, Matrix9, StableNeoHookean};

    fn beam() -> LameParameters {
        LameParameters::from_young_poisson(5e6, 0.45).unwrap()
    }

    #[test]
    fn the_shipped_materials_pass_every_check() {
        for (material, frame_indifference) in [
            (&StableNeoHookean as &dyn HyperelasticMaterial, true),
            (&LinearElastic as &dyn HyperelasticMaterial, false),
        ] {
            let params = MaterialCheckParams {
                frame_indifference,
                ..Default::default()
            };
            let report = check_material(material, &beam(), &params).unwrap();
            assert!(report.stress_error < 1e-6 && report.tangent_error < 1e-6);
            assert_eq!(report.samples, 64);
        }
    }

    /// Neo-Hookean with a tangent off by 1% in one entry: the tangent check must catch it.
    struct WrongTangent;

    impl HyperelasticMaterial for WrongTangent {
        fn name(&self) -> &'static str {
            "wrong tangent"
        }
        fn energy_density(&self, p: &LameParameters, f: &Matrix3<f64>) -> f64 {
            StableNeoHookean.energy_density(p, f)
        }
        fn first_piola_kirchhoff(&self, p: &LameParameters, f: &Matrix3<f64>) -> Matrix3<f64> {
            StableNeoHookean.first_piola_kirchhoff(p, f)
        }
        fn stress_derivative(&self, p: &LameParameters, f: &Matrix3<f64>) -> Matrix9 {
            let mut t = StableNeoHookean.stress_derivative(p, f);
            t[(0, 0)] *= 1.01;
            t
        }
    }

    #[test]
    fn linear_elasticity_is_caught_not_frame_indifferent_when_that_is_required() {
        let err =
            check_material(&LinearElastic, &beam(), &MaterialCheckParams::default()).unwrap_err();
        let MaterialCheckError::Failed { check, .. } = &err;
        assert_eq!(*check, "frame indifference", "{err}");
    }

    #[test]
    fn a_tangent_one_percent_off_in_one_entry_is_caught_and_named() {
        let err =
            check_material(&WrongTangent, &beam(), &MaterialCheckParams::default()).unwrap_err();
        let MaterialCheckError::Failed { check, report, .. } = &err;
        assert_eq!(*check, "∂P/∂F vs FD of P", "{err}");
        assert!(report.stress_error < 1e-6, "{err}");
        assert!(err.to_string().contains("wrong tangent"));
    }
}
