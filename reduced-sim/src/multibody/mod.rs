//! Several objects in one scene: each a [`Simulator`] of its own model and scene
//! (floor, colliders, pins, gravity), coupled by contact between their surface samples
//! ([`crate::contact::body_contact`]).
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
use std::time::Instant;

use faer::linalg::solvers::Llt;
use hyperelastic::HyperelasticMaterial;
use nalgebra::Vector3;
use optimize::{CarriedFactor, NewtonReport};
use rayon::prelude::*;
use rkpm_core::SpatialIndex;
use thiserror::Error;

use crate::contact::body_contact::{BodyContactModel, BodyContactParams, SamplePair};
use crate::model::deformation_map::DeformationMap;
use crate::step::simulator::{ReducedState, Simulator, StateError, StepError};

mod contact_groups;
mod group_potential;
mod group_solve;
#[cfg(test)]
mod tests;

use contact_groups::groups;

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
}
