//! Exact properties of the reduced dynamics on an RKPM basis: rigid motions cost nothing, free
//! fall follows backward Euler's closed form, momentum is conserved without external forces.

mod support;

use hyperelastic::Tangent;
use nalgebra::{Rotation3, Vector3};
use reduced_sim::{DeformationMap, ReducedState, Scene, SimulationParams, Simulator};
use support::BEAM_MATERIAL;

fn small_beam() -> (skin_eigen::SkinningBasis, rkpm_core::IntegrationPoints) {
    support::box_basis(Vector3::new(3.0, 1.0, 1.0), 0.125, 200, 8, &BEAM_MATERIAL)
}

#[test]
fn rigid_motion_of_the_constant_handle_has_zero_elastic_energy_and_force() {
    let (basis, points) = small_beam();
    let model = support::uniform_model(&basis, &points, &BEAM_MATERIAL);
    let layout = model.deformation_map().layout();
    let rotation = Rotation3::from_scaled_axis(Vector3::new(0.7, -1.1, 0.4)).into_inner();
    let translation = Vector3::new(1.5, -2.0, 0.25);
    let z = layout.rigid_motion(&rotation, &translation);

    // The map moves every point rigidly and F = R.
    let x = model.deformation_map().positions(&z);
    for (x, rest) in x.iter().zip(model.rest_positions()) {
        assert!((x - (rotation * rest + translation)).norm() < 1e-12);
    }
    for f in model.deformation_map().deformation_gradients(&z) {
        assert!((f - rotation).norm() < 1e-12);
    }

    // Scale of comparison: the same rotation angle as a shear of the second handle.
    let mut deformed = z.clone();
    deformed[layout.index(1, 0, 1)] = 0.3;
    let reference_energy = model.elastic_energy(&deformed);
    let reference_force = norm(&model.elastic_gradient(&deformed));
    let energy = model.elastic_energy(&z);
    let force = norm(&model.elastic_gradient(&z));
    assert!(
        energy.abs() < 1e-12 * reference_energy,
        "rigid energy {energy:e} J vs {reference_energy:e} J deformed"
    );
    assert!(
        force < 1e-10 * reference_force,
        "rigid force {force:e} vs {reference_force:e} deformed"
    );
    // And the exact Hessian has the rigid translations in its null space.
    let h = model.elastic_hessian(&z, Tangent::Exact);
    for r in 0..3 {
        let column = layout.index(0, r, 3);
        let max = (0..layout.len())
            .map(|i| h[(i, column)].abs())
            .fold(0.0, f64::max);
        assert_eq!(max, 0.0, "translation {r} couples to the elastic Hessian");
    }
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// Backward Euler under constant acceleration: v_n = v₀ + n h g, x_n = x₀ + Σ h v_k, i.e.
/// x(t) = x₀ + v₀ t + ½ g t² + ½ g h t. The last term is the method's O(h) error against the
/// exact parabola; the reduced simulator must reproduce the discrete solution to round-off.
#[test]
fn free_fall_follows_backward_euler_closed_form_with_its_half_g_h_t_error() {
    let (basis, points) = small_beam();
    let model = support::uniform_model(&basis, &points, &BEAM_MATERIAL);
    let layout = model.deformation_map().layout();
    let g = Vector3::new(0.0, -9.8, 0.0);
    let v0 = Vector3::new(2.0, 3.0, -1.0);
    let scene = Scene {
        gravity: Some(g),
        ..Default::default()
    };
    let h = 0.01;
    let mut sim = Simulator::new(model, &scene, SimulationParams::default()).unwrap();
    sim.set_state(ReducedState {
        z: layout.rest(),
        velocity: layout.uniform_velocity(&v0),
        time: 0.0,
    })
    .unwrap();
    let probes = [Vector3::new(0.1, 0.2, 0.3), Vector3::new(2.9, 0.9, 0.5)];
    let map = DeformationMap::new(&basis, &probes).unwrap();
    for _ in 0..50 {
        assert!(sim.step().unwrap().converged());
    }
    let t = sim.state().time;
    assert!((t - 0.5).abs() < 1e-12);
    for (x, rest) in map.positions(&sim.state().z).iter().zip(&probes) {
        let parabola = rest + v0 * t + 0.5 * g * t * t;
        let discrete = parabola + 0.5 * g * h * t;
        let error = (x - discrete).norm();
        assert!(error < 1e-9, "|x - x_BE| = {error:e} m");
        // The O(h) gap to the exact parabola is ½ g h t = 2.45 cm here.
        assert!(((x - parabola).norm() - 0.5 * 9.8 * h * t).abs() < 1e-9);
    }
}

#[test]
fn linear_momentum_is_conserved_without_external_forces() {
    let (basis, points) = small_beam();
    let model = support::uniform_model(&basis, &points, &BEAM_MATERIAL);
    let layout = model.deformation_map().layout();
    // A deforming, spinning, drifting start: every entry of ż non-zero.
    let velocity: Vec<f64> = (0..layout.len())
        .map(|i| 0.5 * (i as f64 * 0.9).sin())
        .collect();
    let mut sim = Simulator::new(model, &Scene::default(), SimulationParams::default()).unwrap();
    sim.set_state(ReducedState {
        z: layout.rest(),
        velocity,
        time: 0.0,
    })
    .unwrap();
    let momentum = |sim: &Simulator<_>| -> Vector3<f64> {
        let model = sim.model();
        // ẋ_i = B_i ż: the map's displacement of ż.
        let velocities = model.deformation_map().displacements(&sim.state().velocity);
        velocities
            .iter()
            .zip(model.volumes().iter().zip(model.densities()))
            .map(|(u, (v, rho))| u * (v * rho))
            .sum()
    };
    let before = momentum(&sim);
    let mut cuts = 0;
    for _ in 0..30 {
        let report = sim.step().unwrap();
        assert!(report.converged());
        cuts += report.line_search_cuts;
    }
    let after = momentum(&sim);
    assert_eq!(
        cuts, 0,
        "a damped line search step breaks exact conservation"
    );
    let scale = before.norm().max(1.0);
    assert!(
        (after - before).norm() < 1e-9 * scale,
        "momentum {before:?} -> {after:?} (kg m/s)"
    );
}
