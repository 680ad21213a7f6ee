//! The error-vs-time study (design §5) on the beam Bend: sweep the knobs that trade time for
//! error — modes m, kernels K, simulation points, Newton tolerance, and coarser FEM as its own
//! method — and mark the Pareto front (no other configuration is both faster and more accurate).

use optimize::{HessianReuse, NewtonParams};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use baselines::SimplicitsParams;
use fem_ref::ElementOrder;
use serde::{Deserialize, Serialize};

use crate::EvalError;
use crate::beam::mpm::MpmStudyConfig;
use crate::beam::particle_baseline::{ParticleBeamRun, ParticleMethod};
use crate::beam::particle_config::ParticleConfig;
use crate::beam::reduced::{
    EXACT_INSET_KERNEL_RADII, ReducedSettings, build_beam_basis_for, exact_pin_hold,
    run_reduced_beam, run_reduced_beam_with,
};
use crate::beam::simplicits::train_beam_simplicits;
use crate::beam::sph::SphStudyConfig;
use crate::beam::study::{beam_length_scale, region_drift};
use crate::beam::{BeamTest, beam_material};
use crate::fem_reference::{FemResolution, beam_seconds_per_step_here, run_fem_beam};
use crate::report::plot::{AxisScale, PlotSpec, Series};
use artifact::write_atomically;
use freeform::metrics::trajectory_errors;
use freeform::terminal_progress::TerminalProgress;
use freeform::{PinHold, RunReport};
use reduced_sim::{CubatureParams, QuadratureRule, SimulationParams};

/// The cubature of the bench's cubature series: [`CubatureParams::default`] (relative force
/// error 0.02 on the training poses, at most 400 points).
pub const CUBATURE: QuadratureRule = QuadratureRule::Cubature(CubatureParams::DEFAULT);

/// The bench's knob names with their plot labels, in plot order.
const FREEFORM_SERIES: [(&str, &str); 11] = [
    ("m", "FreeForm, varying m"),
    ("K", "FreeForm, varying K"),
    ("points", "FreeForm, varying points"),
    ("tolerance", "FreeForm, varying tolerance"),
    ("pin factor", "FreeForm, varying pin factor"),
    ("Hessian reuse", "FreeForm with Hessian reuse, varying m"),
    ("cubature", "FreeForm on a cubature, varying m"),
    (
        "cubature + reuse",
        "FreeForm on a cubature with Hessian reuse, varying m",
    ),
    (
        "quadrature points",
        "FreeForm m=16 on fewer points (cubature tolerance, random subsets)",
    ),
    (
        "exact pins",
        "FreeForm, exact pins, cubature with Hessian reuse, varying m",
    ),
    (
        "basis grid",
        "FreeForm on a cubature of the basis grid with Hessian reuse, varying m",
    ),
];

/// The fast-step series at modes `modes` on `base`: Hessian reuse on every point,
/// then the cubature with fresh and with reused Hessians.
fn fast_step_runs(base: ReducedSettings, modes: &[usize]) -> Vec<(String, BenchMethod)> {
    let mut runs = Vec::new();
    for (knob, quadrature, hessian_reuse) in [
        (
            "Hessian reuse",
            QuadratureRule::Full,
            SimulationParams::HESSIAN_REUSE,
        ),
        ("cubature", CUBATURE, HessianReuse::Never),
        (
            "cubature + reuse",
            CUBATURE,
            SimulationParams::HESSIAN_REUSE,
        ),
    ] {
        for &m in modes {
            runs.push((
                knob.into(),
                BenchMethod::FreeForm(ReducedSettings {
                    modes: m,
                    quadrature,
                    hessian_reuse,
                    ..base
                }),
            ));
        }
    }
    runs
}

/// One configuration to time.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum BenchMethod {
    /// FreeForm with these settings.
    FreeForm(ReducedSettings),
    /// FreeForm with these settings and the clamped end held exactly, on the end shrunk by this
    /// many median kernel radii ([`exact_pin_hold`]).
    FreeFormExact(ReducedSettings, f64),
    /// The FEM at a coarser resolution than the ground truth.
    Fem(FemResolution),
    /// The Simplicits baseline (network trained on the basis grid of the settings, cached),
    /// simulated with these settings.
    Simplicits(ReducedSettings, SimplicitsParams),
    /// The MPM baseline at this grid spacing (m), otherwise [`MpmStudyConfig::default`]
    /// (trajectories cached, shared with Table 1).
    Mpm(f64),
    /// The SPH baseline at this particle spacing (m), otherwise [`SphStudyConfig::default`]
    /// (trajectories cached, shared with Table 1).
    Sph(f64),
}

