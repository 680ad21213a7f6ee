//! Several objects in one scene: each a [`Simulator`] of its own model and scene
//! (floor, colliders, pins, gravity), coupled by contact between their surface samples
//! ([`crate::body_contact`]).
//!
//! A step finds the sample pairs of different objects that may touch during the step (those
//! whose inertial motions over the step bring them within 1.5 d̂, searched in a k-d tree per
//! object), and splits the objects into contact-connected groups. The objects alone are
//! stepped side by side on several threads, each by its own simulator, exactly as without the
//! others (Hessian reuse and friction lagging included). A group is solved as one
//! backward-Euler problem over its objects' reduced coordinates side by side,
//!
//! ```text
//! E(z_1, …, z_k) = Σ_o E_o(z_o) + Σ_pairs e(‖x_a(z_o) − x_b(z_p)‖) + D_pairs,
//! ```
//!
//! E_o each object's incremental potential, e the pair repulsion and D the lagged friction
//! between objects; its Hessian has each object's dense block on the diagonal and the contact
//! coupling off it, factored together (with the objects' Hessian reuse rule within the step,
//! never across steps). After the solve, any
//! pair closer than d̂ that was not a candidate makes the step solved again with it.

use std::collections::{HashMap, HashSet};
use std::ops::Range;
use std::time::Instant;

use faer::linalg::solvers::{Llt, Solve};
use faer::{Mat, Side};
use hyperelastic::HyperelasticMaterial;
use nalgebra::{Matrix3, Vector3};
use optimize::{CarriedFactor, NewtonObjective, NewtonReport};
use rayon::prelude::*;
use rkpm_core::SpatialIndex;
use thiserror::Error;

use crate::body_contact::{
    BodyContactModel, BodyContactParams, LaggedPair, PairFriction, RelativeDerivatives, SamplePair,
    add_cross_hessians, lagged_friction, repulsion_derivatives,
};
use crate::contact_friction::{LAG_TOLERANCE, same_lagged_forces};
use crate::deformation_map::DeformationMap;
use crate::hessian_tangent::{HessianTangent, StepTangents};
use crate::incremental_potential::IncrementalPotential;
use crate::simulator::{ReducedState, Simulator, StateError, StepError, solve_step};

/// One object of a [`MultiBodySimulator`]: its simulator and its contact samples.
pub struct Body<M: HyperelasticMaterial> {
    simulator: Simulator<M>,
    samples: DeformationMap,
}

impl<M: HyperelasticMaterial> Body<M> {
    /// An object stepped by `simulator`, touching others at `samples`: its deformation map at
    /// points on its surface, spaced about [`BodyContactParams::radius`] apart (built with the
    /// same basis as the model, e.g. `DeformationMap::new(&basis, &surface_points)`).
    ///
    /// # Errors
    /// [`MultiBodyError::NoSamples`] or [`MultiBodyError::SampleLayout`] (reported for object 0;
    /// [`MultiBodySimulator::new`] renumbers).
    pub fn new(simulator: Simulator<M>, samples: DeformationMap) -> Result<Self, MultiBodyError> {
        let model = simulator.model().deformation_map().layout().handles();
        if samples.is_empty() {
            return Err(MultiBodyError::NoSamples { body: 0 });
        }
        if samples.layout().handles() != model {
            return Err(MultiBodyError::SampleLayout {
                body: 0,
                samples: samples.layout().handles(),
                model,
            });
        }
        Ok(Body { simulator, samples })
    }

    /// Its simulator.
    pub fn simulator(&self) -> &Simulator<M> {
        &self.simulator
    }

    /// Its contact samples.
    pub fn contact_samples(&self) -> &DeformationMap {
        &self.samples
    }

    /// Where its contact samples are now (m).
    pub fn sample_positions(&self) -> Vec<Vector3<f64>> {
        self.samples.positions(&self.simulator.state().z)
    }
}

/// The objects do not make a scene.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum MultiBodyError {
    /// No objects were given.
    #[error("a scene needs at least one object")]
    Empty,
    /// An object has no contact samples.
    #[error("object {body} has no contact samples")]
    NoSamples {
        /// The object.
        body: usize,
    },
    /// An object's contact samples were mapped with another basis than its model.
    #[error(
        "object {body}: its contact samples were mapped with {samples} handles, its model has {model}"
    )]
    SampleLayout {
        /// The object.
        body: usize,
        /// Handles of the samples' map.
        samples: usize,
        /// Handles of the model.
        model: usize,
    },
    /// The objects do not share one time step.
    #[error(
        "object {body} steps by {time_step} s but object 0 by {first} s; all objects share one time step"
    )]
    TimeStep {
        /// The object.
        body: usize,
        /// Its time step (s).
        time_step: f64,
        /// Object 0's (s).
        first: f64,
    },
    /// The contact options are invalid.
    #[error("contact between objects: invalid {0}")]
    Contact(String),
}

/// A step failed; every object's state is left as it was before the step.
#[derive(Clone, Debug, Error, PartialEq)]
#[error("object {body}: {source}")]
pub struct MultiBodyStepError {
    /// The object whose solve failed (the first of its group).
    pub body: usize,
    /// Why.
    #[source]
    pub source: StepError,
}

/// What one step of a [`MultiBodySimulator`] did.
#[derive(Clone, Debug, PartialEq)]
pub struct MultiBodyReport {
    /// Each object's Newton solve (objects solved together carry their group's report).
    pub bodies: Vec<NewtonReport>,
    /// Every solve of the step once: one per object alone, one per group.
    pub solves: Vec<NewtonReport>,
    /// Groups of two or more objects solved together.
    pub joint_groups: usize,
    /// Candidate sample pairs between objects.
    pub candidate_pairs: usize,
    /// Sample pairs closer than d̂ at the end of the step.
    pub active_pairs: usize,
    /// Seconds spent finding pairs and groups (before and after the solves).
    pub contact_search_seconds: f64,
    /// Times the step was solved again because a pair that was not a candidate came within d̂.
    pub resolves: usize,
}

impl MultiBodyReport {
    /// Whether every object's solve converged.
    pub fn converged(&self) -> bool {
        self.bodies.iter().all(NewtonReport::converged)
    }
}

/// Backward-Euler simulation of several objects that touch one another.
pub struct MultiBodySimulator<M: HyperelasticMaterial> {
    bodies: Vec<Body<M>>,
    contact: BodyContactParams,
    /// The largest `d̂ − n·p` of a contact pair at the end of the last step (m; 0 without
    /// contact).
    overlap: f64,
    /// The sample pairs of different objects closer than d̂ in the current state, with their
    /// distance (m): found once per step (and after [`MultiBodySimulator::set_state`]) for the
    /// step's check, [`MultiBodySimulator::contact_gap`] and the contact energy.
    touching: Vec<(SamplePair, f64)>,
    /// With Hessian reuse: each contact group's last factorization (keyed by its objects) and
    /// the steps since it was assembled, carried into the group's next step as an object alone
    /// carries its own (chord steps while they contract; a solve that does not converge that
    /// way is solved again fresh). Dropped for groups not solved in a step and on a restore.
    group_factors: HashMap<Vec<usize>, CarriedFactor<Llt<f64>>>,
}

