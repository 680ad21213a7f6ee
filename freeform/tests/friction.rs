//! Floor friction: a block on a 30° incline sticks when μ > tan 30° and slides with
//! Coulomb's acceleration g (sin θ − μ cos θ) when μ < tan 30°.
//!
//! The incline is the floor y ≥ 0 with gravity tilted by θ: `g = 9.8 (sin θ, −cos θ, 0)` m/s²,
//! so the block's bottom face starts on the plane and "down the slope" is +x.

mod support;

use freeform::{FloorSpec, SceneSpec};
use nalgebra::Vector3;
use support::{H, mean_x, run_cube};

const G: f64 = 9.8;
const THETA: f64 = std::f64::consts::FRAC_PI_6;

/// The block's volume-weighted mean x (m) after each of `steps` steps on the incline with
/// friction coefficient `friction`; the run's mechanical energy never rises over a step (a
/// block on a still floor: gravity does work, friction and backward Euler take it out).
fn slide(friction: f64, steps: usize) -> Vec<f64> {
    let scene = SceneSpec {
        gravity: Some(Vector3::new(G * THETA.sin(), -G * THETA.cos(), 0.0)),
        floor: Some(FloorSpec {
            normal: Vector3::y(),
            offset: 0.0,
            friction,
        }),
        ..Default::default()
    };
    let mut x = Vec::new();
    let report = run_cube(0.2, &scene, steps, |positions, volumes| {
        x.push(mean_x(positions, volumes));
    });
    let [start, end] = report.energy;
    assert!(end < start, "energy {start} J -> {end} J");
    assert!(
        report.max_energy_rise <= 1e-9 * (start - end),
        "energy rose by {} J in a step ({start} J -> {end} J)",
        report.max_energy_rise
    );
    x
}

#[test]
fn a_block_on_a_30_degree_incline_sticks_with_friction_0_7() {
    let x = slide(0.7, 120);
    // One second after the first 0.1 s, in which the penalty floor takes up the weight: the
    // block sinks into it and bounces, and slips about 6 mm while the normal force is short of
    // its weight. After that the smoothed friction creeps at about 0.58 ε_v (0.6 mm/s).
    let moved = (x[110] - x[10]).abs();
    assert!(moved < 1e-3, "moved {moved} m in 1 s");
}

#[test]
fn a_block_on_a_30_degree_incline_slides_at_coulombs_acceleration_with_friction_0_2() {
    let friction = 0.2;
    let x = slide(friction, 100);
    // Least squares x(t) = c₀ + c₁ t + a t²/2 over t ∈ [0.2, 1] s (backward Euler's positions
    // under a constant acceleration are exactly such a quadratic).
    let samples: Vec<(f64, f64)> = (20..=100).map(|n| (n as f64 * H, x[n])).collect();
    let design = nalgebra::DMatrix::from_fn(samples.len(), 3, |i, j| {
        let t = samples[i].0;
        [1.0, t, 0.5 * t * t][j]
    });
    let rhs = nalgebra::DVector::from_iterator(samples.len(), samples.iter().map(|s| s.1));
    let fit = design
        .svd(true, true)
        .solve(&rhs, 1e-12)
        .expect("full column rank");
    let expected = G * (THETA.sin() - friction * THETA.cos());
    let acceleration = fit[2];
    // The issue asks for 5%; the lagged normal force has settled by 0.2 s, so the fit is far
    // closer (about 1e-9 relative), and 0.5% still catches a friction force off by 1%.
    assert!(
        (acceleration - expected).abs() <= 0.005 * expected,
        "acceleration {acceleration} m/s², Coulomb {expected} m/s²"
    );
}

/// A scene whose only term is a floor y ≥ 0 with friction `friction`.
fn with_friction(friction: f64) -> SceneSpec {
    SceneSpec {
        floor: Some(FloorSpec {
            normal: Vector3::y(),
            offset: 0.0,
            friction,
        }),
        ..Default::default()
    }
}

#[test]
fn a_negative_friction_is_a_named_error_and_a_positive_one_valid() {
    assert!(matches!(
        with_friction(-0.1).validate(),
        Err(freeform::SceneSpecError::Invalid(why)) if why.contains("friction")
    ));
    assert!(with_friction(0.3).validate().is_ok());
}

#[cfg(feature = "fem")]
#[test]
fn a_frictional_floor_is_refused_by_the_fem_translation_and_a_frictionless_one_taken() {
    assert!(matches!(
        with_friction(0.3).fem_scene(&[Vector3::zeros()], 1e4),
        Err(freeform::SceneSpecError::FemFriction { friction }) if friction == 0.3
    ));
    assert!(
        with_friction(0.0)
            .fem_scene(&[Vector3::zeros()], 1e4)
            .is_ok()
    );
}

#[test]
fn scene_labels_without_friction_or_colliders_keep_the_form_cached_results_were_keyed_by() {
    let scene = SceneSpec {
        gravity: Some(Vector3::new(0.0, -9.8, 0.0)),
        floor: Some(FloorSpec {
            normal: Vector3::y(),
            offset: 0.5,
            friction: 0.0,
        }),
        ..Default::default()
    };
    // The derived Debug of the scene before floor friction and colliders existed.
    assert_eq!(
        scene.label(),
        "SceneSpec { gravity: Some([[0.0, -9.8, 0.0]]), constraints: [], floor: \
         Some(FloorSpec { normal: [[0.0, 1.0, 0.0]], offset: 0.5 }) }"
    );
    let rubbing = SceneSpec {
        floor: Some(FloorSpec {
            friction: 0.4,
            ..scene.floor.unwrap()
        }),
        ..scene.clone()
    };
    assert_ne!(rubbing.label(), scene.label());
}
