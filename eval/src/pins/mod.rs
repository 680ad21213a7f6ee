//! The pin sweep: the beam tests at several Poisson ratios and m, each with every
//! pin factor under both pin moduli, against the FEM reference at the same material: which rule
//! and factor are accurate across materials, and how far the pinned points drift. Beside them,
//! the regions held exactly (the exact pins, and one setting with no parameter to tune, such as
//! the weighted basis), run unchanged at every ν.

use std::collections::HashMap;
use std::collections::hash_map::Entry;
use std::path::PathBuf;

use hyperelastic::MaterialSample;
use nalgebra::Vector3;
use reduced_sim::{PinModulus, SimulationParams};
use serde::{Deserialize, Serialize};
use skin_eigen::SkinningBasis;

use crate::EvalError;
use crate::beam_protocol::evaluation::region_drift;
use crate::beam_protocol::reduced::{
    build_beam_basis, build_beam_basis_for, exact_pin_hold, run_reduced_beam_with,
};
use crate::beam_scenario::{BeamTest, beam_length_scale, beam_material};
use crate::fem_reference::{FemResolution, converged_fem_beam};
use crate::reduced_run::ReducedRun;
use crate::reduced_settings::{EXACT_INSET_KERNEL_RADII, ReducedSettings};
use freeform::failure_chain;
use freeform::metrics::{TrajectoryErrors, trajectory_errors};
use freeform::terminal_progress::TerminalProgress;

use self::table::modulus_name;

pub mod table;

/// What the sweep runs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PinSweepConfig {
    /// Poisson ratios of the beam (E and ρ stay the beam's).
    pub poisson_ratios: Vec<f64>,
    /// Modes m.
    pub modes: Vec<usize>,
    /// Tests.
    pub tests: Vec<BeamTest>,
    /// Pin penalty factors.
    pub factors: Vec<f64>,
    /// Pin moduli.
    pub moduli: Vec<PinModulus>,
    /// Everything else of the reduced runs (its `modes`, `pin_factor`, `pin_modulus` are set
    /// per run).
    pub settings: ReducedSettings,
    /// Steps per test; `None` for design §4.1's.
    pub steps: Option<usize>,
    /// The FEM reference.
    pub fem: FemResolution,
    /// Cache folder.
    pub cache_dir: PathBuf,
    /// Also run each (ν, test, m) with the regions held exactly, shrunk by this many median
    /// kernel radii ([`exact_pin_hold`]); `None` leaves them out.
    #[serde(default)]
    pub exact_inset_radii: Option<f64>,
    /// Also run each (ν, test, m) with these settings (their `modes` set per row), the same at
    /// every ν: a hold with nothing to tune per material, such as the weighted basis
    /// ([`ReducedSettings::converging`]); `None` leaves them out.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub parameter_free: Option<ReducedSettings>,
}

impl PinSweepConfig {
    /// ν ∈ {0.3, 0.45, 0.49}, m ∈ {16, 32}, Bend and Twist, factors 1e2…3e4 under both moduli,
    /// every point with Hessian reuse (same MSE as fresh Hessians, 5× faster), FEM P2 res 6;
    /// beside them the exact pins and the parameter-free [`ReducedSettings::converging`].
    pub fn full(cache_dir: PathBuf) -> Self {
        PinSweepConfig {
            poisson_ratios: vec![0.3, 0.45, 0.49],
            modes: vec![16, 32],
            tests: BeamTest::ALL.to_vec(),
            factors: vec![1e2, 3e2, 1e3, 3e3, 1e4, 3e4],
            moduli: vec![PinModulus::PWave, PinModulus::Young],
            settings: ReducedSettings {
                hessian_reuse: SimulationParams::HESSIAN_REUSE,
                ..ReducedSettings::default()
            },
            steps: None,
            fem: FemResolution::GROUND_TRUTH,
            cache_dir,
            exact_inset_radii: Some(EXACT_INSET_KERNEL_RADII),
            parameter_free: Some(ReducedSettings::default().converging()),
        }
    }

    /// A few-minute version: ν ∈ {0.3, 0.49}, m = 16, 100 Bend steps, FEM P2 res 4, K = 500
    /// (the parameter-free rows too, on 10 000 basis and 5000 simulation points).
    pub fn quick(cache_dir: PathBuf) -> Self {
        PinSweepConfig {
            poisson_ratios: vec![0.3, 0.49],
            modes: vec![16],
            settings: ReducedSettings {
                kernels: 500,
                basis_points: 10_000,
                hessian_reuse: SimulationParams::HESSIAN_REUSE,
                ..ReducedSettings::default()
            },
            steps: Some(100),
            fem: FemResolution {
                cells_per_metre: 4,
                ..FemResolution::GROUND_TRUTH
            },
            parameter_free: Some(ReducedSettings {
                kernels: 500,
                basis_points: 10_000,
                simulation_points: 5000,
                ..ReducedSettings::default().converging()
            }),
            ..PinSweepConfig::full(cache_dir)
        }
    }
}