impl<M: HyperelasticMaterial> MultiBodySimulator<M> {
    /// The objects, each at its simulator's state, with contact `contact` between them.
    ///
    /// # Errors
    /// [`MultiBodyError`]: no objects, different time steps, held regions, invalid contact
    /// options, samples of the wrong basis.
    pub fn new(bodies: Vec<Body<M>>, contact: BodyContactParams) -> Result<Self, MultiBodyError> {
        let first = bodies.first().ok_or(MultiBodyError::Empty)?;
        let h = first.simulator.params().time_step;
        for (body, b) in bodies.iter().enumerate() {
            let time_step = b.simulator.params().time_step;
            if time_step != h {
                return Err(MultiBodyError::TimeStep {
                    body,
                    time_step,
                    first: h,
                });
            }
        }
        if let Some(why) = contact.defect() {
            return Err(MultiBodyError::Contact(why));
        }
        let mut simulator = MultiBodySimulator {
            bodies,
            contact,
            overlap: 0.0,
            touching: Vec::new(),
            group_factors: HashMap::new(),
        };
        simulator.touching = simulator.touching_pairs(&simulator.sample_positions());
        Ok(simulator)
    }

    /// Every object's contact samples where they are now (m).
    fn sample_positions(&self) -> Vec<Vec<Vector3<f64>>> {
        self.bodies.iter().map(Body::sample_positions).collect()
    }

    /// The sample pairs of different objects closer than d̂ at `positions`, with their
    /// distance (m).
    fn touching_pairs(&self, positions: &[Vec<Vector3<f64>>]) -> Vec<(SamplePair, f64)> {
        self.pairs_within(positions, None, self.contact.radius)
            .into_iter()
            .map(|p| {
                (
                    p,
                    (positions[p.a.0][p.a.1] - positions[p.b.0][p.b.1]).norm(),
                )
            })
            .collect()
    }

    /// The objects.
    pub fn bodies(&self) -> &[Body<M>] {
        &self.bodies
    }

    /// The contact options.
    pub fn contact(&self) -> &BodyContactParams {
        &self.contact
    }

    /// Simulated time (s).
    pub fn time(&self) -> f64 {
        self.bodies[0].simulator.state().time
    }

    /// Replaces object `body`'s state (e.g. its initial pose and velocity).
    ///
    /// # Errors
    /// [`StateError`] for a wrong length or non-finite entries.
    ///
    /// # Panics
    /// If `body` is out of range.
    pub fn set_state(&mut self, body: usize, state: ReducedState) -> Result<(), StateError> {
        self.bodies[body].simulator.set_state(state)?;
        self.touching = self.touching_pairs(&self.sample_positions());
        Ok(())
    }

    /// The total linear momentum `Σ_objects Σ_i ρ_i v_i ẋ_i` (kg·m/s).
    pub fn linear_momentum(&self) -> Vector3<f64> {
        self.bodies
            .iter()
            .map(|b| b.simulator.linear_momentum())
            .sum()
    }

    /// The mechanical energy now (J): every object's ([`Simulator::mechanical_energy`]) and the
    /// repulsion of their samples closer than d̂ (at their distance `‖p‖`).
    pub fn mechanical_energy(&self) -> f64 {
        let v = self.contact.sample_volume();
        let contact: f64 = self
            .touching
            .iter()
            .map(|&(p, d)| {
                let psi = self
                    .contact
                    .profile(d)
                    .map_or(f64::INFINITY, |(psi, _, _)| psi);
                self.pair_stiffness(p.a.0, p.b.0) * v * psi
            })
            .sum();
        let own: f64 = self
            .bodies
            .iter()
            .map(|b| b.simulator.mechanical_energy())
            .sum();
        own + contact
    }

    /// κ of a pair of objects: `stiffness_factor · max(E_a, E_b) / min(L_a, L_b)²` (Pa/m²; E
    /// the largest p-wave modulus, L the largest rest bounding-box side).
    fn pair_stiffness(&self, a: usize, b: usize) -> f64 {
        let (ma, mb) = (
            self.bodies[a].simulator.model(),
            self.bodies[b].simulator.model(),
        );
        let modulus = ma.max_p_wave_modulus().max(mb.max_p_wave_modulus());
        let size = ma.bounds().largest_side().min(mb.bounds().largest_side());
        self.contact.stiffness_factor * modulus / (size * size)
    }

    /// The smallest distance (m) between contact samples of different objects now, among those
    /// closer than d̂; `None` when no two objects are that close. With the penalty,
    /// `d̂ − gap` is how far the contact shells overlap; the barrier keeps it positive.
    pub fn contact_gap(&self) -> Option<f64> {
        self.touching.iter().map(|&(_, d)| d).min_by(f64::total_cmp)
    }

    /// How far (m) the last step's contact pairs between objects ended inside each other's
    /// contact shells: the largest `d̂ − n·p` (0 without contact). With the barrier it stays
    /// below d̂.
    pub fn contact_overlap(&self) -> f64 {
        self.overlap
    }

    /// The deepest penetration now (m): of any object into the floor or a collider, and
    /// between objects that of the last step's contact pairs at its end, with the penalty
    /// `d̂ − d` (how far a sample got into the other's contact shell along the pair's normal)
    /// and with the barrier `−d` (a sample through the other's contact plane; never positive).
    pub fn max_penetration(&self) -> f64 {
        let own = self
            .bodies
            .iter()
            .map(|b| b.simulator.max_penetration())
            .fold(0.0, f64::max);
        let between = match self.contact.model {
            BodyContactModel::Penalty => self.overlap,
            BodyContactModel::Barrier => self.overlap - self.contact.radius,
        };
        own.max(between.max(0.0))
    }

    /// Sample pairs of different objects that come closer than `radius` (m) while every
    /// sample moves linearly from `positions` by `motions` (per object; `None`: at rest): the
    /// smallest distance of `p + s q` over s ∈ [0, 1], p and q the pair's relative position and
    /// motion. Each object's samples are searched in a k-d tree of the other's, in the frame
    /// moving with the other's mean motion; object pairs whose swept boxes are farther apart
    /// are skipped.
    fn pairs_within(
        &self,
        positions: &[Vec<Vector3<f64>>],
        motions: Option<&[Vec<Vector3<f64>>]>,
        radius: f64,
    ) -> Vec<SamplePair> {
        let count = positions.len();
        let still: Vec<Vec<Vector3<f64>>>;
        let motions = match motions {
            Some(m) => m,
            None => {
                still = positions
                    .iter()
                    .map(|x| vec![Vector3::zeros(); x.len()])
                    .collect();
                &still
            }
        };
        let boxes: Vec<(Vector3<f64>, Vector3<f64>)> = (0..count)
            .map(|o| {
                positions[o].iter().zip(&motions[o]).fold(
                    (
                        Vector3::repeat(f64::INFINITY),
                        Vector3::repeat(f64::NEG_INFINITY),
                    ),
                    |(lo, hi), (x, m)| (lo.inf(x).inf(&(x + m)), hi.sup(x).sup(&(x + m))),
                )
            })
            .collect();
        // Each object's mean motion and the largest deviation of a sample's from it.
        let mean: Vec<Vector3<f64>> = motions
            .iter()
            .map(|m| m.iter().sum::<Vector3<f64>>() / m.len().max(1) as f64)
            .collect();
        let spread: Vec<f64> = motions
            .iter()
            .zip(&mean)
            .map(|(m, c)| m.iter().map(|v| (v - c).norm()).fold(0.0, f64::max))
            .collect();
        let mut pairs = Vec::new();
        let mut trees: Vec<Option<SpatialIndex>> = (0..count).map(|_| None).collect();
        for b in 1..count {
            for a in 0..b {
                let apart = (0..3).any(|k| {
                    boxes[a].0[k] - radius > boxes[b].1[k] || boxes[b].0[k] - radius > boxes[a].1[k]
                });
                if apart {
                    continue;
                }
                let tree = trees[b].get_or_insert_with(|| SpatialIndex::new(&positions[b]));
                for (i, (x, m)) in positions[a].iter().zip(&motions[a]).enumerate() {
                    let relative = m - mean[b];
                    let reach = radius + 0.5 * relative.norm() + spread[b];
                    for (j, _) in tree.within(&(x + 0.5 * relative), reach) {
                        let p = x - positions[b][j];
                        let q = m - motions[b][j];
                        let qq = q.norm_squared();
                        let s = if qq > 0.0 {
                            (-p.dot(&q) / qq).clamp(0.0, 1.0)
                        } else {
                            0.0
                        };
                        if (p + q * s).norm() < radius {
                            pairs.push(SamplePair {
                                a: (a, i),
                                b: (b, j),
                            });
                        }
                    }
                }
            }
        }
        pairs.sort_unstable();
        pairs
    }

