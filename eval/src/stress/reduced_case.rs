//! One stress case on the reduced simulator: the object, the run, and the diagnostics
//! (finiteness, Newton convergence, min det F, energy balance).

use crate::beam_scenario::{BEAM_MAX, BEAM_MIN, BeamTest, beam_material};
use freeform::scene::{Constraint, FloorSpec, Motion, Region, SceneSpec};
use hyperelastic::MaterialSample;
use hyperelastic::{LameParameters, StableNeoHookean};
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use reduced_sim::{
    PinTarget, QuadratureRule, ReducedModel, ReducedState, Scene, SimulationParams, Simulator,
};
use rkpm_core::{IntegrationPoints, sample_box_grid};
use skin_eigen::{BasisParams, build_basis};

use super::fem_case::run_fem_case;
use super::{CaseStatus, DegenerateSampling, StressCase, StressOutcome, StressScene, StressSolver};

/// The object of a case: basis points, simulation points, per-point materials of each, scene.
pub(super) struct CaseObject {
    pub(super) basis_points: IntegrationPoints,
    pub(super) basis_materials: Vec<MaterialSample>,
    pub(super) simulation_points: IntegrationPoints,
    pub(super) simulation_materials: Vec<MaterialSample>,
    pub(super) scene: SceneSpec,
    /// Initial uniform velocity (m/s).
    pub(super) velocity: Vector3<f64>,
}

pub(super) fn material(youngs_modulus: f64, poisson_ratio: f64) -> MaterialSample {
    MaterialSample {
        youngs_modulus,
        poisson_ratio,
        density: 1000.0,
    }
}

fn grid(min: Vector3<f64>, max: Vector3<f64>, points: usize) -> Result<IntegrationPoints, String> {
    let spacing = ((max - min).product() / points as f64).cbrt();
    sample_box_grid(min, max, spacing).map_err(|e| e.to_string())
}

fn gravity() -> Option<Vector3<f64>> {
    Some(Vector3::new(0.0, -9.8, 0.0))
}

fn pinned_below(axis: usize, value: f64) -> Constraint {
    Constraint {
        region: Region::Below { axis, value },
        motion: Motion::Rest,
    }
}

/// Gravity and the floor y = 0, nothing pinned.
fn floor_drop_scene() -> SceneSpec {
    SceneSpec {
        gravity: gravity(),
        constraints: Vec::new(),
        floor: Some(FloorSpec {
            normal: Vector3::y(),
            offset: 0.0,
            friction: 0.0,
        }),
        colliders: Vec::new(),
    }
}

/// The beam scenes of design §4.1 ([`BeamTest::scene`]), the twist at its own rate.
fn beam_scene(scene: StressScene) -> SceneSpec {
    match scene {
        StressScene::BeamTwist { degrees_per_second } => {
            let mut spec = BeamTest::Twist.scene();
            for constraint in &mut spec.constraints {
                if let Motion::Rotate {
                    rate_degrees_per_second,
                    ..
                } = &mut constraint.motion
                {
                    *rate_degrees_per_second = degrees_per_second;
                }
            }
            spec
        }
        _ => BeamTest::Bend.scene(),
    }
}

