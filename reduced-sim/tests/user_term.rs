//! A term written outside the crate (the `spring_to_target` example's zero-length springs)
//! passes the finite-difference check and holds a block where the force balance says.

use std::sync::Arc;

use nalgebra::Vector3;
use reduced_sim::{Scene, SimulationParams, Simulator, TermCheckParams, TermPoint, check_term};

#[path = "../examples/spring_to_target.rs"]
mod spring_to_target;

use spring_to_target::{HandPath, block_model, mean_stretch, top_springs};

fn still_hand() -> HandPath {
    Arc::new(|_| Vector3::zeros())
}

#[test]
fn springs_written_outside_the_crate_pass_the_finite_difference_check() {
    let model = block_model();
    let rising: HandPath = Arc::new(|t: f64| Vector3::new(0.0, 0.2 * t, 0.05 * t));
    let springs = top_springs(&model, 2e4, rising);
    assert!(
        springs.points.len() >= 20,
        "{} springs",
        springs.points.len()
    );
    let z: Vec<f64> = (0..model.deformation_map().layout().len())
        .map(|i| 0.01 * (i as f64 * 0.7).sin())
        .collect();
    let at = TermPoint::new(model.deformation_map(), model.volumes(), &z, 0.5);
    let report = check_term(&springs, &at, &TermCheckParams::default()).unwrap();
    assert!(report.gradient_error < 1e-6, "{report:?}");
    assert!(report.hessian_error < 1e-6, "{report:?}");
}

/// Elastic forces are internal (the energy does not change under a translation, which the
/// basis holds exactly), so at equilibrium the springs carry the weight:
/// `k Σ_j (x_j − X_j) = M g`, a mean stretch of `M g / (P k)` whatever the block's deformation.
#[test]
fn a_block_hung_from_springs_settles_at_the_force_balance_stretch() {
    let model = block_model();
    let stiffness = 2e3;
    let springs = top_springs(&model, stiffness, still_hand());
    let expected = model.total_mass() * 9.8 / (springs.points.len() as f64 * stiffness);
    let scene = Scene {
        gravity: Some(Vector3::new(0.0, -9.8, 0.0)),
        ..Scene::default()
    };
    let mut simulator = Simulator::new(model, &scene, SimulationParams::default()).unwrap();
    simulator.add_term(Box::new(top_springs(
        simulator.model(),
        stiffness,
        still_hand(),
    )));
    let report = simulator.solve_static(0.0).unwrap();
    assert!(report.converged(), "{report:?}");
    let stretch = mean_stretch(&simulator, &springs);
    assert!(expected > 0.01, "a visible stretch: {expected} m");
    assert!(
        (stretch.y + expected).abs() < 1e-6 * expected,
        "stretch {stretch:?} m, expected {expected} m down"
    );
    assert!(
        stretch.x.abs() < 1e-9 && stretch.z.abs() < 1e-9,
        "{stretch:?}"
    );
}

/// Without the springs the same scene has no equilibrium: the term is what holds the block.
#[test]
fn without_the_springs_the_block_falls_freely() {
    let model = block_model();
    let scene = Scene {
        gravity: Some(Vector3::new(0.0, -9.8, 0.0)),
        ..Scene::default()
    };
    let mut simulator = Simulator::new(model, &scene, SimulationParams::default()).unwrap();
    for _ in 0..10 {
        simulator.step().unwrap();
    }
    let momentum = simulator.linear_momentum().y / simulator.model().total_mass();
    // Backward Euler: the velocity after n steps of free fall is exactly −g n h.
    assert!(
        (momentum + 9.8 * 0.1).abs() < 1e-6,
        "velocity {momentum} m/s"
    );
}
