//! A run shared by the contact tests: a small stiff cube in a scene.

use freeform::{Geometry, RunReport, SceneSpec, Simulation, run};
use hyperelastic::{MaterialField, MaterialSample, StableNeoHookean};
use nalgebra::Vector3;
use reduced_sim::{QuadratureRule, SimulationParams};
use skin_eigen::{BasisParams, build_basis};

/// Time step of [`run_cube`] (s).
pub const H: f64 = 0.01;

/// A cube `[0, side]³` of stiff rubber (E = 1 MPa, ν = 0.3, ρ = 1000 kg/m³) on about 800 grid
/// points, with a small basis (m = 4, K = 60) and every point as quadrature, run `steps` steps
/// of [`H`] in `scene`. `observe` gets the integration points' positions (m) and volumes (m³)
/// at every frame, rest included. Returns the run's report.
///
/// # Panics
/// If the run fails or a step does not converge.
pub fn run_cube(
    side: f64,
    scene: &SceneSpec,
    steps: usize,
    mut observe: impl FnMut(&[Vector3<f64>], &[f64]),
) -> RunReport {
    let geometry = Geometry::cuboid(Vector3::zeros(), Vector3::repeat(side));
    let points = geometry.integration_points(800).unwrap();
    let material = MaterialSample {
        youngs_modulus: 1e6,
        poisson_ratio: 0.3,
        density: 1000.0,
    };
    let lame = vec![material.lame_parameters().unwrap(); points.len()];
    let params = BasisParams::default().with_modes(4).with_kernels(60);
    let (basis, _, _) = build_basis(&points, &lame, &params).unwrap();
    let material = MaterialField::Uniform(material);
    let simulation = Simulation::new(&basis, &points, &material, StableNeoHookean, scene)
        .with_params(SimulationParams {
            time_step: H,
            ..Default::default()
        })
        .with_quadrature(QuadratureRule::Full);
    let report = run(&simulation, steps, |frame| {
        let map = frame.simulator.model().deformation_map();
        observe(&map.positions(&frame.simulator.state().z), points.volumes());
        Ok(())
    })
    .unwrap();
    assert_eq!(report.unconverged_steps, 0);
    report
}

/// The volume-weighted mean of x over the points (m).
pub fn mean_x(positions: &[Vector3<f64>], volumes: &[f64]) -> f64 {
    let volume: f64 = volumes.iter().sum();
    positions
        .iter()
        .zip(volumes)
        .map(|(x, v)| x.x * v)
        .sum::<f64>()
        / volume
}