    /// Advances every object by one step h (see the module docs). An unconverged solve still
    /// advances and says so in the report.
    ///
    /// # Errors
    /// [`MultiBodyStepError`] on a non-finite value or a singular system; every state is then
    /// as before the step.
    pub fn step(&mut self) -> Result<MultiBodyReport, MultiBodyStepError> {
        let search_start = Instant::now();
        self.overlap = 0.0;
        let saved: Vec<ReducedState> = self
            .bodies
            .iter()
            .map(|b| b.simulator.state().clone())
            .collect();
        let start = self.sample_positions();
        let motions: Vec<Vec<Vector3<f64>>> = self
            .bodies
            .iter()
            .zip(&start)
            .map(|(b, x0)| {
                let predicted = b.samples.positions(&b.simulator.predicted_coordinates());
                predicted.iter().zip(x0).map(|(p, x)| p - x).collect()
            })
            .collect();
        let d_hat = self.contact.radius;
        // Pairs the inertial motion brings within 1.5 d̂: the half is slack for the solution
        // straying from the prediction (a pair that still comes closer makes the step solved
        // again with it).
        let mut candidates = self.pairs_within(&start, Some(&motions), 1.5 * d_hat);
        let mut search_seconds = search_start.elapsed().as_secs_f64();
        let mut resolves = 0;
        loop {
            let groups = groups(self.bodies.len(), &candidates);
            // The objects alone first, side by side (each solve is the same whichever thread
            // runs it), then the groups.
            let alone: Vec<bool> = (0..self.bodies.len())
                .map(|b| groups.iter().any(|g| g[..] == [b]))
                .collect();
            let mut stepped: Vec<Option<Result<NewtonReport, StepError>>> = self
                .bodies
                .par_iter_mut()
                .zip(&alone)
                .map(|(body, &alone)| alone.then(|| body.simulator.step()))
                .collect();
            let mut reports: Vec<Option<NewtonReport>> = vec![None; self.bodies.len()];
            let mut joint_groups = 0;
            let mut solves = Vec::with_capacity(groups.len());
            for group in &groups {
                let outcome = if let [body] = group[..] {
                    let stepped = stepped[body].take().expect("stepped above");
                    stepped.map(|report| {
                        reports[body] = Some(report);
                        solves.push(report);
                    })
                } else {
                    joint_groups += 1;
                    let pairs: Vec<SamplePair> = candidates
                        .iter()
                        .filter(|p| group.binary_search(&p.a.0).is_ok())
                        .copied()
                        .collect();
                    self.solve_group(group, &pairs, &start).map(|report| {
                        for &body in group {
                            reports[body] = Some(report);
                        }
                        solves.push(report);
                    })
                };
                if let Err(source) = outcome {
                    self.restore(&saved);
                    return Err(MultiBodyStepError {
                        body: group[0],
                        source,
                    });
                }
            }
            let check = Instant::now();
            let touching = self.touching_pairs(&self.sample_positions());
            let known: HashSet<SamplePair> = candidates.iter().copied().collect();
            let missing: Vec<SamplePair> = touching
                .iter()
                .map(|&(p, _)| p)
                .filter(|p| !known.contains(p))
                .collect();
            search_seconds += check.elapsed().as_secs_f64();
            if missing.is_empty() || resolves >= 3 {
                // Factorizations only for groups that were solved this step.
                self.group_factors
                    .retain(|objects, _| groups.contains(objects));
                let active_pairs = touching.len();
                self.touching = touching;
                return Ok(MultiBodyReport {
                    bodies: reports
                        .into_iter()
                        .map(|r| r.expect("every object solved"))
                        .collect(),
                    solves,
                    joint_groups,
                    candidate_pairs: candidates.len(),
                    active_pairs,
                    contact_search_seconds: search_seconds,
                    resolves,
                });
            }
            resolves += 1;
            self.restore(&saved);
            candidates.extend(missing);
            candidates.sort_unstable();
        }
    }

    /// Puts every object back to `saved` (their carried Hessians are dropped).
    fn restore(&mut self, saved: &[ReducedState]) {
        self.group_factors.clear();
        for (b, state) in self.bodies.iter_mut().zip(saved) {
            b.simulator
                .set_state(state.clone())
                .expect("a state the simulator had");
        }
    }

