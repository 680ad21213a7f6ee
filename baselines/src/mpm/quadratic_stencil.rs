//! The quadratic B-spline stencil of one point on a regular grid: the 3 × 3 × 3 nodes it
//! touches, their weights and weight gradients (Jiang et al. 2016, "The Material Point Method
//! for Simulating Continuum Materials", Sec. 9.3; warp-mpm's `p2g_apic_with_stress`).
//!
//! Per axis, with g = (x − o)/Δx the position in cell units and b = ⌊g − ½⌋ the first node,
//! f = g − b ∈ [½, 3/2):
//!
//! N₀ = ½(3/2 − f)², N₁ = ¾ − (f − 1)², N₂ = ½(f − ½)²,
//! N₀' = (f − 3/2)/Δx, N₁' = −2(f − 1)/Δx, N₂' = (f − ½)/Δx.
//!
//! The node weight is w = N_i(x) N_j(y) N_k(z) and ∇w is its gradient (1/m). The stencil
//! reproduces constants and linear fields exactly: Σw = 1, Σ w (xᵢ − x) = 0, Σ∇w = 0,
//! Σ (xᵢ − x) ⊗ ∇w = I, and Σ w (xᵢ − x)(xᵢ − x)ᵀ = Δx²/4 · I (the APIC inertia D).

use nalgebra::{Matrix3, Vector3};

/// The 27 nodes, weights and weight gradients of one point.
#[derive(Clone, Copy, Debug)]
pub struct QuadraticStencil {
    /// Integer index of the first node per axis (node n sits at `o + n Δx`).
    pub base: [i64; 3],
    /// Position of the point relative to the first node, in cells (each in [½, 3/2)).
    pub fraction: Vector3<f64>,
    /// `weights[axis][i]`: the 1D weight of node `base + i` along `axis`.
    pub weights: [[f64; 3]; 3],
    /// `derivatives[axis][i]`: its derivative (1/m).
    pub derivatives: [[f64; 3]; 3],
}

impl QuadraticStencil {
    /// The stencil of `x` (m) on the grid with node 0 at `origin` (m) and spacing
    /// `1 / inverse_spacing` (m).
    pub fn new(x: &Vector3<f64>, origin: &Vector3<f64>, inverse_spacing: f64) -> Self {
        let mut base = [0i64; 3];
        let mut fraction = Vector3::zeros();
        let mut weights = [[0.0; 3]; 3];
        let mut derivatives = [[0.0; 3]; 3];
        for a in 0..3 {
            let g = (x[a] - origin[a]) * inverse_spacing;
            let b = (g - 0.5).floor();
            let f = g - b;
            base[a] = b as i64;
            fraction[a] = f;
            weights[a] = [
                0.5 * (1.5 - f).powi(2),
                0.75 - (f - 1.0).powi(2),
                0.5 * (f - 0.5).powi(2),
            ];
            derivatives[a] = [
                (f - 1.5) * inverse_spacing,
                -2.0 * (f - 1.0) * inverse_spacing,
                (f - 0.5) * inverse_spacing,
            ];
        }
        QuadraticStencil {
            base,
            fraction,
            weights,
            derivatives,
        }
    }

    /// Weight of node `base + (i, j, k)`.
    pub fn weight(&self, i: usize, j: usize, k: usize) -> f64 {
        self.weights[0][i] * self.weights[1][j] * self.weights[2][k]
    }

    /// Gradient of that weight with respect to the point's position (1/m).
    pub fn weight_gradient(&self, i: usize, j: usize, k: usize) -> Vector3<f64> {
        let w = &self.weights;
        let d = &self.derivatives;
        Vector3::new(
            d[0][i] * w[1][j] * w[2][k],
            w[0][i] * d[1][j] * w[2][k],
            w[0][i] * w[1][j] * d[2][k],
        )
    }

    /// `(xᵢ − x) / Δx` for node `base + (i, j, k)`: the node's offset from the point in cells.
    pub fn node_offset(&self, i: usize, j: usize, k: usize) -> Vector3<f64> {
        Vector3::new(i as f64, j as f64, k as f64) - self.fraction
    }
}

