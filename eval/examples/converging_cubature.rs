//! How well the converging setting's cubature integrates the beam's reduced elastic forces
//! (`ReducedSettings::converging`: the weighted basis of the Bend's held region, 40 000
//! simulation points): for the material's own volumetric term and for the projected one, and
//! for each candidate pool, the optimization's report (points, what stopped it, training and
//! validation error, seconds) and the force error on unseen poses of the model integrated by
//! the cubature (its pressure projected over the cubature's points) against the full model,
//! in the compliance-weighted norm of `force_weights`: RMS and largest over the poses.
//!
//! ```sh
//! cargo run --release -p eval --example converging_cubature -- --modes 32 --candidates 5000,10000
//! ```

use std::time::Instant;

use clap::Parser;
use eval::beam_protocol::reduced::{beam_pressure_space, build_beam_basis_for};
use eval::beam_scenario::{BeamTest, beam_material};
use eval::reduced_settings::ReducedSettings;
use hyperelastic::StableNeoHookean;
use reduced_sim::quadrature::cubature::{force_weights, training_poses};
use reduced_sim::{CubatureParams, ReducedModel, optimize_cubature};

/// Command-line options.
#[derive(Parser)]
struct Args {
    /// Modes m.
    #[arg(long, default_value_t = 32)]
    modes: usize,
    /// Candidate pools to optimize with, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "5000,10000")]
    candidates: Vec<usize>,
    /// Unseen poses per amplitude level (twice as many field poses).
    #[arg(long, default_value_t = 3)]
    unseen_per_amplitude: usize,
    /// Points the greedy selection adds at least per batch.
    #[arg(long, default_value_t = CubatureParams::DEFAULT.batch)]
    batch: usize,
    /// Least distance between the points of one batch, in candidate spacings (0: none).
    #[arg(long, default_value_t = CubatureParams::DEFAULT.batch_spacing)]
    batch_spacing: f64,
    /// Training poses per amplitude level.
    #[arg(long, default_value_t = CubatureParams::DEFAULT.poses_per_amplitude)]
    poses_per_amplitude: usize,
    /// Training twists and bends.
    #[arg(long, default_value_t = CubatureParams::DEFAULT.field_poses)]
    field_poses: usize,
}

/// `‖ω ∘ (a − b)‖ / ‖ω ∘ b‖`.
fn relative_error(a: &[f64], b: &[f64], omega: &[f64]) -> f64 {
    let difference: f64 = a
        .iter()
        .zip(b)
        .zip(omega)
        .map(|((a, b), w)| ((a - b) * w).powi(2))
        .sum();
    let reference: f64 = b.iter().zip(omega).map(|(b, w)| (b * w).powi(2)).sum();
    (difference / reference).sqrt()
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let settings = ReducedSettings {
        modes: args.modes,
        ..ReducedSettings::default()
    }
    .converging();
    let test = BeamTest::Bend;
    let basis = build_beam_basis_for(test, &settings)?.basis;
    let points = settings
        .simulation_sampling
        .beam_points(settings.simulation_points)?;
    let materials = vec![beam_material(); points.len()];
    let pressure_params = settings.pressure.unwrap_or_default();
    let space = beam_pressure_space(test, &settings, &pressure_params)?;
    let model = |projected: bool| -> anyhow::Result<ReducedModel<StableNeoHookean>> {
        let model = ReducedModel::new(&basis, &points, &materials, StableNeoHookean)?;
        Ok(if projected {
            model.with_projected_dilatation(
                space.values(points.positions())?,
                space.dilatation_params(),
            )?
        } else {
            model
        })
    };
    println!(
        "beam Bend, m = {}, weighted basis, {} simulation points",
        args.modes,
        points.len()
    );
    println!(
        "| volumetric term | candidates | points | stopped | training | validation | seconds | unseen RMS | unseen max |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for projected in [false, true] {
        for &candidates in &args.candidates {
            let full = model(projected)?;
            let params = CubatureParams {
                candidates,
                batch: args.batch,
                batch_spacing: args.batch_spacing,
                poses_per_amplitude: args.poses_per_amplitude,
                field_poses: args.field_poses,
                ..CubatureParams::DEFAULT
            };
            let start = Instant::now();
            let (quadrature, report) = optimize_cubature(&full, &params)?;
            let seconds = start.elapsed().as_secs_f64();
            let omega = force_weights(&full, params.time_step);
            let unseen = training_poses(
                &full,
                &CubatureParams {
                    poses_per_amplitude: args.unseen_per_amplitude,
                    field_poses: 2 * args.unseen_per_amplitude,
                    seed: 77,
                    ..params
                },
            )?;
            let forces: Vec<Vec<f64>> = unseen.iter().map(|z| full.elastic_gradient(z)).collect();
            let integrated = model(projected)?.with_elastic_quadrature(quadrature)?;
            let errors: Vec<f64> = unseen
                .iter()
                .zip(&forces)
                .map(|(z, f)| relative_error(&integrated.elastic_gradient(z), f, &omega))
                .collect();
            let rms = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
            let largest = errors.iter().copied().fold(0.0, f64::max);
            println!(
                "| {} | {candidates} | {} | {:?} | {:.2e} | {:.2e} | {seconds:.2} | {rms:.2e} | {largest:.2e} |",
                if projected { "projected" } else { "pointwise" },
                report.points,
                report.stop,
                report.training_error,
                report.validation_error,
            );
        }
    }
    Ok(())
}
