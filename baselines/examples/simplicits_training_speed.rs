//! Seconds per Simplicits training step on a 5 m beam of 5000 points (the paper's
//! 10 000 steps per shape must fit the time budget):
//! `cargo run --release -p baselines --example simplicits_training_speed -- --steps 200 --modes 32`.

use baselines::{SimplicitsParams, train_simplicits};
use hyperelastic::MaterialSample;
use nalgebra::Vector3;
use rkpm_core::sample_box_grid;

/// Command-line options.
#[derive(clap::Parser)]
struct Args {
    /// Adam steps to time.
    #[arg(long, default_value_t = 200)]
    steps: usize,
    /// Skinning weights m.
    #[arg(long, default_value_t = 32)]
    modes: usize,
}

fn main() {
    let args: Args = clap::Parser::parse();
    let points =
        sample_box_grid(Vector3::zeros(), Vector3::new(5.0, 1.0, 1.0), 0.1).expect("a valid box");
    let material = MaterialSample {
        youngs_modulus: 1e5,
        poisson_ratio: 0.45,
        density: 1000.0,
    };
    let lame = vec![material.lame_parameters().expect("valid material"); points.len()];
    let params = SimplicitsParams {
        modes: args.modes,
        steps: args.steps,
        ..SimplicitsParams::default()
    };
    let (_, report) = train_simplicits(&points, &lame, &params, |_, _| {}).expect("training");
    println!(
        "{} points, m = {}, {} steps: {:.2} ms/step (10 000 steps: {:.1} min); loss {:.3e} -> {:.3e} \
         (last exactly {:?}, for bit-for-bit comparisons)",
        points.len(),
        args.modes,
        args.steps,
        1e3 * report.seconds / args.steps as f64,
        report.seconds / args.steps as f64 * 1e4 / 60.0,
        report.first.total,
        report.last.total,
        report.last.total
    );
}
