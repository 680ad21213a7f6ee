//! The MPM baseline on the beam, frame by frame: tip position, fastest particle, the range of
//! det F and the drift of the pinned particles, to watch a run develop.
//!
//! `cargo run --release -p eval --example mpm_beam -- [bend|twist] [Δx m, default 0.1]
//! [fixed-corotated|stable-neo-hookean] [seconds, default 0.6]`

use baselines::mpm::{MpmMaterial, MpmParams, MpmSimulator};
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
    let material = match args.get(3).map(String::as_str) {
        None | Some("fixed-corotated") => MpmMaterial::FixedCorotated,
        Some("stable-neo-hookean") => MpmMaterial::StableNeoHookean,
        Some(other) => return Err(format!("unknown material {other}").into()),
    };
    let seconds: f64 = args.get(4).map_or(Ok(0.6), |s| s.parse())?;
    let particles = sample_box_grid(BEAM_MIN, BEAM_MAX, spacing / 2.0)?;
    let scene = test.scene().reduced_scene(particles.positions())?;
    let params = MpmParams {
        grid_spacing: spacing,
        material,
        ..MpmParams::default()
    };
    // Tracer 0 at the tip; the others on the vertices of the FEM ground truth's mesh (P2 res 6:
    // a 31 × 7 × 7 lattice), where the metrics are taken.
    let mut tracers = vec![Vector3::new(5.0, 0.5, 0.5)];
    for i in 0..=30 {
        for j in 0..=6 {
            for k in 0..=6 {
                tracers.push(Vector3::new(i as f64, j as f64, k as f64) / 6.0);
            }
        }
    }
    let tracer_regions = test.scene().reduced_scene(&tracers)?.pins;
    let mut sim = MpmSimulator::new(&particles, &[beam_material()], &scene, params)?
        .with_tracers(&tracers, &tracer_regions)?;
    println!(
        "{} at Δx = {spacing} m, {} particles, {}",
        test.name(),
        particles.len(),
        material.name()
    );
    let frames = (seconds / 0.01).round() as usize;
    for frame in 1..=frames {
        sim.advance(0.01)?;
        if frame % 5 == 0 {
            let speed = sim
                .velocities()
                .iter()
                .map(|v| v.norm())
                .fold(0.0, f64::max);
            let (jmin, jmax) = sim
                .deformation_gradients()
                .iter()
                .map(|f| f.determinant())
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), j| {
                    (a.min(j), b.max(j))
                });
            let t = sim.tracer_positions()[0];
            // How far the tracers have strayed from the material: the largest distance of a
            // tracer to its nearest particle.
            let (stray, which) = sim.tracer_positions()[1..]
                .iter()
                .enumerate()
                .map(|(i, x)| {
                    let d = sim
                        .positions()
                        .iter()
                        .map(|p| (p - x).norm_squared())
                        .fold(f64::INFINITY, f64::min);
                    (d.sqrt(), i)
                })
                .fold((0.0, 0), |a, b| if b.0 > a.0 { b } else { a });
            println!(
                "t = {:.2} s: tip ({:+.4}, {:+.4}, {:+.4}) m, fastest particle {speed:.3} m/s, det F in [{jmin:.4}, {jmax:.4}], pinned drift {:.2e} m, farthest tracer {stray:.3} m from the material (vertex {which} at {:?})",
                sim.time(),
                t.x,
                t.y,
                t.z,
                sim.max_pin_deviation(),
                tracers[which + 1].as_slice()
            );
        }
    }
    Ok(())
}
