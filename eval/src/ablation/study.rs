//! The training ablations on the beam at one m (default 16): Table 3 (how the skinning weights
//! are found: Simplicits, our coefficients by Adam on two losses and two kinds of points, our
//! eigen solve) and Table 4 (grid or random integration points at simulation time).

use baselines::{CoefficientLoss, CoefficientTrainingParams, SimplicitsParams, TrainingPoints};
use reduced_sim::SkinningField;
use serde::{Deserialize, Serialize};
use skin_eigen::BasisParams;

use crate::EvalError;
use crate::ablation::coefficients::train_beam_coefficients;
use crate::beam_protocol::evaluation::{FemReference, FemSummary, evaluate_field, fem_references};
use crate::beam_protocol::reduced::build_beam_basis;
use crate::beam_protocol::study_config::BeamStudyConfig;
use crate::beam_scenario::BeamTest;
use crate::reduced_settings::{ReducedSettings, SimulationSampling};
use crate::simplicits_cache::train_beam_simplicits;
use freeform::terminal_progress::TerminalProgress;

/// What the ablation study runs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AblationStudyConfig {
    /// Tests, settings, steps, FEM reference, cache; `modes` must hold the one m studied and
    /// `simplicits` the training options every trained row shares (steps, points per step,
    /// learning rate, loss weights, seed).
    pub base: BeamStudyConfig,
    /// Table 3's four coefficient-training rows (minutes each the first time).
    pub coefficient_ablations: bool,
    /// Table 4's random-point simulations.
    pub sampling_ablation: bool,
    /// Seed of Table 4's random simulation points (default 1).
    pub random_points_seed: u64,
}

impl AblationStudyConfig {
    /// The paper's configuration: m = 16, the full beam study's settings.
    pub fn full(base: BeamStudyConfig) -> Self {
        AblationStudyConfig {
            base: BeamStudyConfig {
                modes: vec![16],
                simplicits: base.simplicits.or(Some(SimplicitsParams::default())),
                exact_pins: None,
                mpm: None,
                sph: None,
                ..base
            },
            coefficient_ablations: true,
            sampling_ablation: true,
            random_points_seed: 1,
        }
    }

    /// The one m studied.
    pub fn modes(&self) -> usize {
        self.base.modes.first().copied().unwrap_or(16)
    }

    /// The training options the trained rows share.
    pub fn training(&self) -> SimplicitsParams {
        SimplicitsParams {
            modes: self.modes(),
            ..self.base.simplicits.unwrap_or_default()
        }
    }

    /// The coefficient ablation with `loss` and `points`: Simplicits' step count, batch,
    /// transforms, learning rate, loss weights and seed; our kernels (K from the settings).
    pub fn coefficient_params(
        &self,
        loss: CoefficientLoss,
        points: TrainingPoints,
    ) -> CoefficientTrainingParams {
        let t = self.training();
        let ours = BasisParams::default().with_kernels(self.base.settings.kernels);
        CoefficientTrainingParams {
            modes: t.modes,
            kernels: ours.kernels,
            shape_functions: ours.shape_functions,
            steps: t.steps,
            points_per_step: t.points_per_step,
            transforms_per_step: t.transforms_per_step,
            transform_std: t.transform_std,
            learning_rate: t.learning_rate,
            elastic_weight: t.elastic_weight,
            ortho_weight: t.ortho_weight,
            seed: t.seed,
            ..CoefficientTrainingParams::new(loss, points)
        }
    }
}

/// One method's score on one test.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TestScore {
    /// Bend ("Drop") or Twist.
    pub test: BeamTest,
    /// Normalized MSE against FEM.
    pub mse: f64,
    /// Normalized max error.
    pub max: f64,
    /// Steps whose Newton solve did not converge.
    pub unconverged_steps: usize,
}

/// A Table 3 row: how the weights were found, and what they give.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AblationRow {
    /// "Simplicits", "random-z + random points", …, "eigen solve (ours)".
    pub method: String,
    /// One score per test.
    pub scores: Vec<TestScore>,
    /// Wall time of training / basis construction (s), from the run that produced it.
    pub training_seconds: f64,
    /// The trained model came from the cache.
    pub cached: bool,
    /// Total loss at the first and last training step (trained rows).
    pub loss: Option<(f64, f64)>,
}

/// A Table 4 row: one method and test with grid and random simulation points.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SamplingRow {
    /// "Simplicits" or "FreeForm".
    pub method: String,
    /// Bend ("Drop") or Twist.
    pub test: BeamTest,
    /// Normalized MSE with grid points.
    pub grid_mse: f64,
    /// Normalized MSE with random points.
    pub random_mse: f64,
}