/// `Σ w (xᵢ − x)(xᵢ − x)ᵀ = Δx²/4 · I`, the APIC inertia tensor of the quadratic stencil (m²);
/// its inverse scales the affine velocity `C = D⁻¹ Σ w vᵢ (xᵢ − x)ᵀ`.
pub fn apic_inertia(spacing: f64) -> Matrix3<f64> {
    Matrix3::identity() * (0.25 * spacing * spacing)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn sums(
        x: Vector3<f64>,
        spacing: f64,
    ) -> (f64, Vector3<f64>, Vector3<f64>, Matrix3<f64>, Matrix3<f64>) {
        let origin = Vector3::new(-3.0, -2.0, -1.0);
        let s = QuadraticStencil::new(&x, &origin, 1.0 / spacing);
        let mut w_sum = 0.0;
        let mut moment = Vector3::zeros();
        let mut grad_sum = Vector3::zeros();
        let mut linear = Matrix3::zeros();
        let mut inertia = Matrix3::zeros();
        for i in 0..3 {
            for j in 0..3 {
                for k in 0..3 {
                    let w = s.weight(i, j, k);
                    let node = origin
                        + Vector3::new(
                            (s.base[0] + i as i64) as f64,
                            (s.base[1] + j as i64) as f64,
                            (s.base[2] + k as i64) as f64,
                        ) * spacing;
                    let d = node - x;
                    // The offset the stencil reports is the same vector in cells.
                    assert!((s.node_offset(i, j, k) * spacing - d).norm() < 1e-12);
                    w_sum += w;
                    moment += w * d;
                    grad_sum += s.weight_gradient(i, j, k);
                    linear += d * s.weight_gradient(i, j, k).transpose();
                    inertia += w * d * d.transpose();
                }
            }
        }
        (w_sum, moment, grad_sum, linear, inertia)
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 200, rng_seed: proptest::test_runner::RngSeed::Fixed(11), ..ProptestConfig::default() })]

        #[test]
        fn stencil_reproduces_constants_and_linear_fields(
            x in -2.0..2.0f64, y in -1.5..1.5f64, z in -0.5..0.5f64, spacing in 0.01..0.5f64,
        ) {
            let (w, moment, grad, linear, inertia) = sums(Vector3::new(x, y, z), spacing);
            prop_assert!((w - 1.0).abs() < 1e-12);
            prop_assert!(moment.norm() < 1e-12 * spacing);
            prop_assert!(grad.norm() < 1e-10 / spacing);
            prop_assert!((linear - Matrix3::identity()).norm() < 1e-10);
            prop_assert!((inertia - apic_inertia(spacing)).norm() < 1e-12 * spacing * spacing);
        }
    }

    #[test]
    fn weight_gradient_matches_finite_differences() {
        let origin = Vector3::zeros();
        let x = Vector3::new(0.731, 0.402, 0.268);
        let spacing = 0.1;
        let s = QuadraticStencil::new(&x, &origin, 1.0 / spacing);
        let eps = 1e-7;
        for a in 0..3 {
            let mut e = Vector3::zeros();
            e[a] = eps;
            let plus = QuadraticStencil::new(&(x + e), &origin, 1.0 / spacing);
            let minus = QuadraticStencil::new(&(x - e), &origin, 1.0 / spacing);
            assert_eq!(plus.base, s.base, "the probe must stay in the same stencil");
            assert_eq!(
                minus.base, s.base,
                "the probe must stay in the same stencil"
            );
            for i in 0..3 {
                for j in 0..3 {
                    for k in 0..3 {
                        let fd = (plus.weight(i, j, k) - minus.weight(i, j, k)) / (2.0 * eps);
                        let g = s.weight_gradient(i, j, k)[a];
                        assert!(
                            (fd - g).abs() < 1e-6,
                            "axis {a} node {i}{j}{k}: {fd} vs {g}"
                        );
                    }
                }
            }
        }
    }
}
