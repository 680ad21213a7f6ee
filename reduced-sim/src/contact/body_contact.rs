//! Contact between objects: a swappable repulsion between the contact samples of
//! different objects, and their smoothed, lagged Coulomb friction.
//!
//! Each object carries contact samples on its surface at spacing about r, moved by its own
//! deformation map (`x_a = X_a + B_a z`). Two samples a, b of different objects that may come
//! within the contact distance d̂ = r during a step form a pair with the lagged normal
//! `n = p/‖p‖`, `p = x_a − x_b`, taken at the start of the step (and again at its solution
//! while the normals of touching pairs turn). Through the solve the pair's gap is its distance
//! along that normal, `d = n·p`, and it repels with
//!
//! ```text
//! penalty:  e(d) = κ v ½ (d̂ − d)²                       (d < d̂)
//! barrier:  e(d) = κ v b(d),  b(d) = −(d − d̂)² ln(d/d̂)   (0 < d < d̂; +∞ at d ≤ 0)
//! ```
//!
//! and nothing beyond d̂. `v = r³` (m³) is a sample's share of the object near its surface and
//! κ = `stiffness_factor · E / L²` (Pa/m²) the floor's rule ([`crate::PenaltyParams`]) with the
//! larger p-wave modulus of the two objects and the smaller of their bounding-box sides, so
//! the energies are in J and the overlap a given load causes scales with the objects. With
//! ψ = e/(κv), the derivatives in p are
//!
//! ```text
//! ∇_p e  = κ v ψ'(d) n,      ∇²_p e = κ v ψ''(d) n nᵀ    (ψ'' ≥ 0: positive semidefinite),
//! ```
//!
//! and `−` the gradient for x_b. The energy depends on positions only through p, so the contact
//! forces on the two objects are equal and opposite and linear momentum is conserved. (The
//! distance between the points themselves, `‖p‖`, would repel too, but its transverse
//! curvature `ψ'/‖p‖ (I − n nᵀ)` is negative: many such pairs make a bumpy landscape on which
//! Newton with a positive semidefinite Hessian crawls. The lagged normal keeps each pair a
//! convex function of the positions.)
//!
//! Friction between objects is IPC's, as at the floor
//! ([`crate::PenaltyParams::friction_slip_speed`]), on the relative slip `u = T (p − p̄)`,
//! `T = I − n nᵀ`, with the normal force `λ = −κ v ψ'(d)`, the normal and p̄ lagged at the
//! start of the step.

use faer::{Accum, Mat, MatMut, MatRef, Par};
use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

use crate::contact::friction_smoothing::{f0, slip_derivatives};
use crate::contact::log_barrier::log_barrier;
use crate::model::deformation_map::DeformationMap;

/// How the contact samples of different objects repel.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BodyContactModel {
    /// A quadratic penalty on the overlap `d̂ − d` (default): cheap and smooth, but samples may
    /// come closer than d̂ by an amount that shrinks as the stiffness grows.
    #[default]
    Penalty,
    /// IPC's log barrier: infinite at d = 0, so no pair ever closes; the Newton line search
    /// stops each step short of the first pair's contact.
    Barrier,
}

/// Options of contact between objects.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BodyContactParams {
    /// Contact distance d̂ = r (m): samples of different objects closer than this repel. Place
    /// the contact samples at a spacing of at most r so surfaces cannot slip between them.
    pub radius: f64,
    /// Penalty or barrier (default penalty).
    #[serde(default)]
    pub model: BodyContactModel,
    /// Stiffness factor (dimensionless, default 1e4, the floor's): κ = factor · E / L².
    #[serde(default = "default_stiffness_factor")]
    pub stiffness_factor: f64,
    /// Coulomb friction coefficient μ between objects (default 0: frictionless).
    #[serde(default)]
    pub friction: f64,
}

fn default_stiffness_factor() -> f64 {
    1e4
}

impl BodyContactParams {
    /// Penalty contact at distance `radius` (m), the default stiffness, no friction.
    pub fn with_radius(radius: f64) -> Self {
        BodyContactParams {
            radius,
            model: BodyContactModel::Penalty,
            stiffness_factor: default_stiffness_factor(),
            friction: 0.0,
        }
    }

    /// What is wrong with these options, if anything: a radius or stiffness factor that is not
    /// finite and positive, a negative or non-finite friction coefficient.
    pub fn defect(&self) -> Option<String> {
        let positive = |v: f64| v.is_finite() && v > 0.0;
        if !positive(self.radius) {
            Some(format!("contact radius {} m", self.radius))
        } else if !positive(self.stiffness_factor) {
            Some(format!("stiffness factor {}", self.stiffness_factor))
        } else if !(self.friction.is_finite() && self.friction >= 0.0) {
            Some(format!("friction coefficient {}", self.friction))
        } else {
            None
        }
    }

    /// The sample share v = r³ (m³) that scales each pair's energy.
    pub(crate) fn sample_volume(&self) -> f64 {
        self.radius.powi(3)
    }

