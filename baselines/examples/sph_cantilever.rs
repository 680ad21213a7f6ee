//! The SPH baseline's time stepping on a cantilever: clamp 0.2 m of a 1.2 × 0.1 × 0.05 m bar
//! (E = 100 MPa, ν = 0.3), gravity, and watch the tip against the Euler–Bernoulli static
//! deflection δ = 1.5 ρ g L⁴ / (E h²) (first bending period 0.196 s). Prints the tip every
//! sixth of the run and its mean over the second half.
//!
//! What it shows (2026-11-23): with the paper's one stretching solve per step, the rotations
//! of the solve are those of the predicted positions and the solve penalizes every change of
//! rotation from them (‖F − R‖² is not rotation-free for a frozen R), with weight
//! 2Δt²μ/(ρ s²) against inertia (≈ 500 at Δt = 2 ms, s = 0.025 m). Bending, which turns
//! material elements, then responds slowly: the tip oscillates with a period of 1–3 s instead
//! of 0.2 s and backward Euler's damping does not settle it within the run. The energies
//! themselves converge to Euler–Bernoulli (`examples/sph_static_cantilever.rs`).
//!
//! `cargo run --release -p baselines --example sph_cantilever -- [Δt s, default 0.01]
//! [seconds, default 3] [spacing m...]`

use baselines::sph::{SphParams, SphSimulator};
use hyperelastic::MaterialSample;
use nalgebra::Vector3;
use reduced_sim::{PinTarget, PinnedRegion, Scene};
use rkpm_core::sample_box_grid;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<f64> = std::env::args()
        .skip(1)
        .map(|s| s.parse())
        .collect::<Result<_, _>>()?;
    let time_step = args.first().copied().unwrap_or(0.01);
    let seconds = args.get(1).copied().unwrap_or(3.0);
    let spacings = if args.len() > 2 {
        args[2..].to_vec()
    } else {
        vec![0.025, 0.0125]
    };
    let (length, clamp, h): (f64, f64, f64) = (1.0, 0.2, 0.1);
    let material = MaterialSample {
        youngs_modulus: 1e8,
        poisson_ratio: 0.3,
        density: 1000.0,
    };
    let g = 9.8;
    let expected = 1.5 * material.density * g * length.powi(4) / (material.youngs_modulus * h * h);
    for spacing in spacings {
        let points = sample_box_grid(
            Vector3::new(-clamp, 0.0, 0.0),
            Vector3::new(length, h, h / 2.0),
            spacing,
        )?;
        let clamped: Vec<usize> = (0..points.len())
            .filter(|&i| points.positions()[i].x <= 0.0)
            .collect();
        let scene = Scene {
            gravity: Some(Vector3::new(0.0, -g, 0.0)),
            pins: vec![PinnedRegion {
                points: clamped,
                target: PinTarget::Rest,
            }],
            ..Scene::default()
        };
        let params = SphParams {
            time_step,
            ..SphParams::default()
        };
        let steps = (seconds / time_step).round() as usize;
        let mut sim = SphSimulator::new(&points, &[material], &scene, params)?
            .with_probes(&[Vector3::new(length, h / 2.0, h / 4.0)], &[])?;
        let mut mean = 0.0;
        for step in 1..=steps {
            sim.step()?;
            let deflection = h / 2.0 - sim.probe_positions()[0].y;
            if step % (steps / 6).max(1) == 0 {
                println!(
                    "  spacing {spacing} m, t = {:.3} s: tip deflection {deflection:.4e} m",
                    sim.time()
                );
            }
            if step > steps / 2 {
                mean += deflection / (steps - steps / 2) as f64;
            }
        }
        let t = sim.timings();
        println!(
            "spacing {spacing} m ({} particles), Δt = {time_step} s: mean tip deflection over the second half {mean:.4e} m vs Euler–Bernoulli {expected:.4e} m ({:+.1}%); {:.2} ms/step, {:.0} CG iterations/step",
            points.len(),
            100.0 * (mean - expected) / expected,
            1e3 * t.stepping() / t.steps as f64,
            t.volume_iterations as f64 / t.steps as f64
        );
    }
    Ok(())
}
