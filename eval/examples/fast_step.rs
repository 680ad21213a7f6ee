//! What each shortcut of a fast step buys and costs on the beam: for each test and
//! m, the reduced run with every combination of elastic quadrature (every point, the paper's
//! setting, or an optimized cubature at each `--cubature-tolerance`) and Hessian reuse (fresh
//! Hessians, the paper's setting, or `HessianReuse::WhileContracting { contraction }` at each
//! `--reuse-contraction`, default the library's 0.7),
//! all against the FEM ground truth (P2, 6 per metre): ms per step split into assembly / solve
//! / line search, Hessians and Newton iterations per step, quadrature points and cubature
//! training time, normalized MSE and its ratio to the full-quadrature, fresh-Hessian MSE, and
//! the normalized MSE between each run and that one ("MSE to full": what the shortcut itself
//! changes, without the FEM).
//!
//! ```sh
//! cargo run --release -p eval --example fast_step -- --modes 6,16,32 --tests bend,twist
//! ```
//! `--simulation-points N`, `--basis-points N` and `--kernels K` change the point sets and the
//! kernel count (the cubature is then trained on, and for, the N simulation points);
//! `--no-full` leaves out the every-point rows, `--pin-factor F` changes the pin penalty.
//! `--cubature-smallest-amplitude` and `--cubature-amplitude-levels` change the cubature's training-pose strains (on the beam at
//! m = 32, 0.005 over 5 levels did not lower the Bend MSE of 0.02 over 4). The FEM runs are cached under
//! `freeform-cache/` (or `$FREEFORM_CACHE`).

use clap::Parser;
use eval::beam_protocol::reduced::{build_beam_basis_for, exact_pin_hold, run_reduced_beam_with};
use eval::beam_scenario::{BeamTest, beam_length_scale, beam_material};
use eval::fem_reference::{FemResolution, run_fem_beam};
use eval::reduced_settings::ReducedSettings;
use freeform::RecordedRun;
use freeform::metrics::trajectory_errors;
use freeform::terminal_progress::TerminalProgress;
use optimize::{HessianReuse, NewtonParams};
use reduced_sim::{CubatureParams, HessianTangent, QuadratureRule, SimulationParams};

#[derive(Parser)]
struct Args {
    /// Modes m, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "6,16,32")]
    modes: Vec<usize>,
    /// Tests (bend, twist), comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "bend,twist")]
    tests: Vec<String>,
    /// Relative force errors the cubature is optimized to, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "0.02")]
    cubature_tolerance: Vec<f64>,
    /// Point budget of the cubature.
    #[arg(long, default_value_t = CubatureParams::default().max_points)]
    cubature_points: usize,
    /// Candidate pool of the cubature.
    #[arg(long, default_value_t = CubatureParams::default().candidates)]
    cubature_candidates: usize,
    /// Random handle-transform training poses per amplitude level of the cubature.
    #[arg(long, default_value_t = CubatureParams::default().poses_per_amplitude)]
    cubature_poses_per_amplitude: usize,
    /// Smallest root-mean-square Green strain of the cubature's training poses.
    #[arg(long, default_value_t = CubatureParams::default().smallest_amplitude)]
    cubature_smallest_amplitude: f64,
    /// Amplitude levels of the cubature's training poses.
    #[arg(long, default_value_t = CubatureParams::default().amplitude_levels)]
    cubature_amplitude_levels: usize,
    /// Whole-body twist and bend training poses of the cubature.
    #[arg(long, default_value_t = CubatureParams::default().field_poses)]
    cubature_field_poses: usize,
    /// Seeds of the cubature's training poses and candidates, comma-separated (one cubature
    /// per tolerance and seed).
    #[arg(long, value_delimiter = ',', default_value = "0")]
    cubature_seed: Vec<u64>,
    /// Skip the Hessian-reuse rows.
    #[arg(long)]
    no_reuse: bool,
    /// Contraction ratios of the Hessian-reuse rows, comma-separated (default the library's,
    /// `SimulationParams::HESSIAN_REUSE`).
    #[arg(long, value_delimiter = ',')]
    reuse_contraction: Vec<f64>,
    /// Also run every configuration with the exact tangent wherever the Newton system is
    /// definite (`HessianTangent::ExactWhenDefinite`).
    #[arg(long)]
    exact_when_definite: bool,
    /// Hold the clamped (and twisted) ends exactly, on each end shrunk by this many median
    /// kernel radii (a basis built for them), instead of the pin penalty.
    #[arg(long)]
    exact_pins: Option<f64>,
    /// Grid points the simulation integrates over (mass, gravity, pins, and the cubature's
    /// candidates and target), instead of the default 5000.
    #[arg(long)]
    simulation_points: Option<usize>,
    /// Grid points the basis is built on, instead of the default 20 000.
    #[arg(long)]
    basis_points: Option<usize>,
    /// RKPM kernels K, instead of the default 1000.
    #[arg(long)]
    kernels: Option<usize>,
    /// Pin penalty factor (default the library's, `ReducedSettings::default().pin_factor`).
    #[arg(long)]
    pin_factor: Option<f64>,
    /// Leave out the full-quadrature rows (the MSE ratio is then to the first cubature row).
    #[arg(long)]
    no_full: bool,
}

