//! What carrying the Hessian factorization across steps buys and costs on the beam (issue 18):
//! for each test and m, the reduced run with fresh Hessians (the paper's setting) and with
//! `HessianReuse::WhileContracting { contraction: 0.5 }`, both against the FEM ground truth
//! (P2, 6 per metre): ms per step, Hessians per step, Newton iterations per step, normalized MSE.
//!
//! ```sh
//! cargo run --release -p eval --example hessian_reuse -- --modes 6,16,32 --tests bend,twist
//! ```
//! The FEM runs are cached under `freeform-cache/` (or `$FREEFORM_CACHE`).

use clap::Parser;
use eval::beam::BeamTest;
use eval::beam::reduced::{ReducedSettings, build_beam_basis, run_reduced_beam};
use eval::beam::study::beam_length_scale;
use eval::bench::HESSIAN_REUSE;
use eval::fem_reference::{FemResolution, run_fem_beam};
use eval::metrics::trajectory_errors;
use eval::progress::Progress;
use optimize::{HessianReuse, NewtonParams};

#[derive(Parser)]
struct Args {
    /// Modes m, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "6,16,32")]
    modes: Vec<usize>,
    /// Tests (bend, twist), comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "bend,twist")]
    tests: Vec<String>,
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let progress = Progress::default();
    let cache = eval::default_cache_dir();
    println!(
        "| test | m | Hessians | ms/step | Hessians/step | Newton it./step | unconverged | MSE |"
    );
    println!("|---|---|---|---|---|---|---|---|");
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
            let base = ReducedSettings {
                modes: m,
                ..ReducedSettings::default()
            };
            let basis = build_beam_basis(&base)?;
            for hessian_reuse in [HessianReuse::Never, HESSIAN_REUSE] {
                let settings = ReducedSettings {
                    hessian_reuse,
                    ..base
                };
                let run = run_reduced_beam(
                    test,
                    &basis.basis,
                    &settings,
                    fem.vertices(),
                    steps,
                    &progress,
                )?;
                let errors =
                    trajectory_errors(&run.frames[1..], &reference[1..], beam_length_scale())?;
                println!(
                    "| {} | {m} | {} | {:.2} | {:.2} | {:.2} | {} | {:.3e} |",
                    test.name(),
                    if hessian_reuse == HessianReuse::Never {
                        "fresh"
                    } else {
                        "reused"
                    },
                    run.report.ms_per_step,
                    run.report.hessians_per_step,
                    run.report.iterations_per_step,
                    run.report.unconverged_steps,
                    errors.normalized_mse
                );
            }
        }
    }
    Ok(())
}