/// What to sweep.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BenchConfig {
    /// Bend steps (300 = design §4.1).
    pub steps: usize,
    /// The ground truth.
    pub ground_truth: FemResolution,
    /// (knob being varied, configuration).
    pub runs: Vec<(String, BenchMethod)>,
    /// Cache folder.
    pub cache_dir: PathBuf,
}

impl BenchConfig {
    /// The full sweep around the default (m = 16, K = 1000, 5000 points, tolerance 1e-6), the
    /// Simplicits baseline at the four m of Table 1 (trained once, about 10 min per m on 2
    /// cores, then cached), and five coarser FEM levels.
    pub fn full(cache_dir: PathBuf) -> Self {
        let base = ReducedSettings::default();
        let mut runs = Vec::new();
        for m in [6, 9, 16, 32] {
            runs.push((
                "m".into(),
                BenchMethod::FreeForm(ReducedSettings { modes: m, ..base }),
            ));
        }
        runs.extend(fast_step_runs(base, &[6, 9, 16, 32]));
        // The simulation on the basis's own grid (20 000 points instead of 5000): the cubature
        // keeps the step's cost, and the Bend MSE at m = 32 drops about 4×.
        for m in [6, 9, 16, 32] {
            runs.push((
                "basis grid".into(),
                BenchMethod::FreeForm(ReducedSettings {
                    modes: m,
                    simulation_points: base.basis_points,
                    quadrature: CUBATURE,
                    hessian_reuse: SimulationParams::HESSIAN_REUSE,
                    ..base
                }),
            ));
        }
        for m in [6, 9, 16, 32] {
            runs.push((
                "exact pins".into(),
                BenchMethod::FreeFormExact(
                    ReducedSettings {
                        modes: m,
                        ..ReducedSettings::library_default()
                    },
                    EXACT_INSET_KERNEL_RADII,
                ),
            ));
        }
        for tolerance in [0.05, 0.005] {
            runs.push((
                "quadrature points".into(),
                BenchMethod::FreeForm(ReducedSettings {
                    quadrature: QuadratureRule::Cubature(CubatureParams {
                        tolerance,
                        ..CubatureParams::DEFAULT
                    }),
                    ..base
                }),
            ));
        }
        for points in [150, 500] {
            runs.push((
                "quadrature points".into(),
                BenchMethod::FreeForm(ReducedSettings {
                    quadrature: QuadratureRule::RandomSubset { points, seed: 0 },
                    ..base
                }),
            ));
        }
        for k in [250, 500, 2000] {
            runs.push((
                "K".into(),
                BenchMethod::FreeForm(ReducedSettings { kernels: k, ..base }),
            ));
        }
        for n in [1000, 2000, 10_000] {
            runs.push((
                "points".into(),
                BenchMethod::FreeForm(ReducedSettings {
                    simulation_points: n,
                    ..base
                }),
            ));
        }
        for tol in [1e-2, 1e-4] {
            runs.push((
                "tolerance".into(),
                BenchMethod::FreeForm(ReducedSettings {
                    tolerance: tol,
                    ..base
                }),
            ));
        }
        for pin_factor in [1e2, 1e4] {
            runs.push((
                "pin factor".into(),
                BenchMethod::FreeForm(ReducedSettings { pin_factor, ..base }),
            ));
        }
        for m in [6, 9, 16, 32] {
            runs.push((
                "m".into(),
                BenchMethod::Simplicits(
                    ReducedSettings { modes: m, ..base },
                    SimplicitsParams {
                        modes: m,
                        ..SimplicitsParams::default()
                    },
                ),
            ));
        }
        // Δx = 0.05 m would add more than an hour (Table 1 runs it).
        for spacing in [0.2, 0.1] {
            runs.push(("MPM Δx".into(), BenchMethod::Mpm(spacing)));
        }
        // 0.05 m (40 000 particles) takes about 3 min for the 300 steps; Table 1 runs it.
        for spacing in [0.2, 0.1] {
            runs.push(("SPH spacing".into(), BenchMethod::Sph(spacing)));
        }
        for (order, r) in [
            (ElementOrder::Linear, 2),
            (ElementOrder::Linear, 4),
            (ElementOrder::Linear, 8),
            (ElementOrder::Quadratic, 2),
            (ElementOrder::Quadratic, 4),
        ] {
            runs.push((
                "FEM".into(),
                BenchMethod::Fem(FemResolution {
                    order,
                    cells_per_metre: r,
                }),
            ));
        }
        BenchConfig {
            steps: BeamTest::Bend.steps(),
            ground_truth: FemResolution::GROUND_TRUTH,
            runs,
            cache_dir,
        }
    }

