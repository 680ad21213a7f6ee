//! The time stepper: a model, a scene, and the reduced state advanced by backward Euler
//! (design §3.7, paper Eqs. 1-2).

use faer::linalg::solvers::Llt;
use hyperelastic::HyperelasticMaterial;
use nalgebra::Vector3;
use optimize::{
    CarriedFactor, HessianReuse, NewtonError, NewtonObjective, NewtonParams, NewtonReport,
    minimize, minimize_reusing,
};
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::model::reduced_model::ReducedModel;
use crate::scene::{PenaltyParams, Scene};
use crate::scene_error::SceneError;
use crate::step::hessian_tangent::{HessianTangent, StepTangents};
use crate::step::incremental_potential::{IncrementalPotential, Inertia};
use crate::terms::friction_term::ContactFriction;
use crate::terms::scene_terms::{SceneTerms, term_point};
use crate::terms::step_term::StepTerm;

/// Minimizes `objective` from z (updated in place), carrying `factor` across when `newton`
/// reuses Hessians. A solve that does not converge with the library's shortcuts (Hessian reuse,
/// or the exact tangent where definite) is solved again from the same start in the paper's
/// setting, fresh Hessians with the tangent projected at every point (with the
/// absolute-eigenvalue tangent for [`HessianTangent::ExactElseAbsolute`]: each tangent's
/// [`HessianTangent::fallback`]), so the shortcuts are never less robust than it (the report
/// counts both attempts): chord steps can spend the iteration budget Newton needs, and an
/// exact Hessian can be definite yet a poor model far from the solution. One object's step ([`Simulator::step`]) and a group's
/// ([`crate::MultiBodySimulator`]) both solve this way.
///
/// # Errors
/// [`StepError::Newton`]; z is then Newton's last iterate.
pub(crate) fn solve_step<O>(
    objective: &mut O,
    z: &mut Vec<f64>,
    newton: &NewtonParams,
    factor: &mut Option<Llt<f64>>,
) -> Result<NewtonReport, StepError>
where
    O: NewtonObjective<Factor = Llt<f64>> + StepTangents,
{
    let reuse = newton.hessian_reuse != HessianReuse::Never;
    let tangents = objective.tangents();
    let exact_first = tangents.iter().any(|t| t.fallback().is_some());
    if !reuse && !exact_first {
        return Ok(minimize(&*objective, z, newton)?);
    }
    let start = z.clone();
    let first = if reuse {
        minimize_reusing(&*objective, z, newton, factor)?
    } else {
        minimize(&*objective, z, newton)?
    };
    if first.converged() {
        return Ok(first);
    }
    z.clone_from(&start);
    *factor = None;
    let paper = NewtonParams {
        hessian_reuse: HessianReuse::Never,
        ..*newton
    };
    let fallbacks: Vec<HessianTangent> = tangents
        .iter()
        .map(|&t| t.fallback().map_or(t, HessianTangent::from))
        .collect();
    objective.set_tangents(&fallbacks);
    let retried = minimize_reusing(&*objective, z, &paper, factor);
    objective.set_tangents(&tangents);
    Ok(first.followed_by(&retried?))
}

/// Options of a simulation.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SimulationParams {
    /// Time step h (s, default 0.01).
    pub time_step: f64,
    /// Newton options (the workspace's one solver, [`optimize::minimize`]). The default
    /// carries the Hessian factorization across steps while chord steps contract by 0.7
    /// ([`SimulationParams::HESSIAN_REUSE`]); [`SimulationParams::paper_setting`] assembles a
    /// fresh Hessian every iteration.
    pub newton: NewtonParams,
    /// Material tangent in the Hessian (default [`HessianTangent::ExactWhenDefinite`]: exact
    /// wherever the step's system factors, projected elsewhere, which on the beam Twist halves
    /// the Hessians at the same MSE; [`SimulationParams::paper_setting`] projects every point,
    /// which keeps every system positive definite; `Exact` is only safe while it stays so, and
    /// a failed factorization is then reported).
    pub tangent: HessianTangent,
    /// Penalty stiffness rules for pins and floor.
    pub penalty: PenaltyParams,
    /// With Hessian reuse ([`optimize::HessianReuse::WhileContracting`] in `newton`): the
    /// most steps one factorization is carried across (default 50). The factorization is also
    /// dropped when the set of points in contact with the floor changes between steps (the
    /// floor's Hessian term changes there), and after [`Simulator::set_state`].
    #[serde(default = "default_hessian_max_age")]
    pub hessian_max_age: usize,
}

