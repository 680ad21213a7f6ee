//! Proptest strategies shared by the workspace's property tests.

use nalgebra::{Matrix3, Rotation3, Vector3};
use proptest::prelude::*;

/// A point with coordinates in `[lo, hi]³`.
pub fn point_in_box(lo: f64, hi: f64) -> impl Strategy<Value = [f64; 3]> {
    [lo..hi, lo..hi, lo..hi]
}

/// A deformation gradient `I + A` with entries of `A` in `[-amplitude, amplitude]`.
///
/// With `amplitude ≥ 1` a good fraction of the samples are inverted (`det F < 0`).
pub fn deformation_gradient(amplitude: f64) -> impl Strategy<Value = Matrix3<f64>> {
    proptest::collection::vec(-amplitude..amplitude, 9)
        .prop_map(|a| Matrix3::identity() + Matrix3::from_column_slice(&a))
}

/// A rotation matrix from a random axis-angle vector.
pub fn rotation() -> impl Strategy<Value = Matrix3<f64>> {
    [-3.0..3.0f64, -3.0..3.0f64, -3.0..3.0f64]
        .prop_map(|w| Rotation3::new(Vector3::from(w)).into_inner())
}