    /// A one-minute sweep: 100 steps, ground truth P2 res 4, m ∈ {6, 16} at K = 500, two FEM
    /// levels.
    pub fn quick(cache_dir: PathBuf) -> Self {
        let base = ReducedSettings {
            kernels: 500,
            basis_points: 10_000,
            ..ReducedSettings::default()
        };
        let mut runs: Vec<(String, BenchMethod)> = [6, 16]
            .into_iter()
            .map(|m| {
                (
                    "m".into(),
                    BenchMethod::FreeForm(ReducedSettings { modes: m, ..base }),
                )
            })
            .collect();
        runs.push((
            "points".into(),
            BenchMethod::FreeForm(ReducedSettings {
                simulation_points: 2000,
                ..base
            }),
        ));
        runs.extend(fast_step_runs(base, &[6, 16]));
        for order in [ElementOrder::Linear, ElementOrder::Quadratic] {
            runs.push((
                "FEM".into(),
                BenchMethod::Fem(FemResolution {
                    order,
                    cells_per_metre: 2,
                }),
            ));
        }
        BenchConfig {
            steps: 100,
            ground_truth: FemResolution {
                cells_per_metre: 4,
                ..FemResolution::GROUND_TRUTH
            },
            runs,
            cache_dir,
        }
    }
}

/// One timed configuration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BenchResult {
    /// "freeform", "simplicits" or "fem".
    pub method: String,
    /// The knob varied ("m", "K", "points", "tolerance", "pin factor", "FEM").
    pub knob: String,
    /// Human-readable settings.
    pub label: String,
    /// Wall time per step (ms).
    pub ms_per_step: f64,
    /// Of which Hessian/gradient assembly, factorization and solve, line search (ms; 0 for the
    /// FEM, whose split is not recorded here).
    pub ms_split: [f64; 3],
    /// Hessians assembled per step (1 for the FEM, which assembles every iteration's).
    pub hessians_per_step: f64,
    /// Points the elastic energy is evaluated at (FreeForm and Simplicits; 0 for the FEM).
    pub quadrature_points: usize,
    /// One-off cost before stepping: basis build and quadrature for FreeForm, training for
    /// Simplicits (from the run that produced the cached network) (s); 0 for FEM.
    pub setup_seconds: f64,
    /// Normalized MSE against the ground truth.
    pub normalized_mse: f64,
    /// Normalized max error.
    pub normalized_max: f64,
    /// Largest distance (m) of a ground-truth vertex in the clamped end from its rest position
    /// over the run (0 for the FEM, which holds them).
    #[serde(default)]
    pub region_drift: f64,
    /// On the Pareto front of (ms per step, MSE).
    pub pareto: bool,
}

/// Indices of the results no other result beats in both time and error.
pub fn pareto_front(points: &[(f64, f64)]) -> Vec<usize> {
    (0..points.len())
        .filter(|&i| {
            !(0..points.len()).any(|j| {
                j != i
                    && points[j].0 <= points[i].0
                    && points[j].1 <= points[i].1
                    && (points[j].0 < points[i].0 || points[j].1 < points[i].1)
            })
        })
        .collect()
}

