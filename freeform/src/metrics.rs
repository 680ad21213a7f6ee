//! Error metrics against the FEM reference (design §4.3), at the FEM mesh's vertices over frames
//! t = 1..T, normalized by the largest side L of the rest bounding box:
//!
//! - normalized MSE = (1/(T·N)) Σ_t Σ_i |x_it − x*_it|² / L²
//! - normalized max error = max_t max_i |x_it − x*_it| / L
//! - basis fitting residual = (1/(T·N)) Σ_t Σ_i |x_i(z*_t) − x*_it| / L, with z*_t the
//!   least-squares fit of frame t through the method's deformation map (Sec. 9.1).

use faer::linalg::solvers::Solve;
use faer::{Mat, Side};
use nalgebra::Vector3;
use reduced_sim::DeformationMap;
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Trajectories cannot be compared.
#[derive(Debug, Error, PartialEq)]
pub enum MetricsError {
    /// Different frame or point counts, or nothing to compare.
    #[error("trajectories do not match: {0}")]
    Shape(String),
    /// L is not positive and finite.
    #[error("normalization length {0} is not positive and finite")]
    Length(f64),
    /// A value is NaN or infinite.
    #[error("frame {frame} point {point} is not finite")]
    NonFinite {
        /// Frame index (0 = first compared frame).
        frame: usize,
        /// Point index.
        point: usize,
    },
    /// The deformation map's `B Bᵀ` is singular (too few or degenerate points).
    #[error("the least-squares fit through the deformation map is singular")]
    SingularFit,
}

/// Normalized MSE and max error of one trajectory against the reference.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrajectoryErrors {
    /// (1/(T·N)) Σ |x − x*|² / L².
    pub normalized_mse: f64,
    /// max |x − x*| / L.
    pub normalized_max: f64,
}

fn check_shapes(
    ours: &[Vec<Vector3<f64>>],
    reference: &[Vec<Vector3<f64>>],
    length: f64,
) -> Result<(), MetricsError> {
    if !(length > 0.0 && length.is_finite()) {
        return Err(MetricsError::Length(length));
    }
    if ours.is_empty() || ours.len() != reference.len() {
        return Err(MetricsError::Shape(format!(
            "{} frames against {} reference frames",
            ours.len(),
            reference.len()
        )));
    }
    for (t, (a, b)) in ours.iter().zip(reference).enumerate() {
        if a.is_empty() || a.len() != b.len() {
            return Err(MetricsError::Shape(format!(
                "frame {t}: {} points against {} reference points",
                a.len(),
                b.len()
            )));
        }
        for (point, (p, q)) in a.iter().zip(b).enumerate() {
            if !(p.iter().chain(q.iter()).all(|c| c.is_finite())) {
                return Err(MetricsError::NonFinite { frame: t, point });
            }
        }
    }
    Ok(())
}

/// Normalized MSE and max error of `ours` against `reference` (`frames[t][i]`, frames 1..T:
/// leave the shared rest frame out), with normalization length `length` (m).
///
/// # Errors
/// [`MetricsError`] for mismatched shapes, a bad length or non-finite values.
pub fn trajectory_errors(
    ours: &[Vec<Vector3<f64>>],
    reference: &[Vec<Vector3<f64>>],
    length: f64,
) -> Result<TrajectoryErrors, MetricsError> {
    check_shapes(ours, reference, length)?;
    let mut sum = 0.0;
    let mut count = 0usize;
    let mut max: f64 = 0.0;
    for (a, b) in ours.iter().zip(reference) {
        for (p, q) in a.iter().zip(b) {
            let d2 = (p - q).norm_squared();
            sum += d2;
            max = max.max(d2);
            count += 1;
        }
    }
    Ok(TrajectoryErrors {
        normalized_mse: sum / count as f64 / (length * length),
        normalized_max: max.sqrt() / length,
    })
}

/// Normalized MSE of each frame of `ours` against `reference` (same layout and checks as
/// [`trajectory_errors`]): `(1/N) Σ_i |x_it − x*_it|² / L²` for every t. With the same point
/// count in every frame their mean is the trajectory's normalized MSE.
///
/// # Errors
/// [`MetricsError`] for mismatched shapes, a bad length or non-finite values.
pub fn per_frame_mse(
    ours: &[Vec<Vector3<f64>>],
    reference: &[Vec<Vector3<f64>>],
    length: f64,
) -> Result<Vec<f64>, MetricsError> {
    check_shapes(ours, reference, length)?;
    Ok(ours
        .iter()
        .zip(reference)
        .map(|(a, b)| {
            let sum: f64 = a.iter().zip(b).map(|(p, q)| (p - q).norm_squared()).sum();
            sum / a.len() as f64 / (length * length)
        })
        .collect())
}

