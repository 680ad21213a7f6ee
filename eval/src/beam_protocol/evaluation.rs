//! The beam's FEM references and a skinning field scored against them: the evaluation every
//! beam experiment shares.

use std::path::Path;

use nalgebra::Vector3;
use reduced_sim::SkinningField;
use serde::{Deserialize, Serialize};

use crate::EvalError;
use crate::beam_protocol::reduced::run_reduced_beam_with;
use crate::beam_protocol::study_config::BeamStudyConfig;
use crate::beam_scenario::{BEAM_TIME_STEP, BeamTest, beam_length_scale, beam_material};
use crate::fem_reference::{FEM_TIMING_STEPS, beam_seconds_per_step_here, run_fem_beam};
use crate::reduced_run::ReducedRun;
use crate::reduced_settings::ReducedSettings;
use freeform::fem_reference::FemRun;
use freeform::metrics::TrajectoryErrors;
use freeform::terminal_progress::TerminalProgress;

/// The FEM side of a test.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FemSummary {
    /// Bend or Twist.
    pub test: BeamTest,
    /// "P2 res 6".
    pub resolution: String,
    /// Steps run.
    pub steps: usize,
    /// Free DOFs.
    pub dofs: usize,
    /// Vertices where metrics are evaluated.
    pub vertices: usize,
    /// Seconds per step, timed in this process: over every step when the trajectory was
    /// computed now, over the first [`FEM_TIMING_STEPS`] steps run fresh when it came from the
    /// cache (the cached run's own time is of whatever machine and solver produced it).
    pub seconds_per_step: f64,
    /// Steps `seconds_per_step` was timed over.
    #[serde(default)]
    pub timed_steps: usize,
    /// Newton iterations per step.
    pub iterations_per_step: f64,
    /// The largest Newton iteration count of any step.
    pub max_iterations: usize,
    /// Unconverged steps.
    pub unconverged_steps: usize,
    /// Why the reference is not scored (a step stopped unconverged), or `None` when every step
    /// converged and the test's rows are scored against it.
    pub not_scored: Option<String>,
    /// Loaded from the cache.
    pub cached: bool,
}

/// A test and its FEM ground-truth run.
pub(crate) type FemReference = (BeamTest, FemRun);

/// The FEM reference of every test of `config` (run or loaded from the cache) with its summary.
/// Only references whose every step converged are returned for scoring; the summary of one
/// that did not says why it is not scored (and its test gets no rows).
///
/// # Errors
/// [`EvalError::Fem`] from a failed run.
pub(crate) fn fem_references(
    config: &BeamStudyConfig,
    progress: &TerminalProgress,
) -> Result<(Vec<FemReference>, Vec<FemSummary>), EvalError> {
    let mut references = Vec::new();
    let mut fem = Vec::new();
    for &test in &config.tests {
        let steps = config.steps_of(test);
        let run = run_fem_beam(
            test,
            config.fem,
            config.fem_newton,
            steps,
            &config.cache_dir,
            progress,
        )?;
        if run.cached {
            progress.status(format!(
                "FEM {} {}: timing {} fresh steps",
                test.name(),
                config.fem.label(),
                FEM_TIMING_STEPS.min(steps)
            ));
        }
        let (seconds_per_step, timed_steps) =
            beam_seconds_per_step_here(&run, test, config.fem, config.fem_newton, steps)?;
        let not_scored = run
            .check_converged(config.fem_newton.max_iterations)
            .err()
            .map(|e| e.to_string());
        if let Some(why) = &not_scored {
            progress.status(format!("{}: {why}", test.name()));
        }
        fem.push(FemSummary {
            test,
            resolution: config.fem.label(),
            steps,
            dofs: run.dofs,
            vertices: run.vertices().len(),
            seconds_per_step,
            timed_steps,
            iterations_per_step: run.iterations_per_step,
            max_iterations: run.max_iterations(),
            unconverged_steps: run.unconverged_steps,
            not_scored: not_scored.clone(),
            cached: run.cached,
        });
        if not_scored.is_none() {
            references.push((test, run));
        }
    }
    Ok((references, fem))
}

/// A skinning field's run of one test, scored against the FEM reference.
pub(crate) struct FieldEvaluation {
    pub(crate) run: ReducedRun,
    pub(crate) errors: TrajectoryErrors,
    pub(crate) per_frame_mse: Vec<f64>,
    pub(crate) fitting_residual: f64,
}

/// Simulates `test` with `field` and scores it at the reference's vertices.
pub(crate) fn evaluate_field<B: SkinningField + ?Sized>(
    test: BeamTest,
    field: &B,
    settings: &ReducedSettings,
    reference: &FemRun,
    steps: usize,
    cache_dir: &Path,
    progress: &TerminalProgress,
) -> Result<FieldEvaluation, EvalError> {
    let run = run_reduced_beam_with(
        test,
        field,
        settings,
        beam_material(),
        Some(cache_dir),
        reference.vertices(),
        steps,
        progress,
    )
    .map_err(|source| EvalError::BeamRun {
        test: test.name(),
        modes: settings.modes,
        source: Box::new(source),
    })?;
    let scores = reference.score(field, &run.frames, beam_length_scale())?;
    Ok(FieldEvaluation {
        run,
        errors: scores.errors,
        per_frame_mse: scores.per_frame_mse,
        fitting_residual: scores.fitting_residual,
    })
}
/// The largest distance (m) of a vertex in one of `test`'s constrained regions from its target,
/// over `frames` (frame f at t = f h) of positions at `vertices`.
pub(crate) fn region_drift(
    test: BeamTest,
    vertices: &[Vector3<f64>],
    frames: &[Vec<Vector3<f64>>],
) -> f64 {
    let scene = test.scene();
    let mut drift: f64 = 0.0;
    for c in &scene.constraints {
        let inside: Vec<usize> = (0..vertices.len())
            .filter(|&i| c.region.contains(&vertices[i]))
            .collect();
        for (f, frame) in frames.iter().enumerate() {
            let t = f as f64 * BEAM_TIME_STEP;
            for &i in &inside {
                drift = drift.max((frame[i] - c.motion.at(&vertices[i], t)).norm());
            }
        }
    }
    drift
}