/// Runs every configuration against the ground truth.
///
/// # Errors
/// [`EvalError`] from any run.
pub fn run_bench(
    config: &BenchConfig,
    progress: &TerminalProgress,
) -> Result<Vec<BenchResult>, EvalError> {
    let truth = run_fem_beam(
        BeamTest::Bend,
        config.ground_truth,
        NewtonParams::default(),
        config.steps,
        &config.cache_dir,
        progress,
    )?;
    truth.check_converged(NewtonParams::default().max_iterations)?;
    let truth_frames = truth.vertex_frames();
    let vertices = truth.vertices().to_vec();
    let length = beam_length_scale();
    let (default_mpm, default_sph) = (MpmStudyConfig::default(), SphStudyConfig::default());
    let mut results = Vec::new();
    for (knob, method) in &config.runs {
        let exact;
        let method = match method {
            BenchMethod::FreeFormExact(s, radii) => {
                exact = BenchMethod::FreeForm(ReducedSettings {
                    pins: exact_pin_hold(s, *radii)?,
                    ..*s
                });
                &exact
            }
            method => method,
        };
        let mut drift = 0.0;
        let (name, label, timing, setup, frames) = match method {
            BenchMethod::FreeForm(s) => {
                let basis = build_beam_basis_for(BeamTest::Bend, s)?;
                let run = run_reduced_beam_with(
                    BeamTest::Bend,
                    &basis.basis,
                    s,
                    beam_material(),
                    Some(&config.cache_dir),
                    &vertices,
                    config.steps,
                    progress,
                )?;
                drift = region_drift(BeamTest::Bend, &vertices, &run.frames);
                (
                    "freeform",
                    format!(
                        "m={} K={} pts={} tol={:e} pin={}{}{}",
                        s.modes,
                        s.kernels,
                        run.report.simulation_points,
                        s.tolerance,
                        match s.pins {
                            PinHold::Penalty => format!("{:e}", s.pin_factor),
                            PinHold::Exact { inset } => format!("exact(inset {inset:.3} m)"),
                            PinHold::Weighted { .. } => "weighted".to_string(),
                        },
                        match s.hessian_reuse {
                            HessianReuse::Never => String::new(),
                            HessianReuse::WhileContracting { contraction } => {
                                format!(" reuse={contraction}")
                            }
                        },
                        quadrature_label(&s.quadrature, run.report.quadrature.points),
                    ),
                    Timing::of(&run.report),
                    basis.seconds + run.report.setup_seconds,
                    run.frames,
                )
            }
            BenchMethod::Simplicits(s, params) => {
                let net =
                    train_beam_simplicits(params, s.basis_points, &config.cache_dir, progress)?;
                let run = run_reduced_beam(
                    BeamTest::Bend,
                    &net.trained.field,
                    s,
                    &vertices,
                    config.steps,
                    progress,
                )?;
                (
                    "simplicits",
                    format!(
                        "m={} pts={} ({} training steps)",
                        s.modes, run.report.simulation_points, params.steps
                    ),
                    Timing::of(&run.report),
                    net.trained.report.seconds,
                    {
                        drift = region_drift(BeamTest::Bend, &vertices, &run.frames);
                        run.frames
                    },
                )
            }
            BenchMethod::Mpm(spacing) | BenchMethod::Sph(spacing) => {
                let particle = match method {
                    BenchMethod::Mpm(_) => ParticleConfig::Mpm(&default_mpm),
                    _ => ParticleConfig::Sph(&default_sph),
                };
                let method = particle.method();
                let ParticleBeamRun { row, frames } = particle.run(
                    BeamTest::Bend,
                    *spacing,
                    config.steps,
                    &truth,
                    &config.cache_dir,
                    progress,
                )?;
                if let Some(why) = &row.failure {
                    progress.status(format!(
                        "{} {} = {spacing} m left out: {why}",
                        method.label(),
                        method.spacing_name()
                    ));
                    continue;
                }
                drift = row.max_pin_deviation;
                (
                    method.key(),
                    format!(
                        "{}={} m ({} particles, {} steps per 0.01 s)",
                        method.spacing_name(),
                        row.spacing,
                        row.particles,
                        row.substeps_per_step
                    ),
                    Timing {
                        ms_per_step: row.ms_per_step,
                        split: [0.0; 3],
                        hessians_per_step: 0.0,
                        quadrature_points: 0,
                    },
                    row.setup_seconds,
                    frames,
                )
            }
            BenchMethod::FreeFormExact(..) => unreachable!("resolved to FreeForm above"),
            BenchMethod::Fem(r) => {
                let run = run_fem_beam(
                    BeamTest::Bend,
                    *r,
                    NewtonParams::default(),
                    config.steps,
                    &config.cache_dir,
                    progress,
                )?;
                let frames = run.frames_at(&vertices)?;
                let (seconds_per_step, _) = beam_seconds_per_step_here(
                    &run,
                    BeamTest::Bend,
                    *r,
                    NewtonParams::default(),
                    config.steps,
                )?;
                (
                    "fem",
                    format!("{} ({} DOFs)", r.label(), run.dofs),
                    Timing {
                        ms_per_step: 1e3 * seconds_per_step,
                        split: [0.0; 3],
                        hessians_per_step: 1.0,
                        quadrature_points: 0,
                    },
                    0.0,
                    frames,
                )
            }
        };
        let errors = trajectory_errors(&frames[1..], &truth_frames[1..], length)?;
        progress.status(format!(
            "{name} {label}: {:.2} ms/step, MSE {:.2e}",
            timing.ms_per_step, errors.normalized_mse
        ));
        results.push(BenchResult {
            method: name.into(),
            knob: knob.clone(),
            label,
            ms_per_step: timing.ms_per_step,
            ms_split: timing.split,
            hessians_per_step: timing.hessians_per_step,
            quadrature_points: timing.quadrature_points,
            setup_seconds: setup,
            normalized_mse: errors.normalized_mse,
            normalized_max: errors.normalized_max,
            region_drift: drift,
            pareto: false,
        });
    }
    let points: Vec<(f64, f64)> = results
        .iter()
        .map(|r| (r.ms_per_step, r.normalized_mse))
        .collect();
    for i in pareto_front(&points) {
        results[i].pareto = true;
    }
    Ok(results)
}

