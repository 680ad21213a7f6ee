//! The backward-Euler incremental potential of one step (design §3.7):
//!
//! ```text
//! E(z) = 1/(2h²) (z - ẑ)ᵀ M_z (z - ẑ) + Σ_i v_i Ψ(F_i(z)) + E_grav(z) + E_pin(z, t+h) + E_floor(z)
//!        + D(z)
//! ```
//!
//! with E_floor including the kinematic colliders' penalties, and D the lagged friction
//! potential of the floor and the colliders (`terms::friction_term`, when one has μ > 0).
//!
//! with `ẑ = z_t + h ż_t`. Without the inertia term it is the static equilibrium problem.
//!
//! [`crate::Simulator::step_potential`] hands out the potential of the next step, so a caller
//! can evaluate it, check its derivatives, or minimize it with its own solver (it implements
//! [`optimize::NewtonObjective`]).

use faer::linalg::solvers::Llt;
use faer::linalg::triangular_solve;
use faer::{Mat, Par, Side};
use hyperelastic::{HyperelasticMaterial, Tangent};
use optimize::NewtonObjective;

use crate::model::reduced_model::{ReducedModel, add_block_diagonal_product};
use crate::step::deformation_cache::DeformationCache;
use crate::step::hessian_tangent::{HessianTangent, StepTangents};
use crate::terms::friction_term::ContactFriction;
use crate::terms::scene_terms::{SceneTerms, term_point};
use crate::terms::step_term::StepTerm;

/// `1/(2h²) (z - ẑ)ᵀ M_z (z - ẑ)`.
pub(crate) struct Inertia<'a> {
    pub(crate) predicted: &'a [f64],
    pub(crate) inverse_step_squared: f64,
}

/// E(z) of one step (Eq. 2 with backward Euler, design §3.7), with its gradient and Hessian
/// (material tangent by [`HessianTangent`]). z has length 12(m + 1) (the
/// [`crate::ReducedLayout`]); E is in J up to a constant.
pub struct IncrementalPotential<'a, M: HyperelasticMaterial> {
    pub(crate) model: &'a ReducedModel<M>,
    pub(crate) terms: &'a SceneTerms,
    /// The time (s) the scene's terms are evaluated at: the end of the step.
    pub(crate) time: f64,
    pub(crate) inertia: Option<Inertia<'a>>,
    pub(crate) tangent: HessianTangent,
    /// With held regions ([`crate::Scene::held`]): the entries of z Newton solves
    /// for; the others stay as prescribed.
    pub(crate) free: Option<&'a [usize]>,
    /// The floor's friction, lagged at the start of the step (dynamic steps only).
    pub(crate) friction: Option<ContactFriction>,
    /// The elastic points' deformation at the z last evaluated.
    pub(crate) deformation: DeformationCache,
}

