//! Tests of several objects in contact.

use hyperelastic::StableNeoHookean;
use nalgebra::{DMatrix, Matrix3, Vector3};
use optimize::NewtonObjective;
use test_support::finite_difference;

use super::*;
use crate::model::analytic_field::{AnalyticField, analytic_model_with_spacing};
use crate::scene::{Floor, Scene};
use crate::step::simulator::SimulationParams;

/// The grid points of spacing `spacing` on the surface of the box `[0, size]`.
fn box_surface(size: Vector3<f64>, spacing: f64) -> Vec<Vector3<f64>> {
    let counts = size.map(|s| (s / spacing).round() as usize);
    let mut points = Vec::new();
    for i in 0..=counts.x {
        for j in 0..=counts.y {
            for k in 0..=counts.z {
                let on_surface =
                    i == 0 || j == 0 || k == 0 || i == counts.x || j == counts.y || k == counts.z;
                if on_surface {
                    let f = Vector3::new(i, j, k)
                        .cast::<f64>()
                        .component_div(&counts.cast());
                    points.push(f.component_mul(&size));
                }
            }
        }
    }
    points
}

/// The analytic 2 × 1 × 1 m block in `scene`, moved rigidly by `translation` (m) and moving
/// at `velocity` (m/s), with contact samples 0.1 m apart.
fn block(
    scene: &Scene,
    params: SimulationParams,
    translation: Vector3<f64>,
    velocity: Vector3<f64>,
) -> Body<StableNeoHookean> {
    coarse_block(scene, params, translation, velocity, 0.2)
}

/// [`block`] integrated on a grid of `spacing` (m).
/// Gravity (9.8 m/s² along −y) and the floor y = `offset` (m) with friction `friction`.
fn floor_scene(offset: f64, friction: f64) -> Scene {
    Scene {
        gravity: Some(Vector3::new(0.0, -9.8, 0.0)),
        floor: Some(Floor {
            normal: Vector3::y(),
            offset,
            friction,
        }),
        ..Scene::default()
    }
}

fn coarse_block(
    scene: &Scene,
    params: SimulationParams,
    translation: Vector3<f64>,
    velocity: Vector3<f64>,
    spacing: f64,
) -> Body<StableNeoHookean> {
    let (model, _) = analytic_model_with_spacing(spacing);
    let samples = DeformationMap::new(
        &AnalyticField,
        &box_surface(Vector3::new(2.0, 1.0, 1.0), 0.1),
    )
    .unwrap();
    let layout = model.deformation_map().layout();
    let mut simulator = Simulator::new(model, scene, params).unwrap();
    simulator
        .set_state(ReducedState {
            z: layout.rigid_motion(&Matrix3::identity(), &translation),
            velocity: layout.uniform_velocity(&velocity),
            time: 0.0,
        })
        .unwrap();
    Body::new(simulator, samples).unwrap()
}

