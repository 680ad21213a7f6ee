//! One reduced simulation of any skinning field on any scene (Eqs. 1-2): the loop shared by the
//! beam tables, the shape tables and the benchmarks. It records positions at given output
//! points (usually the FEM vertices) every step, with timings and convergence counts.

use hyperelastic::MaterialSample;
use std::time::Instant;

use nalgebra::Vector3;
use reduced_sim::{DeformationMap, ReducedModel, SimulationParams, Simulator, SkinningField};
use rkpm_core::IntegrationPoints;

use crate::EvalError;
use crate::progress::Progress;
use crate::scene_spec::SceneSpec;

/// Everything one reduced run needs.
pub struct ReducedProblem<'a, B: SkinningField + ?Sized> {
    /// The skinning field (our basis or a baseline's network).
    pub field: &'a B,
    /// Integration points of the simulation (rest positions in m, volumes in m³).
    pub points: &'a IntegrationPoints,
    /// One homogeneous material.
    pub material: MaterialSample,
    /// What acts on the object.
    pub scene: &'a SceneSpec,
    /// Time step, Newton and penalty options.
    pub params: SimulationParams,
    /// Rest positions (m) where positions are recorded every step.
    pub output_points: &'a [Vector3<f64>],
    /// Steps to run.
    pub steps: usize,
}

/// A reduced trajectory at the output points, with timings.
#[derive(Clone, Debug)]
pub struct ReducedRun {
    /// Output-point positions per frame, frame 0 = rest (m); `steps + 1` frames.
    pub frames: Vec<Vec<Vector3<f64>>>,
    /// Wall time per step (ms).
    pub ms_per_step: f64,
    /// Hessian/gradient assembly per step (ms).
    pub ms_assembly_per_step: f64,
    /// Mean Newton iterations per step.
    pub iterations_per_step: f64,
    /// Steps whose Newton solve did not converge.
    pub unconverged_steps: usize,
    /// Largest distance of a pinned point from its target over the run (m).
    pub max_pin_deviation: f64,
    /// Model and scene setup (s).
    pub setup_seconds: f64,
    /// Integration points simulated.
    pub simulation_points: usize,
    /// Integration points held in each constrained region of the scene.
    pub region_points: Vec<usize>,
}

/// Simulates `problem.steps` steps, showing a bar labelled `label`.
///
/// # Errors
/// [`EvalError::Setup`] for a model, scene or output map that cannot be built (e.g. a region
/// that selects no integration point), [`EvalError::Reduced`] for a failed step.
pub fn run_reduced<B: SkinningField + ?Sized>(
    problem: &ReducedProblem<'_, B>,
    label: &str,
    progress: &Progress,
) -> Result<ReducedRun, EvalError> {
    let start = Instant::now();
    let points = problem.points;
    let model = ReducedModel::new(
        problem.field,
        points,
        &vec![problem.material; points.len()],
        hyperelastic::StableNeoHookean,
    )
    .map_err(|e| EvalError::Setup(e.to_string()))?;
    let scene = problem.scene.reduced_scene(model.rest_positions())?;
    let region_points = scene.pins.iter().map(|p| p.points.len()).collect();
    let mut sim = Simulator::new(model, &scene, problem.params)
        .map_err(|e| EvalError::Setup(e.to_string()))?;
    let output = DeformationMap::new(problem.field, problem.output_points)
        .map_err(|e| EvalError::Setup(e.to_string()))?;
    let setup_seconds = start.elapsed().as_secs_f64();

    let steps = problem.steps;
    let bar = progress.bar(steps, label);
    let mut frames = Vec::with_capacity(steps + 1);
    frames.push(output.positions(&sim.state().z));
    let (mut iterations, mut unconverged) = (0usize, 0usize);
    let (mut stepping, mut assembly) = (0.0, 0.0);
    let mut max_pin_deviation: f64 = 0.0;
    for step in 1..=steps {
        let t = Instant::now();
        let report = sim
            .step()
            .map_err(|e| EvalError::Reduced(format!("step {step}: {e}")))?;
        stepping += t.elapsed().as_secs_f64();
        assembly += report.timings.assembly;
        iterations += report.iterations;
        unconverged += usize::from(!report.converged());
        max_pin_deviation = max_pin_deviation.max(sim.max_pin_deviation().unwrap_or(0.0));
        frames.push(output.positions(&sim.state().z));
        bar.inc(1);
    }
    bar.finish_and_clear();
    let n = steps.max(1) as f64;
    Ok(ReducedRun {
        frames,
        ms_per_step: 1e3 * stepping / n,
        ms_assembly_per_step: 1e3 * assembly / n,
        iterations_per_step: iterations as f64 / n,
        unconverged_steps: unconverged,
        max_pin_deviation,
        setup_seconds,
        simulation_points: points.len(),
        region_points,
    })
}