/// Every point (unless `--no-full`), then a cubature per (tolerance, seed).
fn quadrature_rules(args: &Args) -> Vec<QuadratureRule> {
    let mut rules = if args.no_full {
        Vec::new()
    } else {
        vec![QuadratureRule::Full]
    };
    for &tolerance in &args.cubature_tolerance {
        for &seed in &args.cubature_seed {
            rules.push(QuadratureRule::Cubature(CubatureParams {
                tolerance,
                max_points: args.cubature_points,
                candidates: args.cubature_candidates,
                poses_per_amplitude: args.cubature_poses_per_amplitude,
                field_poses: args.cubature_field_poses,
                smallest_amplitude: args.cubature_smallest_amplitude,
                amplitude_levels: args.cubature_amplitude_levels,
                seed,
                ..CubatureParams::default()
            }));
        }
    }
    rules
}

/// Fresh Hessians, then (unless `--no-reuse`) the library's reuse or each asked contraction.
fn hessian_reuses(args: &Args) -> Vec<HessianReuse> {
    let mut reuses = vec![HessianReuse::Never];
    if !args.no_reuse {
        if args.reuse_contraction.is_empty() {
            reuses.push(SimulationParams::HESSIAN_REUSE);
        }
        reuses.extend(
            args.reuse_contraction
                .iter()
                .map(|&contraction| HessianReuse::WhileContracting { contraction }),
        );
    }
    reuses
}

/// One printed row: the settings a run changed and what it measured.
struct Row<'a> {
    test: BeamTest,
    m: usize,
    settings: &'a ReducedSettings,
    run: &'a RecordedRun,
    /// Normalized MSE against the FEM.
    mse: f64,
    /// The first run's MSE (every point, fresh Hessians).
    full: f64,
    /// Normalized MSE between this run and the first.
    gap: f64,
}