/// Everything Tables 3 and 4 print.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AblationStudy {
    /// What was run.
    pub config: AblationStudyConfig,
    /// Table 3 rows in the paper's order (empty rows left out when not run).
    pub table3: Vec<AblationRow>,
    /// Table 4 rows (empty when not run).
    pub table4: Vec<SamplingRow>,
    /// The FEM side of each test.
    pub fem: Vec<FemSummary>,
}

impl AblationRow {
    /// The MSE on `test`, if it was run.
    pub fn mse(&self, test: BeamTest) -> Option<f64> {
        self.scores.iter().find(|s| s.test == test).map(|s| s.mse)
    }
}

/// Scores of `field` on every reference with the given settings.
fn score_all<B: SkinningField + ?Sized>(
    field: &B,
    settings: &ReducedSettings,
    config: &BeamStudyConfig,
    references: &[FemReference],
    progress: &TerminalProgress,
) -> Result<Vec<TestScore>, EvalError> {
    references
        .iter()
        .map(|(test, reference)| {
            let e = evaluate_field(
                *test,
                field,
                settings,
                reference,
                config.steps_of(*test),
                &config.cache_dir,
                progress,
            )?;
            Ok(TestScore {
                test: *test,
                mse: e.errors.normalized_mse,
                max: e.errors.normalized_max,
                unconverged_steps: e.run.report.unconverged_steps,
            })
        })
        .collect()
}

/// Table 4's rows for one method from its grid and random scores.
fn sampling_rows(method: &str, grid: &[TestScore], random: &[TestScore]) -> Vec<SamplingRow> {
    grid.iter()
        .zip(random)
        .map(|(g, r)| SamplingRow {
            method: method.into(),
            test: g.test,
            grid_mse: g.mse,
            random_mse: r.mse,
        })
        .collect()
}

/// Runs the study.
///
/// # Errors
/// [`EvalError`] from any run; nothing is half-reported.
pub fn run_ablation_study(
    config: &AblationStudyConfig,
    progress: &TerminalProgress,
) -> Result<AblationStudy, EvalError> {
    let base = &config.base;
    let (references, fem) = fem_references(base, progress)?;
    let m = config.modes();
    let settings = ReducedSettings {
        modes: m,
        ..base.settings
    };
    let random_settings = ReducedSettings {
        simulation_sampling: SimulationSampling::Random {
            seed: config.random_points_seed,
        },
        ..settings
    };

    progress.status(format!("basis m = {m}, K = {}", settings.kernels));
    let ours = build_beam_basis(&settings)?;
    let ours_scores = score_all(&ours.basis, &settings, base, &references, progress)?;
    let simplicits = train_beam_simplicits(
        &config.training(),
        settings.basis_points,
        &base.cache_dir,
        progress,
    )?;
    let simplicits_scores = score_all(
        &simplicits.trained.field,
        &settings,
        base,
        &references,
        progress,
    )?;

    let mut table3 = vec![AblationRow {
        method: "Simplicits".into(),
        scores: simplicits_scores.clone(),
        training_seconds: simplicits.trained.report.seconds,
        cached: simplicits.cached,
        loss: Some((
            simplicits.trained.report.first.total,
            simplicits.trained.report.last.total,
        )),
    }];
    if config.coefficient_ablations {
        for loss in [
            CoefficientLoss::RandomHandles,
            CoefficientLoss::WeightHessian,
        ] {
            for points in [TrainingPoints::Random, TrainingPoints::Grid] {
                let params = config.coefficient_params(loss, points);
                let trained = train_beam_coefficients(
                    &params,
                    settings.basis_points,
                    &base.cache_dir,
                    progress,
                )?;
                let report = &trained.trained.report;
                table3.push(AblationRow {
                    method: params.label().into(),
                    scores: score_all(
                        &trained.trained.basis,
                        &settings,
                        base,
                        &references,
                        progress,
                    )?,
                    training_seconds: report.seconds,
                    cached: trained.cached,
                    loss: Some((report.first.total, report.last.total)),
                });
            }
        }
    }
    table3.push(AblationRow {
        method: "eigen solve (ours)".into(),
        scores: ours_scores.clone(),
        training_seconds: ours.seconds,
        cached: false,
        loss: None,
    });

    let mut table4 = Vec::new();
    if config.sampling_ablation {
        let random = score_all(
            &simplicits.trained.field,
            &random_settings,
            base,
            &references,
            progress,
        )?;
        table4.extend(sampling_rows("Simplicits", &simplicits_scores, &random));
        let random = score_all(&ours.basis, &random_settings, base, &references, progress)?;
        table4.extend(sampling_rows("FreeForm", &ours_scores, &random));
    }
    Ok(AblationStudy {
        config: config.clone(),
        table3,
        table4,
        fem,
    })
}