impl<M: HyperelasticMaterial> IncrementalPotential<'_, M> {
    /// E(z) (J, up to a constant). Non-finite when some term is.
    pub fn energy(&self, z: &[f64]) -> f64 {
        let at = term_point(self.model, z, self.time);
        let deformation = self.deformation.at(self.model, z);
        let mut e = self.model.elastic_energy_at(&deformation) + self.terms.energy(&at);
        if let Some(friction) = &self.friction {
            friction.add_energy(&at, &mut e);
        }
        if let Some(inertia) = &self.inertia {
            let d: Vec<f64> = z
                .iter()
                .zip(inertia.predicted)
                .map(|(a, b)| a - b)
                .collect();
            e += 0.5 * inertia.inverse_step_squared * mass_inner(self.model, &d, &d);
        }
        e
    }

    /// `(∂E/∂z, ∂²E/∂z²)` at z (J, J; the Hessian 12(m+1) square, dense), the Hessian with
    /// the potential's [`HessianTangent`]: for [`HessianTangent::ExactWhenDefinite`] the exact
    /// one when it (restricted to the free coordinates) has a Cholesky factorization, else the
    /// projected one (assembled again); likewise the absolute-eigenvalue one for
    /// [`HessianTangent::ExactElseAbsolute`] ([`HessianTangent::fallback`]).
    pub fn derivatives(&self, z: &[f64]) -> (Vec<f64>, Mat<f64>) {
        let first = self.derivatives_with(z, self.tangent.first_try());
        if let Some(fallback) = self.tangent.fallback()
            && self.free_block(&first.1).llt(Side::Lower).is_err()
        {
            return self.derivatives_with(z, fallback);
        }
        first
    }

    /// [`IncrementalPotential::derivatives`] with the material tangent `tangent`.
    fn derivatives_with(&self, z: &[f64], tangent: Tangent) -> (Vec<f64>, Mat<f64>) {
        // F formed once for the gradient and the Hessian (or taken from the energy at the
        // same z), the same bits as the F of the one-pass gradient of `gradient` below, so
        // the two gradients agree to the bit.
        let deformation = self.deformation.at(self.model, z);
        let mut gradient = self.model.elastic_gradient_at(&deformation);
        let mut hessian = Mat::zeros(z.len(), z.len());
        self.model
            .add_elastic_hessian_at(&deformation, tangent, &mut hessian);
        let at = term_point(self.model, z, self.time);
        self.terms
            .add_derivatives(&at, tangent, &mut gradient, Some(&mut hessian));
        if let Some(friction) = &self.friction {
            friction.add_derivatives(&at, tangent, &mut gradient, Some(&mut hessian));
        }
        self.add_inertia(z, &mut gradient, Some(&mut hessian));
        (gradient, hessian)
    }

    /// `∂E/∂z` alone (no Hessian work): from the deformation of the last energy evaluation
    /// when that was at this z, else in one pass that forms F as it goes.
    pub fn gradient(&self, z: &[f64]) -> Vec<f64> {
        let mut gradient = match self.deformation.stored(z) {
            Some(deformation) => self.model.elastic_gradient_at(&deformation),
            None => self.model.elastic_gradient(z),
        };
        let at = term_point(self.model, z, self.time);
        let tangent = self.tangent.first_try();
        self.terms
            .add_derivatives(&at, tangent, &mut gradient, None);
        if let Some(friction) = &self.friction {
            friction.add_derivatives(&at, tangent, &mut gradient, None);
        }
        self.add_inertia(z, &mut gradient, None);
        gradient
    }

    /// The rows and columns of the free coordinates of a full-size Hessian (all of it without
    /// held regions).
    fn free_block(&self, hessian: &Mat<f64>) -> Mat<f64> {
        match self.free {
            None => hessian.clone(),
            Some(free) => Mat::from_fn(free.len(), free.len(), |a, b| hessian[(free[a], free[b])]),
        }
    }

    /// Adds the inertia term's gradient `M_z (z - ẑ)/h²` and Hessian `M_z/h²`.
    fn add_inertia(&self, z: &[f64], gradient: &mut [f64], hessian: Option<&mut Mat<f64>>) {
        let Some(inertia) = &self.inertia else {
            return;
        };
        let k = inertia.inverse_step_squared;
        let mass = self.model.mass_block();
        let n4 = mass.nrows();
        let dz: Vec<f64> = z
            .iter()
            .zip(inertia.predicted)
            .map(|(z, predicted)| z - predicted)
            .collect();
        add_block_diagonal_product(gradient, mass, &dz, k);
        if let Some(h) = hessian {
            for offset in [0, n4, 2 * n4] {
                for b in 0..n4 {
                    for (a, m) in mass.col_as_slice(b).iter().enumerate() {
                        h[(offset + a, offset + b)] += k * m;
                    }
                }
            }
        }
    }
}

/// The step's minimization problem for [`optimize::minimize`]: dense Hessian (12(m+1) square),
/// dense Cholesky, and the step norm `sqrt(Δzᵀ M_z Δz / mass) / L` (L the largest side of the
/// rest bounding box).
///
/// With held regions the gradient and Hessian are those of the free entries of z only (the
/// prescribed ones eliminated), and steps are zero on the prescribed entries.
impl<M: HyperelasticMaterial> StepTangents for IncrementalPotential<'_, M> {
    fn tangents(&self) -> Vec<HessianTangent> {
        vec![self.tangent]
    }

    fn set_tangents(&mut self, tangents: &[HessianTangent]) {
        self.tangent = tangents[0];
    }
}

