//! The SPH baseline on the beam, frame by frame: setup time, the tip, the pinned particles'
//! drift, conjugate-gradient iterations and time per step, to watch a run develop.
//!
//! `cargo run --release -p eval --example sph_beam -- [bend|twist] [spacing m, default 0.1]
//! [α, default 0.1] [seconds, default 0.5] [volume tolerance, default 1e-4]`

use baselines::sph::{SphParams, SphSimulator};
use eval::beam_scenario::{BEAM_MAX, BEAM_MIN, BeamTest, beam_material};
use nalgebra::Vector3;
use rkpm_core::sample_box_grid;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let test = match args.get(1).map(String::as_str) {
        None | Some("bend") => BeamTest::Bend,
        Some("twist") => BeamTest::Twist,
        Some(other) => return Err(format!("unknown test {other}").into()),
    };
    let spacing: f64 = args.get(2).map_or(Ok(0.1), |s| s.parse())?;
    let alpha: f64 = args.get(3).map_or(Ok(0.1), |s| s.parse())?;
    let seconds: f64 = args.get(4).map_or(Ok(0.5), |s| s.parse())?;
    let tolerance: f64 = args.get(5).map_or(Ok(1e-4), |s| s.parse())?;
    let particles = sample_box_grid(BEAM_MIN, BEAM_MAX, spacing)?;
    let scene = test.scene().reduced_scene(particles.positions())?;
    let params = SphParams {
        zero_energy_alpha: alpha,
        volume_tolerance: tolerance,
        ..SphParams::default()
    };
    let tip = [Vector3::new(5.0, 0.5, 0.5)];
    let mut sim = SphSimulator::new(&particles, &[beam_material()], &scene, params)?
        .with_probes(&tip, &[])?;
    println!(
        "{} at spacing {spacing} m: {} particles, setup {:.2} s, {} stored entries in the factored matrix",
        test.name(),
        particles.len(),
        sim.timings().setup,
        sim.system_nonzeros()
    );
    let frames = (seconds / params.time_step).round() as usize;
    let mut iterations = 0;
    for frame in 1..=frames {
        sim.step()?;
        if frame % 5 == 0 {
            let t = sim.timings();
            println!(
                "t = {:.2} s: tip {:?} m, pinned drift {:.2e} m, {:.0} CG iterations/step, {:.1} ms/step (stretching {:.0}%, volume {:.0}%)",
                sim.time(),
                sim.probe_positions()[0].as_slice(),
                sim.max_pin_deviation(),
                (t.volume_iterations - iterations) as f64 / 5.0,
                1e3 * t.stepping() / t.steps as f64,
                100.0 * t.stretching / t.stepping(),
                100.0 * t.volume / t.stepping()
            );
            iterations = t.volume_iterations;
        }
    }
    Ok(())
}