fn check_group_derivatives(model: BodyContactModel) {
    let params = SimulationParams {
        tangent: crate::HessianTangent::Exact,
        ..SimulationParams::default()
    };
    let scene = Scene {
        gravity: Some(Vector3::new(0.0, -9.8, 0.0)),
        ..Scene::default()
    };
    // B's end face 0.04 m beyond A's, shifted so samples do not face each other exactly.
    let bodies = vec![
        block(&scene, params, Vector3::zeros(), Vector3::zeros()),
        block(
            &scene,
            params,
            Vector3::new(2.04, 0.03, 0.05),
            Vector3::zeros(),
        ),
    ];
    let contact = BodyContactParams {
        model,
        friction: 0.5,
        ..BodyContactParams::with_radius(0.1)
    };
    let sim = MultiBodySimulator::new(bodies, contact).unwrap();
    let start = sim.sample_positions();
    let pairs = sim.pairs_within(&start, None, 0.15);
    assert!(pairs.len() > 50, "{} pairs", pairs.len());
    let predicted: Vec<Vec<f64>> = sim
        .bodies
        .iter()
        .map(|b| b.simulator.predicted_coordinates())
        .collect();
    let mut objective = sim.group_potential(&[0, 1], &pairs, &start, &predicted);
    let len = objective.offsets[2];
    let probe = |amplitude: f64| -> Vec<f64> {
        let base = predicted.concat();
        (0..len)
            .map(|i| base[i] + amplitude * ((i as f64 * 1.37).sin() + 0.3 * (i as f64).cos()))
            .collect()
    };
    // Contact and friction lagged at another state, so slips straddle ε.
    objective.epsilon = 0.002;
    objective.pairs = objective.lag(&probe(-0.002));
    objective.friction = objective.lagged_friction(&probe(-0.002));
    assert!(
        objective.friction.len() > 20,
        "{} rubbing pairs",
        objective.friction.len()
    );
    let z = probe(0.001);
    let active = objective.pair_derivatives(&z).len();
    assert!(
        active > objective.friction.len() + 20,
        "{active} active terms"
    );
    let energy = |z: &[f64]| NewtonObjective::energy(&objective, z);
    let (gradient, hessian) = objective.gradient_and_hessian(&z, None);
    assert_eq!(gradient, NewtonObjective::gradient(&objective, &z));
    let numeric = finite_difference::gradient(energy, &z, 1e-7);
    let err = finite_difference::relative_error(
        &DMatrix::from_column_slice(len, 1, &gradient),
        &DMatrix::from_column_slice(len, 1, numeric.as_slice()),
        1e-12,
    );
    assert!(err < 1e-6, "{model:?}: gradient relative error {err:e}");
    let numeric =
        finite_difference::jacobian(|z| NewtonObjective::gradient(&objective, z), &z, 1e-7);
    let analytic = DMatrix::from_fn(len, len, |i, j| hessian[(i, j)]);
    let err = finite_difference::relative_error(&analytic, &numeric, 1e-12);
    assert!(err < 1e-6, "{model:?}: Hessian relative error {err:e}");
    // The coupling blocks are there (not only the objects' own).
    let n = objective.offsets[1];
    let coupling = (0..n)
        .flat_map(|i| (n..len).map(move |j| (i, j)))
        .map(|(i, j)| hessian[(i, j)].abs())
        .fold(0.0, f64::max);
    assert!(coupling > 0.0);
}

#[test]
fn joint_gradient_and_hessian_with_contact_and_friction_match_finite_differences() {
    check_group_derivatives(BodyContactModel::Penalty);
    check_group_derivatives(BodyContactModel::Barrier);
}

#[test]
fn objects_that_never_touch_follow_the_trajectories_they_have_alone() {
    let scene = floor_scene(-0.2, 0.3);
    let params = SimulationParams::default();
    let offset = Vector3::new(0.0, 0.0, 3.0);
    let spin = Vector3::new(0.5, 0.0, 0.0);
    let mut together = MultiBodySimulator::new(
        vec![
            block(&scene, params, Vector3::zeros(), spin),
            block(&scene, params, offset, -spin),
        ],
        BodyContactParams::with_radius(0.1),
    )
    .unwrap();
    let mut alone = [
        block(&scene, params, Vector3::zeros(), spin),
        block(&scene, params, offset, -spin),
    ];
    for _ in 0..40 {
        let report = together.step().unwrap();
        assert_eq!(report.joint_groups, 0);
        for body in &mut alone {
            body.simulator.step().unwrap();
        }
    }
    for (a, b) in together.bodies().iter().zip(&alone) {
        assert_eq!(a.simulator().state(), b.simulator().state());
    }
    assert!(
        together.bodies()[0]
            .simulator()
            .state()
            .z
            .iter()
            .any(|&v| v != 0.0)
    );
}

/// Two blocks sliding side by side onto a floor with friction, close enough to be solved
/// as one group but never within the contact distance: the floor's friction is lagged
/// again at each step's solution in the group as for an object alone, so the group slides
/// as the two blocks do alone, landing step included.
#[test]
fn a_group_lags_floor_friction_at_the_solution_like_an_object_alone() {
    let scene = floor_scene(-0.15, 0.5);
    let params = SimulationParams::default();
    let velocity = Vector3::new(1.0, -1.0, 0.0);
    // The blocks are 1 m deep in z: 1.12 m apart leaves a 0.12 m gap, within the 1.5 d̂
    // = 0.15 m candidate reach but beyond d̂ = 0.1 m.
    let side = Vector3::new(0.0, 0.0, 1.12);
    let make = |shift: Vector3<f64>| block(&scene, params, shift, velocity);
    let mut grouped = MultiBodySimulator::new(
        vec![make(Vector3::zeros()), make(side)],
        BodyContactParams::with_radius(0.1),
    )
    .unwrap();
    let mut alone = [make(Vector3::zeros()), make(side)];
    let mut joint = 0;
    for _ in 0..20 {
        joint += grouped.step().unwrap().joint_groups;
        for body in &mut alone {
            body.simulator.step().unwrap();
        }
    }
    assert!(joint >= 10, "{joint} joint solves");
    let mean_x = |b: &Body<StableNeoHookean>| {
        let x = b.sample_positions();
        x.iter().map(|p| p.x).sum::<f64>() / x.len() as f64
    };
    for (g, a) in grouped.bodies().iter().zip(&alone) {
        let (x_group, x_alone) = (mean_x(g), mean_x(a));
        // Measured: 1.3e-4 m apart after 0.2 s of sliding; 1.1e-2 m when the group kept
        // the floor's friction lagged at the start of each step only.
        assert!(
            (x_group - x_alone).abs() < 1e-3,
            "grouped {x_group} m, alone {x_alone} m"
        );
    }
}