    /// Solves the objects of `group` (ascending) together over one step with the candidate
    /// `pairs` between them; `start` holds every object's sample positions at the step's start.
    fn solve_group(
        &mut self,
        group: &[usize],
        pairs: &[SamplePair],
        start: &[Vec<Vector3<f64>>],
    ) -> Result<NewtonReport, StepError> {
        for &b in group {
            self.bodies[b].simulator.check_clear()?;
        }
        let params = *self.bodies[group[0]].simulator.params();
        let newton = params.newton;
        let predicted: Vec<Vec<f64>> = group
            .iter()
            .map(|&b| self.bodies[b].simulator.predicted_coordinates())
            .collect();
        let carried = self.group_factors.remove(group);
        let (z, report, offsets, overlap, factor, carried_age) = {
            let mut objective = self.group_potential(group, pairs, start, &predicted);
            let start_z: Vec<f64> = group
                .iter()
                .flat_map(|&b| self.bodies[b].simulator.state().z.iter().copied())
                .collect();
            objective.pairs = objective.lag(&start_z);
            objective.friction = objective.lagged_friction(&start_z);
            // From where the step starts, not the inertial prediction: the prediction may have
            // carried samples through each other's contact planes, where no force pulls them
            // back (IPC starts there too).
            let mut z = start_z;
            // Objects holding regions exactly start the solve with them on their targets.
            for (slot, &b) in group.iter().enumerate() {
                let range = objective.range(slot);
                let time = objective.potentials[slot].time;
                self.bodies[b].simulator.prescribe(&mut z[range], time);
            }
            // One factorization carried through the step's solves (the lagged re-solves
            // change the objective little) and, while the group stays together, into its next
            // step.
            let reuse = newton.hessian_reuse != optimize::HessianReuse::Never;
            let (mut factor, carried_age) =
                CarriedFactor::usable(carried.filter(|_| reuse), params.hessian_max_age);
            let mut report = solve_step(&mut objective, &mut z, &newton, &mut factor)?;
            // The normals lagged again at the solution while those of touching pairs turn.
            for _ in 0..MAX_CONTACT_LAGS {
                let pairs = objective.lag(&z);
                let positions = objective.positions(&z);
                let turned = pairs.len() != objective.pairs.len()
                    || pairs.iter().zip(&objective.pairs).any(|(new, old)| {
                        let touching = new
                            .normal
                            .dot(&GroupPotential::<M>::relative(&positions, &new.pair))
                            < self.contact.radius;
                        touching && (new.normal - old.normal).norm() > NORMAL_LAG_TOLERANCE
                    });
                if !turned {
                    break;
                }
                objective.pairs = pairs;
                let again = solve_step(&mut objective, &mut z, &newton, &mut factor)?;
                report = report.followed_by(&again);
            }
            // Friction lagging as for one object: contacts, normals and normal forces taken
            // again at the solution while they move, between the objects and each object's
            // with the floor and the colliders.
            for _ in 0..params.penalty.friction_lag_iterations {
                let friction = objective.lagged_friction(&z);
                let pairs_moved = !friction.is_empty()
                    && !same_friction(&objective.friction, &friction, LAG_TOLERANCE);
                let own: Vec<_> = group
                    .iter()
                    .enumerate()
                    .map(|(slot, &b)| {
                        let range = objective.offsets[slot]..objective.offsets[slot + 1];
                        self.bodies[b].simulator.friction_lagged_at(&z[range])
                    })
                    .collect();
                let own_moved = own
                    .iter()
                    .zip(&objective.potentials)
                    .any(|(new, potential)| {
                        new.as_ref()
                            .is_some_and(|new| new.moved_from(potential.friction.as_ref()))
                    });
                if !pairs_moved && !own_moved {
                    break;
                }
                if pairs_moved {
                    objective.friction = friction;
                }
                for (potential, new) in objective.potentials.iter_mut().zip(own) {
                    if new.is_some() {
                        potential.friction = new;
                    }
                }
                let again = solve_step(&mut objective, &mut z, &newton, &mut factor)?;
                report = report.followed_by(&again);
            }
            let positions = objective.positions(&z);
            let overlap = objective
                .pairs
                .iter()
                .map(|l| {
                    self.contact.radius
                        - l.normal
                            .dot(&GroupPotential::<M>::relative(&positions, &l.pair))
                })
                .fold(0.0, f64::max);
            (
                z,
                report,
                objective.offsets,
                overlap,
                factor.filter(|_| reuse),
                carried_age,
            )
        };
        self.overlap = self.overlap.max(overlap);
        for (slot, &b) in group.iter().enumerate() {
            let range = offsets[slot]..offsets[slot + 1];
            self.bodies[b].simulator.commit_step(z[range].to_vec());
        }
        // Carried into the group's next step while no object's floor or collider contacts
        // changed, as an object alone carries its own.
        let unchanged = group
            .iter()
            .all(|&b| !self.bodies[b].simulator.contacts_changed());
        if let Some(carried) =
            CarriedFactor::after(factor, carried_age, &report).filter(|_| unchanged)
        {
            self.group_factors.insert(group.to_vec(), carried);
        }
        Ok(report)
    }

    /// The joint potential of the objects of `group` (ascending) over the next step, with the
    /// candidate `pairs` between them (`start`: every object's sample positions at the step's
    /// start; `predicted`: each group object's inertial prediction), without friction.
    fn group_potential<'a>(
        &'a self,
        group: &[usize],
        pairs: &[SamplePair],
        start: &[Vec<Vector3<f64>>],
        predicted: &'a [Vec<f64>],
    ) -> GroupPotential<'a, M> {
        let params = self.bodies[group[0]].simulator.params();
        // Each object's samples that take part, and the pairs renumbered into them.
        let slot_of = |body: usize| group.binary_search(&body).expect("pair inside the group");
        let mut involved: Vec<Vec<usize>> = vec![Vec::new(); group.len()];
        for p in pairs {
            involved[slot_of(p.a.0)].push(p.a.1);
            involved[slot_of(p.b.0)].push(p.b.1);
        }
        for samples in &mut involved {
            samples.sort_unstable();
            samples.dedup();
        }
        let local = |slot: usize, sample: usize| {
            involved[slot]
                .binary_search(&sample)
                .expect("sample listed")
        };
        let mut offsets = vec![0];
        for &b in group {
            let len = self.bodies[b]
                .simulator
                .model()
                .deformation_map()
                .layout()
                .len();
            offsets.push(offsets.last().unwrap() + len);
        }
        let potentials: Vec<IncrementalPotential<'a, M>> = group
            .iter()
            .zip(predicted)
            .map(|(&b, predicted)| self.bodies[b].simulator.step_potential(predicted))
            .collect();
        let free = potentials.iter().any(|p| p.free.is_some()).then(|| {
            potentials
                .iter()
                .enumerate()
                .flat_map(|(s, p)| {
                    let (offset, end) = (offsets[s], offsets[s + 1]);
                    let own: Vec<usize> = match p.free {
                        Some(free) => free.iter().map(|i| offset + i).collect(),
                        None => (offset..end).collect(),
                    };
                    own
                })
                .collect()
        });
        GroupPotential {
            potentials,
            free,
            offsets,
            samples: group
                .iter()
                .zip(&involved)
                .map(|(&b, s)| self.bodies[b].samples.subset(s))
                .collect(),
            candidates: pairs
                .iter()
                .map(|p| {
                    let (sa, sb) = (slot_of(p.a.0), slot_of(p.b.0));
                    let local_pair = SamplePair {
                        a: (sa, local(sa, p.a.1)),
                        b: (sb, local(sb, p.b.1)),
                    };
                    (local_pair, self.pair_stiffness(p.a.0, p.b.0))
                })
                .collect(),
            pairs: Vec::new(),
            start: group
                .iter()
                .zip(&involved)
                .map(|(&body, samples)| samples.iter().map(|&i| start[body][i]).collect())
                .collect(),
            contact: self.contact,
            friction: Vec::new(),
            epsilon: params.penalty.friction_slip_speed * params.time_step,
        }
    }
}

/// Most times a group's step is solved again with its contact normals lagged at the last
/// solution.
const MAX_CONTACT_LAGS: usize = 3;

/// How far (in unit-vector length, about radians) a touching pair's normal may turn between
/// the lag and the solution before the step is solved again with the new normals.
const NORMAL_LAG_TOLERANCE: f64 = 0.05;

/// Whether two lagged friction sets between objects have the same pairs and normals and
/// limits within `tolerance` of the largest ([`same_lagged_forces`]).
fn same_friction(a: &[PairFriction], b: &[PairFriction], tolerance: f64) -> bool {
    same_lagged_forces(
        a.iter().map(|f| ((f.pair, &f.normal), &f.limit)),
        b.iter().map(|f| ((f.pair, &f.normal), &f.limit)),
        tolerance,
    )
}

/// The contact-connected groups of `count` objects under `pairs`, each ascending, in order
/// of their first object.
fn groups(count: usize, pairs: &[SamplePair]) -> Vec<Vec<usize>> {
    let mut parent: Vec<usize> = (0..count).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for p in pairs {
        let (a, b) = (root(&mut parent, p.a.0), root(&mut parent, p.b.0));
        if a != b {
            parent[a.max(b)] = a.min(b);
        }
    }
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut group_of = vec![usize::MAX; count];
    for i in 0..count {
        let r = root(&mut parent, i);
        if group_of[r] == usize::MAX {
            group_of[r] = groups.len();
            groups.push(Vec::new());
        }
        groups[group_of[r]].push(i);
    }
    groups
}

/// The pair ends on one object: sample, x-gradient and x-Hessian of each.
#[derive(Default)]
struct PairEnds {
    points: Vec<usize>,
    forces: Vec<Vector3<f64>>,
    stiffnesses: Vec<Matrix3<f64>>,
}