/// A run's step cost as the bench reports it.
struct Timing {
    ms_per_step: f64,
    split: [f64; 3],
    hessians_per_step: f64,
    quadrature_points: usize,
}

impl Timing {
    fn of(report: &RunReport) -> Timing {
        Timing {
            ms_per_step: report.ms_per_step,
            split: [
                report.ms_assembly_per_step,
                report.ms_solve_per_step,
                report.ms_line_search_per_step,
            ],
            hessians_per_step: report.hessians_per_step,
            quadrature_points: report.quadrature.points,
        }
    }
}

/// " cubature(tol=0.02, 142 pts)", " random(500 pts)", or "" for every point.
pub fn quadrature_label(rule: &QuadratureRule, points: usize) -> String {
    match rule {
        QuadratureRule::Full => String::new(),
        QuadratureRule::RandomSubset { .. } => format!(" random({points} pts)"),
        QuadratureRule::Cubature(p) => format!(" cubature(tol={}, {points} pts)", p.tolerance),
        QuadratureRule::Automatic(p) => {
            format!(" automatic(tol={}, {points} pts)", p.tolerance)
        }
    }
}

/// Writes `bench.csv` and `bench.md` under `dir`; returns the Markdown and the paths.
///
/// # Errors
/// [`EvalError`] for a file that cannot be written.
pub fn write_bench(
    results: &[BenchResult],
    config: &BenchConfig,
    dir: &Path,
) -> Result<(String, Vec<PathBuf>), EvalError> {
    let mut csv = String::from(
        "method,knob,label,ms_per_step,ms_assembly,ms_solve,ms_line_search,hessians_per_step,quadrature_points,setup_seconds,normalized_mse,normalized_max,region_drift,pareto\n",
    );
    let mut md = format!(
        "## Error vs time, beam Bend ({} steps; ground truth FEM {}; {} threads)\n\n\
         | method | knob | settings | ms/step | assembly / solve / line search | Hessians/step | setup s | MSE | max | clamp drift (mm) | Pareto |\n|---|---|---|---|---|---|---|---|---|---|---|\n",
        config.steps,
        config.ground_truth.label(),
        rayon::current_num_threads()
    );
    for r in results {
        let _ = writeln!(
            csv,
            "{},{},\"{}\",{},{},{},{},{},{},{},{:e},{:e},{:e},{}",
            r.method,
            r.knob,
            r.label,
            r.ms_per_step,
            r.ms_split[0],
            r.ms_split[1],
            r.ms_split[2],
            r.hessians_per_step,
            r.quadrature_points,
            r.setup_seconds,
            r.normalized_mse,
            r.normalized_max,
            r.region_drift,
            r.pareto
        );
        let _ = writeln!(
            md,
            "| {} | {} | {} | {:.2} | {:.2} / {:.2} / {:.2} | {:.2} | {:.1} | {:.2e} | {:.2e} | {:.1} | {} |",
            r.method,
            r.knob,
            r.label,
            r.ms_per_step,
            r.ms_split[0],
            r.ms_split[1],
            r.ms_split[2],
            r.hessians_per_step,
            r.setup_seconds,
            r.normalized_mse,
            r.normalized_max,
            1e3 * r.region_drift,
            if r.pareto { "★" } else { "" }
        );
    }
    let mut written = Vec::new();
    for (name, text) in [("bench.csv", &csv), ("bench.md", &md)] {
        let path = dir.join(name);
        write_atomically(&path, text.as_bytes())?;
        written.push(path);
    }
    Ok((md, written))
}