/// Two blocks stacked on a floor, solved as one group every step: carrying the group's
/// factorization from step to step reaches the states fresh Hessians reach (to 1e-5 m over
/// 60 steps, Newton tolerance 1e-8) with fewer Hessians.
#[test]
fn a_group_carrying_its_factorization_across_steps_reaches_the_fresh_states() {
    let scene = floor_scene(0.0, 0.0);
    let run = |reuse: optimize::HessianReuse| {
        let params = SimulationParams {
            newton: optimize::NewtonParams {
                hessian_reuse: reuse,
                tolerance: 1e-8,
                ..SimulationParams::default().newton
            },
            ..SimulationParams::default()
        };
        let bodies = (0..2)
            .map(|k| {
                let shift = Vector3::new(0.0, 1.12 * k as f64 + 0.01, 0.0);
                coarse_block(&scene, params, shift, Vector3::zeros(), 1.0 / 3.0)
            })
            .collect();
        let mut sim = MultiBodySimulator::new(bodies, BodyContactParams::with_radius(0.1)).unwrap();
        let (mut hessians, mut joint) = (0, 0);
        for _ in 0..60 {
            let report = sim.step().unwrap();
            assert!(report.converged());
            hessians += report
                .solves
                .iter()
                .map(|s| s.hessian_assemblies)
                .sum::<usize>();
            joint += report.joint_groups;
        }
        let x: Vec<Vector3<f64>> = sim
            .bodies()
            .iter()
            .flat_map(|b| b.sample_positions())
            .collect();
        (x, hessians, joint)
    };
    let (fresh, fresh_hessians, _) = run(optimize::HessianReuse::Never);
    let (carried, carried_hessians, joint) = run(SimulationParams::HESSIAN_REUSE);
    assert!(joint >= 50, "{joint} joint solves");
    let deviation = fresh
        .iter()
        .zip(&carried)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    assert!(deviation < 1e-5, "samples {deviation} m apart");
    // Measured: 178 Hessians carried, 242 fresh, 198 with the factorization kept within
    // each step only (the lower block's floor contacts change while it settles, and each
    // change drops the carried one).
    assert!(
        4 * carried_hessians < 3 * fresh_hessians,
        "{carried_hessians} Hessians carried, {fresh_hessians} fresh"
    );
}

/// Two blocks 0.3 m apart closing at 2 m/s without gravity; returns the simulator after
/// `steps` steps with the largest momentum change and smallest gap seen.
fn head_on(
    model: BodyContactModel,
    steps: usize,
) -> (MultiBodySimulator<StableNeoHookean>, f64, f64) {
    let mut params = SimulationParams::default();
    params.newton.tolerance = 1e-9;
    let scene = Scene::default();
    let speed = Vector3::new(1.0, 0.0, 0.0);
    let contact = BodyContactParams {
        model,
        ..BodyContactParams::with_radius(0.1)
    };
    let mut sim = MultiBodySimulator::new(
        vec![
            block(&scene, params, Vector3::zeros(), speed),
            block(&scene, params, Vector3::new(2.3, 0.02, -0.03), -speed),
        ],
        contact,
    )
    .unwrap();
    let p0 = sim.linear_momentum();
    let scale: f64 = sim
        .bodies()
        .iter()
        .map(|b| b.simulator().linear_momentum().norm())
        .sum();
    let (mut drift, mut gap) = (0.0_f64, f64::INFINITY);
    let mut joint = 0;
    let start_energy = sim.mechanical_energy();
    let mut energy = start_energy;
    for _ in 0..steps {
        let report = sim.step().unwrap();
        assert!(report.converged(), "{report:?}");
        joint += report.joint_groups;
        // Backward Euler and frictionless contact take energy out, never put it in (a
        // lagged normal is a linearization: allow 0.1% of the start per step).
        let now = sim.mechanical_energy();
        assert!(
            now <= energy + 1e-3 * start_energy,
            "{model:?}: energy rose from {energy} J to {now} J"
        );
        energy = now;
        drift = drift.max((sim.linear_momentum() - p0).norm() / scale);
        if let Some(g) = sim.contact_gap() {
            gap = gap.min(g);
        }
    }
    assert!(
        joint > 3,
        "the blocks were solved together in {joint} steps"
    );
    eprintln!("{model:?}: energy {start_energy} J -> {energy} J");
    (sim, drift, gap)
}

