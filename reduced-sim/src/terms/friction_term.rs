//! Smoothed, lagged Coulomb friction at the object's contacts with the floor and with
//! kinematic colliders (IPC's model, Li et al. 2020, Sec. 5).
//!
//! Every integration point i in contact gets its normal force `λ_i = κ v_i d_i` (N; κ the
//! contact stiffness, v_i the volume, d_i the penetration depth) and its contact normal n_i,
//! taken at the start of the step and then again at the step's solution (IPC's lagging,
//! [`crate::PenaltyParams::friction_lag_iterations`] times), and held fixed through each
//! solve. Slips are measured from where the point would be if it moved with the surface it
//! touches: `x̄_i = x_i^t + Δc_i`, Δc_i the surface's displacement over the step at `x_i^t`
//! (0 for the floor). The friction potential is
//!
//! ```text
//! D(z) = Σ_i μ λ_i f₀(‖u_i‖),   u_i = T_i (x_i(z) − x̄_i),   T_i = I − n_i n_iᵀ,
//! f₀(y) = −y³/(3ε²) + y²/ε + ε/3  (y < ε),   y  (y ≥ ε),     ε = ε_v h,
//! ```
//!
//! so the tangential force `μ λ_i f₁(‖u_i‖)` (f₁ = f₀') grows smoothly from 0 to the Coulomb
//! limit `μ λ_i` as the slip speed ‖u_i‖/h reaches ε_v ([`crate::PenaltyParams::friction_slip_speed`]),
//! and is `μ λ_i` against the slip beyond. Below ε_v the contact creeps: a load `s μ λ`
//! (s < 1) slides at `(1 − sqrt(1 − s)) ε_v`. The Hessian with respect to x_i,
//!
//! ```text
//! μλ [ f₁'(y) − f₁(y)/y ] T û ûᵀ T + μλ f₁(y)/y T,   û = u/y,
//! ```
//!
//! is positive semidefinite (eigenvalues f₁'(y) ≥ 0 along u, f₁(y)/y > 0 across it, 0 along
//! n), so it is used as is. Positions are linear in z (`x_i = X_i + B_i z`), so gradient and
//! Hessian in z are `B_iᵀ g_i` and `B_iᵀ H_i B_i`.

use faer::Mat;
use hyperelastic::Tangent;
use nalgebra::Vector3;

use crate::contact::friction_smoothing::{f0, slip_derivatives};
use crate::terms::step_term::{StepTerm, TermPoint};

/// One contact of a step's friction, lagged.
#[derive(Clone, Copy, Debug)]
pub(crate) struct FrictionContact {
    /// The integration point.
    pub(crate) point: usize,
    /// x̄: where the point is at no slip (m).
    pub(crate) previous: Vector3<f64>,
    /// `μ λ` (N): the friction coefficient times the lagged normal force.
    pub(crate) limit: f64,
    /// The unit contact normal n.
    pub(crate) normal: Vector3<f64>,
}

