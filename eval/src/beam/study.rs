//! The beam study behind Tables 1, 5 and 6: for each m, one basis; for each test, the FEM ground
//! truth (cached) and a reduced run evaluated at the FEM vertices.

use optimize::NewtonParams;
use std::path::{Path, PathBuf};

use baselines::SimplicitsParams;
use freeform::PinHold;
use nalgebra::Vector3;
use reduced_sim::{QuadratureReport, SkinningField};
use serde::{Deserialize, Serialize};

use crate::EvalError;
use crate::beam::mpm::MpmStudyConfig;
use crate::beam::particle_baseline::ParticleBaselineRow;
use crate::beam::particle_config::ParticleConfig;
use crate::beam::reduced::{
    EXACT_INSET_KERNEL_RADII, ReducedSettings, build_beam_basis, build_beam_basis_for,
    exact_pin_hold, run_reduced_beam_with,
};
use crate::beam::simplicits::train_beam_simplicits;
use crate::beam::sph::SphStudyConfig;
use crate::beam::{BEAM_MAX, BEAM_MIN, BEAM_TIME_STEP, BeamTest, beam_material};
use crate::fem_reference::{
    FEM_TIMING_STEPS, FemResolution, beam_seconds_per_step_here, run_fem_beam,
};
use crate::reduced_run::ReducedRun;
use freeform::fem_reference::FemRun;
use freeform::metrics::TrajectoryErrors;
use freeform::terminal_progress::TerminalProgress;

/// What the study runs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BeamStudyConfig {
    /// Modes m to run.
    pub modes: Vec<usize>,
    /// Tests to run.
    pub tests: Vec<BeamTest>,
    /// Everything but m.
    pub settings: ReducedSettings,
    /// Steps per test; `None` for design §4.1's (300 Bend, 30 Twist).
    pub steps: Option<usize>,
    /// The FEM ground truth.
    pub fem: FemResolution,
    /// The FEM's Newton options (default: 20 iterations, tolerance 1e-6). A reference any of
    /// whose steps stops unconverged is not scored.
    #[serde(default = "NewtonParams::default")]
    pub fem_newton: NewtonParams,
    /// The Simplicits baseline's training options (its `modes` is set per m), or `None` to
    /// leave it out.
    pub simplicits: Option<SimplicitsParams>,
    /// Cache folder (FEM trajectories under `fem/`, networks under `simplicits/`).
    pub cache_dir: PathBuf,
    /// Also run every (test, m) with the pinned regions held exactly, shrunk by this many
    /// median kernel radii ([`exact_pin_hold`], a basis per test), beside the penalty (issue
    /// 25); `None` to leave it out.
    #[serde(default)]
    pub exact_pins: Option<f64>,
    /// The MPM baseline at each of its grid spacings on every test, or `None` to
    /// leave it out.
    #[serde(default)]
    pub mpm: Option<MpmStudyConfig>,
    /// The SPH baseline at each of its particle spacings on every test, or `None` to
    /// leave it out.
    #[serde(default)]
    pub sph: Option<SphStudyConfig>,
}

impl BeamStudyConfig {
    /// The paper's configuration: m ∈ {6, 9, 16, 32}, both tests, K = 1000, design §4.1's steps,
    /// FEM P2 res 6.
    pub fn full(cache_dir: PathBuf) -> Self {
        BeamStudyConfig {
            modes: vec![6, 9, 16, 32],
            tests: BeamTest::ALL.to_vec(),
            settings: ReducedSettings::default(),
            steps: None,
            fem: FemResolution::GROUND_TRUTH,
            fem_newton: NewtonParams::default(),
            simplicits: Some(SimplicitsParams::default()),
            cache_dir,
            exact_pins: Some(EXACT_INSET_KERNEL_RADII),
            mpm: Some(MpmStudyConfig::default()),
            sph: Some(SphStudyConfig::default()),
        }
    }

    /// A few-minute version: m ∈ {6, 16}, K = 500 on 10k basis points, 100 Bend steps (Twist
    /// keeps its 30), FEM P2 res 4, Simplicits trained for 500 steps instead of 10 000, no MPM
    /// or SPH.
    pub fn quick(cache_dir: PathBuf) -> Self {
        BeamStudyConfig {
            modes: vec![6, 16],
            settings: ReducedSettings {
                kernels: 500,
                basis_points: 10_000,
                ..ReducedSettings::default()
            },
            steps: Some(100),
            fem: FemResolution {
                cells_per_metre: 4,
                ..FemResolution::GROUND_TRUTH
            },
            simplicits: Some(SimplicitsParams {
                steps: 500,
                ..SimplicitsParams::default()
            }),
            mpm: None,
            sph: None,
            ..BeamStudyConfig::full(cache_dir)
        }
    }

    /// Steps of `test` in this configuration (Twist never runs past its 30 steps).
    pub fn steps_of(&self, test: BeamTest) -> usize {
        self.steps.unwrap_or(test.steps()).min(test.steps())
    }
}

