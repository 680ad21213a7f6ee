//! How far the FEM ground truth is from a finer FEM, in the tables' own metric: the normalized
//! MSE and max error (design §4.3) between P2 at `--coarse` and P2 at `--fine` elements per
//! metre, evaluated at the coarse mesh's vertices. If this is far below the errors a table
//! reports, the ground truth is fine enough for that table.
//!
//! ```sh
//! cargo run --release -p eval --example reference_convergence -- --test twist --coarse 6 --fine 8
//! ```
//! Options: `--test bend|twist` (default twist), `--coarse R` (default 6), `--fine R` (default
//! 8), `--steps N` (default the test's). Both runs are cached under `freeform-cache/`.

use clap::Parser;
use eval::beam_scenario::{BeamTest, beam_length_scale};
use eval::fem_reference::{FemResolution, run_fem_beam};
use fem_ref::ElementOrder;
use freeform::metrics::trajectory_errors;
use freeform::terminal_progress::TerminalProgress;
use optimize::NewtonParams;

#[derive(Parser)]
struct Args {
    #[arg(long, default_value = "twist")]
    test: String,
    #[arg(long, default_value_t = 6)]
    coarse: usize,
    #[arg(long, default_value_t = 8)]
    fine: usize,
    #[arg(long)]
    steps: Option<usize>,
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let test = match args.test.as_str() {
        "bend" => BeamTest::Bend,
        "twist" => BeamTest::Twist,
        other => anyhow::bail!("--test must be bend or twist, not {other}"),
    };
    let steps = args.steps.unwrap_or(test.steps());
    let cache = freeform::default_cache_dir();
    let progress = TerminalProgress::default();
    let p2 = |cells_per_metre| FemResolution {
        order: ElementOrder::Quadratic,
        cells_per_metre,
    };
    let coarse = run_fem_beam(
        test,
        p2(args.coarse),
        NewtonParams::default(),
        steps,
        &cache,
        &progress,
    )?;
    let fine = run_fem_beam(
        test,
        p2(args.fine),
        NewtonParams::default(),
        steps,
        &cache,
        &progress,
    )?;
    let fine_at_coarse = fine.frames_at(coarse.vertices())?;
    let errors = trajectory_errors(
        &coarse.vertex_frames()[1..],
        &fine_at_coarse[1..],
        beam_length_scale(),
    )?;
    println!(
        "{} {steps} steps: P2 res {} ({} DOFs, {:.2} s/step) vs P2 res {} ({} DOFs, {:.2} s/step): \
         normalized MSE {:.3e}, normalized max {:.3e}",
        test.name(),
        args.coarse,
        coarse.dofs,
        coarse.seconds_per_step,
        args.fine,
        fine.dofs,
        fine.seconds_per_step,
        errors.normalized_mse,
        errors.normalized_max
    );
    Ok(())
}