/// Whether two lagged friction sets, each a list of ((contact, normal), Coulomb limit), have
/// the same contacts in the same order, the same normals (to 1e-12) and limits within
/// `tolerance` of the first set's largest limit: the rule that ends friction lagging, for the
/// floor and colliders ([`ContactFriction::matches`]) and between objects.
pub(crate) fn same_lagged_forces<'a, K: PartialEq + 'a>(
    a: impl ExactSizeIterator<Item = ((K, &'a Vector3<f64>), &'a f64)> + Clone,
    b: impl ExactSizeIterator<Item = ((K, &'a Vector3<f64>), &'a f64)>,
    tolerance: f64,
) -> bool {
    let largest = a.clone().fold(0.0_f64, |m, (_, &l)| m.max(l));
    a.len() == b.len()
        && a.zip(b).all(|(((ka, na), la), ((kb, nb), lb))| {
            ka == kb && (na - nb).norm() <= 1e-12 && (la - lb).abs() <= tolerance * largest
        })
}

/// The lagged friction of one step.
#[derive(Clone, Debug)]
pub(crate) struct ContactFriction {
    points: Vec<usize>,
    previous: Vec<Vector3<f64>>,
    limit: Vec<f64>,
    normals: Vec<Vector3<f64>>,
    /// ε = ε_v h (m): the slip over one step at which friction reaches the Coulomb limit.
    epsilon: f64,
}

/// The relative change of the lagged normal forces below which friction is not lagged again
/// (1%, [`crate::PenaltyParams::friction_lag_iterations`]).
pub(crate) const LAG_TOLERANCE: f64 = 0.01;

impl ContactFriction {
    /// Whether this friction, lagged anew at a solution, differs from `lagged`, the one the
    /// step was solved with (none, other contacts or normals, or a limit off by more than
    /// [`LAG_TOLERANCE`]): then the step is solved again with it.
    pub(crate) fn moved_from(&self, lagged: Option<&ContactFriction>) -> bool {
        lagged.is_none_or(|old| !old.matches(self, LAG_TOLERANCE))
    }

    /// The friction of `contacts` with slip threshold `epsilon` = ε_v h (m); `None` when there
    /// is no contact with a positive limit.
    pub(crate) fn new(contacts: &[FrictionContact], epsilon: f64) -> Option<Self> {
        let active: Vec<&FrictionContact> = contacts.iter().filter(|c| c.limit > 0.0).collect();
        (!active.is_empty()).then(|| ContactFriction {
            points: active.iter().map(|c| c.point).collect(),
            previous: active.iter().map(|c| c.previous).collect(),
            limit: active.iter().map(|c| c.limit).collect(),
            normals: active.iter().map(|c| c.normal).collect(),
            epsilon,
        })
    }

    /// Whether `other` has the same contacts and normals and Coulomb limits close to these
    /// ([`same_lagged_forces`]): solving again with it would change little.
    pub(crate) fn matches(&self, other: &ContactFriction, tolerance: f64) -> bool {
        same_lagged_forces(
            self.points.iter().zip(&self.normals).zip(&self.limit),
            other.points.iter().zip(&other.normals).zip(&other.limit),
            tolerance,
        )
    }

    /// `T_k (x − x̄_k)` of contact k.
    fn slip(&self, k: usize, x: &Vector3<f64>) -> Vector3<f64> {
        let d = x - self.previous[k];
        d - self.normals[k] * self.normals[k].dot(&d)
    }

    /// Contact points of this step.
    #[cfg(test)]
    pub(crate) fn points(&self) -> &[usize] {
        &self.points
    }
}

/// `D(z) = Σ_k μλ_k f₀(|T_k (x_k(z) − x̄_k)|)` (J), the lagged friction of one step (IPC's
/// smoothed Coulomb friction, see the module docs).
impl StepTerm for ContactFriction {
    fn name(&self) -> &str {
        "friction"
    }

    fn add_energy(&self, at: &TermPoint<'_>, energy: &mut f64) {
        let x = at.map.subset(&self.points).positions(at.z);
        *energy += x
            .iter()
            .enumerate()
            .map(|(k, x)| self.limit[k] * f0(self.slip(k, x).norm(), self.epsilon))
            .sum::<f64>();
    }

    fn add_derivatives(
        &self,
        at: &TermPoint<'_>,
        _tangent: Tangent,
        gradient: &mut [f64],
        hessian: Option<&mut Mat<f64>>,
    ) {
        let (map, z) = (at.map, at.z);
        let mut forces = Vec::with_capacity(self.points.len());
        let mut stiffnesses = Vec::with_capacity(self.points.len());
        for (k, &i) in self.points.iter().enumerate() {
            let u = self.slip(k, &map.position(i, z));
            let (g, h) = slip_derivatives(&u, &self.normals[k], self.limit[k], self.epsilon);
            forces.push(g);
            stiffnesses.push(h);
        }
        map.add_point_gradients(&self.points, &forces, gradient);
        if let Some(hessian) = hessian {
            map.add_point_hessians(&self.points, &stiffnesses, hessian);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::analytic_field::{analytic_model, probe_z};
    use crate::terms::scene_terms::term_point;
    use crate::terms::term_check::{TermCheckParams, check_term};

    /// Contacts on every fourth point with turned normals, slips both below and beyond ε.
    #[test]
    fn lagged_friction_passes_the_term_check() {
        let (model, _) = analytic_model();
        let map = model.deformation_map();
        let z = probe_z(map.layout().len(), 0.02);
        let contacts: Vec<FrictionContact> = (0..map.len())
            .step_by(4)
            .map(|i| FrictionContact {
                point: i,
                previous: map.rest_positions()[i]
                    + Vector3::new(0.002 * (i % 7) as f64, 0.0, 0.001),
                limit: 10.0 + i as f64,
                normal: Vector3::new(0.1 * (i % 3) as f64, 1.0, 0.0).normalize(),
            })
            .collect();
        let friction = ContactFriction::new(&contacts, 5e-3).unwrap();
        let at = term_point(&model, &z, 0.0);
        check_term(&friction, &at, &TermCheckParams::default()).unwrap();
    }
}