/// One (test, m) result.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BeamRow {
    /// Bend or Twist.
    pub test: BeamTest,
    /// Modes.
    pub m: usize,
    /// Normalized MSE against FEM (design §4.3).
    pub ours_mse: f64,
    /// Normalized max error against FEM.
    pub ours_max: f64,
    /// Normalized MSE of each frame 1..T (their mean is `ours_mse`).
    pub ours_per_frame_mse: Vec<f64>,
    /// Basis fitting residual of the FEM trajectory through our deformation map.
    pub fitting_residual: f64,
    /// Wall time per step (ms).
    pub ms_per_step: f64,
    /// Mean Newton iterations per step.
    pub iterations_per_step: f64,
    /// Mean Hessians assembled per step (1 without Hessian reuse at 2 iterations, ...).
    #[serde(default)]
    pub hessians_per_step: f64,
    /// The elastic quadrature of the run (kind, points, cubature report).
    #[serde(default)]
    pub quadrature: Option<QuadratureReport>,
    /// Steps that did not converge.
    pub unconverged_steps: usize,
    /// Largest pinned-point drift (m): of the integration points the simulator holds.
    pub max_pin_deviation: f64,
    /// Largest distance (m) of an FEM vertex in a constrained region from its target over the
    /// run: the drift of what the FEM holds exactly.
    #[serde(default)]
    pub region_drift: f64,
    /// The same run with the regions held exactly, if it was run.
    #[serde(default)]
    pub exact: Option<ExactRow>,
    /// Basis build time (s).
    pub basis_seconds: f64,
    /// The Simplicits baseline at the same m, if it was run.
    pub simplicits: Option<BaselineRow>,
}

/// A (test, m) run with the pinned regions held exactly ([`exact_pin_hold`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ExactRow {
    /// The inset of the held regions (m).
    pub inset: f64,
    /// Normalized MSE against FEM.
    pub mse: f64,
    /// Normalized max error against FEM.
    pub max: f64,
    /// Largest drift of the held integration points (m).
    pub max_pin_deviation: f64,
    /// Largest drift of the FEM vertices in the (whole) constrained regions (m).
    pub region_drift: f64,
    /// Wall time per step (ms).
    pub ms_per_step: f64,
    /// Steps that did not converge.
    pub unconverged_steps: usize,
    /// Basis build time (s).
    pub basis_seconds: f64,
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

/// A baseline's result for one (test, m).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BaselineRow {
    /// Normalized MSE against FEM.
    pub mse: f64,
    /// Normalized max error against FEM.
    pub max: f64,
    /// Normalized MSE of each frame 1..T (their mean is `mse`).
    pub per_frame_mse: Vec<f64>,
    /// Basis fitting residual.
    pub fitting_residual: f64,
    /// Wall time per step (ms).
    pub ms_per_step: f64,
    /// Training time of the run that produced the network (s).
    pub training_seconds: f64,
    /// Steps that did not converge.
    pub unconverged_steps: usize,
}

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

/// Everything the beam tables print.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BeamStudy {
    /// What was run.
    pub config: BeamStudyConfig,
    /// One row per (test, m), tests outermost.
    pub rows: Vec<BeamRow>,
    /// One summary per test.
    pub fem: Vec<FemSummary>,
    /// The particle baselines (MPM, SPH) per (method, test, spacing), if run.
    #[serde(default)]
    pub particle_baselines: Vec<ParticleBaselineRow>,
}

/// Largest side of the beam's rest box, the normalization length L (m).
pub fn beam_length_scale() -> f64 {
    (BEAM_MAX - BEAM_MIN).max()
}

