//! The beam Bend scene of design §4.1 on the FEM reference: 5 m × 1 m × 1 m, E = 5 MPa,
//! ν = 0.45, ρ = 1000 kg/m³, nodes with x ≤ 0.5 m fixed (the plane x = 0.5 included), gravity
//! 9.8 m/s² along -y, 100 steps of h = 0.01 s.
//!
//! ```sh
//! cargo run --release -p fem-ref --example beam_bend -- --order 2 --res 4 --json
//! ```
//! Options: `--order 1|2` (default 2), `--res r` (elements across the 1 m side, default 4; the
//! mesh has 5r × r × r cubes of 6 tetrahedra), `--steps S` (default 100), `--tangent psd|exact|exact-when-definite`
//! (default psd), `--tolerance T` (Newton, default 1e-6), `--reuse` (carry the Cholesky
//! factor across steps while chord steps contract), `--json`.
//!
//! `tip_y`: the y displacement (m) of the end face x = 5, the mean over an 11 × 11 lattice of
//! points on it interpolated from the elements, at t = 0.5 s and 1.0 s.

#[path = "common/beam.rs"]
mod beam;

use beam::{BeamScene, TangentArg, run_beam};
use fem_ref::ElementOrder;

/// Command-line options.
#[derive(clap::Parser)]
struct Args {
    /// Machine-readable output.
    #[arg(long)]
    json: bool,
    /// Element order.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u32).range(1..=2))]
    order: u32,
    /// Elements across the 1 m side.
    #[arg(long, default_value_t = 4)]
    res: usize,
    /// Steps of 0.01 s.
    #[arg(long, default_value_t = 100)]
    steps: usize,
    /// Newton tolerance.
    #[arg(long, default_value_t = 1e-6)]
    tolerance: f64,
    /// Element tangent.
    #[arg(long, value_enum, default_value_t = TangentArg::Psd)]
    tangent: TangentArg,
    /// Carry the Cholesky factor across steps while chord steps contract by 0.5 (the reduced
    /// simulator's default; off: a fresh factorization every Newton iteration).
    #[arg(long)]
    reuse: bool,
}

fn run() -> Result<(), String> {
    let args: Args = clap::Parser::parse();
    let Args {
        json,
        res,
        steps,
        tolerance,
        ..
    } = args;
    let order = if args.order == 1 {
        ElementOrder::Linear
    } else {
        ElementOrder::Quadratic
    };
    let tangent = args.tangent.into();
    if res == 0 || steps == 0 {
        return Err("--res and --steps must be positive".into());
    }
    let run = run_beam(
        BeamScene::Bend,
        order,
        res,
        steps,
        &[50, 100],
        tangent,
        optimize::NewtonParams {
            tolerance,
            hessian_reuse: if args.reuse {
                optimize::HessianReuse::WhileContracting { contraction: 0.5 }
            } else {
                optimize::HessianReuse::Never
            },
            ..Default::default()
        },
    )?;
    let tip: Vec<(String, f64)> = run
        .probes
        .iter()
        .map(|(t, v)| (format!("{t:.1}"), *v))
        .collect();
    if json {
        let tips: Vec<String> = tip
            .iter()
            .map(|(k, v)| format!("\"{k}\": {v:.8e}"))
            .collect();
        println!(
            "{{\"order\": {}, \"res\": {res}, \"steps\": {steps}, \"tip_y\": {{{}}}, \
             \"seconds_per_step\": {:.5}, \"assembly_seconds_per_step\": {:.5}, \
             \"factorization_seconds_per_step\": {:.5}, \"newton_iterations_mean\": {:.3}, \
             \"factorizations_mean\": {:.3}, \"unconverged_steps\": {}, \"dofs\": {}, \
             \"matrix_nonzeros\": {}}}",
            if order == ElementOrder::Linear { 1 } else { 2 },
            tips.join(", "),
            run.seconds_per_step,
            run.assembly_per_step,
            run.factorization_per_step,
            run.iterations_per_step,
            run.factorizations_per_step,
            run.unconverged_steps,
            run.dofs,
            run.nonzeros,
        );
    } else {
        println!(
            "FEM beam Bend, {order:?} elements, res {res}: {} free DOFs",
            run.dofs
        );
        for (k, v) in &tip {
            println!("tip y at t = {k} s: {v:.6} m");
        }
        println!(
            "{:.3} s/step (assembly {:.3}, factorization + solves {:.3}), {:.2} Newton \
             iterations and {:.2} factorizations per step, {} unconverged steps",
            run.seconds_per_step,
            run.assembly_per_step,
            run.factorization_per_step,
            run.iterations_per_step,
            run.factorizations_per_step,
            run.unconverged_steps
        );
    }
    Ok(())
}

fn main() {
    if let Err(e) = run() {
        eprintln!("beam_bend: {e}");
        std::process::exit(1);
    }
}
