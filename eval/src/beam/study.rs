//! The beam study behind Tables 1, 5 and 6: for each m, one basis; for each test, the FEM ground
//! truth (cached) and a reduced run evaluated at the FEM vertices.

use baselines::SimplicitsParams;
use freeform::{PinHold, failure_chain};
use reduced_sim::QuadratureReport;
use serde::{Deserialize, Serialize};

use crate::EvalError;
use crate::beam_protocol::evaluation::{
    FemReference, FemSummary, evaluate_field, fem_references, region_drift,
};
use crate::beam_protocol::failed_row::FailedBeamRow;
use crate::beam_protocol::reduced::{
    BeamBasis, build_beam_basis, build_beam_basis_for, exact_pin_hold,
};
use crate::beam_protocol::study_config::BeamStudyConfig;
use crate::beam_scenario::BeamTest;
use crate::particle_baselines::particle_baseline::ParticleBaselineRow;
use crate::particle_baselines::particle_config::ParticleConfig;
use crate::reduced_settings::ReducedSettings;
use crate::simplicits_cache::{CachedSimplicits, train_beam_simplicits};
use freeform::fem_reference::FemRun;
use freeform::terminal_progress::TerminalProgress;

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

/// Everything the beam tables print.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BeamStudy {
    /// What was run.
    pub config: BeamStudyConfig,
    /// One row per (test, m), tests outermost.
    pub rows: Vec<BeamRow>,
    /// The (test, m) runs that failed (a basis that could not be built, a step that stopped),
    /// in the order run.
    #[serde(default)]
    pub failed_rows: Vec<FailedBeamRow>,
    /// One summary per test.
    pub fem: Vec<FemSummary>,
    /// The particle baselines (MPM, SPH) per (method, test, spacing), if run.
    #[serde(default)]
    pub particle_baselines: Vec<ParticleBaselineRow>,
}

/// Runs the study. A (test, m) run that fails (its basis, its steps, its Simplicits or exact
/// run) is recorded in [`BeamStudy::failed_rows`] with its error, and the study goes on with
/// the others.
///
/// # Errors
/// [`EvalError`] from a FEM reference or a particle baseline.
pub fn run_beam_study(
    config: &BeamStudyConfig,
    progress: &TerminalProgress,
) -> Result<BeamStudy, EvalError> {
    let (references, fem) = fem_references(config, progress)?;
    let mut rows = Vec::new();
    let mut failed_rows = Vec::new();
    let mut failed = |test: BeamTest, m: usize, error: &EvalError| {
        let error = failure_chain(error);
        progress.status(format!("{} m = {m} failed: {error}", test.name()));
        failed_rows.push(FailedBeamRow { test, m, error });
    };
    for &m in &config.modes {
        let settings = ReducedSettings {
            modes: m,
            ..config.settings
        };
        progress.status(format!("basis m = {m}, K = {}", settings.kernels));
        let shared = match shared_runs(config, &settings, progress) {
            Ok(shared) => shared,
            Err(e) => {
                for (test, _) in &references {
                    failed(*test, m, &e);
                }
                continue;
            }
        };
        for (test, reference) in &references {
            match beam_row(*test, reference, &settings, &shared, config, progress) {
                Ok(row) => rows.push(row),
                Err(e) => failed(*test, m, &e),
            }
        }
    }
    rows.sort_by_key(|r| (r.test != BeamTest::Bend, r.m));
    let particle_baselines = particle_baseline_rows(config, &references, progress)?;
    Ok(BeamStudy {
        config: config.clone(),
        rows,
        failed_rows,
        fem,
        particle_baselines,
    })
}

/// What every test at one m shares: the penalty's one basis (a basis that holds regions is
/// built per test), the exact pins' settings and the Simplicits network, as configured.
struct SharedRuns {
    basis: Option<BeamBasis>,
    exact: Option<ReducedSettings>,
    simplicits: Option<CachedSimplicits>,
}

/// [`SharedRuns`] at `settings`' m.
fn shared_runs(
    config: &BeamStudyConfig,
    settings: &ReducedSettings,
    progress: &TerminalProgress,
) -> Result<SharedRuns, EvalError> {
    let basis = match settings.pins {
        PinHold::Penalty => Some(build_beam_basis(settings)?),
        PinHold::Exact { .. } | PinHold::Weighted { .. } => None,
    };
    let exact = match config.exact_pins {
        Some(radii) => Some(ReducedSettings {
            pins: exact_pin_hold(settings, radii)?,
            ..*settings
        }),
        None => None,
    };
    let simplicits = match &config.simplicits {
        Some(params) => Some(train_beam_simplicits(
            &SimplicitsParams {
                modes: settings.modes,
                ..*params
            },
            settings.basis_points,
            &config.cache_dir,
            progress,
        )?),
        None => None,
    };
    Ok(SharedRuns {
        basis,
        exact,
        simplicits,
    })
}

/// The row of `test` at `settings`' m against `reference`.
fn beam_row(
    test: BeamTest,
    reference: &FemRun,
    settings: &ReducedSettings,
    shared: &SharedRuns,
    config: &BeamStudyConfig,
    progress: &TerminalProgress,
) -> Result<BeamRow, EvalError> {
    let steps = config.steps_of(test);
    let own;
    let basis = match &shared.basis {
        Some(basis) => basis,
        None => {
            own = build_beam_basis_for(test, settings)?;
            &own
        }
    };
    let ours = evaluate_field(
        test,
        &basis.basis,
        settings,
        reference,
        steps,
        &config.cache_dir,
        progress,
    )?;
    let simplicits = match &shared.simplicits {
        Some(net) => Some(baseline_row(
            test, net, settings, reference, steps, config, progress,
        )?),
        None => None,
    };
    Ok(BeamRow {
        test,
        m: settings.modes,
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
        region_drift: region_drift(test, reference.vertices(), &ours.run.frames),
        exact: match &shared.exact {
            Some(exact) => Some(evaluate_exact(
                test, exact, settings, reference, steps, config, progress,
            )?),
            None => None,
        },
        basis_seconds: basis.seconds,
        simplicits,
    })
}

/// Simplicits' row of `test`: its network simulated and scored against the reference, with
/// `settings`' step but the baseline's own treatment: penalty pins (its field holds no region)
/// and the material's volumetric term at every point.
fn baseline_row(
    test: BeamTest,
    net: &CachedSimplicits,
    settings: &ReducedSettings,
    reference: &FemRun,
    steps: usize,
    config: &BeamStudyConfig,
    progress: &TerminalProgress,
) -> Result<BaselineRow, EvalError> {
    let settings = ReducedSettings {
        pins: PinHold::Penalty,
        pressure: None,
        ..*settings
    };
    let e = evaluate_field(
        test,
        &net.trained.field,
        &settings,
        reference,
        steps,
        &config.cache_dir,
        progress,
    )?;
    Ok(BaselineRow {
        mse: e.errors.normalized_mse,
        max: e.errors.normalized_max,
        per_frame_mse: e.per_frame_mse,
        fitting_residual: e.fitting_residual,
        ms_per_step: e.run.report.ms_per_step,
        training_seconds: net.trained.report.seconds,
        unconverged_steps: e.run.report.unconverged_steps,
    })
}

/// The particle baselines' rows: every (method, test, spacing) run cheapest first, so that the
/// long runs come last, and reported by method, test, then coarsest first.
fn particle_baseline_rows(
    config: &BeamStudyConfig,
    references: &[FemReference],
    progress: &TerminalProgress,
) -> Result<Vec<ParticleBaselineRow>, EvalError> {
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
    Ok(particle_baselines)
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