/// Builds the object and scene of `case`.
pub(super) fn case_object(case: &StressCase) -> Result<CaseObject, String> {
    let nu = case.poisson_ratio;
    let uniform = |points: &IntegrationPoints, e: f64| vec![material(e, nu); points.len()];
    let two_grids = |min: Vector3<f64>, max: Vector3<f64>| -> Result<_, String> {
        Ok((
            grid(min, max, case.basis_points)?,
            grid(min, max, case.simulation_points)?,
        ))
    };
    match case.scene {
        StressScene::BeamBend | StressScene::BeamTwist { .. } => {
            let (basis, simulation) = two_grids(BEAM_MIN, BEAM_MAX)?;
            let e = beam_material().youngs_modulus;
            Ok(CaseObject {
                basis_materials: uniform(&basis, e),
                simulation_materials: uniform(&simulation, e),
                basis_points: basis,
                simulation_points: simulation,
                scene: beam_scene(case.scene),
                velocity: Vector3::zeros(),
            })
        }
        StressScene::CubeImpact { speed } => {
            let (min, max) = (Vector3::new(0.0, 0.02, 0.0), Vector3::new(1.0, 1.02, 1.0));
            let (basis, simulation) = two_grids(min, max)?;
            Ok(CaseObject {
                basis_materials: uniform(&basis, 1e5),
                simulation_materials: uniform(&simulation, 1e5),
                basis_points: basis,
                simulation_points: simulation,
                scene: floor_drop_scene(),
                velocity: Vector3::new(0.0, -speed, 0.0),
            })
        }
        StressScene::LayeredSphereDrop { contrast } => {
            let center = Vector3::new(0.0, 0.6, 0.0);
            let ball = |points: usize| -> Result<IntegrationPoints, String> {
                // A cube grid with ≈ `points` inside the ball (π/6 of the cube).
                let cube = grid(
                    center.add_scalar(-0.5),
                    center.add_scalar(0.5),
                    (points as f64 * 6.0 / std::f64::consts::PI) as usize,
                )?;
                let (positions, volumes): (Vec<_>, Vec<_>) = cube
                    .positions()
                    .iter()
                    .zip(cube.volumes())
                    .filter(|(p, _)| (*p - center).norm() <= 0.5)
                    .map(|(p, v)| (*p, *v))
                    .unzip();
                IntegrationPoints::new(positions, volumes).map_err(|e| e.to_string())
            };
            let layered = |points: &IntegrationPoints| {
                points
                    .positions()
                    .iter()
                    .map(|p| {
                        let shell = ((p - center).norm() / 0.125).floor() as usize;
                        let stiff = shell.is_multiple_of(2);
                        material(if stiff { 1e5 * contrast } else { 1e5 }, nu)
                    })
                    .collect()
            };
            let (basis, simulation) = (ball(case.basis_points)?, ball(case.simulation_points)?);
            Ok(CaseObject {
                basis_materials: layered(&basis),
                simulation_materials: layered(&simulation),
                basis_points: basis,
                simulation_points: simulation,
                scene: floor_drop_scene(),
                velocity: Vector3::zeros(),
            })
        }
        StressScene::Plate {
            thickness,
            sampling,
        } => {
            let max = Vector3::new(1.0, 1.0, thickness);
            let points = match sampling {
                DegenerateSampling::OneLayer => {
                    sample_box_grid(Vector3::zeros(), max, thickness).map_err(|e| e.to_string())?
                }
                DegenerateSampling::SparseNoisy { points } => {
                    let regular = grid(Vector3::zeros(), max, points)?;
                    let h = regular.volumes()[0].cbrt();
                    let mut rng = ChaCha8Rng::seed_from_u64(7);
                    let positions = regular
                        .positions()
                        .iter()
                        .map(|p| p + Vector3::from_fn(|_, _| rng.random_range(-0.4..0.4) * h))
                        .collect();
                    IntegrationPoints::new(positions, regular.volumes().to_vec())
                        .map_err(|e| e.to_string())?
                }
                DegenerateSampling::Duplicated => {
                    let regular = grid(Vector3::zeros(), max, case.basis_points / 2)?;
                    let positions = [regular.positions(), regular.positions()].concat();
                    let halves: Vec<f64> = regular.volumes().iter().map(|v| v / 2.0).collect();
                    IntegrationPoints::new(positions, [&halves[..], &halves[..]].concat())
                        .map_err(|e| e.to_string())?
                }
            };
            Ok(CaseObject {
                basis_materials: uniform(&points, 1e5),
                simulation_materials: uniform(&points, 1e5),
                simulation_points: points.clone(),
                basis_points: points,
                scene: SceneSpec {
                    gravity: gravity(),
                    constraints: vec![pinned_below(0, 0.1)],
                    floor: None,
                    colliders: Vec::new(),
                },
                velocity: Vector3::zeros(),
            })
        }
    }
}

