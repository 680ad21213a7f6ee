//! One reduced run of any skinning field on any scene, recorded at given output points (usually
//! the FEM vertices) every step: the library's [`freeform::run_recorded`] with a bar.

use hyperelastic::StableNeoHookean;
use nalgebra::Vector3;
use reduced_sim::SkinningField;

use crate::EvalError;
use freeform::terminal_progress::{BarProgress, TerminalProgress};
use freeform::{RecordError, RecordedRun, Simulation, run_recorded};

/// Everything one reduced run needs: the library's [`Simulation`] (stable Neo-Hookean, as in
/// every paper experiment) and where and how long to record it.
pub struct ReducedProblem<'a, B: SkinningField + ?Sized> {
    /// The skinning field, points, material, scene, options, quadrature and cubature cache.
    pub simulation: Simulation<'a, B, StableNeoHookean>,
    /// Rest positions (m) where positions are recorded every step.
    pub output_points: &'a [Vector3<f64>],
    /// Steps to run.
    pub steps: usize,
}

/// A reduced trajectory at the output points, with the run's timings and convergence.
pub type ReducedRun = RecordedRun;

/// Simulates `problem.steps` steps, showing a bar labelled `label`
/// ([`freeform::run_recorded`]).
///
/// # Errors
/// [`EvalError::Run`] for a model, scene or step that fails (e.g. a region that selects no
/// integration point); [`EvalError::OutputMap`] if the output points cannot be mapped.
pub fn run_reduced<B: SkinningField + ?Sized>(
    problem: &ReducedProblem<'_, B>,
    label: &str,
    progress: &TerminalProgress,
) -> Result<ReducedRun, EvalError> {
    run_recorded(
        &problem.simulation,
        problem.output_points,
        problem.steps,
        label,
        &BarProgress::new(*progress),
    )
    .map_err(|e| match e {
        RecordError::OutputMap(e) => EvalError::OutputMap(e),
        RecordError::Run(e) => EvalError::Run(e),
    })
}
