//! The stable Neo-Hookean material (paper Eq. 16, supplementary Eqs. 26-27; Smith et al. 2018).

use nalgebra::{Matrix3, SymmetricEigen};

use crate::determinant::{Matrix9, cofactor, determinant_hessian, vectorize};
use crate::lame_parameters::LameParameters;
use crate::material::HyperelasticMaterial;
use crate::signed_svd::SignedSvd;

/// Stable Neo-Hookean:
///
/// ```text
/// Ψ(F) = ½ [ λ̄ (J - γ)² + μ tr(FᵀF) - E₀ ],   J = det F,  λ̄ = λ + μ,  γ = 1 + μ/λ̄,
/// E₀ = 3μ + μ²/λ̄  (so Ψ(I) = 0),
/// P(F) = μ F + λ̄ (J - γ) cof F,
/// ∂P/∂F = μ I₉ + λ̄ vec(cof F) vec(cof F)ᵀ + λ̄ (J - γ) ∂²J/∂F².
/// ```
///
/// Written with the cofactor (no F⁻¹), so every quantity is finite for inverted (J ≤ 0) and
/// degenerate F. At F = I the tangent equals linear elasticity's `μ(I + T) + λ vec(I)vec(I)ᵀ`
/// with the same (λ, μ), the fact behind Prop. 1 (design §3.4, 3.6).
///
/// The PSD projection uses the analytic eigensystem of Smith et al. 2019: with the signed SVD
/// `F = U diag(σ) Vᵀ`, six eigenpairs are closed-form — for each pair (i, j) with third index k,
/// the *twist* `U (e_ie_jᵀ - e_je_iᵀ)/√2 Vᵀ` with eigenvalue `μ + λ̄(J-γ)σ_k` and the *flip*
/// `U (e_ie_jᵀ + e_je_iᵀ)/√2 Vᵀ` with eigenvalue `μ - λ̄(J-γ)σ_k` — and three *scaling* modes
/// `U diag(a) Vᵀ` come from the 3×3 Hessian of Ψ in σ:
/// `A_ii = μ + λ̄ (σ_jσ_k)²`, `A_ij = λ̄ (σ_iσ_jσ_k² + (J-γ)σ_k)`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StableNeoHookean;

#[allow(non_snake_case)]
struct Constants {
    mu: f64,
    lambda_bar: f64,
    gamma: f64,
    E0: f64,
}

fn constants(params: &LameParameters) -> Constants {
    let (lambda, mu) = (params.lambda(), params.mu());
    let lambda_bar = lambda + mu;
    Constants {
        mu,
        lambda_bar,
        gamma: 1.0 + mu / lambda_bar,
        E0: 3.0 * mu + mu * mu / lambda_bar,
    }
}

impl StableNeoHookean {
    /// The nine eigenpairs `(λ_i, vec(Q_i))` of the exact tangent at F (unit-norm `Q_i`), by the
    /// analytic construction in the type docs. `Σ λ_i vec(Q_i) vec(Q_i)ᵀ` equals
    /// [`HyperelasticMaterial::stress_derivative`] up to round-off.
    #[allow(non_snake_case)]
    pub fn eigensystem(
        &self,
        params: &LameParameters,
        f: &Matrix3<f64>,
    ) -> [(f64, nalgebra::SVector<f64, 9>); 9] {
        let c = constants(params);
        let SignedSvd { u, sigma: s, v } = SignedSvd::new(f);
        let J = s.product();
        let r = c.lambda_bar * (J - c.gamma);
        let mut pairs = [(0.0, nalgebra::SVector::<f64, 9>::zeros()); 9];
        let lift = |m: Matrix3<f64>| vectorize(&(u * m * v.transpose()));
        let inv_sqrt2 = std::f64::consts::FRAC_1_SQRT_2;
        for (n, (i, j, k)) in [(0, 1, 2), (1, 2, 0), (0, 2, 1)].into_iter().enumerate() {
            let mut twist = Matrix3::zeros();
            twist[(i, j)] = inv_sqrt2;
            twist[(j, i)] = -inv_sqrt2;
            let mut flip = Matrix3::zeros();
            flip[(i, j)] = inv_sqrt2;
            flip[(j, i)] = inv_sqrt2;
            pairs[2 * n] = (c.mu + r * s[k], lift(twist));
            pairs[2 * n + 1] = (c.mu - r * s[k], lift(flip));
        }
        let A = Matrix3::from_fn(|i, j| {
            if i == j {
                let others = product_of_others(&s, i);
                c.mu + c.lambda_bar * others * others
            } else {
                let k = 3 - i - j;
                c.lambda_bar * (s[i] * s[j] * s[k] * s[k]) + r * s[k]
            }
        });
        let scaling = SymmetricEigen::new(A);
        for m in 0..3 {
            let a = scaling.eigenvectors.column(m);
            pairs[6 + m] = (
                scaling.eigenvalues[m],
                lift(Matrix3::from_diagonal(&a.into_owned())),
            );
        }
        pairs
    }
}

