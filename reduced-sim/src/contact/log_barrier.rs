//! IPC's log barrier (Li et al. 2020), shared by contact between objects
//! ([`crate::BodyContactModel::Barrier`]) and with the floor and colliders
//! ([`crate::FloorContact::Barrier`]).

/// `(b(d), b'(d), b''(d))` (m², m, 1) of `b(d) = −(d − d̂)² ln(d/d̂)` at a distance
/// `0 < d ≤ d̂` (m): positive, decreasing and convex below d̂, infinite as d → 0, and zero with
/// its first two derivatives at d = d̂, so extending it by zero beyond d̂ is C².
pub(crate) fn log_barrier(d: f64, d_hat: f64) -> (f64, f64, f64) {
    let (s, log) = (d - d_hat, (d / d_hat).ln());
    (
        -s * s * log,
        -2.0 * s * log - s * s / d,
        -2.0 * log - 4.0 * s / d + s * s / (d * d),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_barrier_derivatives_match_finite_differences_and_vanish_at_the_reach() {
        let d_hat = 0.02;
        for d in [1e-4, 1e-3, 0.005, 0.01, 0.019] {
            let (_, slope, curvature) = log_barrier(d, d_hat);
            let h = 1e-7 * d;
            let slope_fd = (log_barrier(d + h, d_hat).0 - log_barrier(d - h, d_hat).0) / (2.0 * h);
            let curvature_fd =
                (log_barrier(d + h, d_hat).1 - log_barrier(d - h, d_hat).1) / (2.0 * h);
            assert!((slope - slope_fd).abs() <= 1e-6 * slope.abs(), "b' at {d}");
            assert!(
                (curvature - curvature_fd).abs() <= 1e-6 * curvature.abs(),
                "b'' at {d}"
            );
            assert!(
                slope < 0.0 && curvature > 0.0,
                "decreasing and convex at {d}"
            );
        }
        assert_eq!(log_barrier(d_hat, d_hat), (0.0, 0.0, 0.0));
        assert!(log_barrier(1e-300, d_hat).0 > log_barrier(1e-4, d_hat).0);
    }
}