fn default_hessian_max_age() -> usize {
    SimulationParams::default().hessian_max_age
}

impl SimulationParams {
    /// The default Hessian reuse: chord steps with the carried factorization while each is at
    /// most 0.7 of the previous one; a fresh Hessian otherwise. Chosen on the beam against the
    /// converged FEM (`results/RESULTS.md`, "Hessian reuse").
    pub const HESSIAN_REUSE: HessianReuse = HessianReuse::WhileContracting { contraction: 0.7 };

    /// The paper's setting: the defaults with a fresh Hessian every Newton iteration and the
    /// material tangent projected at every point.
    pub fn paper_setting() -> Self {
        SimulationParams {
            newton: NewtonParams {
                hessian_reuse: HessianReuse::Never,
                ..NewtonParams::default()
            },
            tangent: HessianTangent::ProjectedPsd,
            ..SimulationParams::default()
        }
    }
}

impl Default for SimulationParams {
    fn default() -> Self {
        SimulationParams {
            time_step: 0.01,
            newton: NewtonParams {
                hessian_reuse: SimulationParams::HESSIAN_REUSE,
                ..NewtonParams::default()
            },
            tangent: HessianTangent::ExactWhenDefinite,
            penalty: PenaltyParams::default(),
            hessian_max_age: 50,
        }
    }
}

/// A step failed; the simulator's state is left as it was before the step.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum StepError {
    /// The Newton solve hit a non-finite value or a Hessian it could not factor.
    #[error(transparent)]
    Newton(#[from] NewtonError),
    /// The time step is not finite and positive.
    #[error("the time step must be finite and positive, got {0} s")]
    InvalidTimeStep(f64),
    /// With the floor's barrier ([`crate::FloorContact::Barrier`]) a point is already on or
    /// past the floor or a collider, where the barrier is infinite: the step cannot start.
    #[error(
        "a point is {depth} m into the floor or a collider at t = {time} s; the barrier cannot start from there (start the object clear of them)"
    )]
    StartsInContact {
        /// How deep the deepest point is (m, ≥ 0).
        depth: f64,
        /// The state's time (s).
        time: f64,
    },
}

/// The reduced state: coordinates z, velocities ż (both length 12(m + 1), see
/// [`crate::ReducedLayout`]) and time t (s).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReducedState {
    /// z.
    pub z: Vec<f64>,
    /// ż (1/s).
    pub velocity: Vec<f64>,
    /// t (s).
    pub time: f64,
}

/// A state of the wrong size or with non-finite entries was given.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum StateError {
    /// z or ż has the wrong length.
    #[error("the state has z of length {z} and ż of length {velocity}, expected {expected}")]
    WrongLength {
        /// Length of z.
        z: usize,
        /// Length of ż.
        velocity: usize,
        /// 12(m + 1).
        expected: usize,
    },
    /// A NaN or infinity in the state or its time.
    #[error("the state contains a non-finite value")]
    NonFinite,
}