fn print_row(row: &Row) {
    let Row {
        test,
        m,
        settings,
        run,
        mse,
        full,
        gap,
    } = *row;
    let r = &run.report;
    let (seconds, force) =
        r.quadrature
            .cubature
            .as_ref()
            .map_or(("-".to_string(), "-".to_string()), |c| {
                (
                    format!("{:.2}", c.seconds),
                    format!("{:.1e} / {:.1e}", c.training_error, c.validation_error),
                )
            });
    println!(
        "| {} | {m} | {} | {} | {seconds} | {force} | {} | {:?} | {:.2} | {:.2} | {:.2} \
         | {:.2} | {:.2} | {:.2} | {} | {mse:.3e} | {:.2} | {gap:.1e} |",
        test.name(),
        match settings.quadrature {
            QuadratureRule::Cubature(p) => {
                format!("cubature {} seed {}", p.tolerance, p.seed)
            }
            other => other.name().to_string(),
        },
        r.quadrature.points,
        match settings.hessian_reuse {
            HessianReuse::Never => "fresh".to_string(),
            HessianReuse::WhileContracting { contraction } => {
                format!("reused ({contraction})")
            }
        },
        settings.tangent,
        r.ms_per_step,
        r.ms_assembly_per_step,
        r.ms_solve_per_step,
        r.ms_line_search_per_step,
        r.hessians_per_step,
        r.iterations_per_step,
        r.unconverged_steps,
        mse / full,
    );
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let progress = TerminalProgress::default();
    let cache = freeform::default_cache_dir();
    let rules = quadrature_rules(&args);
    let reuses = hessian_reuses(&args);
    let tangents: &[HessianTangent] = if args.exact_when_definite {
        &[
            HessianTangent::ProjectedPsd,
            HessianTangent::ExactWhenDefinite,
        ]
    } else {
        &[HessianTangent::ProjectedPsd]
    };
    println!(
        "| test | m | quadrature | points | cubature s | force err. (train/unseen) | Hessians \
         | tangent \
         | ms/step | assembly | solve | line search | Hessians/step | Newton it./step \
         | unconverged | MSE | MSE / full | MSE to full |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for name in &args.tests {
        let test = match name.as_str() {
            "bend" => BeamTest::Bend,
            "twist" => BeamTest::Twist,
            other => anyhow::bail!("--tests: bend or twist, not {other}"),
        };
        let steps = test.steps();
        let fem = run_fem_beam(
            test,
            FemResolution::GROUND_TRUTH,
            NewtonParams::default(),
            steps,
            &cache,
            &progress,
        )?;
        fem.check_converged(NewtonParams::default().max_iterations)?;
        let reference = fem.vertex_frames();
        for &m in &args.modes {
            let defaults = ReducedSettings::default();
            let mut base = ReducedSettings {
                modes: m,
                simulation_points: args.simulation_points.unwrap_or(defaults.simulation_points),
                basis_points: args.basis_points.unwrap_or(defaults.basis_points),
                kernels: args.kernels.unwrap_or(defaults.kernels),
                pin_factor: args.pin_factor.unwrap_or(defaults.pin_factor),
                ..defaults
            };
            if let Some(radii) = args.exact_pins {
                base.pins = exact_pin_hold(&base, radii)?;
            }
            let basis = build_beam_basis_for(test, &base)?;
            let mut full_run: Option<(f64, Vec<Vec<nalgebra::Vector3<f64>>>)> = None;
            for &quadrature in &rules {
                for (&hessian_reuse, &tangent) in reuses
                    .iter()
                    .flat_map(|r| tangents.iter().map(move |t| (r, t)))
                {
                    let settings = ReducedSettings {
                        hessian_reuse,
                        quadrature,
                        tangent,
                        ..base
                    };
                    let run = run_reduced_beam_with(
                        test,
                        &basis.basis,
                        &settings,
                        beam_material(),
                        None,
                        fem.vertices(),
                        steps,
                        &progress,
                    )?;
                    let errors =
                        trajectory_errors(&run.frames[1..], &reference[1..], beam_length_scale())?;
                    let mse = errors.normalized_mse;
                    let (full, full_frames) =
                        full_run.get_or_insert_with(|| (mse, run.frames.clone()));
                    // What the shortcut itself changes: the normalized MSE between this run and
                    // the first (every point, fresh Hessians), FEM-free.
                    let gap = trajectory_errors(
                        &run.frames[1..],
                        &full_frames[1..],
                        beam_length_scale(),
                    )?
                    .normalized_mse;
                    print_row(&Row {
                        test,
                        m,
                        settings: &settings,
                        run: &run,
                        mse,
                        full: *full,
                        gap,
                    });
                }
            }
        }
    }
    Ok(())
}
