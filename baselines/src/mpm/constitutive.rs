//! The MPM baseline's stress: the Kirchhoff stress τ = P Fᵀ of the particle's deformation
//! gradient F, which the grid force −Σ_p V⁰_p τ_p ∇w_ip takes (design §3.10).

use hyperelastic::{
    HyperelasticMaterial, LameParameters, SignedSvd, StableNeoHookean, polar_rotation,
};
use nalgebra::Matrix3;
use serde::{Deserialize, Serialize};

/// Which elastic model the particles carry.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MpmMaterial {
    /// Fixed corotated (Stomakhin et al. 2012), warp-mpm's default ("jelly"):
    /// Ψ = μ‖F − R‖² + λ/2 (J − 1)², τ = 2μ(F − R)Fᵀ + λJ(J − 1)I, R the polar rotation of F.
    #[default]
    FixedCorotated,
    /// The project's stable Neo-Hookean (Eq. 16, [`StableNeoHookean`]): τ = P(F) Fᵀ.
    StableNeoHookean,
}

impl MpmMaterial {
    /// Kirchhoff stress τ = P Fᵀ (Pa) of deformation gradient `f` with Lamé parameters `lame`.
    /// Symmetric for both models (up to round-off, which is removed: τ ← (τ + τᵀ)/2, as
    /// warp-mpm does). Non-finite `f` gives non-finite τ (the simulator checks).
    #[allow(non_snake_case)]
    pub fn kirchhoff_stress(&self, lame: &LameParameters, f: &Matrix3<f64>) -> Matrix3<f64> {
        let tau = match self {
            MpmMaterial::FixedCorotated => {
                let R = polar_rotation(f);
                let J = f.determinant();
                2.0 * lame.mu() * (f - R) * f.transpose()
                    + Matrix3::identity() * (lame.lambda() * J * (J - 1.0))
            }
            MpmMaterial::StableNeoHookean => {
                StableNeoHookean.first_piola_kirchhoff(lame, f) * f.transpose()
            }
        };
        0.5 * (tau + tau.transpose())
    }

    /// "fixed corotated" or "stable Neo-Hookean".
    pub fn name(&self) -> &'static str {
        match self {
            MpmMaterial::FixedCorotated => "fixed corotated",
            MpmMaterial::StableNeoHookean => "stable Neo-Hookean",
        }
    }
}

/// Fixed-corotated energy density Ψ = μ‖F − R‖² + λ/2 (J − 1)² (J/m³), for checks of
/// [`MpmMaterial::kirchhoff_stress`] by differentiation.
#[allow(non_snake_case)]
pub fn fixed_corotated_energy_density(lame: &LameParameters, f: &Matrix3<f64>) -> f64 {
    let svd = SignedSvd::new(f);
    let R = svd.u * svd.v.transpose();
    let J = f.determinant();
    lame.mu() * (f - R).norm_squared() + 0.5 * lame.lambda() * (J - 1.0).powi(2)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Rotation3, Vector3};

    fn lame() -> LameParameters {
        LameParameters::from_young_poisson(5e6, 0.45).unwrap()
    }

    #[test]
    fn rigid_rotation_gives_zero_stress_for_both_models() {
        let r = Rotation3::from_axis_angle(&Vector3::y_axis(), 2.3)
            * Rotation3::from_axis_angle(&Vector3::x_axis(), -0.7);
        for material in [MpmMaterial::FixedCorotated, MpmMaterial::StableNeoHookean] {
            let tau = material.kirchhoff_stress(&lame(), r.matrix());
            assert!(
                tau.norm() < 1e-9 * lame().mu(),
                "{}: |τ| = {}",
                material.name(),
                tau.norm()
            );
        }
    }

    #[test]
    fn uniform_stretch_matches_the_fixed_corotated_closed_form() {
        // F = diag(s, 1, 1): R = I, J = s, so τ_xx = 2μ s(s − 1) + λ s(s − 1), τ_yy = τ_zz = λ s(s − 1).
        let l = lame();
        for s in [0.8, 1.05, 1.3] {
            let f = Matrix3::from_diagonal(&Vector3::new(s, 1.0, 1.0));
            let tau = MpmMaterial::FixedCorotated.kirchhoff_stress(&l, &f);
            let xx = 2.0 * l.mu() * s * (s - 1.0) + l.lambda() * s * (s - 1.0);
            let yy = l.lambda() * s * (s - 1.0);
            let expected = Matrix3::from_diagonal(&Vector3::new(xx, yy, yy));
            assert!(
                (tau - expected).norm() <= 1e-10 * expected.norm(),
                "s = {s}: {tau} vs {expected}"
            );
        }
    }

    #[test]
    fn fixed_corotated_stress_is_the_energy_derivative_times_f_transpose() {
        let l = lame();
        let f = Matrix3::new(1.1, 0.2, -0.05, 0.03, 0.92, 0.1, -0.08, 0.04, 1.04);
        let eps = 1e-6;
        let mut p = Matrix3::zeros();
        for i in 0..3 {
            for j in 0..3 {
                let mut plus = f;
                plus[(i, j)] += eps;
                let mut minus = f;
                minus[(i, j)] -= eps;
                p[(i, j)] = (fixed_corotated_energy_density(&l, &plus)
                    - fixed_corotated_energy_density(&l, &minus))
                    / (2.0 * eps);
            }
        }
        let tau = MpmMaterial::FixedCorotated.kirchhoff_stress(&l, &f);
        let fd = p * f.transpose();
        assert!(
            (tau - fd).norm() <= 1e-6 * fd.norm(),
            "τ = {tau}, FD P Fᵀ = {fd}"
        );
    }
}