/// The basis fitting residual: per frame the least-squares `z*` with `x_i(z*) = B_iᵀ z*` closest
/// to the reference positions, then the mean distance over frames and points divided by
/// `length`. `map` must be built at the reference's rest points (`N` points, `B` is
/// `4(m+1) × N`). If `B Bᵀ` is singular (a weight vanishes on every point) the normal
/// equations get a ridge of `1e-10 · diag(B Bᵀ) + 1e-14 · max diag(B Bᵀ)`.
///
/// # Errors
/// [`MetricsError`] for mismatched shapes, a bad length, non-finite values, or a fit that is
/// singular even with the ridge.
pub fn basis_fitting_residual(
    map: &DeformationMap,
    reference: &[Vec<Vector3<f64>>],
    length: f64,
) -> Result<f64, MetricsError> {
    let rest = vec![map.rest_positions().to_vec(); reference.len()];
    check_shapes(&rest, reference, length)?;
    let b = map.position_matrix();
    let n = map.len();
    let normal = b * b.transpose();
    // A weight that vanishes on every point (a mode living on a thin part the reference mesh
    // lacks) leaves B Bᵀ singular; a ridge of 1e-10 · diag + 1e-14 · max diag then holds that
    // coefficient at zero and changes the others by a relative 1e-10.
    let llt = match normal.llt(Side::Lower) {
        Ok(llt) => llt,
        Err(_) => {
            let floor = 1e-14
                * (0..normal.nrows())
                    .map(|i| normal[(i, i)])
                    .fold(0.0, f64::max);
            let regularized = Mat::<f64>::from_fn(normal.nrows(), normal.ncols(), |i, j| {
                normal[(i, j)] * if i == j { 1.0 + 1e-10 } else { 1.0 }
                    + if i == j { floor } else { 0.0 }
            });
            regularized
                .llt(Side::Lower)
                .map_err(|_| MetricsError::SingularFit)?
        }
    };
    let mut sum = 0.0;
    for frame in reference {
        let targets = Mat::<f64>::from_fn(n, 3, |i, c| frame[i][c]);
        let z = llt.solve(b * &targets);
        let fitted = b.transpose() * &z;
        for (i, q) in frame.iter().enumerate() {
            let d = Vector3::new(fitted[(i, 0)], fitted[(i, 1)], fitted[(i, 2)]) - q;
            sum += d.norm();
        }
    }
    Ok(sum / (reference.len() * n) as f64 / length)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frames(values: &[&[[f64; 3]]]) -> Vec<Vec<Vector3<f64>>> {
        values
            .iter()
            .map(|f| f.iter().map(|p| Vector3::from(*p)).collect())
            .collect()
    }

    #[test]
    fn errors_of_hand_made_trajectories_match_the_definitions() {
        // Two frames, two points. Differences: frame 1 (3,4,0) and 0; frame 2: 0 and (0,0,1).
        let reference = frames(&[&[[0.0; 3], [1.0, 0.0, 0.0]], &[[0.0; 3], [0.0, 1.0, 0.0]]]);
        let ours = frames(&[
            &[[3.0, 4.0, 0.0], [1.0, 0.0, 0.0]],
            &[[0.0; 3], [0.0, 1.0, 1.0]],
        ]);
        let e = trajectory_errors(&ours, &reference, 2.0).unwrap();
        // (25 + 0 + 0 + 1) / 4 / 2² = 1.625; max 5 / 2.
        assert!((e.normalized_mse - 1.625).abs() < 1e-15);
        assert!((e.normalized_max - 2.5).abs() < 1e-15);
        let same = trajectory_errors(&reference, &reference, 2.0).unwrap();
        assert_eq!(same.normalized_mse, 0.0);
        assert_eq!(same.normalized_max, 0.0);
        // Per frame: (25 + 0) / 2 / 4 = 3.125 and (0 + 1) / 2 / 4 = 0.125; their mean is the MSE.
        let frames = per_frame_mse(&ours, &reference, 2.0).unwrap();
        assert_eq!(frames, vec![3.125, 0.125]);
        assert!((0.5 * (frames[0] + frames[1]) - e.normalized_mse).abs() < 1e-15);
    }

    #[test]
    fn mismatched_or_non_finite_trajectories_are_errors() {
        let a = frames(&[&[[0.0; 3]]]);
        let b = frames(&[&[[0.0; 3]], &[[0.0; 3]]]);
        assert!(matches!(
            trajectory_errors(&a, &b, 1.0),
            Err(MetricsError::Shape(_))
        ));
        let nan = frames(&[&[[f64::NAN, 0.0, 0.0]]]);
        assert_eq!(
            trajectory_errors(&nan, &a, 1.0),
            Err(MetricsError::NonFinite { frame: 0, point: 0 })
        );
        assert_eq!(
            trajectory_errors(&a, &a, 0.0),
            Err(MetricsError::Length(0.0))
        );
    }
}