/// `Π_{k≠i} σ_k` (J with σ_i left out).
fn product_of_others(s: &nalgebra::Vector3<f64>, i: usize) -> f64 {
    (0..3).filter(|&k| k != i).map(|k| s[k]).product()
}

impl HyperelasticMaterial for StableNeoHookean {
    /// `½ λ (J − 1)²`: the rest, `Ψ − ½ λ (J − 1)² = ½ μ [(J − 1)² − 2(J − 1) + tr FᵀF − 3]`,
    /// does not depend on λ, is stress-free at F = I and has the rest tangent `μ(I + T)` of
    /// linear elasticity's shear part (positive semi-definite). (λ̄ (J − γ)² would not do: its
    /// rest stress −μ cof F balances the μ term, and the rest alone would be unstable.)
    fn volumetric_part(&self, params: &LameParameters) -> Option<crate::VolumetricPart> {
        Some(crate::VolumetricPart {
            modulus: params.lambda(),
            rest_ratio: 1.0,
        })
    }

    fn name(&self) -> &'static str {
        "stable Neo-Hookean"
    }

    #[allow(non_snake_case)]
    fn energy_density(&self, params: &LameParameters, f: &Matrix3<f64>) -> f64 {
        let c = constants(params);
        let J = f.determinant();
        0.5 * (c.lambda_bar * (J - c.gamma).powi(2) + c.mu * f.norm_squared() - c.E0)
    }

    #[allow(non_snake_case)]
    fn first_piola_kirchhoff(&self, params: &LameParameters, f: &Matrix3<f64>) -> Matrix3<f64> {
        let c = constants(params);
        let J = f.determinant();
        f * c.mu + cofactor(f) * (c.lambda_bar * (J - c.gamma))
    }

    #[allow(non_snake_case)]
    fn stress_derivative(&self, params: &LameParameters, f: &Matrix3<f64>) -> Matrix9 {
        let c = constants(params);
        let J = f.determinant();
        let g = vectorize(&cofactor(f));
        Matrix9::identity() * c.mu
            + g * g.transpose() * c.lambda_bar
            + determinant_hessian(f) * (c.lambda_bar * (J - c.gamma))
    }

    fn projected_stress_derivative(&self, params: &LameParameters, f: &Matrix3<f64>) -> Matrix9 {
        let pairs = self.eigensystem(params, f);
        if pairs.iter().all(|(l, _)| *l >= 0.0) {
            return self.stress_derivative(params, f);
        }
        pairs
            .iter()
            .filter(|(l, _)| *l > 0.0)
            .map(|(l, q)| q * q.transpose() * *l)
            .sum()
    }

    fn absolute_stress_derivative(&self, params: &LameParameters, f: &Matrix3<f64>) -> Matrix9 {
        let pairs = self.eigensystem(params, f);
        if pairs.iter().all(|(l, _)| *l >= 0.0) {
            return self.stress_derivative(params, f);
        }
        pairs.iter().map(|(l, q)| q * q.transpose() * l.abs()).sum()
    }
}