/// One (ν, test, m, modulus, factor) result.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PinSweepRow {
    /// Poisson ratio.
    pub poisson_ratio: f64,
    /// Bend or Twist.
    pub test: BeamTest,
    /// Modes.
    pub m: usize,
    /// Pin modulus.
    pub modulus: PinModulus,
    /// Pin factor.
    pub factor: f64,
    /// Normalized MSE against the FEM at the same ν.
    pub mse: f64,
    /// Normalized max error.
    pub max: f64,
    /// Largest pinned-point drift over the run (m).
    pub max_pin_deviation: f64,
    /// Steps that did not converge.
    pub unconverged_steps: usize,
    /// Why the run stopped, when it did (then the errors are NaN).
    pub failure: Option<String>,
}

/// One (ν, test, m) run with the regions held exactly (the exact pins, or the parameter-free
/// setting).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HeldSweepRow {
    /// Poisson ratio.
    pub poisson_ratio: f64,
    /// Bend or Twist.
    pub test: BeamTest,
    /// Modes.
    pub m: usize,
    /// Normalized MSE against the FEM at the same ν.
    pub mse: f64,
    /// Normalized max error.
    pub max: f64,
    /// Largest drift of the exactly held points (m).
    pub max_held_deviation: f64,
    /// Largest drift of the FEM vertices in the whole constrained regions (m).
    pub region_drift: f64,
    /// Steps that did not converge.
    pub unconverged_steps: usize,
    /// Why the run stopped, when it did (then the errors are NaN).
    pub failure: Option<String>,
}

/// The sweep's rows and the references it could not score against.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PinSweep {
    /// One per (ν, test, m, modulus, factor) whose FEM reference converged.
    pub rows: Vec<PinSweepRow>,
    /// One per (ν, test, m) with exact pins, when the sweep ran them.
    #[serde(default)]
    pub exact_rows: Vec<HeldSweepRow>,
    /// One per (ν, test, m) with [`PinSweepConfig::parameter_free`], when the sweep ran it.
    #[serde(default)]
    pub parameter_free_rows: Vec<HeldSweepRow>,
    /// "ν = …, test: why" for each FEM reference with an unconverged step (its test has no rows
    /// at that ν).
    pub refused_references: Vec<String>,
}

/// Runs the sweep. A FEM reference with an unconverged step is refused for scoring: its test
/// has no rows at that ν and [`PinSweep::refused_references`] says why.
///
/// # Errors
/// [`EvalError`] from a FEM run or a metric; a reduced run that fails is a row with its
/// `failure`.
pub fn run_pin_sweep(
    config: &PinSweepConfig,
    progress: &TerminalProgress,
) -> Result<PinSweep, EvalError> {
    let mut rows = Vec::new();
    let mut exact_rows = Vec::new();
    let mut parameter_free_rows = Vec::new();
    // The held bases per (test, m): a uniform material scales the weight-space Hessian, not its
    // eigenvectors, so one serves every ν.
    let mut parameter_free_bases = HashMap::new();
    let mut refused_references = Vec::new();
    for &nu in &config.poisson_ratios {
        let material = MaterialSample {
            poisson_ratio: nu,
            ..beam_material()
        };
        for &test in &config.tests {
            let steps = config.steps.unwrap_or(test.steps()).min(test.steps());
            let fem = match converged_fem_beam(
                test,
                config.fem,
                material,
                steps,
                &config.cache_dir,
                progress,
            )? {
                Ok(fem) => fem,
                Err(why) => {
                    progress.status(why.clone());
                    refused_references.push(why);
                    continue;
                }
            };
            let reference = fem.vertex_frames();
            let scored = ScoredRuns {
                test,
                material,
                vertices: fem.vertices(),
                reference: &reference,
                steps,
                config,
                progress,
            };
            for &m in &config.modes {
                let base = ReducedSettings {
                    modes: m,
                    ..config.settings
                };
                if let Some(radii) = config.exact_inset_radii {
                    let exact = ReducedSettings {
                        pins: exact_pin_hold(&base, radii)?,
                        ..base
                    };
                    let basis = build_beam_basis_for(test, &exact)?;
                    exact_rows.push(scored.held_row(&basis.basis, &exact, "exact")?);
                }
                if let Some(settings) = config.parameter_free {
                    let settings = ReducedSettings {
                        modes: m,
                        ..settings
                    };
                    let basis = match parameter_free_bases.entry((test, m)) {
                        Entry::Occupied(basis) => basis.into_mut(),
                        Entry::Vacant(entry) => {
                            entry.insert(build_beam_basis_for(test, &settings)?.basis)
                        }
                    };
                    parameter_free_rows.push(scored.held_row(
                        basis,
                        &settings,
                        "parameter-free",
                    )?);
                }
                // A uniform material scales the weight-space Hessian, not its eigenvectors: the
                // basis is the same at every ν.
                let basis = build_beam_basis(&base)?;
                for &modulus in &config.moduli {
                    for &factor in &config.factors {
                        rows.push(scored.factor_row(&basis.basis, &base, modulus, factor)?);
                    }
                }
            }
        }
    }
    Ok(PinSweep {
        rows,
        exact_rows,
        parameter_free_rows,
        refused_references,
    })
}

