//! The one step loop of a run, for one object ([`crate::run`]) and several
//! ([`crate::simulate_objects`]): each step timed, its Newton solves and the system's state
//! accumulated into one [`StepStatistics`], then handed to the caller (frames, the automatic
//! quadrature's choice, per-object summaries).

use std::time::Instant;

use hyperelastic::HyperelasticMaterial;
use optimize::NewtonReport;
use reduced_sim::{MultiBodyReport, MultiBodySimulator, MultiBodyStepError, Simulator, StepError};

/// A system the loop steps: one object's [`Simulator`] or a [`MultiBodySimulator`].
pub(crate) trait SteppedSystem {
    /// What one step reports.
    type Report;
    /// Why a step failed.
    type Error;

    /// Advances one step.
    fn step(&mut self) -> Result<Self::Report, Self::Error>;
    /// The step's Newton solves (one per object alone, one per group solved together).
    fn solves(report: &Self::Report) -> &[NewtonReport];
    /// Whether every solve of the step converged.
    fn converged(report: &Self::Report) -> bool;
    /// Seconds spent finding contact pairs and groups (0 for one object).
    fn contact_search_seconds(_report: &Self::Report) -> f64 {
        0.0
    }
    /// Groups of objects solved together (0 for one object).
    fn joint_groups(_report: &Self::Report) -> usize {
        0
    }
    /// Kinetic plus potential energy now (J).
    fn mechanical_energy(&self) -> f64;
    /// Deepest penetration of the floor or a collider now (m).
    fn max_penetration(&self) -> f64;
    /// Largest distance of a penalty-pinned point from its target now (m).
    fn max_pin_deviation(&self) -> f64 {
        0.0
    }
    /// Largest distance of an exactly held point from its target now (m).
    fn max_held_deviation(&self) -> f64 {
        0.0
    }
    /// Largest overlap of a sample into another object's contact shell now (m).
    fn contact_overlap(&self) -> f64 {
        0.0
    }
    /// Smallest distance between samples of different objects now (m), if any are close.
    fn contact_gap(&self) -> Option<f64> {
        None
    }
}

impl<M: HyperelasticMaterial + Clone> SteppedSystem for Simulator<M> {
    type Report = NewtonReport;
    type Error = StepError;

    fn step(&mut self) -> Result<NewtonReport, StepError> {
        Simulator::step(self)
    }

    fn solves(report: &NewtonReport) -> &[NewtonReport] {
        std::slice::from_ref(report)
    }

    fn converged(report: &NewtonReport) -> bool {
        report.converged()
    }

    fn mechanical_energy(&self) -> f64 {
        Simulator::mechanical_energy(self)
    }

    fn max_penetration(&self) -> f64 {
        Simulator::max_penetration(self)
    }

    fn max_pin_deviation(&self) -> f64 {
        Simulator::max_pin_deviation(self).unwrap_or(0.0)
    }

    fn max_held_deviation(&self) -> f64 {
        Simulator::max_held_deviation(self).unwrap_or(0.0)
    }
}

impl<M: HyperelasticMaterial + Clone> SteppedSystem for MultiBodySimulator<M> {
    type Report = MultiBodyReport;
    type Error = MultiBodyStepError;

    fn step(&mut self) -> Result<MultiBodyReport, MultiBodyStepError> {
        MultiBodySimulator::step(self)
    }

    fn solves(report: &MultiBodyReport) -> &[NewtonReport] {
        &report.solves
    }

    fn converged(report: &MultiBodyReport) -> bool {
        report.converged()
    }

    fn contact_search_seconds(report: &MultiBodyReport) -> f64 {
        report.contact_search_seconds
    }

    fn joint_groups(report: &MultiBodyReport) -> usize {
        report.joint_groups
    }

    fn mechanical_energy(&self) -> f64 {
        MultiBodySimulator::mechanical_energy(self)
    }

    fn max_penetration(&self) -> f64 {
        MultiBodySimulator::max_penetration(self)
    }

    fn contact_overlap(&self) -> f64 {
        MultiBodySimulator::contact_overlap(self)
    }

    fn contact_gap(&self) -> Option<f64> {
        MultiBodySimulator::contact_gap(self)
    }
}

