//! Exactly held regions (`PinTreatment::Subspace`): the regions follow their targets
//! at every step, a translated body moves rigidly, the constrained step's derivatives match
//! finite differences, and a basis not built for the regions is refused.

mod support;

use std::f64::consts::PI;
use std::sync::Arc;

use hyperelastic::{LameParameters, StableNeoHookean};
use nalgebra::{DMatrix, Rotation3, Vector3};
use optimize::NewtonObjective;
use reduced_sim::{
    PinTarget, PinnedRegion, ReducedModel, ReducedState, Scene, SceneError, SimulationParams,
    Simulator,
};
use rkpm_core::{IntegrationPoints, sample_box_grid};
use skin_eigen::{BasisParams, RegionConstraintParams, SkinningBasis, build_basis_with_regions};
use support::BEAM_MATERIAL;
use test_support::finite_difference::{gradient, jacobian, relative_error};

const LENGTH: f64 = 2.0;

fn bar() -> IntegrationPoints {
    sample_box_grid(Vector3::zeros(), Vector3::new(LENGTH, 0.5, 0.5), 0.125).unwrap()
}

fn select(points: &IntegrationPoints, keep: impl Fn(&Vector3<f64>) -> bool) -> Vec<usize> {
    (0..points.len())
        .filter(|&i| keep(&points.positions()[i]))
        .collect()
}

fn held_basis(points: &IntegrationPoints, regions: &[Vec<usize>]) -> SkinningBasis {
    let lame = LameParameters::from_young_poisson(
        BEAM_MATERIAL.youngs_modulus,
        BEAM_MATERIAL.poisson_ratio,
    )
    .unwrap();
    let params = BasisParams::default().with_kernels(80).with_modes(6);
    let at: Vec<Vec<Vector3<f64>>> = regions
        .iter()
        .map(|r| r.iter().map(|&i| points.positions()[i]).collect())
        .collect();
    let (basis, _, _) = build_basis_with_regions(
        points,
        &vec![lame; points.len()],
        &params,
        &at,
        &RegionConstraintParams::default(),
        &[],
    )
    .unwrap();
    basis
}

fn model(basis: &SkinningBasis, points: &IntegrationPoints) -> ReducedModel<StableNeoHookean> {
    support::uniform_model(basis, points, &BEAM_MATERIAL)
}

/// The end x ≤ 0.25 held at rest and the end x ≥ L − 0.25 turned about the bar's axis by
/// `angle(t)` (rad).
fn twist_scene(
    points: &IntegrationPoints,
    angle: impl Fn(f64) -> f64 + Send + Sync + 'static,
) -> (Vec<Vec<usize>>, Scene) {
    let regions = vec![
        select(points, |x| x.x <= 0.25),
        select(points, |x| x.x >= LENGTH - 0.25),
    ];
    let axis = Vector3::new(0.0, 0.25, 0.25);
    let scene = Scene {
        gravity: None,
        pins: Vec::new(),
        held: vec![
            PinnedRegion {
                points: regions[0].clone(),
                target: PinTarget::Rest,
            },
            PinnedRegion {
                points: regions[1].clone(),
                target: PinTarget::Moving(Arc::new(move |x, t| {
                    let rotation = Rotation3::from_axis_angle(&Vector3::x_axis(), angle(t));
                    axis + rotation * (x - axis)
                })),
            },
        ],
        floor: None,
        colliders: Vec::new(),
    };
    (regions, scene)
}

#[test]
fn a_rotating_region_follows_its_rotation_at_every_step_to_90_360_and_648_degrees() {
    let points = bar();
    for degrees in [90.0_f64, 360.0, 648.0] {
        let steps = 24;
        let h = 0.01;
        let total = degrees.to_radians();
        let (regions, scene) = twist_scene(&points, move |t| total * (t / (steps as f64 * h)));
        let basis = held_basis(&points, &regions);
        let mut sim =
            Simulator::new(model(&basis, &points), &scene, SimulationParams::default()).unwrap();
        for step in 0..steps {
            let report = sim.step().unwrap();
            let drift = sim.max_held_deviation().unwrap();
            assert!(
                drift <= 1e-6 * LENGTH,
                "{degrees}°: step {step} leaves the held regions {drift:e} m off their targets ({report:?})"
            );
        }
        // The far end did turn: its corner is where the rotation puts it.
        let corner =
            sim.model().deformation_map().positions(&sim.state().z)[*regions[1].last().unwrap()];
        let rest = points.positions()[*regions[1].last().unwrap()];
        let axis = Vector3::new(0.0, 0.25, 0.25);
        let expected = axis + Rotation3::from_axis_angle(&Vector3::x_axis(), total) * (rest - axis);
        assert!(
            (corner - expected).norm() < 1e-6,
            "{degrees}°: corner at {corner:?}, expected {expected:?}"
        );
    }
}

#[test]
fn a_body_whose_only_region_translates_moves_rigidly_with_zero_elastic_energy() {
    let points = bar();
    let regions = vec![select(&points, |x| x.x <= 0.25)];
    let basis = held_basis(&points, &regions);
    let velocity = Vector3::new(0.3, -0.2, 0.1);
    let scene = Scene {
        gravity: None,
        pins: Vec::new(),
        held: vec![PinnedRegion {
            points: regions[0].clone(),
            target: PinTarget::Moving(Arc::new(move |x, t| x + t * velocity)),
        }],
        floor: None,
        colliders: Vec::new(),
    };
    let mut sim =
        Simulator::new(model(&basis, &points), &scene, SimulationParams::default()).unwrap();
    let layout = sim.model().deformation_map().layout();
    sim.set_state(ReducedState {
        z: layout.rest(),
        velocity: layout.uniform_velocity(&velocity),
        time: 0.0,
    })
    .unwrap();
    for _ in 0..10 {
        assert!(sim.step().unwrap().converged());
    }
    let t = sim.state().time;
    let positions = sim.model().deformation_map().positions(&sim.state().z);
    let worst = positions
        .iter()
        .zip(points.positions())
        .map(|(x, rest)| (x - (rest + t * velocity)).norm())
        .fold(0.0, f64::max);
    assert!(
        worst < 1e-9,
        "the body is {worst:e} m off the rigid translation"
    );
    let energy = sim.model().elastic_energy(&sim.state().z);
    assert!(energy.abs() < 1e-9, "elastic energy {energy:e} J");
}

