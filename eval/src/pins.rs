//! The pin sweep: the beam tests at several Poisson ratios and m, each with every
//! pin factor under both pin moduli, against the FEM reference at the same material: which rule
//! and factor are accurate across materials, and how far the pinned points drift.

use std::fmt::Write as _;
use std::path::PathBuf;

use hyperelastic::MaterialSample;
use nalgebra::Vector3;
use optimize::NewtonParams;
use reduced_sim::{PinModulus, SimulationParams};
use serde::{Deserialize, Serialize};
use skin_eigen::SkinningBasis;

use crate::EvalError;
use crate::beam_protocol::evaluation::region_drift;
use crate::beam_protocol::reduced::{
    build_beam_basis, build_beam_basis_for, exact_pin_hold, run_reduced_beam_with,
};
use crate::beam_scenario::{BeamTest, beam_length_scale, beam_material};
use crate::fem_reference::{FemResolution, run_fem_beam_with};
use crate::reduced_run::ReducedRun;
use crate::reduced_settings::{EXACT_INSET_KERNEL_RADII, ReducedSettings};
use freeform::failure_chain;
use freeform::metrics::{TrajectoryErrors, trajectory_errors};
use freeform::terminal_progress::TerminalProgress;

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
}

impl PinSweepConfig {
    /// ν ∈ {0.3, 0.45, 0.49}, m ∈ {16, 32}, Bend and Twist, factors 1e2…3e4 under both moduli,
    /// every point with Hessian reuse (same MSE as fresh Hessians, 5× faster), FEM P2 res 6.
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
        }
    }

    /// A few-minute version: ν ∈ {0.3, 0.49}, m = 16, 100 Bend steps, FEM P2 res 4, K = 500.
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

