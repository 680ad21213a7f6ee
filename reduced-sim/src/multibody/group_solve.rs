//! Solving a contact-connected group of objects as one backward-Euler problem.

use hyperelastic::HyperelasticMaterial;
use nalgebra::Vector3;
use optimize::{CarriedFactor, NewtonReport};

use crate::contact::body_contact::{PairFriction, SamplePair};
use crate::step::incremental_potential::IncrementalPotential;
use crate::step::simulator::{StepError, solve_step};
use crate::terms::friction_term::{LAG_TOLERANCE, same_lagged_forces};

use super::MultiBodySimulator;
use super::group_potential::GroupPotential;

impl<M: HyperelasticMaterial> MultiBodySimulator<M> {
    /// Solves the objects of `group` (ascending) together over one step with the candidate
    /// `pairs` between them; `start` holds every object's sample positions at the step's start.
    pub(super) fn solve_group(
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
                if !self.relag_normals(&mut objective, &z) {
                    break;
                }
                let again = solve_step(&mut objective, &mut z, &newton, &mut factor)?;
                report = report.followed_by(&again);
            }
            // Friction lagging as for one object: contacts, normals and normal forces taken
            // again at the solution while they move, between the objects and each object's
            // with the floor and the colliders.
            for _ in 0..params.penalty.friction_lag_iterations {
                if !self.relag_friction(group, &mut objective, &z) {
                    break;
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

    /// Lags the contact normals of `objective` again at its solution `z` when those of
    /// touching pairs turned by more than [`NORMAL_LAG_TOLERANCE`] (or pairs came or went);
    /// whether it did (the step is then solved again).
    fn relag_normals(&self, objective: &mut GroupPotential<'_, M>, z: &[f64]) -> bool {
        let pairs = objective.lag(z);
        let positions = objective.positions(z);
        let turned = pairs.len() != objective.pairs.len()
            || pairs.iter().zip(&objective.pairs).any(|(new, old)| {
                let touching = new
                    .normal
                    .dot(&GroupPotential::<M>::relative(&positions, &new.pair))
                    < self.contact.radius;
                touching && (new.normal - old.normal).norm() > NORMAL_LAG_TOLERANCE
            });
        if turned {
            objective.pairs = pairs;
        }
        turned
    }

    /// Lags the friction of `objective` (between the objects of `group`, and each object's
    /// with the floor and the colliders) again at its solution `z` when it moved; whether it
    /// did (the step is then solved again).
    fn relag_friction(
        &self,
        group: &[usize],
        objective: &mut GroupPotential<'_, M>,
        z: &[f64],
    ) -> bool {
        let friction = objective.lagged_friction(z);
        let pairs_moved =
            !friction.is_empty() && !same_friction(&objective.friction, &friction, LAG_TOLERANCE);
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
            return false;
        }
        if pairs_moved {
            objective.friction = friction;
        }
        for (potential, new) in objective.potentials.iter_mut().zip(own) {
            if new.is_some() {
                potential.friction = new;
            }
        }
        true
    }

    /// The joint potential of the objects of `group` (ascending) over the next step, with the
    /// candidate `pairs` between them (`start`: every object's sample positions at the step's
    /// start; `predicted`: each group object's inertial prediction), without friction.
    pub(super) fn group_potential<'a>(
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