#[test]
fn the_constrained_steps_gradient_and_hessian_match_finite_differences() {
    let points = bar();
    let (_, mut scene) = twist_scene(&points, |t| 3.0 * PI * t);
    let regions: Vec<Vec<usize>> = scene.held.iter().map(|p| p.points.clone()).collect();
    let basis = held_basis(&points, &regions);
    // A penalized band beside the held end, as `freeform::PinHold::Exact` sets up.
    scene.pins.push(PinnedRegion {
        points: select(&points, |x| x.x > 0.25 && x.x <= 0.5),
        target: PinTarget::Rest,
    });
    let params = SimulationParams {
        tangent: reduced_sim::HessianTangent::Exact,
        ..SimulationParams::default()
    };
    let sim = Simulator::new(model(&basis, &points), &scene, params).unwrap();
    let free = sim.free_coordinates().unwrap().to_vec();
    assert_eq!(free.len(), sim.state().z.len() - 2 * 12);
    let predicted = sim.predicted_coordinates();
    let potential = sim.step_potential(&predicted);
    let mut z: Vec<f64> = predicted
        .iter()
        .enumerate()
        .map(|(i, v)| v + 0.02 * ((i * 7 % 11) as f64 / 11.0 - 0.5))
        .collect();
    sim.prescribe(&mut z, sim.state().time + sim.params().time_step);
    let embed = |y: &[f64]| -> Vec<f64> {
        let mut full = z.clone();
        for (&i, v) in free.iter().zip(y) {
            full[i] = *v;
        }
        full
    };
    let y: Vec<f64> = free.iter().map(|&i| z[i]).collect();
    let (g, hessian) = NewtonObjective::gradient_and_hessian(&potential, &z, None);
    assert_eq!(g.len(), free.len());
    let fd = gradient(|y| potential.energy(&embed(y)), &y, 1e-6);
    let g = DMatrix::from_column_slice(g.len(), 1, &g);
    let fd = DMatrix::from_column_slice(fd.len(), 1, fd.as_slice());
    let gradient_error = relative_error(&g, &fd, 1e-8);
    assert!(gradient_error < 1e-6, "gradient vs FD: {gradient_error:e}");
    let fd_hessian = jacobian(
        |y| NewtonObjective::gradient(&potential, &embed(y)),
        &y,
        1e-6,
    );
    let h = DMatrix::from_fn(free.len(), free.len(), |i, j| hessian[(i, j)]);
    let hessian_error = relative_error(&h, &fd_hessian, 1e-8);
    assert!(hessian_error < 1e-5, "Hessian vs FD: {hessian_error:e}");
}

#[test]
fn a_newton_step_leaves_the_prescribed_entries_alone() {
    let points = bar();
    let (regions, scene) = twist_scene(&points, |t| 3.0 * PI * t);
    let basis = held_basis(&points, &regions);
    let sim = Simulator::new(model(&basis, &points), &scene, SimulationParams::default()).unwrap();
    let predicted = sim.predicted_coordinates();
    let potential = sim.step_potential(&predicted);
    let mut z = predicted.clone();
    sim.prescribe(&mut z, 0.01);
    let (g, hessian) = NewtonObjective::gradient_and_hessian(&potential, &z, None);
    let factor = potential
        .factor(hessian)
        .expect("the projected tangent is definite");
    let step = potential.solve(&factor, &g);
    let free = sim.free_coordinates().unwrap();
    assert!(free.iter().any(|&i| step[i] != 0.0));
    for i in (0..z.len()).filter(|i| !free.contains(i)) {
        assert_eq!(step[i], 0.0, "the step moves prescribed entry {i}");
    }
}

#[test]
fn a_basis_not_built_for_the_regions_is_refused_by_name() {
    let points = bar();
    let (regions, scene) = twist_scene(&points, |t| t);
    let free_basis =
        support::box_basis(Vector3::new(LENGTH, 0.5, 0.5), 0.125, 80, 6, &BEAM_MATERIAL).0;
    let err = Simulator::new(
        model(&free_basis, &points),
        &scene,
        SimulationParams::default(),
    )
    .err()
    .unwrap();
    assert!(
        matches!(err, SceneError::RegionNotHeld { region: 0, .. }),
        "{err}"
    );
    // The regions in the other order are not the basis's regions either.
    let swapped = vec![regions[1].clone(), regions[0].clone()];
    let basis = held_basis(&points, &swapped);
    let err = Simulator::new(model(&basis, &points), &scene, SimulationParams::default())
        .err()
        .unwrap();
    assert!(matches!(err, SceneError::RegionNotHeld { .. }), "{err}");
    // Held regions beyond the basis's handles.
    let mut many = scene.clone();
    let first = many.held[0].clone();
    many.held.extend(std::iter::repeat_n(first, 8));
    let err = Simulator::new(model(&basis, &points), &many, SimulationParams::default())
        .err()
        .unwrap();
    assert!(
        matches!(err, SceneError::TooFewHandles { regions: 10, .. }),
        "{err}"
    );
}