/// Runs the study.
///
/// # Errors
/// [`EvalError`] from any run; nothing is half-reported.
pub fn run_beam_study(
    config: &BeamStudyConfig,
    progress: &TerminalProgress,
) -> Result<BeamStudy, EvalError> {
    let (references, fem) = fem_references(config, progress)?;
    let mut rows = Vec::new();
    for &m in &config.modes {
        let settings = ReducedSettings {
            modes: m,
            ..config.settings
        };
        progress.status(format!("basis m = {m}, K = {}", settings.kernels));
        let basis = build_beam_basis(&settings)?;
        let exact = match config.exact_pins {
            Some(radii) => Some(ReducedSettings {
                pins: exact_pin_hold(&settings, radii)?,
                ..settings
            }),
            None => None,
        };
        let simplicits = match &config.simplicits {
            Some(params) => Some(train_beam_simplicits(
                &SimplicitsParams {
                    modes: m,
                    ..*params
                },
                settings.basis_points,
                &config.cache_dir,
                progress,
            )?),
            None => None,
        };
        for (test, reference) in &references {
            let steps = config.steps_of(*test);
            let ours = evaluate_field(
                *test,
                &basis.basis,
                &settings,
                reference,
                steps,
                &config.cache_dir,
                progress,
            )?;
            let simplicits = match &simplicits {
                Some(net) => {
                    let e = evaluate_field(
                        *test,
                        &net.trained.field,
                        &settings,
                        reference,
                        steps,
                        &config.cache_dir,
                        progress,
                    )?;
                    Some(BaselineRow {
                        mse: e.errors.normalized_mse,
                        max: e.errors.normalized_max,
                        per_frame_mse: e.per_frame_mse,
                        fitting_residual: e.fitting_residual,
                        ms_per_step: e.run.report.ms_per_step,
                        training_seconds: net.trained.report.seconds,
                        unconverged_steps: e.run.report.unconverged_steps,
                    })
                }
                None => None,
            };
            rows.push(BeamRow {
                test: *test,
                m,
                ours_mse: ours.errors.normalized_mse,
                ours_max: ours.errors.normalized_max,
                ours_per_frame_mse: ours.per_frame_mse,
                fitting_residual: ours.fitting_residual,
                ms_per_step: ours.run.report.ms_per_step,
                iterations_per_step: ours.run.report.iterations_per_step,
                hessians_per_step: ours.run.report.hessians_per_step,
                quadrature: Some(ours.run.report.quadrature.clone()),
                unconverged_steps: ours.run.report.unconverged_steps,
                max_pin_deviation: ours.run.report.max_pin_deviation,
                region_drift: region_drift(*test, reference.vertices(), &ours.run.frames),
                exact: match &exact {
                    Some(exact) => Some(evaluate_exact(
                        *test, exact, &settings, reference, steps, config, progress,
                    )?),
                    None => None,
                },
                basis_seconds: basis.seconds,
                simplicits,
            });
        }
    }
    rows.sort_by_key(|r| (r.test != BeamTest::Bend, r.m));
    let mut particle_baselines = Vec::new();
    // Every (method, test, spacing), cheapest first, so that the long runs come last.
    let configs: Vec<ParticleConfig> = config
        .mpm
        .iter()
        .map(ParticleConfig::Mpm)
        .chain(config.sph.iter().map(ParticleConfig::Sph))
        .collect();
    let mut runs: Vec<(ParticleConfig, &FemReference, f64)> = references
        .iter()
        .flat_map(|r| {
            configs
                .iter()
                .flat_map(move |c| c.spacings().iter().map(move |&h| (*c, r, h)))
        })
        .collect();
    let cost = |(c, r, h): &(ParticleConfig, &FemReference, f64)| {
        config.steps_of(r.0) as f64 * c.cost_per_frame(*h)
    };
    runs.sort_by(|a, b| cost(a).total_cmp(&cost(b)));
    for (particle, (test, reference), spacing) in runs {
        let method = particle.method();
        let row = particle
            .run(
                *test,
                spacing,
                config.steps_of(*test),
                reference,
                &config.cache_dir,
                progress,
            )?
            .row;
        if let Some(mse) = row.mse {
            progress.status(format!(
                "{} {} {} = {spacing} m: MSE {mse:.2e}, {:.1} ms per 0.01 s",
                method.label(),
                test.name(),
                method.spacing_name(),
                row.ms_per_step
            ));
        }
        particle_baselines.push(row);
    }
    // Reported by method, test, then coarsest first, whatever order they ran in.
    particle_baselines.sort_by(|a, b| {
        (a.method, a.test != BeamTest::Bend)
            .cmp(&(b.method, b.test != BeamTest::Bend))
            .then(b.spacing.total_cmp(&a.spacing))
    });
    Ok(BeamStudy {
        config: config.clone(),
        rows,
        fem,
        particle_baselines,
    })
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

/// `test` with the regions held exactly (`exact.pins`): a basis built for the test's regions,
/// run and scored against the reference.
fn evaluate_exact(
    test: BeamTest,
    exact: &ReducedSettings,
    settings: &ReducedSettings,
    reference: &FemRun,
    steps: usize,
    config: &BeamStudyConfig,
    progress: &TerminalProgress,
) -> Result<ExactRow, EvalError> {
    let PinHold::Exact { inset } = exact.pins else {
        return Err(EvalError::InvalidInput(
            "exact rows need PinHold::Exact settings".into(),
        ));
    };
    progress.status(format!(
        "basis m = {} held exactly for {} (inset {inset:.3} m)",
        settings.modes,
        test.name()
    ));
    let basis = build_beam_basis_for(test, exact)?;
    let run = evaluate_field(
        test,
        &basis.basis,
        exact,
        reference,
        steps,
        &config.cache_dir,
        progress,
    )?;
    Ok(ExactRow {
        inset,
        mse: run.errors.normalized_mse,
        max: run.errors.normalized_max,
        max_pin_deviation: run.run.report.max_held_deviation,
        region_drift: region_drift(test, reference.vertices(), &run.run.frames),
        ms_per_step: run.run.report.ms_per_step,
        unconverged_steps: run.run.report.unconverged_steps,
        basis_seconds: basis.seconds,
    })
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
    )?;
    let scores = reference.score(field, &run.frames, beam_length_scale())?;
    Ok(FieldEvaluation {
        run,
        errors: scores.errors,
        per_frame_mse: scores.per_frame_mse,
        fitting_residual: scores.fitting_residual,
    })
}