/// One (ν, test, m) run with the regions held exactly.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ExactSweepRow {
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
    pub exact_rows: Vec<ExactSweepRow>,
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
    let mut refused_references = Vec::new();
    for &nu in &config.poisson_ratios {
        let material = MaterialSample {
            poisson_ratio: nu,
            ..beam_material()
        };
        for &test in &config.tests {
            let steps = config.steps.unwrap_or(test.steps()).min(test.steps());
            let fem = run_fem_beam_with(
                test,
                config.fem,
                material,
                NewtonParams::default(),
                steps,
                &config.cache_dir,
                progress,
            )?;
            if let Err(why) = fem.check_converged(NewtonParams::default().max_iterations) {
                progress.status(format!("ν = {nu} {}: {why}", test.name()));
                refused_references.push(format!("ν = {nu}, {}: {why}", test.name()));
                continue;
            }
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
                    exact_rows.push(scored.exact_row(&base, radii)?);
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
    /// The row of the exact pins at `base`'s m, the regions shrunk by `radii` kernel radii.
    fn exact_row(&self, base: &ReducedSettings, radii: f64) -> Result<ExactSweepRow, EvalError> {
        let (test, nu, m, progress) = (
            self.test,
            self.material.poisson_ratio,
            base.modes,
            self.progress,
        );
        let exact = ReducedSettings {
            pins: exact_pin_hold(base, radii)?,
            ..*base
        };
        let basis = build_beam_basis_for(test, &exact)?;
        let mut row = ExactSweepRow {
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
        match self.run(&basis.basis, &exact)? {
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
            "ν = {nu} {} m = {m} exact: MSE {:.3e}, held drift {:.2e} m",
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

/// The sweep as Markdown: one row per (test, m, modulus, factor), one MSE and pin-drift column
/// pair per ν, and the best factor of each (test, m, ν, modulus) marked.
pub fn pin_sweep_table(config: &PinSweepConfig, sweep: &PinSweep) -> String {
    let rows = &sweep.rows;
    let mut md = format!(
        "## Pin sweep: beam, MSE against the FEM ({}) and largest pin drift (m)\n\n\
         E = 5 MPa, ρ = 1000 kg/m³, K = {}, {} simulation points, every point with Hessian \
         reuse. κ_pin = factor · (λ + 2μ or E) / L². ★ = lowest MSE of its (test, m, ν, \
         modulus).\n\n",
        config.fem.label(),
        config.settings.kernels,
        config.settings.simulation_points
    );
    for why in &sweep.refused_references {
        let _ = writeln!(md, "Not scored: {why}.\n");
    }
    md += "| test | m | modulus | factor |";
    for nu in &config.poisson_ratios {
        let _ = write!(md, " MSE ν={nu} | drift ν={nu} |");
    }
    md += "\n|---|---|---|---|";
    md += &"---|---|".repeat(config.poisson_ratios.len());
    md += "\n";
    let find = |test, m, modulus, factor, nu| {
        rows.iter().find(|r| {
            r.test == test
                && r.m == m
                && r.modulus == modulus
                && r.factor == factor
                && r.poisson_ratio == nu
        })
    };
    let best = |test, m, modulus, nu| {
        rows.iter()
            .filter(|r| {
                r.test == test
                    && r.m == m
                    && r.modulus == modulus
                    && r.poisson_ratio == nu
                    && r.failure.is_none()
            })
            .min_by(|a, b| a.mse.total_cmp(&b.mse))
            .map(|r| r.factor)
    };
    for &test in &config.tests {
        for &m in &config.modes {
            for &modulus in &config.moduli {
                for &factor in &config.factors {
                    let _ = write!(
                        md,
                        "| {} | {m} | {} | {factor:e} |",
                        test.name(),
                        modulus_name(modulus)
                    );
                    for &nu in &config.poisson_ratios {
                        match find(test, m, modulus, factor, nu) {
                            Some(r) if r.failure.is_some() => md += " failed | — |",
                            Some(r) => {
                                let star = if best(test, m, modulus, nu) == Some(factor) {
                                    " ★"
                                } else {
                                    ""
                                };
                                let _ = write!(
                                    md,
                                    " {:.3e}{star} | {:.2e} |",
                                    r.mse, r.max_pin_deviation
                                );
                            }
                            None => md += " — | — |",
                        }
                    }
                    md += "\n";
                }
            }
        }
    }
    md
}

/// The exact-pin rows as Markdown beside the best penalty of each (test, m, ν) (empty when the
/// sweep ran none).
pub fn exact_sweep_table(config: &PinSweepConfig, sweep: &PinSweep) -> String {
    let Some(radii) = config.exact_inset_radii else {
        return String::new();
    };
    let mut md = format!(
        "\n## Exact pins beside the best penalty\n\nRegions held exactly on the region shrunk by \
         {radii} median kernel radii (compact kernels, a basis per test), the band between kept \
         by the penalty. Drift: held points / FEM vertices of the whole region (m). Best \
         penalty: the lowest MSE of the sweep's factors and moduli at that (test, m, ν).\n\n\
         | test | m |"
    );
    for nu in &config.poisson_ratios {
        let _ = write!(
            md,
            " exact MSE ν={nu} | drift ν={nu} | best penalty ν={nu} |"
        );
    }
    md += "\n|---|---|";
    md += &"---|---|---|".repeat(config.poisson_ratios.len());
    md += "\n";
    for &test in &config.tests {
        for &m in &config.modes {
            let _ = write!(md, "| {} | {m} |", test.name());
            for &nu in &config.poisson_ratios {
                let exact = sweep
                    .exact_rows
                    .iter()
                    .find(|r| r.test == test && r.m == m && r.poisson_ratio == nu);
                let best = sweep
                    .rows
                    .iter()
                    .filter(|r| {
                        r.test == test && r.m == m && r.poisson_ratio == nu && r.failure.is_none()
                    })
                    .map(|r| r.mse)
                    .min_by(f64::total_cmp);
                let best = best.map_or("—".to_string(), |v| format!("{v:.3e}"));
                match exact {
                    Some(r) if r.failure.is_some() => {
                        let _ = write!(md, " failed | — | {best} |");
                    }
                    Some(r) => {
                        let _ = write!(
                            md,
                            " {:.3e} | {:.1e} / {:.2e} | {best} |",
                            r.mse, r.max_held_deviation, r.region_drift
                        );
                    }
                    None => {
                        let _ = write!(md, " — | — | {best} |");
                    }
                }
            }
            md += "\n";
        }
    }
    md
}

/// "λ+2μ" or "E".
fn modulus_name(modulus: PinModulus) -> &'static str {
    match modulus {
        PinModulus::PWave => "λ+2μ",
        PinModulus::Young => "E",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(nu: f64, modulus: PinModulus, factor: f64, mse: f64) -> PinSweepRow {
        PinSweepRow {
            poisson_ratio: nu,
            test: BeamTest::Bend,
            m: 16,
            modulus,
            factor,
            mse,
            max: 0.1,
            max_pin_deviation: 0.01,
            unconverged_steps: 0,
            failure: None,
        }
    }

    #[test]
    fn the_table_stars_the_lowest_mse_per_material_and_modulus_and_names_failures() {
        let config = PinSweepConfig {
            poisson_ratios: vec![0.3, 0.49],
            modes: vec![16],
            tests: vec![BeamTest::Bend],
            factors: vec![1e2, 1e3],
            moduli: vec![PinModulus::Young],
            ..PinSweepConfig::quick(PathBuf::from("unused"))
        };
        let mut failed = row(0.49, PinModulus::Young, 1e3, f64::NAN);
        failed.failure = Some("step 3 failed".into());
        let rows = vec![
            row(0.3, PinModulus::Young, 1e2, 2e-4),
            row(0.3, PinModulus::Young, 1e3, 1e-4),
            row(0.49, PinModulus::Young, 1e2, 3e-4),
            failed,
        ];
        let sweep = PinSweep {
            rows,
            exact_rows: vec![ExactSweepRow {
                poisson_ratio: 0.3,
                test: BeamTest::Bend,
                m: 16,
                mse: 5e-5,
                max: 1e-2,
                max_held_deviation: 1e-12,
                region_drift: 2e-2,
                unconverged_steps: 0,
                failure: None,
            }],
            refused_references: vec!["ν = 0.3, twist: not converged".into()],
        };
        let md = pin_sweep_table(&config, &sweep);
        assert!(
            md.contains("Not scored: ν = 0.3, twist: not converged."),
            "{md}"
        );
        let lines: Vec<&str> = md.lines().filter(|l| l.starts_with("| bend")).collect();
        assert_eq!(lines.len(), 2, "{md}");
        // ν = 0.3: 1e3 is best; ν = 0.49: 1e2 is the only one that ran.
        assert!(
            lines[0].contains("2.000e-4 |") && lines[0].contains("3.000e-4 ★"),
            "{md}"
        );
        assert!(
            lines[1].contains("1.000e-4 ★") && lines[1].contains("failed"),
            "{md}"
        );
        // The exact row sits beside the best penalty of its (test, m, ν).
        let exact = exact_sweep_table(&config, &sweep);
        let line = exact
            .lines()
            .find(|l| l.starts_with("| bend | 16 |"))
            .expect("an exact row");
        assert!(
            line.contains("5.000e-5 | 1.0e-12 / 2.00e-2 | 1.000e-4 |"),
            "{exact}"
        );
    }
}
