//! Smoothed, lagged Coulomb friction against the floor (IPC's model, Li et al. 2020, Sec. 5),
//! for issue 21.
//!
//! Every integration point i below the floor gets its normal force `λ_i = κ v_i d_i` (N; κ the
//! floor stiffness, v_i the volume, d_i the depth), taken at the start of the step and then
//! again at the step's solution (IPC's lagging, [`crate::PenaltyParams::friction_lag_iterations`]
//! times), and held fixed through each solve; slips are measured from the positions `x_i^t` at
//! the start of the step. The friction potential is
//!
//! ```text
//! D(z) = Σ_i μ λ_i f₀(‖u_i‖),   u_i = T (x_i(z) − x_i^t),   T = I − n nᵀ,
//! f₀(y) = −y³/(3ε²) + y²/ε + ε/3  (y < ε),   y  (y ≥ ε),     ε = ε_v h,
//! ```
//!
//! so the tangential force `μ λ_i f₁(‖u_i‖)` (f₁ = f₀') grows smoothly from 0 to the Coulomb
//! limit `μ λ_i` as the slip speed ‖u_i‖/h reaches ε_v ([`crate::PenaltyParams::friction_slip_speed`]),
//! and is `μ λ_i` against the slip beyond. Below ε_v the contact creeps: a load `s μ λ`
//! (s < 1) slides at `(1 − sqrt(1 − s)) ε_v`. The Hessian with respect to x,
//!
//! ```text
//! μλ [ f₁'(y) − f₁(y)/y ] T û ûᵀ T + μλ f₁(y)/y T,   û = u/y,
//! ```
//!
//! is positive semidefinite for a plane (eigenvalues f₁'(y) ≥ 0 along u, f₁(y)/y > 0 across
//! it, 0 along n), so it is used as is. Positions are linear in z (`x_i = B_i z`), so gradient
//! and Hessian in z are `B_iᵀ g_i` and `B_iᵀ H_i B_i`.

use faer::{Accum, Mat, MatRef, Par};
use nalgebra::{Matrix3, Vector3};

use crate::deformation_map::DeformationMap;

/// The lagged friction of one step: the floor's contacts at its start.
#[derive(Clone, Debug)]
pub(crate) struct FloorFriction {
    /// Contact points (integration point indices).
    points: Vec<usize>,
    /// Their positions at the start of the step (m).
    previous: Vec<Vector3<f64>>,
    /// `μ λ_i` (N): the friction coefficient times the lagged normal force.
    limit: Vec<f64>,
    /// The floor's unit normal.
    normal: Vector3<f64>,
    /// ε = ε_v h (m): the slip over one step at which friction reaches the Coulomb limit.
    epsilon: f64,
}

