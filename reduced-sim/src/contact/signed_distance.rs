//! A signed distance with its derivatives.

use nalgebra::{Matrix3, Vector3};

/// The signed distance of a shape at one point, with its derivatives (frame of the point).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SignedDistance {
    /// φ (m), negative inside.
    pub distance: f64,
    /// ∇φ (unit length where φ is differentiable).
    pub gradient: Vector3<f64>,
    /// ∇²φ (1/m).
    pub hessian: Matrix3<f64>,
}