/// Running diagnostics of one case.
struct Diagnostics {
    all_finite: bool,
    min_det_f: f64,
    initial_energy: Option<f64>,
    initial_gravity: f64,
    scale: f64,
    work: f64,
    max_growth: f64,
}

/// Runs one case, catching nothing: errors become [`CaseStatus::Error`].
#[allow(non_snake_case)]
pub(super) fn run_case(case: &StressCase) -> StressOutcome {
    if case.solver == StressSolver::Fem {
        return run_fem_case(case);
    }
    let mut outcome = StressOutcome::not_run(case);
    let fail = |mut outcome: StressOutcome, message: String| {
        outcome.status = CaseStatus::Error(message);
        outcome
    };
    let object = match case_object(case) {
        Ok(object) => object,
        Err(e) => return fail(outcome, format!("sampling: {e}")),
    };
    let lame: Result<Vec<LameParameters>, _> = object
        .basis_materials
        .iter()
        .map(|m| m.lame_parameters())
        .collect();
    let lame = match lame {
        Ok(lame) => lame,
        Err(e) => return fail(outcome, format!("material: {e}")),
    };
    let params = BasisParams::default()
        .with_modes(case.modes)
        .with_kernels(case.kernels);
    let basis = match build_basis(&object.basis_points, &lame, &params) {
        Ok((basis, _, _)) => basis,
        Err(e) => return fail(outcome, format!("basis: {e}")),
    };
    let model = match ReducedModel::new(
        &basis,
        &object.simulation_points,
        &object.simulation_materials,
        StableNeoHookean,
    ) {
        Ok(model) => model,
        Err(e) => return fail(outcome, format!("model: {e}")),
    };
    // The library defaults throughout: an optimized cubature and Hessian reuse.
    let model = match QuadratureRule::default().apply(model) {
        Ok((model, _)) => model,
        Err(e) => return fail(outcome, format!("elastic quadrature: {e}")),
    };
    let scene = match object.scene.reduced_scene(model.rest_positions()) {
        Ok(scene) => scene,
        Err(e) => return fail(outcome, format!("scene: {e}")),
    };
    let sim_params = SimulationParams {
        time_step: case.time_step,
        ..SimulationParams::default()
    };
    let floor_stiffness = sim_params.penalty.floor_factor * model.max_p_wave_modulus()
        / model.bounds().extent().max().powi(2);
    let mut sim = match Simulator::new(model, &scene, sim_params) {
        Ok(sim) => sim,
        Err(e) => return fail(outcome, format!("simulator: {e}")),
    };
    if object.velocity != Vector3::zeros() {
        let layout = sim.model().deformation_map().layout();
        let state = ReducedState {
            z: layout.rest(),
            velocity: layout.uniform_velocity(&object.velocity),
            time: 0.0,
        };
        if let Err(e) = sim.set_state(state) {
            return fail(outcome, format!("initial state: {e}"));
        }
    }

    let mut diagnostics = Diagnostics {
        all_finite: true,
        min_det_f: f64::INFINITY,
        initial_energy: None,
        initial_gravity: 0.0,
        scale: 0.0,
        work: 0.0,
        max_growth: f64::NEG_INFINITY,
    };
    let mut forces = pin_anchor_forces(&sim, &scene);
    observe(&sim, &scene, floor_stiffness, &mut diagnostics);
    for step in 1..=case.steps {
        let t_old = sim.state().time;
        match sim.step() {
            Ok(report) => {
                outcome.steps_run = step;
                outcome.unconverged_steps += usize::from(!report.converged());
            }
            Err(e) => {
                outcome.status = CaseStatus::Error(format!("step {step}: {e}"));
                break;
            }
        }
        // Work of the moving anchors: ½ (f_old + f_new) · Δtarget per pinned point.
        let new_forces = pin_anchor_forces(&sim, &scene);
        let t_new = sim.state().time;
        let rest = sim.model().rest_positions();
        for (region, (old, new)) in scene.pins.iter().zip(forces.iter().zip(&new_forces)) {
            if let PinTarget::Moving(_) = region.target {
                for (k, &i) in region.points.iter().enumerate() {
                    let moved =
                        region.target.at(&rest[i], t_new) - region.target.at(&rest[i], t_old);
                    diagnostics.work += 0.5 * (old[k] + new[k]).dot(&moved);
                }
            }
        }
        forces = new_forces;
        observe(&sim, &scene, floor_stiffness, &mut diagnostics);
        if !diagnostics.all_finite {
            break;
        }
    }
    outcome.all_finite = diagnostics.all_finite;
    outcome.min_det_f = diagnostics.min_det_f;
    outcome.max_energy_growth = diagnostics.max_growth / diagnostics.scale.max(1e-12);
    outcome
}