    /// `(ψ(d), ψ'(d), ψ''(d))` (m², m, 1) of one pair at distance d (m), zero from d̂ on;
    /// `None` where the barrier is infinite (d ≤ 0).
    pub(crate) fn profile(&self, d: f64) -> Option<(f64, f64, f64)> {
        let d_hat = self.radius;
        if d >= d_hat {
            return Some((0.0, 0.0, 0.0));
        }
        match self.model {
            BodyContactModel::Penalty => {
                let overlap = d_hat - d;
                Some((0.5 * overlap * overlap, -overlap, 1.0))
            }
            BodyContactModel::Barrier => {
                if d <= 0.0 {
                    return None;
                }
                Some(log_barrier(d, d_hat))
            }
        }
    }
}

/// A sample of one object near a sample of another: `(object, sample)` twice, first object
/// index smaller. Sample indices are into the objects' contact-sample maps.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub(crate) struct SamplePair {
    pub(crate) a: (usize, usize),
    pub(crate) b: (usize, usize),
}

/// A pair with its lagged unit normal n (from b towards a) and its stiffness κ (Pa/m²).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct LaggedPair {
    pub(crate) pair: SamplePair,
    pub(crate) normal: Vector3<f64>,
    pub(crate) stiffness: f64,
}

/// One pair's gradient and Hessian with respect to `p = x_a − x_b` (for x_b: both negated).
pub(crate) struct RelativeDerivatives {
    pub(crate) gradient: Vector3<f64>,
    pub(crate) hessian: Matrix3<f64>,
}

/// The derivatives in p of κ v ψ(n·p) (zero beyond d̂; `None` at n·p ≤ 0 for the barrier).
pub(crate) fn repulsion_derivatives(
    contact: &BodyContactParams,
    stiffness: f64,
    normal: &Vector3<f64>,
    p: &Vector3<f64>,
) -> Option<RelativeDerivatives> {
    let (_, slope, curvature) = contact.profile(normal.dot(p))?;
    let k = stiffness * contact.sample_volume();
    Some(RelativeDerivatives {
        gradient: normal * (k * slope),
        hessian: normal * normal.transpose() * (k * curvature),
    })
}

/// The lagged friction of one pair over a step.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PairFriction {
    pub(crate) pair: SamplePair,
    /// p̄: the relative position at the start of the step (m).
    pub(crate) previous: Vector3<f64>,
    /// The unit normal n at the lag point.
    pub(crate) normal: Vector3<f64>,
    /// μλ (N).
    pub(crate) limit: f64,
}

impl PairFriction {
    /// The tangential slip `T (p − p̄)`.
    fn slip(&self, p: &Vector3<f64>) -> Vector3<f64> {
        let d = p - self.previous;
        d - self.normal * self.normal.dot(&d)
    }

    /// `μλ f₀(‖u‖)` (J) with slip threshold ε (m).
    pub(crate) fn energy(&self, p: &Vector3<f64>, epsilon: f64) -> f64 {
        self.limit * f0(self.slip(p).norm(), epsilon)
    }

    /// Its derivatives in p.
    pub(crate) fn derivatives(&self, p: &Vector3<f64>, epsilon: f64) -> RelativeDerivatives {
        let (gradient, hessian) =
            slip_derivatives(&self.slip(p), &self.normal, self.limit, epsilon);
        RelativeDerivatives { gradient, hessian }
    }
}

/// The friction of the `pairs` that touch at the sample positions
/// `positions` (per object), with the limit `μ λ` taken there, the pair's normal, and slips
/// measured from `start`.
pub(crate) fn lagged_friction(
    contact: &BodyContactParams,
    pairs: &[LaggedPair],
    positions: &[Vec<Vector3<f64>>],
    start: &[Vec<Vector3<f64>>],
) -> Vec<PairFriction> {
    if contact.friction <= 0.0 {
        return Vec::new();
    }
    let v = contact.sample_volume();
    pairs
        .iter()
        .filter_map(|lagged| {
            let pair = lagged.pair;
            let p = positions[pair.a.0][pair.a.1] - positions[pair.b.0][pair.b.1];
            let (_, slope, _) = contact.profile(lagged.normal.dot(&p))?;
            (slope < 0.0).then(|| PairFriction {
                pair,
                previous: start[pair.a.0][pair.a.1] - start[pair.b.0][pair.b.1],
                normal: lagged.normal,
                limit: contact.friction * lagged.stiffness * v * -slope,
            })
        })
        .collect()
}