/// Backward-Euler simulation of a [`ReducedModel`] in a [`Scene`].
pub struct Simulator<M: HyperelasticMaterial> {
    model: ReducedModel<M>,
    terms: SceneTerms,
    params: SimulationParams,
    state: ReducedState,
    /// The last step's Hessian factorization and its age, kept for the next step when
    /// `params.newton.hessian_reuse` allows it.
    carried: Option<CarriedFactor<Llt<f64>>>,
    /// The points in contact with the floor at the current state.
    contacts: Vec<usize>,
    /// Whether the last step changed `contacts` (a carried Hessian is then dropped).
    contacts_changed: bool,
}

impl<M: HyperelasticMaterial> Simulator<M> {
    /// A simulator at rest (z = 0, ż = 0, t = 0).
    ///
    /// # Errors
    /// [`SceneError`] when the scene does not fit the model (pin indices, non-finite gravity or
    /// floor, invalid penalty factors).
    pub fn new(
        model: ReducedModel<M>,
        scene: &Scene,
        params: SimulationParams,
    ) -> Result<Self, SceneError> {
        let terms = SceneTerms::new(&model, scene, &params.penalty)?;
        let layout = model.deformation_map().layout();
        Ok(Simulator {
            model,
            terms,
            params,
            state: ReducedState {
                z: layout.rest(),
                velocity: layout.rest(),
                time: 0.0,
            },
            carried: None,
            contacts: Vec::new(),
            contacts_changed: false,
        })
    }

    /// The model.
    pub fn model(&self) -> &ReducedModel<M> {
        &self.model
    }

    /// The options.
    pub fn params(&self) -> &SimulationParams {
        &self.params
    }

    /// The current state.
    pub fn state(&self) -> &ReducedState {
        &self.state
    }

    /// With held regions ([`crate::Scene::held`]): the entries of z Newton solves
    /// for (ascending); `None` when all are free.
    pub fn free_coordinates(&self) -> Option<&[usize]> {
        self.terms.free_coordinates()
    }

    /// With held regions: sets the held handles' entries of `z` (length 12(m + 1)) to the
    /// regions' transforms at time `time` (s); does nothing with penalty pins.
    pub fn prescribe(&self, z: &mut [f64], time: f64) {
        self.terms.prescribe(z, time);
    }

    /// The pin penalty stiffness κ_pin in use (Pa/m², see [`PenaltyParams`]).
    pub fn pin_stiffness(&self) -> f64 {
        self.terms.pin_stiffness()
    }

    /// Adds `term` to every step's incremental potential, after the scene's own terms (a
    /// spring, a muscle, a magnetic force: see [`StepTerm`], and check it with
    /// [`crate::check_term`] first). A carried Hessian factorization is dropped.
    pub fn add_term(&mut self, term: Box<dyn StepTerm>) {
        self.terms.add_term(term);
        self.carried = None;
    }

