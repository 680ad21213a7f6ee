//! Honest failure: unconverged steps say so, bad input is refused with a named error, and a
//! failed step leaves the state as it was.

mod support;

use hyperelastic::MaterialSample;
use std::sync::Arc;

use hyperelastic::StableNeoHookean;
use nalgebra::Vector3;
use optimize::{NewtonError, NewtonParams, NewtonStop};
use reduced_sim::{
    DeformationMap, DeformationMapError, Floor, FloorContact, PenaltyParams, PinTarget,
    PinnedRegion, ReducedModel, ReducedModelError, ReducedState, Scene, SceneError,
    SimulationParams, Simulator, StateError, StepError,
};
use rkpm_core::IntegrationPoints;
use support::BEAM_MATERIAL;

fn setup() -> (skin_eigen::SkinningBasis, IntegrationPoints) {
    support::box_basis(Vector3::new(3.0, 1.0, 1.0), 0.125, 200, 6, &BEAM_MATERIAL)
}

fn bend_scene(model: &ReducedModel<StableNeoHookean>) -> Scene {
    Scene {
        gravity: Some(Vector3::new(0.0, -9.8, 0.0)),
        pins: vec![PinnedRegion {
            points: model.points_where(|x| x.x <= 0.5),
            target: PinTarget::Rest,
        }],
        floor: None,
        held: Vec::new(),
        colliders: Vec::new(),
    }
}

#[test]
fn step_reports_non_convergence_under_an_impossible_iteration_cap() {
    let (basis, points) = setup();
    let model = support::uniform_model(&basis, &points, &BEAM_MATERIAL);
    let scene = bend_scene(&model);
    let params = SimulationParams {
        newton: NewtonParams {
            max_iterations: 1,
            tolerance: 1e-14,
            ..Default::default()
        },
        ..Default::default()
    };
    let mut sim = Simulator::new(model, &scene, params).unwrap();
    let report = sim.step().unwrap();
    assert!(!report.converged());
    assert_eq!(report.stop, NewtonStop::IterationLimit);
    // One iteration with the exact tangent, one more in the projected retry (the paper's
    // setting) that a solve not converging with the library's shortcuts gets.
    assert_eq!(report.iterations, 2);
    assert_eq!(report.hessian_assemblies, 2);
    let paper = SimulationParams {
        newton: params.newton,
        ..SimulationParams::paper_setting()
    };
    let model = support::uniform_model(&basis, &points, &BEAM_MATERIAL);
    let mut paper_sim = Simulator::new(model, &scene, paper).unwrap();
    let paper_report = paper_sim.step().unwrap();
    assert!(!paper_report.converged());
    assert_eq!(
        paper_report.iterations, 1,
        "the paper's setting has no retry"
    );
    assert!(report.residual >= 1e-14, "residual {:e}", report.residual);
    // The state still advanced to Newton's last iterate.
    assert!((sim.state().time - 0.01).abs() < 1e-15);
}

#[test]
fn non_finite_pin_target_stops_the_step_and_keeps_the_state() {
    let (basis, points) = setup();
    let model = support::uniform_model(&basis, &points, &BEAM_MATERIAL);
    let pinned = model.points_where(|x| x.x <= 0.5);
    let scene = Scene {
        pins: vec![PinnedRegion {
            points: pinned,
            target: PinTarget::Moving(Arc::new(|x, t| {
                if t > 0.015 {
                    Vector3::repeat(f64::NAN)
                } else {
                    *x
                }
            })),
        }],
        ..Default::default()
    };
    let mut sim = Simulator::new(model, &scene, SimulationParams::default()).unwrap();
    sim.step().unwrap();
    let before = sim.state().clone();
    let err = sim.step().unwrap_err();
    assert!(
        matches!(
            err,
            StepError::Newton(NewtonError::NonFinite {
                quantity: "energy",
                ..
            })
        ),
        "{err}"
    );
    assert_eq!(sim.state(), &before);
}