/// The joint incremental potential of a contact-connected group (module docs).
struct GroupPotential<'a, M: HyperelasticMaterial> {
    potentials: Vec<IncrementalPotential<'a, M>>,
    /// With objects holding regions exactly: the entries of the joint z Newton solves for
    /// (ascending); `None` when all are free.
    free: Option<Vec<usize>>,
    /// Start of each object's coordinates in the joint z, then its length.
    offsets: Vec<usize>,
    /// Each object's deformation map at its samples that take part.
    samples: Vec<DeformationMap>,
    /// Candidate pairs, as (slot, sample in `samples[slot]`), with κ of each (Pa/m²).
    candidates: Vec<(SamplePair, f64)>,
    /// The contact pairs of this solve with their lagged normals ([`GroupPotential::lag`]).
    pairs: Vec<LaggedPair>,
    /// Each object's samples that take part, where they were at the step's start (m).
    start: Vec<Vec<Vector3<f64>>>,
    contact: BodyContactParams,
    friction: Vec<PairFriction>,
    /// ε = ε_v h (m).
    epsilon: f64,
}

impl<M: HyperelasticMaterial> StepTangents for GroupPotential<'_, M> {
    fn tangents(&self) -> Vec<HessianTangent> {
        self.potentials.iter().map(|p| p.tangent).collect()
    }

    fn set_tangents(&mut self, tangents: &[HessianTangent]) {
        for (potential, &tangent) in self.potentials.iter_mut().zip(tangents) {
            potential.tangent = tangent;
        }
    }
}

impl<M: HyperelasticMaterial> GroupPotential<'_, M> {
    fn range(&self, slot: usize) -> Range<usize> {
        self.offsets[slot]..self.offsets[slot + 1]
    }

    /// Every object's sample positions at the joint z.
    fn positions(&self, z: &[f64]) -> Vec<Vec<Vector3<f64>>> {
        (0..self.samples.len())
            .map(|s| self.samples[s].positions(&z[self.range(s)]))
            .collect()
    }

    fn relative(positions: &[Vec<Vector3<f64>>], pair: &SamplePair) -> Vector3<f64> {
        positions[pair.a.0][pair.a.1] - positions[pair.b.0][pair.b.1]
    }

    /// The contact pairs lagged at z: every candidate, with the normal `p/‖p‖` there (pairs
    /// at one point, with no normal, are left out).
    fn lag(&self, z: &[f64]) -> Vec<LaggedPair> {
        let positions = self.positions(z);
        self.candidates
            .iter()
            .filter_map(|&(pair, stiffness)| {
                let p = Self::relative(&positions, &pair);
                let d = p.norm();
                (d > 0.0).then(|| LaggedPair {
                    pair,
                    normal: p / d,
                    stiffness,
                })
            })
            .collect()
    }

    /// The friction of the pairs touching at z, slips measured from the step's start.
    fn lagged_friction(&self, z: &[f64]) -> Vec<PairFriction> {
        lagged_friction(&self.contact, &self.pairs, &self.positions(z), &self.start)
    }

    /// Every pair's (and friction's) derivatives in its relative position, with the pair.
    fn pair_derivatives(&self, z: &[f64]) -> Vec<(SamplePair, RelativeDerivatives)> {
        let positions = self.positions(z);
        let mut out = Vec::new();
        for lagged in &self.pairs {
            let p = Self::relative(&positions, &lagged.pair);
            if let Some(d) =
                repulsion_derivatives(&self.contact, lagged.stiffness, &lagged.normal, &p)
                && d.gradient != Vector3::zeros()
            {
                out.push((lagged.pair, d));
            }
        }
        for f in &self.friction {
            let p = Self::relative(&positions, &f.pair);
            out.push((f.pair, f.derivatives(&p, self.epsilon)));
        }
        out
    }

    /// Adds the pair terms' gradient (and Hessian) to the joint ones.
    fn add_pair_derivatives(
        &self,
        z: &[f64],
        gradient: &mut [f64],
        hessian: Option<&mut Mat<f64>>,
    ) {
        let terms = self.pair_derivatives(z);
        let slots = self.samples.len();
        // Per object: the sample, force and stiffness of each end of each pair.
        let mut ends: Vec<PairEnds> = (0..slots).map(|_| PairEnds::default()).collect();
        for (pair, d) in &terms {
            for (end, sign) in [(pair.a, 1.0), (pair.b, -1.0)] {
                ends[end.0].points.push(end.1);
                ends[end.0].forces.push(d.gradient * sign);
                ends[end.0].stiffnesses.push(d.hessian);
            }
        }
        for (s, end) in ends.iter().enumerate() {
            let range = self.range(s);
            self.samples[s].add_point_gradients(&end.points, &end.forces, &mut gradient[range]);
        }
        let Some(hessian) = hessian else {
            return;
        };
        for (s, end) in ends.iter().enumerate() {
            if end.points.is_empty() {
                continue;
            }
            let n = self.range(s).len();
            let mut block = Mat::zeros(n, n);
            self.samples[s].add_point_hessians(&end.points, &end.stiffnesses, &mut block);
            let o = self.offsets[s];
            for j in 0..n {
                for i in 0..n {
                    hessian[(o + i, o + j)] += block[(i, j)];
                }
            }
        }
        for sa in 0..slots {
            for sb in sa + 1..slots {
                let between: Vec<&(SamplePair, RelativeDerivatives)> = terms
                    .iter()
                    .filter(|(p, _)| p.a.0 == sa && p.b.0 == sb)
                    .collect();
                if between.is_empty() {
                    continue;
                }
                let points_a: Vec<usize> = between.iter().map(|(p, _)| p.a.1).collect();
                let points_b: Vec<usize> = between.iter().map(|(p, _)| p.b.1).collect();
                let stiffnesses: Vec<Matrix3<f64>> =
                    between.iter().map(|(_, d)| d.hessian).collect();
                let (ra, rb) = (self.range(sa), self.range(sb));
                add_cross_hessians(
                    &self.samples[sa],
                    &points_a,
                    &self.samples[sb],
                    &points_b,
                    &stiffnesses,
                    hessian
                        .as_mut()
                        .submatrix_mut(ra.start, rb.start, ra.len(), rb.len()),
                );
                for j in rb.clone() {
                    for i in ra.clone() {
                        hessian[(j, i)] = hessian[(i, j)];
                    }
                }
            }
        }
    }
}