impl<M: HyperelasticMaterial> NewtonObjective for IncrementalPotential<'_, M> {
    type Hessian = Mat<f64>;
    type Factor = Llt<f64>;

    fn energy(&self, z: &[f64]) -> f64 {
        IncrementalPotential::energy(self, z)
    }

    fn gradient(&self, z: &[f64]) -> Vec<f64> {
        let gradient = IncrementalPotential::gradient(self, z);
        match self.free {
            None => gradient,
            Some(free) => free.iter().map(|&i| gradient[i]).collect(),
        }
    }

    /// One pass computes F once for both; a gradient already known is recomputed with the
    /// Hessian (bit-identical: `derivatives` and `gradient` sum in the same order).
    fn gradient_and_hessian(&self, z: &[f64], _gradient: Option<Vec<f64>>) -> (Vec<f64>, Mat<f64>) {
        let (gradient, hessian) = self.derivatives(z);
        match self.free {
            None => (gradient, hessian),
            Some(free) => (
                free.iter().map(|&i| gradient[i]).collect(),
                self.free_block(&hessian),
            ),
        }
    }

    fn factor(&self, hessian: Mat<f64>) -> Option<Llt<f64>> {
        hessian.llt(Side::Lower).ok()
    }

    fn solve(&self, factor: &Llt<f64>, gradient: &[f64]) -> Vec<f64> {
        let mut step = Mat::<f64>::from_fn(gradient.len(), 1, |i, _| -gradient[i]);
        // L Lᵀ step = −g, on this thread: at 12(m + 1) ≤ a few hundred unknowns the two
        // triangular solves are a few tens of µs, less than waking the pool (faer's
        // `solve_in_place` takes the global parallelism).
        let l = factor.L();
        triangular_solve::solve_lower_triangular_in_place(l, step.as_mut(), Par::Seq);
        triangular_solve::solve_upper_triangular_in_place(l.transpose(), step.as_mut(), Par::Seq);
        match self.free {
            None => (0..gradient.len()).map(|i| step[(i, 0)]).collect(),
            Some(free) => {
                let mut full = vec![0.0; self.model.deformation_map().layout().len()];
                for (a, &i) in free.iter().enumerate() {
                    full[i] = step[(a, 0)];
                }
                full
            }
        }
    }

    /// The largest α ≤ 1 every term allows ([`crate::StepTerm::max_step`]): a mesh collider
    /// keeps every point within half its band, the barrier keeps points out of contact.
    fn max_step(&self, z: &[f64], step: &[f64]) -> f64 {
        self.terms
            .max_step(&term_point(self.model, z, self.time), step)
    }

    fn directional_derivative(&self, gradient: &[f64], step: &[f64]) -> f64 {
        match self.free {
            None => gradient.iter().zip(step).map(|(g, s)| g * s).sum(),
            Some(free) => free.iter().zip(gradient).map(|(&i, g)| g * step[i]).sum(),
        }
    }

    fn step_norm(&self, dz: &[f64]) -> f64 {
        (mass_inner(self.model, dz, dz).max(0.0) / self.model.total_mass()).sqrt()
            / self.model.bounds().largest_side()
    }
}