/// The headline figure: normalized MSE against ms per step, log-log, one colour per knob, the
/// coarser FEM levels, and the Pareto front as a line. Draw it with
/// [`crate::report::plot::write_plot`].
pub fn bench_plot(results: &[BenchResult], config: &BenchConfig) -> PlotSpec {
    let mut series: Vec<Series> = Vec::new();
    for (i, (knob, label)) in FREEFORM_SERIES.into_iter().enumerate() {
        let mut points: Vec<(f64, f64)> = results
            .iter()
            .filter(|r| r.method == "freeform" && r.knob == knob)
            .map(|r| (r.ms_per_step, r.normalized_mse))
            .collect();
        if points.is_empty() {
            continue;
        }
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        series.push(Series {
            label: label.into(),
            points,
            line: false,
            // Colours 5-7 are the front, the coarser FEM and Simplicits; 14 and 15 MPM and
            // SPH; 13 is too pale to read (Palette99).
            color: match i {
                0..5 => i,
                5..10 => 8 + i - 5,
                _ => 18 + i - 10,
            },
        });
    }
    let mut simplicits: Vec<(f64, f64)> = results
        .iter()
        .filter(|r| r.method == "simplicits")
        .map(|r| (r.ms_per_step, r.normalized_mse))
        .collect();
    if !simplicits.is_empty() {
        simplicits.sort_by(|a, b| a.0.total_cmp(&b.0));
        series.push(Series {
            label: "Simplicits, varying m".into(),
            points: simplicits,
            line: false,
            color: 7,
        });
    }
    let fem: Vec<(f64, f64)> = results
        .iter()
        .filter(|r| r.method == "fem")
        .map(|r| (r.ms_per_step, r.normalized_mse))
        .collect();
    if !fem.is_empty() {
        series.push(Series {
            label: "coarser FEM (P1/P2)".into(),
            points: fem,
            line: false,
            color: 6,
        });
    }
    for (method, color) in [(ParticleMethod::Mpm, 14), (ParticleMethod::Sph, 15)] {
        let points: Vec<(f64, f64)> = results
            .iter()
            .filter(|r| r.method == method.key())
            .map(|r| (r.ms_per_step, r.normalized_mse))
            .collect();
        if !points.is_empty() {
            series.push(Series {
                label: format!("{}, varying {}", method.label(), method.spacing_name()),
                points,
                line: false,
                color,
            });
        }
    }
    let mut front: Vec<(f64, f64)> = results
        .iter()
        .filter(|r| r.pareto)
        .map(|r| (r.ms_per_step, r.normalized_mse))
        .collect();
    front.sort_by(|a, b| a.0.total_cmp(&b.0));
    // First, so the markers of every configuration are drawn over the front's line.
    series.insert(
        0,
        Series {
            label: "Pareto front".into(),
            points: front,
            line: true,
            color: 5,
        },
    );
    PlotSpec {
        title: format!(
            "Beam Bend: error vs time per step (truth: FEM {})",
            config.ground_truth.label()
        ),
        x_label: "ms per 0.01 s step (this machine)".into(),
        y_label: "normalized MSE vs FEM".into(),
        scale: AxisScale::LogLog,
        series,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pareto_front_keeps_exactly_the_undominated_points() {
        let points = [
            (1.0, 5.0),
            (2.0, 3.0),
            (3.0, 4.0),
            (4.0, 1.0),
            (2.0, 3.0),
            (5.0, 1.0),
        ];
        // (3,4) is beaten by (2,3); (5,1) by (4,1); the duplicate (2,3) pair dominate nothing
        // of each other.
        assert_eq!(pareto_front(&points), vec![0, 1, 3, 4]);
    }
}
