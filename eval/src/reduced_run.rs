//! One reduced run of any skinning field on any scene, recorded at given output points (usually
//! the FEM vertices) every step: the library's [`freeform::run`] with a recorder and a bar.

use hyperelastic::StableNeoHookean;
use nalgebra::Vector3;
use reduced_sim::{DeformationMap, SkinningField};

use crate::EvalError;
use crate::progress::Progress;
use freeform::{RunReport, Simulation, run};

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
#[derive(Clone, Debug)]
pub struct ReducedRun {
    /// Output-point positions per frame, frame 0 = rest (m); `steps + 1` frames.
    pub frames: Vec<Vec<Vector3<f64>>>,
    /// Timings, Newton counts, pin deviation, points simulated and held.
    pub report: RunReport,
}

/// Simulates `problem.steps` steps, showing a bar labelled `label`.
///
/// # Errors
/// [`EvalError::Run`] for a model, scene or step that fails (e.g. a region that selects no
/// integration point); [`EvalError::OutputMap`] if the output points cannot be mapped.
pub fn run_reduced<B: SkinningField + ?Sized>(
    problem: &ReducedProblem<'_, B>,
    label: &str,
    progress: &Progress,
) -> Result<ReducedRun, EvalError> {
    let output = DeformationMap::new(problem.simulation.field, problem.output_points)
        .map_err(EvalError::OutputMap)?;
    let steps = problem.steps;
    let bar = progress.bar(steps, label);
    let mut frames = Vec::with_capacity(steps + 1);
    let report = run(&problem.simulation, steps, |frame| {
        frames.push(output.positions(&frame.simulator.state().z));
        if frame.index > 0 {
            bar.inc(1);
        }
        Ok(())
    });
    bar.finish_and_clear();
    Ok(ReducedRun {
        frames,
        report: report?,
    })
}