/// Adds `−Σ_k B_a,kᵀ H_k B_b,k` to `out` (`3·4(m_a+1) × 3·4(m_b+1)`, the (a, b) block of a
/// Hessian over `[z_a; z_b]`): the cross term of energies of `p = x_a − x_b`.
pub(crate) fn add_cross_hessians(
    map_a: &DeformationMap,
    points_a: &[usize],
    map_b: &DeformationMap,
    points_b: &[usize],
    hessians: &[Matrix3<f64>],
    mut out: MatMut<'_, f64>,
) {
    if points_a.is_empty() {
        return;
    }
    let (na, nb) = (map_a.layout().block_len(), map_b.layout().block_len());
    let count = points_a.len();
    let rows_b: Vec<f64> = points_b
        .iter()
        .flat_map(|&i| map_b.position_row(i).iter().copied())
        .collect();
    let b = MatRef::from_column_major_slice(&rows_b, nb, count);
    let mut weighted = vec![0.0; na * count];
    let mut block = Mat::<f64>::zeros(na, nb);
    for r in 0..3 {
        for q in r..3 {
            for ((column, &i), h) in weighted.chunks_mut(na).zip(points_a).zip(hessians) {
                for (c, b) in column.iter_mut().zip(map_a.position_row(i)) {
                    *c = h[(r, q)] * b;
                }
            }
            faer::linalg::matmul::matmul(
                block.as_mut(),
                Accum::Replace,
                MatRef::from_column_major_slice(&weighted, na, count),
                b.transpose(),
                -1.0,
                Par::Seq,
            );
            // H symmetric: the (r, q) and (q, r) blocks are the same product.
            for c in 0..nb {
                for a in 0..na {
                    out[(r * na + a, q * nb + c)] += block[(a, c)];
                    if q != r {
                        out[(q * na + a, r * nb + c)] += block[(a, c)];
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check_profile(model: BodyContactModel) {
        let contact = BodyContactParams {
            model,
            ..BodyContactParams::with_radius(0.02)
        };
        for &d in &[0.001, 0.005, 0.012, 0.0199] {
            let (_, slope, curvature) = contact.profile(d).unwrap();
            let step = 1e-7;
            let e = |d: f64| contact.profile(d).unwrap().0;
            let de = |d: f64| contact.profile(d).unwrap().1;
            let fd_slope = (e(d + step) - e(d - step)) / (2.0 * step);
            let fd_curvature = (de(d + step) - de(d - step)) / (2.0 * step);
            assert!(
                (slope - fd_slope).abs() <= 1e-6 * slope.abs().max(1e-12),
                "{model:?} d = {d}: ψ' {slope:e} vs {fd_slope:e}"
            );
            assert!(
                (curvature - fd_curvature).abs() <= 1e-5 * curvature.abs(),
                "{model:?} d = {d}: ψ'' {curvature:e} vs {fd_curvature:e}"
            );
            assert!(
                slope < 0.0 && curvature > 0.0,
                "{model:?} d = {d}: not repulsive and convex"
            );
        }
        assert_eq!(contact.profile(0.02), Some((0.0, 0.0, 0.0)));
        assert_eq!(contact.profile(0.05), Some((0.0, 0.0, 0.0)));
    }

    #[test]
    fn penalty_and_barrier_profiles_match_finite_differences_and_repel() {
        check_profile(BodyContactModel::Penalty);
        check_profile(BodyContactModel::Barrier);
        let barrier = BodyContactParams {
            model: BodyContactModel::Barrier,
            ..BodyContactParams::with_radius(0.02)
        };
        assert_eq!(barrier.profile(0.0), None);
        assert_eq!(barrier.profile(-1e-3), None);
        assert!(barrier.profile(1e-12).unwrap().0 > barrier.profile(1e-3).unwrap().0);
    }

    #[test]
    fn relative_derivatives_match_finite_differences_of_the_pair_energy() {
        let normal = Vector3::new(0.3, -0.2, 0.9).normalize();
        for model in [BodyContactModel::Penalty, BodyContactModel::Barrier] {
            let contact = BodyContactParams {
                model,
                ..BodyContactParams::with_radius(0.02)
            };
            let kappa = 3e9;
            let energy = |p: &Vector3<f64>| {
                kappa * contact.sample_volume() * contact.profile(normal.dot(p)).unwrap().0
            };
            let p = Vector3::new(0.006, -0.004, 0.009);
            let exact = repulsion_derivatives(&contact, kappa, &normal, &p).unwrap();
            let step = 1e-8;
            for k in 0..3 {
                let e = Vector3::ith(k, step);
                let fd = (energy(&(p + e)) - energy(&(p - e))) / (2.0 * step);
                assert!(
                    (fd - exact.gradient[k]).abs() <= 1e-6 * exact.gradient.norm(),
                    "{model:?} gradient {k}: {fd:e} vs {:e}",
                    exact.gradient[k]
                );
                let at = |p: Vector3<f64>| {
                    repulsion_derivatives(&contact, kappa, &normal, &p)
                        .unwrap()
                        .gradient
                };
                let fd_column = (at(p + e) - at(p - e)) / (2.0 * step);
                let error = (fd_column - exact.hessian.column(k)).norm();
                assert!(
                    error <= 1e-6 * exact.hessian.norm(),
                    "{model:?} Hessian column {k}: error {error:e}"
                );
            }
            let eigen = exact.hessian.symmetric_eigenvalues();
            assert!(eigen.min() >= -1e-9 * eigen.max(), "not PSD: {eigen:?}");
        }
    }
}
