//! The floor: a half-space the body is pushed out of by a penalty or a barrier.

use faer::{Accum, Mat, MatRef, Par};
use hyperelastic::Tangent;
use nalgebra::Vector3;

use crate::scene::{Floor, FloorContact};
use crate::terms::friction_term::FrictionContact;
use crate::terms::step_term::{StepTerm, TermPoint};

/// How hard the floor and the colliders push a point at gap g: `e(g) = κ v ψ(g)` with the
/// profile ψ of [`FloorContact`] and κ (Pa/m²) from [`crate::PenaltyParams::floor_factor`].
#[derive(Clone, Copy, Debug)]
pub(crate) struct ContactLaw {
    /// κ (Pa/m²).
    pub(crate) stiffness: f64,
    /// Penalty or barrier.
    pub(crate) contact: FloorContact,
}

impl ContactLaw {
    /// `(e, e', e'')` per unit of the profile: `κ v (ψ, ψ', ψ'')` at gap `gap` (m) of a point of
    /// volume `volume` (m³).
    pub(crate) fn weighted_profile(&self, gap: f64, volume: f64) -> (f64, f64, f64) {
        let w = self.stiffness * volume;
        let (psi, slope, curvature) = self.contact.profile(gap);
        (w * psi, w * slope, w * curvature)
    }

    /// The normal force `−κ v ψ'(g)` (N) at gap g (m) on a point of volume `volume` (m³).
    pub(crate) fn normal_force(&self, gap: f64, volume: f64) -> f64 {
        -self.stiffness * volume * self.contact.profile(gap).1
    }

    /// Whether the contact is IPC's barrier.
    pub(crate) fn is_barrier(&self) -> bool {
        matches!(self.contact, FloorContact::Barrier { .. })
    }

    /// The gap (m) below which a point is in contact ([`FloorContact::reach`]).
    pub(crate) fn reach(&self) -> f64 {
        self.contact.reach()
    }
}

/// `E_floor(z) = Σ_i κ v_i ψ(g_i(z))`, `g_i = n·x_i − offset` (J; design §3.7): gradient
/// `κ v ψ' n ⊗ B_i` and Hessian `κ v ψ'' (n nᵀ) ⊗ B_i B_iᵀ` over the points within reach.
pub(crate) struct FloorTerm {
    /// The floor with a unit normal.
    pub(crate) floor: Floor,
    pub(crate) law: ContactLaw,
}

impl FloorTerm {
    /// The points within reach of the floor at `at` (index order).
    pub(crate) fn contacts(&self, at: &TermPoint<'_>) -> Vec<usize> {
        let reach = self.law.reach();
        let positions = at.positions();
        (0..positions.len())
            .filter(|&i| self.floor.gap(&positions[i]) < reach)
            .collect()
    }

    /// The largest depth (m) of a point below the floor at `at` (negative when all are above).
    pub(crate) fn deepest(&self, at: &TermPoint<'_>) -> f64 {
        at.positions()
            .iter()
            .map(|x| -self.floor.gap(x))
            .fold(f64::NEG_INFINITY, f64::max)
    }

    /// The floor's friction contacts (μ > 0 only) lagged at `contact` (the points at the lag
    /// z), slips measured from `start` (the points at the start of the step).
    pub(crate) fn friction_contacts(
        &self,
        start: &[Vector3<f64>],
        contact: &[Vector3<f64>],
        volumes: &[f64],
    ) -> Vec<FrictionContact> {
        let reach = self.law.reach();
        contact
            .iter()
            .enumerate()
            .filter_map(|(i, x)| {
                let gap = self.floor.gap(x);
                (gap < reach).then(|| FrictionContact {
                    point: i,
                    previous: start[i],
                    limit: self.floor.friction * self.law.normal_force(gap, volumes[i]),
                    normal: self.floor.normal,
                })
            })
            .collect()
    }
}

impl StepTerm for FloorTerm {
    fn name(&self) -> &str {
        "floor"
    }

    fn add_energy(&self, at: &TermPoint<'_>, energy: &mut f64) {
        for (x, &v) in at.positions().iter().zip(at.volumes) {
            *energy += self.law.weighted_profile(self.floor.gap(x), v).0;
        }
    }