/// Reduced runs of one (ν, test) scored against its FEM reference.
struct ScoredRuns<'a> {
    test: BeamTest,
    material: MaterialSample,
    vertices: &'a [Vector3<f64>],
    reference: &'a [Vec<Vector3<f64>>],
    steps: usize,
    config: &'a PinSweepConfig,
    progress: &'a TerminalProgress,
}

impl ScoredRuns<'_> {
    /// The row of `basis` under `settings`, whose hold keeps the regions exactly; `what`
    /// names it in the progress line.
    fn held_row(
        &self,
        basis: &SkinningBasis,
        settings: &ReducedSettings,
        what: &str,
    ) -> Result<HeldSweepRow, EvalError> {
        let (test, nu, m, progress) = (
            self.test,
            self.material.poisson_ratio,
            settings.modes,
            self.progress,
        );
        let mut row = HeldSweepRow {
            poisson_ratio: nu,
            test,
            m,
            mse: f64::NAN,
            max: f64::NAN,
            max_held_deviation: f64::NAN,
            region_drift: f64::NAN,
            unconverged_steps: 0,
            failure: None,
        };
        match self.run(basis, settings)? {
            Ok((errors, run)) => {
                row.mse = errors.normalized_mse;
                row.max = errors.normalized_max;
                row.max_held_deviation = run.report.max_held_deviation;
                row.region_drift = region_drift(test, self.vertices, &run.frames);
                row.unconverged_steps = run.report.unconverged_steps;
            }
            Err(why) => row.failure = Some(why),
        }
        progress.status(format!(
            "ν = {nu} {} m = {m} {what}: MSE {:.3e}, held drift {:.2e} m",
            test.name(),
            row.mse,
            row.max_held_deviation
        ));
        Ok(row)
    }

    /// The row of the penalty `factor` on `modulus` at `base`'s m, on `basis`.
    fn factor_row(
        &self,
        basis: &SkinningBasis,
        base: &ReducedSettings,
        modulus: PinModulus,
        factor: f64,
    ) -> Result<PinSweepRow, EvalError> {
        let (test, nu, m, progress) = (
            self.test,
            self.material.poisson_ratio,
            base.modes,
            self.progress,
        );
        let settings = ReducedSettings {
            pin_factor: factor,
            pin_modulus: modulus,
            ..*base
        };
        let mut row = PinSweepRow {
            poisson_ratio: nu,
            test,
            m,
            modulus,
            factor,
            mse: f64::NAN,
            max: f64::NAN,
            max_pin_deviation: f64::NAN,
            unconverged_steps: 0,
            failure: None,
        };
        match self.run(basis, &settings)? {
            Ok((errors, run)) => {
                row.mse = errors.normalized_mse;
                row.max = errors.normalized_max;
                row.max_pin_deviation = run.report.max_pin_deviation;
                row.unconverged_steps = run.report.unconverged_steps;
            }
            // A pin too soft or too stiff for the step: reported in its row.
            Err(why) => row.failure = Some(why),
        }
        progress.status(format!(
            "ν = {nu} {} m = {m} {} factor {factor:e}: MSE {:.3e}, pin drift \
             {:.2e} m",
            test.name(),
            modulus_name(modulus),
            row.mse,
            row.max_pin_deviation
        ));
        Ok(row)
    }

    /// `basis` under `settings`, with its errors against the reference; `Ok(Err(why))` when the
    /// run stopped (a pin too soft or too stiff for the step), which the sweep reports in its
    /// row.
    ///
    /// # Errors
    /// [`EvalError`] from the metric.
    fn run(
        &self,
        basis: &SkinningBasis,
        settings: &ReducedSettings,
    ) -> Result<Result<(TrajectoryErrors, ReducedRun), String>, EvalError> {
        let run = run_reduced_beam_with(
            self.test,
            basis,
            settings,
            self.material,
            Some(&self.config.cache_dir),
            self.vertices,
            self.steps,
            self.progress,
        );
        match run {
            Ok(run) => {
                let errors =
                    trajectory_errors(&run.frames[1..], &self.reference[1..], beam_length_scale())?;
                Ok(Ok((errors, run)))
            }
            Err(e) => Ok(Err(failure_chain(&e))),
        }
    }
}
