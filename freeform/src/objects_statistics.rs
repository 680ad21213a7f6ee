//! What the steps of a scene of several objects had, accumulated step by step.

use hyperelastic::HyperelasticMaterial;
use reduced_sim::{MultiBodyReport, MultiBodySimulator};

/// Sums and extremes over the steps of a [`MultiBodySimulator`] (the numbers of
/// [`crate::ObjectsReport`]).
pub(crate) struct ObjectsStatistics {
    /// Wall time of the steps (s).
    pub(crate) stepping: f64,
    /// Assembly, solve, line search, contact search (s).
    pub(crate) split: [f64; 4],
    pub(crate) iterations: usize,
    pub(crate) hessians: usize,
    pub(crate) line_search_cuts: usize,
    pub(crate) joint_groups: usize,
    pub(crate) unconverged: usize,
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

impl ObjectsStatistics {
    /// Nothing stepped yet, `simulator` at its start.
    pub(crate) fn new<M: HyperelasticMaterial>(simulator: &MultiBodySimulator<M>) -> Self {
        let energy = simulator.mechanical_energy();
        ObjectsStatistics {
            stepping: 0.0,
            split: [0.0; 4],
            iterations: 0,
            hessians: 0,
            line_search_cuts: 0,
            joint_groups: 0,
            unconverged: 0,
            max_penetration: 0.0,
            max_overlap: 0.0,
            min_gap: None,
            energy: [energy, energy],
            max_energy_rise: 0.0,
        }
    }

    /// Adds the step `report` that took `seconds` (s) and left `simulator` where it is.
    pub(crate) fn record<M: HyperelasticMaterial>(
        &mut self,
        report: &MultiBodyReport,
        seconds: f64,
        simulator: &MultiBodySimulator<M>,
    ) {
        self.stepping += seconds;
        for solve in &report.solves {
            self.split[0] += solve.timings.assembly;
            self.split[1] += solve.timings.solve;
            self.split[2] += solve.timings.line_search;
            self.iterations += solve.iterations;
            self.hessians += solve.hessian_assemblies;
            self.line_search_cuts += solve.line_search_cuts;
        }
        self.split[3] += report.contact_search_seconds;
        self.joint_groups += report.joint_groups;
        self.unconverged += usize::from(!report.converged());
        self.max_penetration = self.max_penetration.max(simulator.max_penetration());
        self.max_overlap = self.max_overlap.max(simulator.contact_overlap());
        let now = simulator.mechanical_energy();
        self.max_energy_rise = self.max_energy_rise.max(now - self.energy[1]);
        self.energy[1] = now;
        if let Some(gap) = simulator.contact_gap() {
            self.min_gap = Some(self.min_gap.map_or(gap, |g| g.min(gap)));
        }
    }
}