    fn add_derivatives(
        &self,
        at: &TermPoint<'_>,
        _tangent: Tangent,
        gradient: &mut [f64],
        hessian: Option<&mut Mat<f64>>,
    ) {
        // Active points: E = κ v ψ(g), g = n·x − offset, ∂g/∂z_r = n_r b_i.
        let map = at.map;
        let n4 = map.layout().block_len();
        let mut active_b = Vec::new();
        let mut active_bw = Vec::new();
        let reach = self.law.reach();
        for (i, x) in at.positions().iter().enumerate() {
            let gap = self.floor.gap(x);
            if gap < reach {
                let w = self.law.stiffness * at.volumes[i];
                let (_, slope, curvature) = self.law.contact.profile(gap);
                let bi = map.position_row(i);
                for r in 0..3 {
                    let c = w * slope * self.floor.normal[r];
                    for (gk, bk) in gradient[r * n4..(r + 1) * n4].iter_mut().zip(bi) {
                        *gk += c * bk;
                    }
                }
                active_b.extend_from_slice(bi);
                active_bw.extend(bi.iter().map(|b| b * w * curvature));
            }
        }
        let active = active_b.len() / n4;
        let (true, Some(hessian)) = (active > 0, hessian) else {
            return;
        };
        let mut block = Mat::<f64>::zeros(n4, n4);
        faer::linalg::matmul::matmul(
            block.as_mut(),
            Accum::Replace,
            MatRef::from_column_major_slice(&active_bw, n4, active),
            MatRef::from_column_major_slice(&active_b, n4, active).transpose(),
            1.0,
            Par::rayon(0),
        );
        let nrm = self.floor.normal;
        for r in 0..3 {
            for q in 0..3 {
                let c = nrm[r] * nrm[q];
                if c == 0.0 {
                    continue;
                }
                for b in 0..n4 {
                    for a in 0..n4 {
                        hessian[(r * n4 + a, q * n4 + b)] += c * block[(a, b)];
                    }
                }
            }
        }
    }

    /// With the barrier: the largest α ≤ 1 such that no point closes more than 90% of its gap
    /// along α·`step` (exact: the gap is linear in z); 1 with the penalty.
    fn max_step(&self, at: &TermPoint<'_>, step: &[f64]) -> f64 {
        if !self.law.is_barrier() {
            return 1.0;
        }
        let moves = at.map.displacements(step);
        let mut alpha: f64 = 1.0;
        for (x, dx) in at.positions().iter().zip(&moves) {
            let closing = -self.floor.normal.dot(dx);
            if closing > 0.0 {
                alpha = alpha.min(0.9 * self.floor.gap(x) / closing);
            }
        }
        alpha.max(0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::analytic_field::{analytic_model, probe_z};
    use crate::terms::scene_terms::term_point;
    use crate::terms::term_check::{TermCheckParams, check_term};

    fn floor_at(offset: f64, contact: FloorContact) -> FloorTerm {
        FloorTerm {
            floor: Floor {
                normal: Vector3::new(0.0, 1.0, 0.0),
                offset,
                friction: 0.0,
            },
            law: ContactLaw {
                stiffness: 1e8,
                contact,
            },
        }
    }

    #[test]
    fn the_penalty_floor_through_the_block_passes_the_term_check() {
        let (model, _) = analytic_model();
        let z = probe_z(model.deformation_map().layout().len(), 0.02);
        let at = term_point(&model, &z, 0.0);
        let term = floor_at(0.35, FloorContact::Penalty);
        assert!(!term.contacts(&at).is_empty());
        check_term(&term, &at, &TermCheckParams::default()).unwrap();
    }

    #[test]
    fn the_barrier_floor_below_the_block_passes_the_term_check_and_stops_short() {
        let (model, _) = analytic_model();
        let z = probe_z(model.deformation_map().layout().len(), 0.02);
        let at = term_point(&model, &z, 0.0);
        let term = floor_at(-0.05, FloorContact::Barrier { distance: 0.2 });
        assert!(term.deepest(&at) < 0.0 && !term.contacts(&at).is_empty());
        check_term(&term, &at, &TermCheckParams::default()).unwrap();
        // A step straight down: the largest safe fraction closes 90% of the smallest gap.
        let layout = model.deformation_map().layout();
        let mut down = vec![0.0; layout.len()];
        // The constant handle's translation entry along y (the fourth of its block).
        down[layout.block_len() + 3] = -1.0;
        let alpha = term.max_step(&at, &down);
        let gap = -term.deepest(&at);
        assert!(
            (alpha - 0.9 * gap).abs() < 1e-12,
            "α = {alpha}, gap {gap} m"
        );
    }
}