#[test]
fn a_barrier_floor_through_the_object_refuses_the_step_and_keeps_the_state() {
    let (basis, points) = setup();
    let model = support::uniform_model(&basis, &points, &BEAM_MATERIAL);
    // The beam spans y in [0, 1]; this floor cuts it at y = 0.3.
    let scene = Scene {
        gravity: Some(Vector3::new(0.0, -9.8, 0.0)),
        floor: Some(Floor {
            normal: Vector3::y(),
            offset: 0.3,
            friction: 0.0,
        }),
        ..Default::default()
    };
    let params = SimulationParams {
        penalty: PenaltyParams {
            floor_contact: FloorContact::Barrier { distance: 0.05 },
            ..Default::default()
        },
        ..Default::default()
    };
    let mut sim = Simulator::new(model, &scene, params).unwrap();
    let before = sim.state().clone();
    let err = sim.step().unwrap_err();
    match err {
        StepError::StartsInContact { depth, time } => {
            // The lowest points (half a 0.125 m cell above y = 0) are 0.2375 m under it.
            assert!((depth - 0.2375).abs() < 1e-9, "{err}");
            assert_eq!(time, 0.0);
        }
        other => panic!("expected StartsInContact, got {other}"),
    }
    assert_eq!(sim.state(), &before);
    // A barrier distance that is not positive is refused up front.
    let params = SimulationParams {
        penalty: PenaltyParams {
            floor_contact: FloorContact::Barrier { distance: 0.0 },
            ..Default::default()
        },
        ..Default::default()
    };
    let model = support::uniform_model(&basis, &points, &BEAM_MATERIAL);
    assert_eq!(
        Simulator::new(model, &scene, params).err(),
        Some(SceneError::BarrierDistance(0.0))
    );
}

#[test]
fn bad_inputs_are_refused_with_named_errors() {
    let (basis, points) = setup();
    // One material per point.
    let err = ReducedModel::new(&basis, &points, &[BEAM_MATERIAL], StableNeoHookean).err();
    assert!(matches!(
        err,
        Some(ReducedModelError::MaterialCount { materials: 1, .. })
    ));
    // ν ≥ 0.5 and a NaN density, with the point index.
    let mut materials = vec![BEAM_MATERIAL; points.len()];
    materials[7] = MaterialSample {
        poisson_ratio: 0.5,
        ..BEAM_MATERIAL
    };
    let err = ReducedModel::new(&basis, &points, &materials, StableNeoHookean).err();
    assert!(matches!(
        err,
        Some(ReducedModelError::Material { point: 7, .. })
    ));
    materials[7] = MaterialSample {
        density: f64::NAN,
        ..BEAM_MATERIAL
    };
    let err = ReducedModel::new(&basis, &points, &materials, StableNeoHookean).err();
    assert!(matches!(
        err,
        Some(ReducedModelError::Density { point: 7, .. })
    ));
    // A NaN query point.
    let err = DeformationMap::new(&basis, &[Vector3::new(0.0, f64::NAN, 0.0)]).err();
    assert!(matches!(
        err,
        Some(DeformationMapError::NonFinitePoint { point: 0, .. })
    ));

    let model = support::uniform_model(&basis, &points, &BEAM_MATERIAL);
    let n = points.len();
    let layout = model.deformation_map().layout();
    let scenes = [
        (
            Scene {
                pins: vec![PinnedRegion {
                    points: vec![n],
                    target: PinTarget::Rest,
                }],
                ..Default::default()
            },
            SceneError::PinOutOfRange {
                region: 0,
                point: n,
                points: n,
            },
        ),
        (
            Scene {
                pins: vec![PinnedRegion {
                    points: vec![],
                    target: PinTarget::Rest,
                }],
                ..Default::default()
            },
            SceneError::EmptyPin { region: 0 },
        ),
        (
            Scene {
                gravity: Some(Vector3::new(0.0, f64::INFINITY, 0.0)),
                ..Default::default()
            },
            SceneError::Gravity([0.0, f64::INFINITY, 0.0]),
        ),
    ];
    for (scene, expected) in scenes {
        let err = scene.validate(&model, &PenaltyParams::default()).err();
        assert_eq!(err, Some(expected));
    }
    let err = Scene::default()
        .validate(
            &model,
            &PenaltyParams {
                pin_factor: -1.0,
                ..Default::default()
            },
        )
        .err();
    assert!(matches!(err, Some(SceneError::Penalty { .. })));
    let mut sim = Simulator::new(
        model,
        &Scene::default(),
        SimulationParams {
            time_step: 0.0,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(sim.step().unwrap_err(), StepError::InvalidTimeStep(0.0));
    let err = sim.set_state(ReducedState {
        z: vec![f64::NAN; layout.len()],
        velocity: layout.rest(),
        time: 0.0,
    });
    assert_eq!(err, Err(StateError::NonFinite));
    let err = sim.set_state(ReducedState {
        z: vec![0.0; 3],
        velocity: layout.rest(),
        time: 0.0,
    });
    assert!(matches!(err, Err(StateError::WrongLength { z: 3, .. })));
}
