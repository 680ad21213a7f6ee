//! The cubic spline kernel of SPlisHSPlasH (Monaghan's M4 spline written on its support radius),
//! the SPH baseline's W and ∇W.

use nalgebra::Vector3;

/// The cubic spline kernel with support radius h (m): with q = r/h and k = 8/(π h³),
///
/// ```text
/// W(r) = k (6q³ − 6q² + 1)   for q ≤ ½,
///        2k (1 − q)³         for ½ < q ≤ 1,
///        0                   otherwise,
/// ```
///
/// normalized, ∫ W dV = 1 (1/m³). SPlisHSPlasH takes h = 4 × the particle radius, i.e. twice
/// the particle spacing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CubicSplineKernel {
    support: f64,
    k: f64,
    l: f64,
}

impl CubicSplineKernel {
    /// The kernel with support radius `support` (m, positive).
    pub fn new(support: f64) -> Self {
        let h3 = support.powi(3);
        CubicSplineKernel {
            support,
            k: 8.0 / (std::f64::consts::PI * h3),
            l: 48.0 / (std::f64::consts::PI * h3),
        }
    }

    /// The support radius h (m).
    pub fn support(&self) -> f64 {
        self.support
    }

    /// W(r) (1/m³) at offset `r` (m).
    pub fn value(&self, r: &Vector3<f64>) -> f64 {
        let q = r.norm() / self.support;
        if q <= 0.5 {
            self.k * (6.0 * q * q * (q - 1.0) + 1.0)
        } else if q <= 1.0 {
            2.0 * self.k * (1.0 - q).powi(3)
        } else {
            0.0
        }
    }

    /// ∇W(r) (1/m⁴), the gradient with respect to `r` (m): W'(|r|) r/|r|, zero at r = 0.
    pub fn gradient(&self, r: &Vector3<f64>) -> Vector3<f64> {
        let distance = r.norm();
        let q = distance / self.support;
        if distance <= 1e-12 * self.support || q > 1.0 {
            return Vector3::zeros();
        }
        let direction = r / (distance * self.support);
        if q <= 0.5 {
            self.l * q * (3.0 * q - 2.0) * direction
        } else {
            let factor = 1.0 - q;
            -self.l * factor * factor * direction
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_kernel_integrates_to_one() {
        let h = 0.3;
        let kernel = CubicSplineKernel::new(h);
        let n = 60;
        let step = 2.0 * h / n as f64;
        let mut total = 0.0;
        for i in 0..n {
            for j in 0..n {
                for k in 0..n {
                    let r = Vector3::new(i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5) * step
                        - Vector3::repeat(h);
                    total += kernel.value(&r) * step.powi(3);
                }
            }
        }
        assert!((total - 1.0).abs() < 1e-3, "∫W = {total}");
    }

    #[test]
    fn the_gradient_matches_central_differences() {
        let kernel = CubicSplineKernel::new(0.2);
        let eps = 1e-7;
        for r in [
            Vector3::new(0.03, -0.02, 0.05),
            Vector3::new(0.1, 0.07, -0.04),
            Vector3::new(-0.15, 0.05, 0.02),
        ] {
            let g = kernel.gradient(&r);
            for d in 0..3 {
                let mut e = Vector3::zeros();
                e[d] = eps;
                let fd = (kernel.value(&(r + e)) - kernel.value(&(r - e))) / (2.0 * eps);
                assert!(
                    (g[d] - fd).abs() < 1e-6 * g.norm().max(1.0),
                    "{g} vs {fd} ({d})"
                );
            }
        }
    }
}