impl<M: HyperelasticMaterial> NewtonObjective for GroupPotential<'_, M> {
    type Hessian = Mat<f64>;
    type Factor = Llt<f64>;

    fn energy(&self, z: &[f64]) -> f64 {
        // The objects' own terms side by side (summed in order: the same bits on any thread).
        let own: Vec<f64> = (0..self.potentials.len())
            .into_par_iter()
            .map(|s| self.potentials[s].energy(&z[self.range(s)]))
            .collect();
        let mut e: f64 = own.iter().sum();
        let positions = self.positions(z);
        let v = self.contact.sample_volume();
        for lagged in &self.pairs {
            let p = Self::relative(&positions, &lagged.pair);
            match self.contact.profile(lagged.normal.dot(&p)) {
                Some((psi, _, _)) => e += lagged.stiffness * v * psi,
                None => return f64::INFINITY,
            }
        }
        for f in &self.friction {
            e += f.energy(&Self::relative(&positions, &f.pair), self.epsilon);
        }
        e
    }

    fn gradient(&self, z: &[f64]) -> Vec<f64> {
        let own: Vec<Vec<f64>> = (0..self.potentials.len())
            .into_par_iter()
            .map(|s| self.potentials[s].gradient(&z[self.range(s)]))
            .collect();
        let mut gradient = own.concat();
        self.add_pair_derivatives(z, &mut gradient, None);
        match &self.free {
            None => gradient,
            Some(free) => free.iter().map(|&i| gradient[i]).collect(),
        }
    }

    fn gradient_and_hessian(&self, z: &[f64], _gradient: Option<Vec<f64>>) -> (Vec<f64>, Mat<f64>) {
        let n = z.len();
        let mut gradient = Vec::with_capacity(n);
        let mut hessian = Mat::zeros(n, n);
        let own: Vec<(Vec<f64>, Mat<f64>)> = (0..self.potentials.len())
            .into_par_iter()
            .map(|s| self.potentials[s].derivatives(&z[self.range(s)]))
            .collect();
        for (s, (g, h)) in own.into_iter().enumerate() {
            gradient.extend(g);
            let o = self.offsets[s];
            for j in 0..h.ncols() {
                for i in 0..h.nrows() {
                    hessian[(o + i, o + j)] = h[(i, j)];
                }
            }
        }
        self.add_pair_derivatives(z, &mut gradient, Some(&mut hessian));
        match &self.free {
            None => (gradient, hessian),
            Some(free) => (
                free.iter().map(|&i| gradient[i]).collect(),
                Mat::from_fn(free.len(), free.len(), |a, b| hessian[(free[a], free[b])]),
            ),
        }
    }

    fn factor(&self, hessian: Mat<f64>) -> Option<Llt<f64>> {
        hessian.llt(Side::Lower).ok()
    }

    fn solve(&self, factor: &Llt<f64>, gradient: &[f64]) -> Vec<f64> {
        let mut step = Mat::<f64>::from_fn(gradient.len(), 1, |i, _| -gradient[i]);
        factor.solve_in_place(step.as_mut());
        match &self.free {
            None => (0..gradient.len()).map(|i| step[(i, 0)]).collect(),
            Some(free) => {
                let mut full = vec![0.0; *self.offsets.last().expect("offsets")];
                for (a, &i) in free.iter().enumerate() {
                    full[i] = step[(a, 0)];
                }
                full
            }
        }
    }

    fn directional_derivative(&self, gradient: &[f64], step: &[f64]) -> f64 {
        match &self.free {
            None => gradient.iter().zip(step).map(|(g, s)| g * s).sum(),
            Some(free) => free.iter().zip(gradient).map(|(&i, g)| g * step[i]).sum(),
        }
    }

    /// The largest of the objects' step norms.
    fn step_norm(&self, dz: &[f64]) -> f64 {
        (0..self.potentials.len())
            .map(|s| self.potentials[s].step_norm(&dz[self.range(s)]))
            .fold(0.0, f64::max)
    }

    /// The largest α ≤ 1 within every object's own limit (a mesh collider's band) such that
    /// no contact pair's gap `d = n·p` shrinks by more than d̂/2
    /// past d̂ along the step, so no sample passes through the other's contact plane in one
    /// iteration without the line search seeing its energy; with the barrier also such that no
    /// gap shrinks below a tenth of its present value (d is linear in z along the step).
    fn max_step(&self, z: &[f64], step: &[f64]) -> f64 {
        let positions = self.positions(z);
        let moves: Vec<Vec<Vector3<f64>>> = (0..self.samples.len())
            .map(|s| self.samples[s].displacements(&step[self.range(s)]))
            .collect();
        let d_hat = self.contact.radius;
        let barrier = self.contact.model == BodyContactModel::Barrier;
        // Each object's own limit (a mesh collider's band).
        let mut alpha: f64 = (0..self.potentials.len())
            .into_par_iter()
            .map(|s| {
                let range = self.range(s);
                self.potentials[s].max_step(&z[range.clone()], &step[range])
            })
            .reduce(|| 1.0, f64::min);
        for lagged in &self.pairs {
            let gap = lagged.normal.dot(&Self::relative(&positions, &lagged.pair));
            let closing = -lagged.normal.dot(&Self::relative(&moves, &lagged.pair));
            if closing <= 0.0 || gap - closing >= d_hat {
                continue;
            }
            let enter = ((gap - d_hat) / closing).max(0.0);
            alpha = alpha.min(enter + 0.5 * d_hat / closing);
            if barrier && gap > 0.0 {
                alpha = alpha.min(0.9 * gap / closing);
            }
        }
        alpha
    }
}

#[cfg(test)]
mod tests {
    use hyperelastic::StableNeoHookean;
    use nalgebra::{DMatrix, Matrix3, Vector3};
    use test_support::finite_difference;

    use super::*;
    use crate::analytic_field::{AnalyticField, analytic_model_with_spacing};
    use crate::scene::{Floor, Scene};
    use crate::simulator::SimulationParams;

    /// The grid points of spacing `spacing` on the surface of the box `[0, size]`.
    fn box_surface(size: Vector3<f64>, spacing: f64) -> Vec<Vector3<f64>> {
        let counts = size.map(|s| (s / spacing).round() as usize);
        let mut points = Vec::new();
        for i in 0..=counts.x {
            for j in 0..=counts.y {
                for k in 0..=counts.z {
                    let on_surface = i == 0
                        || j == 0
                        || k == 0
                        || i == counts.x
                        || j == counts.y
                        || k == counts.z;
                    if on_surface {
                        let f = Vector3::new(i, j, k)
                            .cast::<f64>()
                            .component_div(&counts.cast());
                        points.push(f.component_mul(&size));
                    }
                }
            }
        }
        points
    }

    /// The analytic 2 × 1 × 1 m block in `scene`, moved rigidly by `translation` (m) and moving
    /// at `velocity` (m/s), with contact samples 0.1 m apart.
    fn block(
        scene: &Scene,
        params: SimulationParams,
        translation: Vector3<f64>,
        velocity: Vector3<f64>,
    ) -> Body<StableNeoHookean> {
        coarse_block(scene, params, translation, velocity, 0.2)
    }

    /// [`block`] integrated on a grid of `spacing` (m).
    /// Gravity (9.8 m/s² along −y) and the floor y = `offset` (m) with friction `friction`.
    fn floor_scene(offset: f64, friction: f64) -> Scene {
        Scene {
            gravity: Some(Vector3::new(0.0, -9.8, 0.0)),
            floor: Some(Floor {
                normal: Vector3::y(),
                offset,
                friction,
            }),
            ..Scene::default()
        }
    }

    fn coarse_block(
        scene: &Scene,
        params: SimulationParams,
        translation: Vector3<f64>,
        velocity: Vector3<f64>,
        spacing: f64,
    ) -> Body<StableNeoHookean> {
        let (model, _) = analytic_model_with_spacing(spacing);
        let samples = DeformationMap::new(
            &AnalyticField,
            &box_surface(Vector3::new(2.0, 1.0, 1.0), 0.1),
        )
        .unwrap();
        let layout = model.deformation_map().layout();
        let mut simulator = Simulator::new(model, scene, params).unwrap();
        simulator
            .set_state(ReducedState {
                z: layout.rigid_motion(&Matrix3::identity(), &translation),
                velocity: layout.uniform_velocity(&velocity),
                time: 0.0,
            })
            .unwrap();
        Body::new(simulator, samples).unwrap()
    }

