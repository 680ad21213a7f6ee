//! Static cantilever under a small distributed load against Euler-Bernoulli beam theory.

mod support;

use hyperelastic::MaterialSample;
use nalgebra::Vector3;
use reduced_sim::{
    DeformationMap, PenaltyParams, PinModulus, PinTarget, PinnedRegion, Scene, SimulationParams,
    Simulator,
};

/// Tip deflection of the reduced model of an `length × 1 × 1` m beam clamped on x ≤ 0.5 under
/// gravity g (m/s²), at the centroid line of the end face.
fn tip_deflection(
    length: f64,
    kernels: usize,
    modes: usize,
    material: &MaterialSample,
    g: f64,
) -> f64 {
    let (basis, points) = support::box_basis(
        Vector3::new(length, 1.0, 1.0),
        0.1,
        kernels,
        modes,
        material,
    );
    let model = support::uniform_model(&basis, &points, material);
    let scene = Scene {
        gravity: Some(Vector3::new(0.0, -g, 0.0)),
        pins: vec![PinnedRegion {
            points: model.points_where(|x| x.x <= 0.5),
            target: PinTarget::Rest,
        }],
        floor: None,
        held: Vec::new(),
        colliders: Vec::new(),
    };
    // A stiff clamp, (λ + 2μ) · 1e4: the comparison is with a fully clamped root. The library's
    // default penalty, E · 3e3, lets the root rotate: m = 32 then gives 1.069 of
    // Euler-Bernoulli here (its softness is chosen to offset the subspace's stiffness on the
    // dynamic beam scenes, see `PenaltyParams::pin_factor`).
    let params = SimulationParams {
        penalty: PenaltyParams {
            pin_factor: 1e4,
            pin_modulus: PinModulus::PWave,
            ..PenaltyParams::default()
        },
        ..SimulationParams::default()
    };
    let mut sim = Simulator::new(model, &scene, params).unwrap();
    let report = sim.solve_static(0.0).unwrap();
    assert!(report.converged(), "{report:?}");
    let face: Vec<Vector3<f64>> = (0..11)
        .flat_map(|a| (0..11).map(move |b| Vector3::new(length, a as f64 / 10.0, b as f64 / 10.0)))
        .collect();
    let x = DeformationMap::new(&basis, &face)
        .unwrap()
        .positions(&sim.state().z);
    -x.iter().zip(&face).map(|(x, r)| x.y - r.y).sum::<f64>() / face.len() as f64
}

/// An 8 × 1 × 1 m beam (7.5 m span) with ν = 0.3 under 1% of gravity stays in the linear
/// regime. Euler-Bernoulli gives δ = qL⁴/(8EI); Timoshenko adds the shear term
/// qL²/(2κGA), +1.8% here, so a converged 3D answer lies about 0-2% above Euler-Bernoulli.
/// Measured (K = 500): m = 8: 0.757, m = 16: 0.953, m = 32: 1.013 of Euler-Bernoulli.
#[test]
fn static_cantilever_tip_converges_to_euler_bernoulli_as_modes_grow() {
    let material = MaterialSample {
        youngs_modulus: 5e6,
        poisson_ratio: 0.3,
        density: 1000.0,
    };
    let (g, length) = (0.098, 8.0f64);
    let span = length - 0.5;
    let q = material.density * g; // N/m over the 1 m² cross-section
    let euler_bernoulli = q * span.powi(4) / (8.0 * material.youngs_modulus / 12.0);
    let coarse = tip_deflection(length, 500, 8, &material, g) / euler_bernoulli;
    let fine = tip_deflection(length, 500, 32, &material, g) / euler_bernoulli;
    eprintln!("tip / Euler-Bernoulli: m = 8: {coarse:.4}, m = 32: {fine:.4}");
    assert!(
        (fine - 1.0).abs() < 0.03,
        "m = 32 tip is {fine:.4} of Euler-Bernoulli"
    );
    assert!(
        (fine - 1.0).abs() < (coarse - 1.0).abs(),
        "more modes must be closer"
    );
}
