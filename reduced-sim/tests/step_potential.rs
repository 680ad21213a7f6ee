//! The public incremental potential of the next step: its gradient and Hessian against central
//! differences of its energy, and its minimizer is the step the simulator takes.

mod support;

use hyperelastic::{StableNeoHookean, Tangent};
use nalgebra::{DMatrix, Vector3};
use optimize::minimize;
use reduced_sim::{Floor, PinTarget, PinnedRegion, Scene, SimulationParams, Simulator};
use support::BEAM_MATERIAL;
use test_support::finite_difference::{gradient, jacobian, relative_error};

fn simulator(tangent: Tangent) -> Simulator<StableNeoHookean> {
    let (basis, points) =
        support::box_basis(Vector3::new(2.0, 0.5, 0.5), 0.125, 80, 4, &BEAM_MATERIAL);
    let model = support::uniform_model(&basis, &points, &BEAM_MATERIAL);
    let scene = Scene {
        gravity: Some(Vector3::new(0.0, -9.8, 0.0)),
        pins: vec![PinnedRegion {
            points: model.points_where(|x| x.x <= 0.3),
            target: PinTarget::Rest,
        }],
        // Above the lowest layer of points (y = 0.0625), so the floor term is active.
        floor: Some(Floor {
            normal: Vector3::y(),
            offset: 0.08,
            friction: 0.0,
        }),
        held: Vec::new(),
        colliders: Vec::new(),
    };
    let params = SimulationParams {
        tangent: tangent.into(),
        ..Default::default()
    };
    Simulator::new(model, &scene, params).unwrap()
}

/// A deformed configuration: the rest coordinates plus a fixed, moderate perturbation.
fn probe(sim: &Simulator<StableNeoHookean>) -> Vec<f64> {
    let z = &sim.state().z;
    z.iter()
        .enumerate()
        .map(|(i, v)| v + 0.02 * ((i * 7 % 11) as f64 / 11.0 - 0.5))
        .collect()
}

#[test]
fn the_step_potentials_gradient_and_exact_hessian_match_central_differences() {
    let sim = simulator(Tangent::Exact);
    let predicted = sim.predicted_coordinates();
    let potential = sim.step_potential(&predicted);
    let z = probe(&sim);
    let (g, hessian) = potential.derivatives(&z);
    let fd = gradient(|z| potential.energy(z), &z, 1e-6);
    let g = DMatrix::from_column_slice(g.len(), 1, &g);
    let fd = DMatrix::from_column_slice(fd.len(), 1, fd.as_slice());
    let gradient_error = relative_error(&g, &fd, 1e-8);
    assert!(gradient_error < 1e-6, "gradient vs FD: {gradient_error:e}");
    assert_eq!(
        potential.gradient(&z),
        g.as_slice(),
        "gradient alone equals the one computed with the Hessian"
    );
    let fd_hessian = jacobian(|z| potential.gradient(z), &z, 1e-6);
    let h = DMatrix::from_fn(z.len(), z.len(), |i, j| hessian[(i, j)]);
    let hessian_error = relative_error(&h, &fd_hessian, 1e-8);
    assert!(hessian_error < 1e-5, "Hessian vs FD: {hessian_error:e}");
}

#[test]
fn minimizing_the_step_potential_gives_the_state_the_simulator_steps_to() {
    let mut sim = simulator(Tangent::ProjectedPsd);
    let predicted = sim.predicted_coordinates();
    let mut z = predicted.clone();
    let params = sim.params().newton;
    minimize(&sim.step_potential(&predicted), &mut z, &params).unwrap();
    sim.step().unwrap();
    assert_eq!(z, sim.state().z);
}