impl FloorFriction {
    /// The friction of a step that starts with the points at `start` (m), lagged at `contact`
    /// (m; the start itself, or the last solution of the step): contacts are the points with
    /// `depth_i > 0` there, each with Coulomb limit `μ κ v_i depth_i` (`stiffness` κ, `volumes`
    /// v_i). `None` when no point touches or `friction` is 0.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn lagged(
        start: &[Vector3<f64>],
        contact: &[Vector3<f64>],
        volumes: &[f64],
        normal: &Vector3<f64>,
        offset: f64,
        stiffness: f64,
        friction: f64,
        epsilon: f64,
    ) -> Option<Self> {
        if friction <= 0.0 {
            return None;
        }
        let mut points = Vec::new();
        let mut previous = Vec::new();
        let mut limit = Vec::new();
        for (i, (x, v)) in contact.iter().zip(volumes).enumerate() {
            let depth = offset - normal.dot(x);
            if depth > 0.0 {
                points.push(i);
                previous.push(start[i]);
                limit.push(friction * stiffness * v * depth);
            }
        }
        (!points.is_empty()).then_some(FloorFriction {
            points,
            previous,
            limit,
            normal: *normal,
            epsilon,
        })
    }

    /// `T (x − x^t)` of contact k.
    fn slip(&self, k: usize, x: &Vector3<f64>) -> Vector3<f64> {
        let d = x - self.previous[k];
        d - self.normal * self.normal.dot(&d)
    }

    /// D(z) (J).
    pub(crate) fn energy(&self, map: &DeformationMap, z: &[f64]) -> f64 {
        let x = map.subset(&self.points).positions(z);
        x.iter()
            .enumerate()
            .map(|(k, x)| self.limit[k] * f0(self.slip(k, x).norm(), self.epsilon))
            .sum()
    }

    /// Adds ∂D/∂z to `gradient` and, when given, ∂²D/∂z² to `hessian`.
    pub(crate) fn add_derivatives(
        &self,
        map: &DeformationMap,
        z: &[f64],
        gradient: &mut [f64],
        hessian: Option<&mut Mat<f64>>,
    ) {
        let n4 = map.layout().block_len();
        let mut forces = Vec::with_capacity(self.points.len());
        let mut stiffnesses = Vec::with_capacity(self.points.len());
        for (k, &i) in self.points.iter().enumerate() {
            // x_i = X_i + B_i z (z = 0 at rest).
            let b = map.position_row(i);
            let position = map.rest_positions()[i]
                + Vector3::from_fn(|r, _| {
                    b.iter()
                        .zip(&z[r * n4..(r + 1) * n4])
                        .map(|(b, z)| b * z)
                        .sum()
                });
            let u = self.slip(k, &position);
            let y = u.norm();
            let (f1_over_y, curvature) = slope_and_curvature(y, self.epsilon);
            let g = u * (self.limit[k] * f1_over_y);
            let tangent = Matrix3::identity() - self.normal * self.normal.transpose();
            let mut h = tangent * (self.limit[k] * f1_over_y);
            if y > 0.0 {
                // [f₁'(y) − f₁(y)/y] û ûᵀ with û = u/y (u already tangential).
                h += u * u.transpose() * (self.limit[k] * curvature / (y * y));
            }
            forces.push(g);
            stiffnesses.push(h);
        }
        for (k, &i) in self.points.iter().enumerate() {
            let b = map.position_row(i);
            for r in 0..3 {
                let c = forces[k][r];
                for (gk, bk) in gradient[r * n4..(r + 1) * n4].iter_mut().zip(b) {
                    *gk += c * bk;
                }
            }
        }
        let Some(hessian) = hessian else {
            return;
        };
        // Σ_k H_k[r, q] b_k b_kᵀ for each pair (r, q), as one product each.
        let rows: Vec<f64> = self
            .points
            .iter()
            .flat_map(|&i| map.position_row(i).iter().copied())
            .collect();
        let b = MatRef::from_column_major_slice(&rows, n4, self.points.len());
        let mut weighted = vec![0.0; rows.len()];
        let mut block = Mat::<f64>::zeros(n4, n4);
        for r in 0..3 {
            for q in r..3 {
                for (k, column) in weighted.chunks_mut(n4).enumerate() {
                    let w = stiffnesses[k][(r, q)];
                    for (c, bk) in column.iter_mut().zip(&rows[k * n4..(k + 1) * n4]) {
                        *c = w * bk;
                    }
                }
                faer::linalg::matmul::matmul(
                    block.as_mut(),
                    Accum::Replace,
                    MatRef::from_column_major_slice(&weighted, n4, self.points.len()),
                    b.transpose(),
                    1.0,
                    Par::Seq,
                );
                for bb in 0..n4 {
                    for a in 0..n4 {
                        hessian[(r * n4 + a, q * n4 + bb)] += block[(a, bb)];
                        if q != r {
                            hessian[(q * n4 + bb, r * n4 + a)] += block[(a, bb)];
                        }
                    }
                }
            }
        }
    }

    /// Contact points of this step.
    #[cfg(test)]
    pub(crate) fn points(&self) -> &[usize] {
        &self.points
    }
}

/// f₀(y) with threshold ε (m).
fn f0(y: f64, epsilon: f64) -> f64 {
    if y < epsilon {
        -y * y * y / (3.0 * epsilon * epsilon) + y * y / epsilon + epsilon / 3.0
    } else {
        y
    }
}

/// `(f₁(y)/y, f₁'(y) − f₁(y)/y)`, finite at y = 0 (where the second is 0).
fn slope_and_curvature(y: f64, epsilon: f64) -> (f64, f64) {
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