/// Sums and extremes over the steps of a run (the numbers of [`crate::RunReport`] and
/// [`crate::ObjectsReport`]).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct StepStatistics {
    /// Steps taken.
    pub(crate) steps: usize,
    /// Wall time of the steps (s).
    pub(crate) stepping: f64,
    /// Assembly, solve, line search, contact search (s).
    pub(crate) split: [f64; 4],
    pub(crate) iterations: usize,
    pub(crate) hessians: usize,
    pub(crate) line_search_cuts: usize,
    pub(crate) joint_groups: usize,
    pub(crate) unconverged: usize,
    /// Largest distance of a penalty-pinned point from its target (m).
    pub(crate) max_pin_deviation: f64,
    /// Largest distance of an exactly held point from its target (m).
    pub(crate) max_held_deviation: f64,
    /// Deepest penetration (m).
    pub(crate) max_penetration: f64,
    /// Largest overlap of a pair into another object's contact shell (m).
    pub(crate) max_overlap: f64,
    /// Smallest distance of samples of different objects (m).
    pub(crate) min_gap: Option<f64>,
    /// Mechanical energy at the start and now (J).
    pub(crate) energy: [f64; 2],
    /// Largest rise of the energy over one step (J).
    pub(crate) max_energy_rise: f64,
}

impl StepStatistics {
    /// Nothing stepped yet, `system` at its start.
    pub(crate) fn new(system: &impl SteppedSystem) -> Self {
        let energy = system.mechanical_energy();
        StepStatistics {
            steps: 0,
            stepping: 0.0,
            split: [0.0; 4],
            iterations: 0,
            hessians: 0,
            line_search_cuts: 0,
            joint_groups: 0,
            unconverged: 0,
            max_pin_deviation: 0.0,
            max_held_deviation: 0.0,
            max_penetration: 0.0,
            max_overlap: 0.0,
            min_gap: None,
            energy: [energy, energy],
            max_energy_rise: 0.0,
        }
    }

    /// Adds the step `report` that took `seconds` (s) and left `system` where it is.
    pub(crate) fn record<S: SteppedSystem>(
        &mut self,
        report: &S::Report,
        seconds: f64,
        system: &S,
    ) {
        self.steps += 1;
        self.stepping += seconds;
        for solve in S::solves(report) {
            self.split[0] += solve.timings.assembly;
            self.split[1] += solve.timings.solve;
            self.split[2] += solve.timings.line_search;
            self.iterations += solve.iterations;
            self.hessians += solve.hessian_assemblies;
            self.line_search_cuts += solve.line_search_cuts;
        }
        self.split[3] += S::contact_search_seconds(report);
        self.joint_groups += S::joint_groups(report);
        self.unconverged += usize::from(!S::converged(report));
        self.max_pin_deviation = self.max_pin_deviation.max(system.max_pin_deviation());
        self.max_held_deviation = self.max_held_deviation.max(system.max_held_deviation());
        self.max_penetration = self.max_penetration.max(system.max_penetration());
        self.max_overlap = self.max_overlap.max(system.contact_overlap());
        let now = system.mechanical_energy();
        self.max_energy_rise = self.max_energy_rise.max(now - self.energy[1]);
        self.energy[1] = now;
        if let Some(gap) = system.contact_gap() {
            self.min_gap = Some(self.min_gap.map_or(gap, |g| g.min(gap)));
        }
    }

    /// `total` per step (the steps taken, at least one).
    pub(crate) fn per_step(&self, total: f64) -> f64 {
        total / self.steps.max(1) as f64
    }

    /// Elastic seconds so far: assembly and line search.
    pub(crate) fn elastic_seconds(&self) -> f64 {
        self.split[0] + self.split[2]
    }
}

/// Steps `system` `steps` times, timing each step and recording it in `statistics`, then
/// calling `after_step` with the step's index (1 …) and report; a failed step is turned into
/// the caller's error by `step_error`, and an error of `after_step` ends the loop.
///
/// # Errors
/// The first of them.
pub(crate) fn run_steps<S: SteppedSystem, E>(
    system: &mut S,
    steps: usize,
    statistics: &mut StepStatistics,
    step_error: impl Fn(usize, S::Error) -> E,
    mut after_step: impl FnMut(&mut S, usize, &S::Report, &StepStatistics) -> Result<(), E>,
) -> Result<(), E> {
    for step in 1..=steps {
        let t = Instant::now();
        let report = system.step().map_err(|e| step_error(step, e))?;
        statistics.record(&report, t.elapsed().as_secs_f64(), system);
        after_step(system, step, &report, statistics)?;
    }
    Ok(())
}
