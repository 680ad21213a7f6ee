//! The static cantilever of the SPH energies in the small-load (linear) limit: the
//! stiffness K of μ‖sym F − I‖² + λ/2 tr(F − I)² and E_h applied through the energies' gradients, K u = f by
//! conjugate gradients with the clamp's particles fixed; tip deflection against
//! Euler–Bernoulli at several spacings.
//!
//! `cargo run --release -p baselines --example sph_static_cantilever [-- SPACING...]`

use baselines::sph::{CorrectedGradients, CubicSplineKernel, SphElasticity};
use hyperelastic::MaterialSample;
use nalgebra::Vector3;
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
    let alpha: f64 = std::env::var("SPH_ALPHA")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(0.1);
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
        let rest = points.positions();
        let kernel = CubicSplineKernel::new(2.0 * spacing);
        let gradients = CorrectedGradients::new(rest, points.volumes(), &kernel)?;
        let lame = vec![material.lame_parameters()?; points.len()];
        let el = SphElasticity::new(gradients, rest, points.volumes(), &lame, &kernel, alpha);
        let free: Vec<bool> = rest.iter().map(|x| x.x > 0.0).collect();
        let weight: Vec<Vector3<f64>> = points
            .volumes()
            .iter()
            .map(|v| Vector3::new(0.0, -g * material.density * v, 0.0))
            .collect();
        let u = el.small_strain_static(&free, &weight, 1e-10, 20_000)?;
        // The tip: mean vertical displacement of the particles in the last layer.
        let last = rest.iter().map(|x| x.x).fold(f64::MIN, f64::max);
        let tip: Vec<f64> = (0..rest.len())
            .filter(|&i| rest[i].x > last - 1e-9)
            .map(|i| -u[i].y)
            .collect();
        let tip = tip.iter().sum::<f64>() / tip.len() as f64;
        // E-B at the last layer's x.
        let xi = last / length;
        let at = expected * (6.0 * xi * xi - 4.0 * xi.powi(3) + xi.powi(4)) / 3.0;
        println!(
            "spacing {spacing} m ({} particles, {:.0} through the thickness): tip deflection {tip:.5e} m at x = {last:.4} m vs Euler–Bernoulli {at:.5e} m ({:+.1}%)",
            rest.len(),
            h / spacing,
            100.0 * (tip - at) / at
        );
    }
    Ok(())
}
