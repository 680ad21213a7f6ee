//! The SPH baseline's cantilever against Euler–Bernoulli at several particle spacings: clamp
//! 0.2 m of a 1.2 × 0.1 × 0.05 m bar, gravity, backward-Euler steps of 0.01 s until it rests,
//! the tip's static deflection against δ = q L⁴ / (8 E I) = 1.5 ρ g L⁴ / (E h²).
//!
//! `cargo run --release -p baselines --example sph_cantilever [-- SPACING...]`

use baselines::sph::{SphParams, SphSimulator};
use hyperelastic::MaterialSample;
use nalgebra::Vector3;
use reduced_sim::{PinTarget, PinnedRegion, Scene};
use rkpm_core::sample_box_grid;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let spacings: Vec<f64> = std::env::args()
        .skip(1)
        .map(|s| s.parse())
        .collect::<Result<_, _>>()?;
    let spacings = if spacings.is_empty() {
        vec![0.025, 0.0167, 0.0125]
    } else {
        spacings
    };
    let (length, clamp, h): (f64, f64, f64) = (1.0, 0.2, 0.1);
    let material = MaterialSample {
        youngs_modulus: 1e8,
        poisson_ratio: std::env::var("SPH_NU")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(0.3),
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
        let start = std::time::Instant::now();
        let env = |name: &str, default: f64| -> f64 {
            std::env::var(name)
                .ok()
                .and_then(|v| v.parse().ok())
                .unwrap_or(default)
        };
        let params = SphParams {
            time_step: env("SPH_DT", 0.01),
            zero_energy_alpha: env("SPH_ALPHA", 0.1),
            ..SphParams::default()
        };
        let steps = (env("SPH_T", 3.0) / params.time_step).round() as usize;
        let mut mean = 0.0;
        let relax = std::env::var("SPH_RELAX").is_ok();
        let mut sim = SphSimulator::new(&points, &[material], &scene, params)?
            .with_probes(&[Vector3::new(length, h / 2.0, h / 4.0)], &[])?;
        let mut last = 0.0;
        for step in 1..=steps {
            sim.step()?;
            if relax {
                let n = sim.velocities().len();
                sim.set_velocities(&vec![Vector3::zeros(); n])?;
            }
            let deflection = h / 2.0 - sim.probe_positions()[0].y;
            if step % (steps / 6) == 0 {
                println!(
                    "  spacing {spacing}: step {step}: tip deflection {deflection:.5e} m (change {:.1e})",
                    deflection - last
                );
            }
            last = deflection;
            if step > steps / 2 {
                mean += deflection / (steps - steps / 2) as f64;
            }
        }
        let t = sim.timings();
        println!(
            "mean over the second half {mean:.5e} m ({:+.1}%)",
            100.0 * (mean - expected) / expected
        );
        println!(
            "spacing {spacing} m ({} particles, h/spacing = {:.1}): tip {last:.5e} m vs Euler–Bernoulli {expected:.5e} m ({:+.1}%); setup {:.2} s, {:.2} ms/step, {:.1} CG iterations/step",
            points.len(),
            h / spacing,
            100.0 * (last - expected) / expected,
            t.setup,
            1e3 * t.stepping() / t.steps as f64,
            t.volume_iterations as f64 / t.steps as f64
        );
    }
    Ok(())
}
