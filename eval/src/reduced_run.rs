//! One reduced run of any skinning field on any scene, recorded at given output points (usually
//! the FEM vertices) every step: the library's [`freeform::run`] with a recorder and a bar.

use hyperelastic::{MaterialField, MaterialSample, StableNeoHookean};
use nalgebra::Vector3;
use reduced_sim::{DeformationMap, QuadratureRule, SimulationParams, SkinningField};
use rkpm_core::IntegrationPoints;

use crate::EvalError;
use crate::progress::Progress;
use freeform::scene::SceneSpec;
use freeform::{RunReport, Simulation, run};

/// Everything one reduced run needs.
pub struct ReducedProblem<'a, B: SkinningField + ?Sized> {
    /// The skinning field (our basis or a baseline's network).
    pub field: &'a B,
    /// Integration points of the simulation (rest positions in m, volumes in m³).
    pub points: &'a IntegrationPoints,
    /// One homogeneous material (stable Neo-Hookean, as in every paper experiment).
    pub material: MaterialSample,
    /// What acts on the object.
    pub scene: &'a SceneSpec,
    /// Time step, Newton and penalty options.
    pub params: SimulationParams,
    /// Where the elastic energy is integrated.
    pub quadrature: QuadratureRule,
    /// Where a cubature is cached (`None`: optimized every run).
    pub cache_dir: Option<&'a std::path::Path>,
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
    let output =
        DeformationMap::new(problem.field, problem.output_points).map_err(EvalError::OutputMap)?;
    let simulation = Simulation {
        field: problem.field,
        points: problem.points,
        material: &MaterialField::Uniform(problem.material),
        material_model: StableNeoHookean,
        scene: problem.scene,
        params: problem.params,
        quadrature: problem.quadrature,
        cache_dir: problem.cache_dir,
    };
    let steps = problem.steps;
    let bar = progress.bar(steps, label);
    let mut frames = Vec::with_capacity(steps + 1);
    let report = run(&simulation, steps, |frame| {
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