    fn check_group_derivatives(model: BodyContactModel) {
        let params = SimulationParams {
            tangent: crate::HessianTangent::Exact,
            ..SimulationParams::default()
        };
        let scene = Scene {
            gravity: Some(Vector3::new(0.0, -9.8, 0.0)),
            ..Scene::default()
        };
        // B's end face 0.04 m beyond A's, shifted so samples do not face each other exactly.
        let bodies = vec![
            block(&scene, params, Vector3::zeros(), Vector3::zeros()),
            block(
                &scene,
                params,
                Vector3::new(2.04, 0.03, 0.05),
                Vector3::zeros(),
            ),
        ];
        let contact = BodyContactParams {
            model,
            friction: 0.5,
            ..BodyContactParams::with_radius(0.1)
        };
        let sim = MultiBodySimulator::new(bodies, contact).unwrap();
        let start = sim.sample_positions();
        let pairs = sim.pairs_within(&start, None, 0.15);
        assert!(pairs.len() > 50, "{} pairs", pairs.len());
        let predicted: Vec<Vec<f64>> = sim
            .bodies
            .iter()
            .map(|b| b.simulator.predicted_coordinates())
            .collect();
        let mut objective = sim.group_potential(&[0, 1], &pairs, &start, &predicted);
        let len = objective.offsets[2];
        let probe = |amplitude: f64| -> Vec<f64> {
            let base = predicted.concat();
            (0..len)
                .map(|i| base[i] + amplitude * ((i as f64 * 1.37).sin() + 0.3 * (i as f64).cos()))
                .collect()
        };
        // Contact and friction lagged at another state, so slips straddle ε.
        objective.epsilon = 0.002;
        objective.pairs = objective.lag(&probe(-0.002));
        objective.friction = objective.lagged_friction(&probe(-0.002));
        assert!(
            objective.friction.len() > 20,
            "{} rubbing pairs",
            objective.friction.len()
        );
        let z = probe(0.001);
        let active = objective.pair_derivatives(&z).len();
        assert!(
            active > objective.friction.len() + 20,
            "{active} active terms"
        );
        let energy = |z: &[f64]| NewtonObjective::energy(&objective, z);
        let (gradient, hessian) = objective.gradient_and_hessian(&z, None);
        assert_eq!(gradient, NewtonObjective::gradient(&objective, &z));
        let numeric = finite_difference::gradient(energy, &z, 1e-7);
        let err = finite_difference::relative_error(
            &DMatrix::from_column_slice(len, 1, &gradient),
            &DMatrix::from_column_slice(len, 1, numeric.as_slice()),
            1e-12,
        );
        assert!(err < 1e-6, "{model:?}: gradient relative error {err:e}");
        let numeric =
            finite_difference::jacobian(|z| NewtonObjective::gradient(&objective, z), &z, 1e-7);
        let analytic = DMatrix::from_fn(len, len, |i, j| hessian[(i, j)]);
        let err = finite_difference::relative_error(&analytic, &numeric, 1e-12);
        assert!(err < 1e-6, "{model:?}: Hessian relative error {err:e}");
        // The coupling blocks are there (not only the objects' own).
        let n = objective.offsets[1];
        let coupling = (0..n)
            .flat_map(|i| (n..len).map(move |j| (i, j)))
            .map(|(i, j)| hessian[(i, j)].abs())
            .fold(0.0, f64::max);
        assert!(coupling > 0.0);
    }

    #[test]
    fn joint_gradient_and_hessian_with_contact_and_friction_match_finite_differences() {
        check_group_derivatives(BodyContactModel::Penalty);
        check_group_derivatives(BodyContactModel::Barrier);
    }

    #[test]
    fn objects_that_never_touch_follow_the_trajectories_they_have_alone() {
        let scene = floor_scene(-0.2, 0.3);
        let params = SimulationParams::default();
        let offset = Vector3::new(0.0, 0.0, 3.0);
        let spin = Vector3::new(0.5, 0.0, 0.0);
        let mut together = MultiBodySimulator::new(
            vec![
                block(&scene, params, Vector3::zeros(), spin),
                block(&scene, params, offset, -spin),
            ],
            BodyContactParams::with_radius(0.1),
        )
        .unwrap();
        let mut alone = [
            block(&scene, params, Vector3::zeros(), spin),
            block(&scene, params, offset, -spin),
        ];
        for _ in 0..40 {
            let report = together.step().unwrap();
            assert_eq!(report.joint_groups, 0);
            for body in &mut alone {
                body.simulator.step().unwrap();
            }
        }
        for (a, b) in together.bodies().iter().zip(&alone) {
            assert_eq!(a.simulator().state(), b.simulator().state());
        }
        assert!(
            together.bodies()[0]
                .simulator()
                .state()
                .z
                .iter()
                .any(|&v| v != 0.0)
        );
    }

    /// Two blocks sliding side by side onto a floor with friction, close enough to be solved
    /// as one group but never within the contact distance: the floor's friction is lagged
    /// again at each step's solution in the group as for an object alone, so the group slides
    /// as the two blocks do alone, landing step included.
    #[test]
    fn a_group_lags_floor_friction_at_the_solution_like_an_object_alone() {
        let scene = floor_scene(-0.15, 0.5);
        let params = SimulationParams::default();
        let velocity = Vector3::new(1.0, -1.0, 0.0);
        // The blocks are 1 m deep in z: 1.12 m apart leaves a 0.12 m gap, within the 1.5 d̂
        // = 0.15 m candidate reach but beyond d̂ = 0.1 m.
        let side = Vector3::new(0.0, 0.0, 1.12);
        let make = |shift: Vector3<f64>| block(&scene, params, shift, velocity);
        let mut grouped = MultiBodySimulator::new(
            vec![make(Vector3::zeros()), make(side)],
            BodyContactParams::with_radius(0.1),
        )
        .unwrap();
        let mut alone = [make(Vector3::zeros()), make(side)];
        let mut joint = 0;
        for _ in 0..20 {
            joint += grouped.step().unwrap().joint_groups;
            for body in &mut alone {
                body.simulator.step().unwrap();
            }
        }
        assert!(joint >= 10, "{joint} joint solves");
        let mean_x = |b: &Body<StableNeoHookean>| {
            let x = b.sample_positions();
            x.iter().map(|p| p.x).sum::<f64>() / x.len() as f64
        };
        for (g, a) in grouped.bodies().iter().zip(&alone) {
            let (x_group, x_alone) = (mean_x(g), mean_x(a));
            // Measured: 1.3e-4 m apart after 0.2 s of sliding; 1.1e-2 m when the group kept
            // the floor's friction lagged at the start of each step only.
            assert!(
                (x_group - x_alone).abs() < 1e-3,
                "grouped {x_group} m, alone {x_alone} m"
            );
        }
    }