    /// The current state as a term point.
    fn now(&self) -> crate::TermPoint<'_> {
        term_point(&self.model, &self.state.z, self.state.time)
    }

    /// How far the pinned and held points are from their targets now: the largest distance (m),
    /// or `None` without pins. The penalty lets them deviate; this is the number to watch when
    /// choosing [`PenaltyParams::pin_factor`].
    pub fn max_pin_deviation(&self) -> Option<f64> {
        self.terms.max_pin_deviation(&self.now(), false)
    }

    /// How far the exactly held points ([`crate::Scene::held`]) are from their targets now: the
    /// largest distance (m), or `None` without held regions. Zero up to round-off and the fit of
    /// an affine transform to targets that are not an affine motion.
    pub fn max_held_deviation(&self) -> Option<f64> {
        // Without held regions, skip evaluating every pin's targets (callers ask every step).
        self.terms.max_pin_deviation(&self.now(), true)
    }

    /// The deepest penetration (m) of an integration point into the floor or a collider at
    /// the current state (0 without contact): how far the penalty lets the object in.
    pub fn max_penetration(&self) -> f64 {
        self.terms.deepest(&self.now()).max(0.0)
    }

    /// The mechanical energy now (J): kinetic `½ żᵀ M_z ż`, elastic, and the scene's potentials
    /// (gravity relative to the rest state, the pin, floor and collider penalties). Without
    /// friction, moving pins or colliders it can only fall over a step (backward Euler
    /// dissipates); a rise is energy put in by them, or a solve that went wrong.
    pub fn mechanical_energy(&self) -> f64 {
        let (z, velocity) = (&self.state.z, &self.state.velocity);
        let kinetic =
            0.5 * crate::step::incremental_potential::mass_inner(&self.model, velocity, velocity);
        kinetic + self.model.elastic_energy(z) + self.terms.energy(&self.now())
    }

    /// Integrates the elastic energy by `quadrature` from the next step on
    /// ([`ReducedModel::set_elastic_quadrature`]), e.g. a cubature trained while the first steps
    /// ran on every point; a carried Hessian factorization is dropped.
    ///
    /// # Errors
    /// As [`ReducedModel::set_elastic_quadrature`]; the simulator is unchanged then.
    pub fn set_elastic_quadrature(
        &mut self,
        quadrature: crate::ElasticQuadrature,
    ) -> Result<(), crate::QuadratureError> {
        self.model.set_elastic_quadrature(quadrature)?;
        self.carried = None;
        Ok(())
    }

    /// Replaces the state (e.g. to start with an initial velocity).
    ///
    /// # Errors
    /// [`StateError`] for a wrong length or non-finite entries.
    pub fn set_state(&mut self, state: ReducedState) -> Result<(), StateError> {
        let expected = self.model.deformation_map().layout().len();
        if state.z.len() != expected || state.velocity.len() != expected {
            return Err(StateError::WrongLength {
                z: state.z.len(),
                velocity: state.velocity.len(),
                expected,
            });
        }
        let finite = state.z.iter().chain(&state.velocity).all(|v| v.is_finite());
        if !finite || !state.time.is_finite() {
            return Err(StateError::NonFinite);
        }
        self.contacts = self
            .terms
            .contacts(&term_point(&self.model, &state.z, state.time));
        self.state = state;
        self.carried = None;
        Ok(())
    }

    /// Advances one step of h: minimizes the incremental potential from `ẑ = z_t + h ż_t`,
    /// then `ż_{t+h} = (z_{t+h} - z_t)/h`. A step that does not converge still advances (to
    /// Newton's last iterate) and says so in its report. With
    /// [`optimize::HessianReuse::WhileContracting`] in `params.newton`, the last step's Hessian
    /// factorization is carried into this one (chord steps while they contract), for at most
    /// [`SimulationParams::hessian_max_age`] steps and while the floor contacts stay the same;
    /// a step that does not converge that way is solved again with fresh Hessians (its report
    /// counts both attempts). Where the energy is not finite at `ẑ` (the prediction inverts a
    /// point of the projected dilatation), Newton starts part of the way from `z_t` towards it,
    /// where the energy is finite.
    ///
    /// # Errors
    /// [`StepError`] on a non-finite value or a singular system; the state is then unchanged.
    pub fn step(&mut self) -> Result<NewtonReport, StepError> {
        let h = self.params.time_step;
        if !(h > 0.0 && h.is_finite()) {
            return Err(StepError::InvalidTimeStep(h));
        }
        let (mut factor, age) =
            CarriedFactor::usable(self.carried.take(), self.params.hessian_max_age);
        self.check_clear()?;
        let predicted = self.predicted_coordinates();
        let mut potential = self.step_potential(&predicted);
        let mut z = predicted.clone();
        if self.terms.has_barrier() {
            // From the start of the step towards the prediction, as far as the barrier's safe
            // step allows: the prediction itself may lie past the floor.
            let start = &self.state.z;
            let towards: Vec<f64> = z.iter().zip(start).map(|(p, s)| p - s).collect();
            let alpha = potential.max_step(start, &towards).min(1.0);
            for ((z, s), t) in z.iter_mut().zip(start).zip(&towards) {
                *z = s + alpha * t;
            }
        }
        self.terms.prescribe(&mut z, potential.time);
        let newton = &self.params.newton;
        let mut report = match solve_step(&mut potential, &mut z, newton, &mut factor) {
            // Newton refused its start (z unmoved, the carried factor dropped): start again
            // where the energy is finite.
            Err(StepError::Newton(NewtonError::NonFinite {
                iteration: 0,
                quantity: "energy",
            })) => {
                z = self.finite_start(&potential, &z);
                solve_step(&mut potential, &mut z, newton, &mut factor)?
            }
            solved => solved?,
        };
        // Friction lagging (IPC): the floor's contacts and normal forces taken again from the
        // solution, the slip still measured from the start of the step, and solved again from
        // there, `friction_lag_iterations` times at most, and only while the lagged forces
        // move (the same contacts and normals, limits within 1%, end it).
        for _ in 0..self.params.penalty.friction_lag_iterations {
            let Some(friction) = self.friction_lagged_at(&z) else {
                break;
            };
            if !friction.moved_from(potential.friction.as_ref()) {
                break;
            }
            potential.friction = Some(friction);
            let again = solve_step(&mut potential, &mut z, &self.params.newton, &mut factor)?;
            report = report.followed_by(&again);
        }
        drop(potential);
        self.finish_step(z, CarriedFactor::after(factor, age, &report));
        Ok(report)
    }

    /// Where a step's Newton solve starts when `potential` is not finite at `prediction`: the
    /// inertial prediction can invert a point, where the projected dilatation's energy is +∞,
    /// while the step's solution does not. The first of `z_t + α (ẑ − z_t)`, α = 1/2, 1/4, …,
    /// 2⁻¹⁰, 0, with a finite energy (held entries prescribed at the end of the step);
    /// `prediction` when none is (Newton then stops with its error).
    fn finite_start(
        &self,
        potential: &IncrementalPotential<'_, M>,
        prediction: &[f64],
    ) -> Vec<f64> {
        let last = &self.state.z;
        let fractions = (1..=10).map(|k| 0.5f64.powi(k)).chain([0.0]);
        for alpha in fractions {
            let mut start: Vec<f64> = last
                .iter()
                .zip(prediction)
                .map(|(s, p)| s + alpha * (p - s))
                .collect();
            self.terms.prescribe(&mut start, potential.time);
            if potential.energy(&start).is_finite() {
                return start;
            }
        }
        prediction.to_vec()
    }

    /// The floor's and colliders' friction over the next step lagged at its solution `z`
    /// (what [`Simulator::step`] re-lags with; `None` without friction or contact there).
    pub(crate) fn friction_lagged_at(&self, z: &[f64]) -> Option<ContactFriction> {
        self.terms.contact_friction(
            &self.model,
            &self.state.z,
            z,
            self.state.time,
            self.params.time_step,
        )
    }

    /// With the floor's barrier: an error when a point of the current state is on or past the
    /// floor or a collider (the barrier is infinite there); `Ok` otherwise.
    pub(crate) fn check_clear(&self) -> Result<(), StepError> {
        if !self.terms.has_barrier() {
            return Ok(());
        }
        let gap = -self.terms.deepest(&self.now());
        if gap > 0.0 {
            Ok(())
        } else {
            Err(StepError::StartsInContact {
                depth: -gap,
                time: self.state.time,
            })
        }
    }

    /// Whether the last step changed the points in contact with the floor and the colliders
    /// (their Hessian terms changed there, so a carried Hessian is dropped).
    pub(crate) fn contacts_changed(&self) -> bool {
        self.contacts_changed
    }

    /// Ends a step whose z was solved elsewhere (objects in contact are solved together by
    /// [`crate::MultiBodySimulator`]): z becomes the state at t + h with `ż = (z − z_t)/h`; the
    /// carried Hessian factorization is dropped.
    pub(crate) fn commit_step(&mut self, z: Vec<f64>) {
        self.finish_step(z, None);
    }

    /// z becomes the state at t + h with `ż = (z − z_t)/h`; `carried` is carried into the next
    /// step while the contact set stays the same.
    fn finish_step(&mut self, z: Vec<f64>, carried: Option<CarriedFactor<Llt<f64>>>) {
        let h = self.params.time_step;
        let time = self.state.time + h;
        let contacts = self.terms.contacts(&term_point(&self.model, &z, time));
        self.contacts_changed = contacts != self.contacts;
        self.carried = carried.filter(|_| !self.contacts_changed);
        self.contacts = contacts;
        let velocity = z
            .iter()
            .zip(&self.state.z)
            .map(|(a, b)| (a - b) / h)
            .collect();
        self.state = ReducedState { z, velocity, time };
    }

    /// The linear momentum `Σ_i ρ_i v_i ẋ_i` (kg·m/s) of the integration points at the
    /// current velocity (`ẋ_i = B_i ż`).
    pub fn linear_momentum(&self) -> Vector3<f64> {
        let velocities = self
            .model
            .deformation_map()
            .displacements(&self.state.velocity);
        velocities
            .iter()
            .zip(self.model.densities())
            .zip(self.model.volumes())
            .map(|((v, rho), vol)| v * (rho * vol))
            .sum()
    }

    /// The inertial prediction `ẑ = z_t + h ż_t` of the next step (length 12(m + 1)).
    pub fn predicted_coordinates(&self) -> Vec<f64> {
        let h = self.params.time_step;
        self.state
            .z
            .iter()
            .zip(&self.state.velocity)
            .map(|(z, v)| z + h * v)
            .collect()
    }

    /// The incremental potential E(z) that [`Simulator::step`] minimizes next: inertia about
    /// `predicted` (normally [`Simulator::predicted_coordinates`]), elasticity, and the scene's
    /// terms at t + h. With held regions ([`crate::Scene::held`]) its
    /// [`optimize::NewtonObjective`] gradient and Hessian are over the free entries of z only
    /// ([`Simulator::free_coordinates`]); [`Simulator::prescribe`] sets the others.
    pub fn step_potential<'a>(&'a self, predicted: &'a [f64]) -> IncrementalPotential<'a, M> {
        let h = self.params.time_step;
        IncrementalPotential {
            model: &self.model,
            terms: &self.terms,
            time: self.state.time + h,
            inertia: Some(Inertia {
                predicted,
                inverse_step_squared: 1.0 / (h * h),
            }),
            tangent: self.params.tangent,
            free: self.terms.free_coordinates(),
            friction: self.terms.contact_friction(
                &self.model,
                &self.state.z,
                &self.state.z,
                self.state.time,
                h,
            ),
            deformation: Default::default(),
        }
    }

    /// Static equilibrium under the scene's loads and pin targets at `time` (s): minimizes the
    /// potential without the inertia term from the current z, then sets ż = 0 and t = `time`.
    /// The scene must remove the rigid motions (pins, or a floor with gravity), otherwise the
    /// system is singular.
    ///
    /// # Errors
    /// [`StepError`]; the state is then unchanged.
    pub fn solve_static(&mut self, time: f64) -> Result<NewtonReport, StepError> {
        let potential = IncrementalPotential {
            model: &self.model,
            terms: &self.terms,
            time,
            inertia: None,
            tangent: self.params.tangent,
            free: self.terms.free_coordinates(),
            friction: None,
            deformation: Default::default(),
        };
        let mut z = self.state.z.clone();
        self.terms.prescribe(&mut z, time);
        let report = minimize(&potential, &mut z, &self.params.newton)?;
        let layout = self.model.deformation_map().layout();
        self.carried = None;
        self.contacts = self.terms.contacts(&term_point(&self.model, &z, time));
        self.state = ReducedState {
            z,
            velocity: layout.rest(),
            time,
        };
        Ok(report)
    }
}
