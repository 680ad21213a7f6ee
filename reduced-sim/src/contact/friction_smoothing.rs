//! IPC's smoothed Coulomb friction of one contact (Li et al. 2020, Sec. 5): the mollifier
//!
//! ```text
//! f₀(y) = −y³/(3ε²) + y²/ε + ε/3  (y < ε),   y  (y ≥ ε),
//! ```
//!
//! and the gradient and positive semidefinite Hessian of `μλ f₀(‖u‖)` in the slip u, shared by
//! the friction against the floor and colliders ([`crate::terms`]) and between objects
//! ([`crate::contact::body_contact`]).

use nalgebra::{Matrix3, Vector3};

/// The gradient and Hessian of `limit · f₀(‖u‖)` with respect to the contact point (or, between
/// two objects, their relative position), u the tangential slip `T (x − x̄)` with normal
/// `normal`: `limit f₁(y)/y u` and the positive semidefinite Hessian of the module docs.
pub(crate) fn slip_derivatives(
    u: &Vector3<f64>,
    normal: &Vector3<f64>,
    limit: f64,
    epsilon: f64,
) -> (Vector3<f64>, Matrix3<f64>) {
    let y = u.norm();
    let (f1_over_y, curvature) = slope_and_curvature(y, epsilon);
    let g = u * (limit * f1_over_y);
    let tangent = Matrix3::identity() - normal * normal.transpose();
    let mut h = tangent * (limit * f1_over_y);
    if y > 0.0 {
        // [f₁'(y) − f₁(y)/y] û ûᵀ with û = u/y (u already tangential).
        h += u * u.transpose() * (limit * curvature / (y * y));
    }
    (g, h)
}

/// f₀(y) with threshold ε (m).
pub(crate) fn f0(y: f64, epsilon: f64) -> f64 {
    if y < epsilon {
        -y * y * y / (3.0 * epsilon * epsilon) + y * y / epsilon + epsilon / 3.0
    } else {
        y
    }
}

/// `(f₁(y)/y, f₁'(y) − f₁(y)/y)`, finite at y = 0 (where the second is 0).
pub(crate) fn slope_and_curvature(y: f64, epsilon: f64) -> (f64, f64) {
    if y < epsilon {
        (
            2.0 / epsilon - y / (epsilon * epsilon),
            -y / (epsilon * epsilon),
        )
    } else {
        (1.0 / y, -1.0 / y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_smoothing_is_continuous_with_its_slope_at_the_threshold_and_reaches_coulomb() {
        let epsilon = 1e-3;
        let below = f0(epsilon * (1.0 - 1e-12), epsilon);
        assert!((below - epsilon).abs() < 1e-12);
        let (slope, _) = slope_and_curvature(epsilon * (1.0 - 1e-12), epsilon);
        assert!(
            (slope * epsilon - 1.0).abs() < 1e-9,
            "f₁(ε) = {}",
            slope * epsilon
        );
        // f₀' = f₁ by central differences inside the smoothed range.
        let y = 0.4 * epsilon;
        let fd = (f0(y + 1e-9, epsilon) - f0(y - 1e-9, epsilon)) / 2e-9;
        assert!((fd - slope_and_curvature(y, epsilon).0 * y).abs() < 1e-6);
    }
}