    /// Two blocks stacked on a floor, solved as one group every step: carrying the group's
    /// factorization from step to step reaches the states fresh Hessians reach (to 1e-5 m over
    /// 60 steps, Newton tolerance 1e-8) with fewer Hessians.
    #[test]
    fn a_group_carrying_its_factorization_across_steps_reaches_the_fresh_states() {
        let scene = floor_scene(0.0, 0.0);
        let run = |reuse: optimize::HessianReuse| {
            let params = SimulationParams {
                newton: optimize::NewtonParams {
                    hessian_reuse: reuse,
                    tolerance: 1e-8,
                    ..SimulationParams::default().newton
                },
                ..SimulationParams::default()
            };
            let bodies = (0..2)
                .map(|k| {
                    let shift = Vector3::new(0.0, 1.12 * k as f64 + 0.01, 0.0);
                    coarse_block(&scene, params, shift, Vector3::zeros(), 1.0 / 3.0)
                })
                .collect();
            let mut sim =
                MultiBodySimulator::new(bodies, BodyContactParams::with_radius(0.1)).unwrap();
            let (mut hessians, mut joint) = (0, 0);
            for _ in 0..60 {
                let report = sim.step().unwrap();
                assert!(report.converged());
                hessians += report
                    .solves
                    .iter()
                    .map(|s| s.hessian_assemblies)
                    .sum::<usize>();
                joint += report.joint_groups;
            }
            let x: Vec<Vector3<f64>> = sim
                .bodies()
                .iter()
                .flat_map(|b| b.sample_positions())
                .collect();
            (x, hessians, joint)
        };
        let (fresh, fresh_hessians, _) = run(optimize::HessianReuse::Never);
        let (carried, carried_hessians, joint) = run(SimulationParams::HESSIAN_REUSE);
        assert!(joint >= 50, "{joint} joint solves");
        let deviation = fresh
            .iter()
            .zip(&carried)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, f64::max);
        assert!(deviation < 1e-5, "samples {deviation} m apart");
        // Measured: 178 Hessians carried, 242 fresh, 198 with the factorization kept within
        // each step only (the lower block's floor contacts change while it settles, and each
        // change drops the carried one).
        assert!(
            4 * carried_hessians < 3 * fresh_hessians,
            "{carried_hessians} Hessians carried, {fresh_hessians} fresh"
        );
    }

    /// Two blocks 0.3 m apart closing at 2 m/s without gravity; returns the simulator after
    /// `steps` steps with the largest momentum change and smallest gap seen.
    fn head_on(
        model: BodyContactModel,
        steps: usize,
    ) -> (MultiBodySimulator<StableNeoHookean>, f64, f64) {
        let mut params = SimulationParams::default();
        params.newton.tolerance = 1e-9;
        let scene = Scene::default();
        let speed = Vector3::new(1.0, 0.0, 0.0);
        let contact = BodyContactParams {
            model,
            ..BodyContactParams::with_radius(0.1)
        };
        let mut sim = MultiBodySimulator::new(
            vec![
                block(&scene, params, Vector3::zeros(), speed),
                block(&scene, params, Vector3::new(2.3, 0.02, -0.03), -speed),
            ],
            contact,
        )
        .unwrap();
        let p0 = sim.linear_momentum();
        let scale: f64 = sim
            .bodies()
            .iter()
            .map(|b| b.simulator().linear_momentum().norm())
            .sum();
        let (mut drift, mut gap) = (0.0_f64, f64::INFINITY);
        let mut joint = 0;
        let start_energy = sim.mechanical_energy();
        let mut energy = start_energy;
        for _ in 0..steps {
            let report = sim.step().unwrap();
            assert!(report.converged(), "{report:?}");
            joint += report.joint_groups;
            // Backward Euler and frictionless contact take energy out, never put it in (a
            // lagged normal is a linearization: allow 0.1% of the start per step).
            let now = sim.mechanical_energy();
            assert!(
                now <= energy + 1e-3 * start_energy,
                "{model:?}: energy rose from {energy} J to {now} J"
            );
            energy = now;
            drift = drift.max((sim.linear_momentum() - p0).norm() / scale);
            if let Some(g) = sim.contact_gap() {
                gap = gap.min(g);
            }
        }
        assert!(
            joint > 3,
            "the blocks were solved together in {joint} steps"
        );
        eprintln!("{model:?}: energy {start_energy} J -> {energy} J");
        (sim, drift, gap)
    }

    #[test]
    fn head_on_collision_conserves_momentum_and_the_blocks_separate() {
        for model in [BodyContactModel::Penalty, BodyContactModel::Barrier] {
            let (sim, drift, gap) = head_on(model, 40);
            assert!(
                drift < 1e-8,
                "{model:?}: momentum drift {drift:e} (relative)"
            );
            let v: Vec<f64> = sim
                .bodies()
                .iter()
                .map(|b| b.simulator().linear_momentum().x / b.simulator().model().total_mass())
                .collect();
            assert!(
                v[0] < 0.0 && v[1] > 0.0,
                "{model:?}: velocities after the collision {v:?}"
            );
            assert!(sim.contact_gap().is_none(), "{model:?}: still touching");
            assert!(gap > 0.0, "{model:?}: smallest gap {gap}");
            eprintln!("{model:?}: drift {drift:e}, smallest gap {gap} m, velocities {v:?}");
        }
    }

    /// Three blocks stacked on a floor for 1000 steps (10 s): the smallest gap between blocks
    /// and the deepest penetration (floor, or shell overlap with the penalty) seen, and the
    /// blocks' final centres (m).
    fn stack(model: BodyContactModel) -> (f64, f64, Vec<Vector3<f64>>) {
        let scene = floor_scene(0.0, 0.0);
        // With the barrier between objects, the floor's barrier too (5 cm).
        let floor_contact = match model {
            BodyContactModel::Penalty => crate::FloorContact::Penalty,
            BodyContactModel::Barrier => crate::FloorContact::Barrier { distance: 0.05 },
        };
        let params = SimulationParams {
            penalty: crate::PenaltyParams {
                floor_contact,
                ..Default::default()
            },
            ..SimulationParams::default()
        };
        let bodies = (0..3)
            .map(|k| {
                let shift = Vector3::new(0.05 * k as f64, 1.12 * k as f64 + 0.01, 0.0);
                // A coarse grid (54 points): the test is about contact over many steps.
                coarse_block(&scene, params, shift, Vector3::zeros(), 1.0 / 3.0)
            })
            .collect();
        let contact = BodyContactParams {
            model,
            ..BodyContactParams::with_radius(0.1)
        };
        let mut sim = MultiBodySimulator::new(bodies, contact).unwrap();
        let (mut gap, mut penetration) = (f64::INFINITY, 0.0_f64);
        for _ in 0..1000 {
            let report = sim.step().unwrap();
            assert!(report.converged(), "{report:?}");
            gap = gap.min(sim.contact_gap().unwrap_or(f64::INFINITY));
            penetration = penetration.max(sim.max_penetration());
        }
        let centres: Vec<Vector3<f64>> = sim
            .bodies()
            .iter()
            .map(|b| {
                let x = b.sample_positions();
                x.iter().sum::<Vector3<f64>>() / x.len() as f64
            })
            .collect();
        (gap, penetration, centres)
    }

    #[test]
    fn a_stack_of_three_blocks_holds_for_1000_steps_without_penetration() {
        for model in [BodyContactModel::Penalty, BodyContactModel::Barrier] {
            let (gap, penetration, centres) = stack(model);
            eprintln!(
                "{model:?}: smallest gap {gap} m, deepest penetration {penetration} m, centres {centres:?}"
            );
            assert!(gap > 0.0, "{model:?}: gap {gap}");
            // Cube side 1 m (the blocks' smallest side): 2% is 0.02 m; none with the barrier.
            let allowed = match model {
                BodyContactModel::Penalty => 0.02,
                BodyContactModel::Barrier => 0.0,
            };
            assert!(
                penetration <= allowed,
                "{model:?}: penetration {penetration} m"
            );
            // Still standing: each block about one height (1 m, plus d̂, less its sag) above the
            // one below, and still on it (frictionless, the 2 m blocks drift sideways a little
            // on the samples' bumps; they started 0.05 m apart in x).
            for pair in centres.windows(2) {
                let rise = pair[1].y - pair[0].y;
                let slide = (pair[1].x - pair[0].x).abs();
                assert!((0.9..1.2).contains(&rise), "{model:?}: centres {centres:?}");
                assert!(slide < 0.5, "{model:?}: centres {centres:?}");
            }
        }
    }
}