/// `aᵀ M_z b` with `M_z = blockdiag(M, M, M)`.
pub(crate) fn mass_inner<M: HyperelasticMaterial>(
    model: &ReducedModel<M>,
    a: &[f64],
    b: &[f64],
) -> f64 {
    let mut mb = vec![0.0; b.len()];
    add_block_diagonal_product(&mut mb, model.mass_block(), b, 1.0);
    a.iter().zip(&mb).map(|(a, y)| a * y).sum()
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use hyperelastic::Tangent;
    use nalgebra::{DMatrix, Vector3};
    use test_support::finite_difference;

    use super::*;
    use crate::contact::collider::{Collider, ColliderShape, Keyframe};
    use crate::model::analytic_field::{analytic_model, probe_z};
    use crate::scene::{Floor, FloorContact, PenaltyParams, PinTarget, PinnedRegion, Scene};
    use nalgebra::UnitQuaternion;

    /// Every term at once: inertia, elasticity, gravity, a moving pin, an active floor, a moving
    /// sphere and a turned box collider, and their friction (lagged at another z, with contacts
    /// both below and beyond the slip threshold).
    fn check_derivatives(tangent: Tangent) {
        let (model, _) = analytic_model();
        let pinned = model.points_where(|x| x.x < 0.3);
        let scene = Scene {
            gravity: Some(Vector3::new(0.0, -9.8, 0.0)),
            pins: vec![PinnedRegion {
                points: pinned,
                target: PinTarget::Moving(Arc::new(|x, t| x + Vector3::new(0.0, 0.1 * t, 0.0))),
            }],
            // The plane y = 0.35 cuts the block, so some points are active.
            floor: Some(Floor {
                normal: Vector3::new(0.0, 1.0, 0.0),
                offset: 0.35,
                friction: 0.6,
            }),
            held: Vec::new(),
            // A moving sphere with friction through the top and a turned box through one end.
            colliders: vec![
                Collider {
                    friction: 0.4,
                    path: vec![
                        Keyframe {
                            time: 0.0,
                            rotation: UnitQuaternion::identity(),
                            translation: Vector3::new(0.9, 0.5, 1.2),
                        },
                        Keyframe {
                            time: 1.0,
                            rotation: UnitQuaternion::identity(),
                            translation: Vector3::new(1.1, 0.5, 1.0),
                        },
                    ],
                    ..Collider::fixed(
                        ColliderShape::Sphere { radius: 0.45 },
                        UnitQuaternion::identity(),
                        Vector3::zeros(),
                    )
                },
                Collider::fixed(
                    ColliderShape::Box {
                        half_extents: Vector3::new(0.25, 0.3, 0.35),
                    },
                    UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.3),
                    Vector3::new(1.95, 0.45, 0.5),
                ),
            ],
        };
        // ε = ε_v h = 1 cm: the slips between the lag and the probe (a few cm) straddle it.
        let penalty = PenaltyParams {
            friction_slip_speed: 1.0,
            ..PenaltyParams::default()
        };
        let terms = SceneTerms::new(&model, &scene, &penalty).unwrap();
        let len = model.deformation_map().layout().len();
        let predicted = probe_z(len, 0.01);
        let potential = IncrementalPotential {
            model: &model,
            terms: &terms,
            time: 0.5,
            inertia: Some(Inertia {
                predicted: &predicted,
                inverse_step_squared: 1e4,
            }),
            tangent: tangent.into(),
            free: None,
            friction: terms.contact_friction(&model, &probe_z(len, -0.02), &predicted, 0.5, 0.01),
            deformation: Default::default(),
        };
        let friction = potential.friction.as_ref().expect("points touch the floor");
        assert!(friction.points().len() > 10);
        let inside_colliders = terms
            .contacts(&term_point(&model, &probe_z(len, 0.03), 0.5))
            .iter()
            .filter(|&&c| c >= model.volumes().len())
            .count();
        assert!(
            inside_colliders > 10,
            "{inside_colliders} points inside the colliders"
        );
        let z = probe_z(len, 0.03);
        let (gradient, hessian) = potential.derivatives(&z);
        let numeric = finite_difference::gradient(|z| potential.energy(z), &z, 1e-7);
        let analytic = DMatrix::from_column_slice(len, 1, &gradient);
        let err = finite_difference::relative_error(
            &analytic,
            &DMatrix::from_column_slice(len, 1, numeric.as_slice()),
            1e-12,
        );
        assert!(
            err < 1e-6,
            "gradient vs finite differences: relative error {err:e}"
        );
        assert_eq!(
            gradient,
            potential.gradient(&z),
            "gradient-only path differs"
        );

        if tangent == Tangent::Exact {
            let numeric = finite_difference::jacobian(|z| potential.gradient(z), &z, 1e-7);
            let analytic = DMatrix::from_fn(len, len, |i, j| hessian[(i, j)]);
            let err = finite_difference::relative_error(&analytic, &numeric, 1e-12);
            assert!(
                err < 1e-6,
                "Hessian vs finite differences: relative error {err:e}"
            );
        }
        let analytic = DMatrix::from_fn(len, len, |i, j| hessian[(i, j)]);
        let asymmetry = (&analytic - analytic.transpose()).norm() / analytic.norm();
        assert!(asymmetry < 1e-14, "Hessian asymmetry {asymmetry:e}");
    }

    #[test]
    fn incremental_potential_gradient_and_exact_hessian_match_finite_differences() {
        check_derivatives(Tangent::Exact);
    }

    #[test]
    fn floor_and_collider_barrier_gradient_and_exact_hessian_match_finite_differences() {
        let (model, _) = analytic_model();
        let len = model.deformation_map().layout().len();
        let (z, lag) = (probe_z(len, 0.01), probe_z(len, -0.005));
        let positions: Vec<Vector3<f64>> = [&z, &lag]
            .iter()
            .flat_map(|z| model.deformation_map().positions(z))
            .collect();
        // A floor 3 cm below the lowest point and a sphere 4 cm above the highest near x = 1,
        // both reaching 15 cm: some points feel them, none touches.
        let lowest = positions.iter().map(|x| x.y).fold(f64::INFINITY, f64::min);
        let center = Vector3::new(1.0, 1.6, 0.5);
        let radius = positions
            .iter()
            .map(|x| (x - center).norm())
            .fold(f64::INFINITY, f64::min)
            - 0.04;
        let scene = Scene {
            gravity: Some(Vector3::new(0.0, -9.8, 0.0)),
            floor: Some(Floor {
                normal: Vector3::new(0.0, 1.0, 0.0),
                offset: lowest - 0.03,
                friction: 0.6,
            }),
            colliders: vec![Collider {
                friction: 0.4,
                ..Collider::fixed(
                    ColliderShape::Sphere { radius },
                    UnitQuaternion::identity(),
                    center,
                )
            }],
            ..Scene::default()
        };
        let penalty = PenaltyParams {
            friction_slip_speed: 1.0,
            floor_contact: FloorContact::Barrier { distance: 0.15 },
            ..PenaltyParams::default()
        };
        let terms = SceneTerms::new(&model, &scene, &penalty).unwrap();
        let predicted = probe_z(len, 0.002);
        let potential = IncrementalPotential {
            model: &model,
            terms: &terms,
            time: 0.0,
            inertia: Some(Inertia {
                predicted: &predicted,
                inverse_step_squared: 1e4,
            }),
            tangent: HessianTangent::Exact,
            free: None,
            friction: terms.contact_friction(&model, &lag, &lag, 0.0, 0.01),
            deformation: Default::default(),
        };
        let n = model.volumes().len();
        let contacts = terms.contacts(&term_point(&model, &z, 0.0));
        let (on_floor, near_sphere) = (
            contacts.iter().filter(|&&c| c < n).count(),
            contacts.iter().filter(|&&c| c >= n).count(),
        );
        assert!(
            on_floor > 10 && near_sphere > 3,
            "{on_floor}, {near_sphere}"
        );
        assert!(potential.friction.is_some());
        assert!(-terms.deepest(&term_point(&model, &z, 0.0)) > 0.0);

        let (gradient, hessian) = potential.derivatives(&z);
        let numeric = finite_difference::gradient(|z| potential.energy(z), &z, 1e-7);
        let err = finite_difference::relative_error(
            &DMatrix::from_column_slice(len, 1, &gradient),
            &DMatrix::from_column_slice(len, 1, numeric.as_slice()),
            1e-12,
        );
        assert!(err < 1e-6, "gradient: relative error {err:e}");
        let numeric = finite_difference::jacobian(|z| potential.gradient(z), &z, 1e-7);
        let analytic = DMatrix::from_fn(len, len, |i, j| hessian[(i, j)]);
        let err = finite_difference::relative_error(&analytic, &numeric, 1e-12);
        assert!(err < 1e-6, "Hessian: relative error {err:e}");

        // Past the floor the barrier is infinite, and the safe step stops short of it.
        let layout = model.deformation_map().layout();
        let down = layout.rigid_motion(&nalgebra::Matrix3::identity(), &-Vector3::y());
        let alpha = potential.max_step(&z, &down);
        let at = |a: f64| -> Vec<f64> { z.iter().zip(&down).map(|(z, d)| z + a * d).collect() };
        let floor_gap = model
            .deformation_map()
            .positions(&z)
            .iter()
            .map(|x| x.y)
            .fold(f64::INFINITY, f64::min)
            - (lowest - 0.03);
        assert!(
            alpha > 0.0 && alpha <= 0.9 * floor_gap * (1.0 + 1e-12),
            "safe step {alpha} for a gap of {floor_gap} m"
        );
        assert!(-terms.deepest(&term_point(&model, &at(alpha), 0.0)) > 0.0);
        assert!(potential.energy(&at(alpha)).is_finite());
        assert_eq!(potential.energy(&at(1.01 * floor_gap)), f64::INFINITY);
    }

    #[test]
    fn exact_first_tangents_take_the_exact_hessian_where_it_factors_and_their_fallback_elsewhere() {
        let (model, _) = analytic_model();
        let scene = Scene {
            gravity: Some(Vector3::new(0.0, -9.8, 0.0)),
            ..Scene::default()
        };
        let terms = SceneTerms::new(&model, &scene, &PenaltyParams::default()).unwrap();
        let len = model.deformation_map().layout().len();
        let predicted = vec![0.0; len];
        let potential = |tangent: HessianTangent, inverse_step_squared: f64| IncrementalPotential {
            model: &model,
            terms: &terms,
            time: 0.0,
            inertia: Some(Inertia {
                predicted: &predicted,
                inverse_step_squared,
            }),
            tangent,
            free: None,
            friction: None,
            deformation: Default::default(),
        };
        let hessian = |tangent, k, z: &[f64]| potential(tangent, k).derivatives(z).1;
        let definite = |h: &Mat<f64>| h.llt(Side::Lower).is_ok();
        // Small strain and a short step: the exact system is definite and is kept.
        let z = probe_z(len, 0.03);
        let exact = hessian(HessianTangent::Exact, 1e4, &z);
        assert!(definite(&exact));
        assert_eq!(hessian(HessianTangent::ExactWhenDefinite, 1e4, &z), exact);
        assert_eq!(hessian(HessianTangent::ExactElseAbsolute, 1e4, &z), exact);
        assert_ne!(hessian(HessianTangent::ProjectedPsd, 1e4, &z), exact);
        // Inverted points and almost no inertia: the exact system is indefinite, so the
        // fallback is taken: the projected one, or the absolute-eigenvalue one (which differs).
        let z = probe_z(len, 0.8);
        let exact = hessian(HessianTangent::Exact, 1e-6, &z);
        assert!(!definite(&exact));
        let projected = hessian(HessianTangent::ProjectedPsd, 1e-6, &z);
        assert_eq!(
            hessian(HessianTangent::ExactWhenDefinite, 1e-6, &z),
            projected
        );
        let absolute = hessian(HessianTangent::AbsoluteEigenvalues, 1e-6, &z);
        assert_ne!(absolute, projected);
        assert_eq!(
            hessian(HessianTangent::ExactElseAbsolute, 1e-6, &z),
            absolute
        );
    }

    #[test]
    fn projected_hessian_is_positive_semidefinite_and_symmetric() {
        check_derivatives(Tangent::ProjectedPsd);
        let (model, _) = analytic_model();
        let len = model.deformation_map().layout().len();
        // A large z inverts some points, where the exact tangent is indefinite.
        let z = probe_z(len, 0.8);
        let h = model.elastic_hessian(&z, Tangent::ProjectedPsd);
        let dense = DMatrix::from_fn(len, len, |i, j| h[(i, j)]);
        let eigen = dense.symmetric_eigenvalues();
        let (min, max) = (eigen.min(), eigen.max());
        assert!(
            min > -1e-10 * max,
            "projected Hessian has eigenvalue {min:e} (max {max:e})"
        );
    }
}
