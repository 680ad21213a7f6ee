//! MPM cantilever against Euler–Bernoulli at a grid spacing of your choice: the convergence
//! study behind the baseline's cantilever test.
//!
//! `cargo run --release -p baselines --example mpm_cantilever -- [grid spacing m, default 0.025]`
//!
//! A 1.2 × 0.1 × 0.05 m bar (E = 100 MPa, ν = 0.3, ρ = 1000 kg/m³) with 0.2 m clamped by
//! particle velocity enforcement, under gravity; 8 particles per cell. Prints the mean tip
//! deflection over the first period (see the test) against δ = q L⁴ / (8 E I), and the time per
//! phase.

use baselines::mpm::{MpmParams, MpmSimulator};
use hyperelastic::MaterialSample;
use nalgebra::Vector3;
use reduced_sim::{PinTarget, PinnedRegion, Scene};
use rkpm_core::sample_box_grid;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let spacing: f64 = match std::env::args().nth(1) {
        Some(s) => s.parse()?,
        None => 0.025,
    };
    let (length, clamp, h, g) = (1.0, 0.2, 0.1, 9.8);
    let material = MaterialSample {
        youngs_modulus: 1e8,
        poisson_ratio: 0.3,
        density: 1000.0,
    };
    let points = sample_box_grid(
        Vector3::new(-clamp, 0.0, 0.0),
        Vector3::new(length, h, h / 2.0),
        spacing / 2.0,
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
    let lame = material.lame_parameters()?;
    let dt = 0.4 * spacing / (lame.p_wave_modulus() / material.density).sqrt();
    let params = MpmParams {
        grid_spacing: spacing,
        time_step: dt,
        ..MpmParams::default()
    };
    let mut sim = MpmSimulator::new(&points, &[material], &scene, params)?
        .with_tracers(&[Vector3::new(length, h / 2.0, h / 4.0)], &[])?;
    let e = material.youngs_modulus;
    let static_deflection = 1.5 * material.density * g * length.powi(4) / (e * h * h);
    let omega = 1.875f64.powi(2) * (e * h * h / (12.0 * material.density * length.powi(4))).sqrt();
    let period = 2.0 * std::f64::consts::PI / omega;
    let samples = 300;
    let sample_time = 0.75 * period / samples as f64;
    let mut deflection = Vec::new();
    for _ in 0..samples {
        sim.advance(sample_time)?;
        deflection.push(h / 2.0 - sim.tracer_positions()[0].y);
    }
    let peak = (0..samples)
        .max_by(|&a, &b| deflection[a].total_cmp(&deflection[b]))
        .unwrap_or(0);
    while deflection.len() < 2 * (peak + 1) {
        sim.advance(sample_time)?;
        deflection.push(h / 2.0 - sim.tracer_positions()[0].y);
    }
    let mean = deflection[..2 * (peak + 1)].iter().sum::<f64>() / (2 * (peak + 1)) as f64;
    let t = sim.timings();
    println!(
        "Δx = {spacing} m, {} particles, Δt = {dt:.3e} s, {} substeps: mean tip deflection \
         {mean:.5e} m vs Euler–Bernoulli {static_deflection:.5e} m ({:+.2}%); MPM period {:.4} s \
         vs {:.4} s",
        points.len(),
        t.substeps,
        100.0 * (mean / static_deflection - 1.0),
        2.0 * (peak + 1) as f64 * sample_time,
        period
    );
    println!(
        "time: {:.2} s total, {:.2} µs per particle-substep (stress {:.0}%, P2G {:.0}%, grid {:.0}%, G2P {:.0}%)",
        t.total(),
        1e6 * t.total() / (t.substeps as f64 * points.len() as f64),
        100.0 * t.stress / t.total(),
        100.0 * t.particle_to_grid / t.total(),
        100.0 * t.grid_update / t.total(),
        100.0 * t.grid_to_particle / t.total()
    );
    Ok(())
}