/// Force each pin's anchor exerts on the body, `κ v_i (target_i − x_i)` (N), per region.
fn pin_anchor_forces(sim: &Simulator<StableNeoHookean>, scene: &Scene) -> Vec<Vec<Vector3<f64>>> {
    let model = sim.model();
    let x = model.deformation_map().positions(&sim.state().z);
    let (rest, volumes, t) = (model.rest_positions(), model.volumes(), sim.state().time);
    scene
        .pins
        .iter()
        .map(|region| {
            region
                .points
                .iter()
                .map(|&i| {
                    (region.target.at(&rest[i], t) - x[i]) * (sim.pin_stiffness() * volumes[i])
                })
                .collect()
        })
        .collect()
}

/// Updates finiteness, det F and the energy balance with the simulator's current state.
#[allow(non_snake_case)]
fn observe(
    sim: &Simulator<StableNeoHookean>,
    scene: &Scene,
    floor_stiffness: f64,
    d: &mut Diagnostics,
) {
    let model = sim.model();
    let state = sim.state();
    let map = model.deformation_map();
    let x = map.positions(&state.z);
    let finite = state.z.iter().chain(&state.velocity).all(|v| v.is_finite())
        && x.iter().all(|p| p.iter().all(|c| c.is_finite()));
    if !finite {
        d.all_finite = false;
        return;
    }
    for F in map.deformation_gradients(&state.z) {
        d.min_det_f = d.min_det_f.min(F.determinant());
    }
    let (volumes, densities, rest) = (model.volumes(), model.densities(), model.rest_positions());
    let velocities = map.displacements(&state.velocity);
    let kinetic: f64 = (0..x.len())
        .map(|i| 0.5 * densities[i] * volumes[i] * velocities[i].norm_squared())
        .sum();
    let gravity: f64 = scene.gravity.map_or(0.0, |g| {
        (0..x.len())
            .map(|i| -densities[i] * volumes[i] * g.dot(&x[i]))
            .sum()
    });
    let pins: f64 = scene
        .pins
        .iter()
        .flat_map(|region| {
            region.points.iter().map(|&i| {
                0.5 * sim.pin_stiffness()
                    * volumes[i]
                    * (x[i] - region.target.at(&rest[i], state.time)).norm_squared()
            })
        })
        .sum();
    let floor: f64 = scene.floor.map_or(0.0, |f| {
        (0..x.len())
            .map(|i| {
                let depth = (f.offset - f.normal.dot(&x[i])).max(0.0);
                0.5 * floor_stiffness * volumes[i] * depth * depth
            })
            .sum()
    });
    let total = kinetic + model.elastic_energy(&state.z) + gravity + pins + floor;
    let initial = *d.initial_energy.get_or_insert_with(|| {
        d.initial_gravity = gravity;
        d.scale = kinetic;
        total
    });
    d.scale = d
        .scale
        .max(d.work.abs())
        .max((gravity - d.initial_gravity).abs());
    d.max_growth = d.max_growth.max(total - initial - d.work);
}