#[test]
fn head_on_collision_conserves_momentum_and_the_blocks_separate() {
    for model in [BodyContactModel::Penalty, BodyContactModel::Barrier] {
        let (sim, drift, gap) = head_on(model, 40);
        assert!(
            drift < 1e-8,
            "{model:?}: momentum drift {drift:e} (relative)"
        );
        let v: Vec<f64> = sim
            .bodies()
            .iter()
            .map(|b| b.simulator().linear_momentum().x / b.simulator().model().total_mass())
            .collect();
        assert!(
            v[0] < 0.0 && v[1] > 0.0,
            "{model:?}: velocities after the collision {v:?}"
        );
        assert!(sim.contact_gap().is_none(), "{model:?}: still touching");
        assert!(gap > 0.0, "{model:?}: smallest gap {gap}");
        eprintln!("{model:?}: drift {drift:e}, smallest gap {gap} m, velocities {v:?}");
    }
}

/// Three blocks stacked on a floor for 1000 steps (10 s): the smallest gap between blocks
/// and the deepest penetration (floor, or shell overlap with the penalty) seen, and the
/// blocks' final centres (m).
fn stack(model: BodyContactModel) -> (f64, f64, Vec<Vector3<f64>>) {
    let scene = floor_scene(0.0, 0.0);
    // With the barrier between objects, the floor's barrier too (5 cm).
    let floor_contact = match model {
        BodyContactModel::Penalty => crate::FloorContact::Penalty,
        BodyContactModel::Barrier => crate::FloorContact::Barrier { distance: 0.05 },
    };
    let params = SimulationParams {
        penalty: crate::PenaltyParams {
            floor_contact,
            ..Default::default()
        },
        ..SimulationParams::default()
    };
    let bodies = (0..3)
        .map(|k| {
            let shift = Vector3::new(0.05 * k as f64, 1.12 * k as f64 + 0.01, 0.0);
            // A coarse grid (54 points): the test is about contact over many steps.
            coarse_block(&scene, params, shift, Vector3::zeros(), 1.0 / 3.0)
        })
        .collect();
    let contact = BodyContactParams {
        model,
        ..BodyContactParams::with_radius(0.1)
    };
    let mut sim = MultiBodySimulator::new(bodies, contact).unwrap();
    let (mut gap, mut penetration) = (f64::INFINITY, 0.0_f64);
    for _ in 0..1000 {
        let report = sim.step().unwrap();
        assert!(report.converged(), "{report:?}");
        gap = gap.min(sim.contact_gap().unwrap_or(f64::INFINITY));
        penetration = penetration.max(sim.max_penetration());
    }
    let centres: Vec<Vector3<f64>> = sim
        .bodies()
        .iter()
        .map(|b| {
            let x = b.sample_positions();
            x.iter().sum::<Vector3<f64>>() / x.len() as f64
        })
        .collect();
    (gap, penetration, centres)
}

#[test]
fn a_stack_of_three_blocks_holds_for_1000_steps_without_penetration() {
    for model in [BodyContactModel::Penalty, BodyContactModel::Barrier] {
        let (gap, penetration, centres) = stack(model);
        eprintln!(
            "{model:?}: smallest gap {gap} m, deepest penetration {penetration} m, centres {centres:?}"
        );
        assert!(gap > 0.0, "{model:?}: gap {gap}");
        // Cube side 1 m (the blocks' smallest side): 2% is 0.02 m; none with the barrier.
        let allowed = match model {
            BodyContactModel::Penalty => 0.02,
            BodyContactModel::Barrier => 0.0,
        };
        assert!(
            penetration <= allowed,
            "{model:?}: penetration {penetration} m"
        );
        // Still standing: each block about one height (1 m, plus d̂, less its sag) above the
        // one below, and still on it (frictionless, the 2 m blocks drift sideways a little
        // on the samples' bumps; they started 0.05 m apart in x).
        for pair in centres.windows(2) {
            let rise = pair[1].y - pair[0].y;
            let slide = (pair[1].x - pair[0].x).abs();
            assert!((0.9..1.2).contains(&rise), "{model:?}: centres {centres:?}");
            assert!(slide < 0.5, "{model:?}: centres {centres:?}");
        }
    }
}
