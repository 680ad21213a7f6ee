//! The numerical stress suite (`freeform stress`): the reduced simulator pushed to the edges a
//! user will hit — near-incompressible materials, stiffness contrast, large time steps, fast
//! twists that invert material, a 10 m/s impact, extreme m and K, degenerate sampling — with
//! per-case diagnostics that make a failure loud.
//!
//! Per case: finished or the named error it stopped with (a panic is caught and reported as a
//! bug), all values finite, Newton convergence per step, the largest energy growth
//! `max_t (H_t − H_0 − W_t) / S` and the smallest det F reached. Here
//! `H = kinetic + elastic + gravity potential + pin and floor penalty energy`, `W_t` the work
//! the moving pins did on the body up to step t (trapezoidal), and `S` the largest energy
//! exchanged (`max |W_t|`, `max |ΔU_gravity|`, the initial kinetic energy). Backward Euler only
//! dissipates, so a growth above the Newton tolerance's noise means energy was created.

use hyperelastic::MaterialSample;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::time::Instant;

use hyperelastic::{LameParameters, StableNeoHookean};
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use reduced_sim::{PinTarget, ReducedModel, ReducedState, Scene, SimulationParams, Simulator};
use rkpm_core::{IntegrationPoints, sample_box_grid};
use serde::{Deserialize, Serialize};
use skin_eigen::{BasisParams, build_basis};

use crate::beam::{BEAM_MAX, BEAM_MIN, BeamTest, beam_material};
use crate::scene_spec::{Constraint, FloorSpec, Motion, Region, SceneSpec};

/// The object and what happens to it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum StressScene {
    /// The beam of DESIGN 4.1 (5 × 1 × 1 m, E = 5 MPa) under gravity, x ≤ 0.5 pinned.
    BeamBend,
    /// The beam with x ≤ 0.5 pinned and x ≥ 4.5 rotated about its axis at this rate up to 720°.
    BeamTwist {
        /// Degrees per second (DESIGN 4.1: 2160).
        degrees_per_second: f64,
    },
    /// A 1 m cube (E = 0.1 MPa) starting 2 cm above a floor, moving down at this speed.
    CubeImpact {
        /// m/s.
        speed: f64,
    },
    /// The paper's layered sphere (Sec. 9.2): radius 0.5 m, four concentric shells
    /// stiff-soft-stiff-soft (soft E = 0.1 MPa, stiff `contrast` times that), dropped from
    /// 0.1 m onto a floor (it lands after about 14 steps of 0.01 s).
    LayeredSphereDrop {
        /// Stiff / soft Young's modulus.
        contrast: f64,
    },
    /// A 1 × 1 × `thickness` m plate (E = 0.1 MPa) under gravity, x ≤ 0.1 pinned, sampled by
    /// the given degenerate rule.
    Plate {
        /// Plate thickness (m).
        thickness: f64,
        /// How its points are placed.
        sampling: DegenerateSampling,
    },
}

/// Sampling rules a careless user might feed the basis builder.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum DegenerateSampling {
    /// A grid whose spacing equals the thickness: one layer of coplanar points.
    OneLayer,
    /// A jittered grid of about this many points, each moved by up to 40% of the spacing.
    SparseNoisy {
        /// Number of points.
        points: usize,
    },
    /// A grid with every point given twice.
    Duplicated,
}

/// Which simulator a case runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum StressSolver {
    /// FreeForm's reduced simulator (default).
    #[default]
    Reduced,
    /// The FEM reference, P2 tetrahedra at 2 cells per metre (beam scenes only; no energy
    /// balance: its Dirichlet handles' work is not tracked, so the growth column is NaN).
    Fem,
}

/// One case of the suite.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StressCase {
    /// The simulator.
    pub solver: StressSolver,
    /// Group ("ν", "dt", "twist", …) and short name.
    pub group: String,
    /// What varies, e.g. "ν = 0.499".
    pub name: String,
    /// The object and its scene.
    pub scene: StressScene,
    /// Poisson ratio ν.
    pub poisson_ratio: f64,
    /// Time step h (s).
    pub time_step: f64,
    /// Steps to run.
    pub steps: usize,
    /// Modes m.
    pub modes: usize,
    /// Kernels K.
    pub kernels: usize,
    /// Grid points for the basis (grid scenes).
    pub basis_points: usize,
    /// Grid points for the simulation (grid scenes).
    pub simulation_points: usize,
}

impl StressCase {
    fn beam(group: &str, name: String, scene: StressScene, steps: usize) -> Self {
        StressCase {
            solver: StressSolver::Reduced,
            group: group.into(),
            name,
            scene,
            poisson_ratio: 0.45,
            time_step: 0.01,
            steps,
            modes: 16,
            kernels: 500,
            basis_points: 10_000,
            simulation_points: 5000,
        }
    }
}

/// How a case ended.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum CaseStatus {
    /// Every step ran.
    Finished,
    /// Stopped with a named error (setup or a step): a safe failure.
    Error(String),
    /// A panic: a bug, whatever the input.
    Panicked(String),
}

/// One case's diagnostics.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StressOutcome {
    /// The case.
    pub case: StressCase,
    /// How it ended.
    pub status: CaseStatus,
    /// Steps completed.
    pub steps_run: usize,
    /// Steps whose Newton solve stopped before its tolerance.
    pub unconverged_steps: usize,
    /// Every coordinate, velocity and point position stayed finite.
    pub all_finite: bool,
    /// `max(0, max_t (H_t − H_0 − W_t)) / S` (see the module docs); positive means energy was
    /// created.
    pub max_energy_growth: f64,
    /// Smallest det F over the simulation points and steps.
    pub min_det_f: f64,
    /// Wall time including the basis (s).
    pub seconds: f64,
}

impl StressOutcome {
    /// The outcome of `case` before it runs: finished, nothing run, nothing measured.
    fn not_run(case: &StressCase) -> Self {
        StressOutcome {
            case: case.clone(),
            status: CaseStatus::Finished,
            steps_run: 0,
            unconverged_steps: 0,
            all_finite: true,
            max_energy_growth: f64::NAN,
            min_det_f: f64::NAN,
            seconds: 0.0,
        }
    }

    /// Acceptable: finished or stopped with a named error, and never a non-finite value.
    pub fn acceptable(&self) -> bool {
        self.all_finite && !matches!(self.status, CaseStatus::Panicked(_))
    }
}

/// The cases to run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StressConfig {
    /// The cases, in order.
    pub cases: Vec<StressCase>,
}

impl StressConfig {
    /// The matrix: ν ∈ {0.3, 0.45, 0.49, 0.499}; contrast 10² and 10⁴; dt ∈ {0.01,
    /// 0.05, 0.1}; the 720° Twist, held past 720°, and 4× faster; a 10 m/s impact; m from 1 to
    /// 64 and K from 64 to 4000; the FEM reference at ν = 0.3 and 0.499, dt = 0.1 and the fast
    /// twist; a one-layer plate, a sparse noisy cloud, duplicated points.
    pub fn full() -> Self {
        let mut cases = Vec::new();
        for nu in [0.3, 0.45, 0.49, 0.499] {
            cases.push(StressCase {
                poisson_ratio: nu,
                ..StressCase::beam("ν", format!("Bend ν = {nu}"), StressScene::BeamBend, 300)
            });
        }
        for contrast in [1e2, 1e4] {
            cases.push(StressCase {
                kernels: 400,
                basis_points: 8000,
                simulation_points: 4000,
                ..StressCase::beam(
                    "contrast",
                    format!("layered sphere, contrast {contrast:.0e}"),
                    StressScene::LayeredSphereDrop { contrast },
                    100,
                )
            });
        }
        for dt in [0.01, 0.05, 0.1] {
            cases.push(StressCase {
                time_step: dt,
                ..StressCase::beam(
                    "dt",
                    format!("Bend dt = {dt}"),
                    StressScene::BeamBend,
                    (3.0 / dt).round() as usize,
                )
            });
        }
        for (name, rate, steps) in [
            ("Twist 720° (34 steps)", 2160.0, 34),
            ("Twist held at 720° to 1 s", 2160.0, 100),
            ("Twist 4× faster (8640°/s)", 8640.0, 34),
        ] {
            cases.push(StressCase::beam(
                "twist",
                name.into(),
                StressScene::BeamTwist {
                    degrees_per_second: rate,
                },
                steps,
            ));
        }
        cases.push(StressCase {
            kernels: 400,
            basis_points: 8000,
            simulation_points: 4000,
            ..StressCase::beam(
                "impact",
                "cube at 10 m/s onto a floor".into(),
                StressScene::CubeImpact { speed: 10.0 },
                60,
            )
        });
        for m in [1, 4, 16, 64] {
            cases.push(StressCase {
                modes: m,
                kernels: 1000,
                basis_points: 20_000,
                ..StressCase::beam("m", format!("Bend m = {m}"), StressScene::BeamBend, 100)
            });
        }
        for k in [64, 250, 1000, 4000] {
            cases.push(StressCase {
                kernels: k,
                basis_points: 20_000,
                ..StressCase::beam("K", format!("Bend K = {k}"), StressScene::BeamBend, 100)
            });
        }
        for (name, nu, dt, scene, steps) in [
            ("FEM Bend ν = 0.3", 0.3, 0.01, StressScene::BeamBend, 300),
            (
                "FEM Bend ν = 0.499",
                0.499,
                0.01,
                StressScene::BeamBend,
                300,
            ),
            ("FEM Bend dt = 0.1", 0.45, 0.1, StressScene::BeamBend, 30),
            (
                "FEM Twist 4× faster (8640°/s)",
                0.45,
                0.01,
                StressScene::BeamTwist {
                    degrees_per_second: 8640.0,
                },
                34,
            ),
        ] {
            cases.push(StressCase {
                solver: StressSolver::Fem,
                poisson_ratio: nu,
                time_step: dt,
                ..StressCase::beam("FEM", name.into(), scene, steps)
            });
        }
        for (name, thickness, sampling) in [
            ("plate one point thick", 0.05, DegenerateSampling::OneLayer),
            (
                "sparse noisy cloud (300 points)",
                0.3,
                DegenerateSampling::SparseNoisy { points: 300 },
            ),
            (
                "every point duplicated",
                0.3,
                DegenerateSampling::Duplicated,
            ),
        ] {
            cases.push(StressCase {
                modes: 8,
                kernels: 64,
                basis_points: 2000,
                simulation_points: 2000,
                ..StressCase::beam(
                    "sampling",
                    name.into(),
                    StressScene::Plate {
                        thickness,
                        sampling,
                    },
                    30,
                )
            });
        }
        StressConfig { cases }
    }

    /// A subset that runs in well under a minute on 2 cores: ν = 0.499, dt = 0.1, the fast
    /// twist, the impact, contrast 10⁴, m = 1, the FEM at ν = 0.499, and the three degenerate
    /// samplings, all short and coarse.
    pub fn quick() -> Self {
        let full = StressConfig::full();
        let pick = |name: &str| {
            full.cases
                .iter()
                .find(|c| c.name == name)
                .cloned()
                .expect("a case of the full matrix")
        };
        let coarse = |c: StressCase, steps: usize| StressCase {
            steps,
            kernels: c.kernels.min(150),
            basis_points: c.basis_points.min(3000),
            simulation_points: c.simulation_points.min(1500),
            ..c
        };
        let cases = vec![
            coarse(pick("Bend ν = 0.499"), 20),
            coarse(pick("Bend dt = 0.1"), 10),
            coarse(pick("Twist 4× faster (8640°/s)"), 12),
            coarse(pick("cube at 10 m/s onto a floor"), 15),
            coarse(pick("layered sphere, contrast 1e4"), 25),
            coarse(pick("Bend m = 1"), 10),
            coarse(pick("FEM Bend ν = 0.499"), 10),
            pick("plate one point thick"),
            coarse(pick("sparse noisy cloud (300 points)"), 10),
            coarse(pick("every point duplicated"), 10),
        ];
        StressConfig { cases }
    }
}

/// Runs every case (a panic inside a case is caught and reported), calling `on_case` after each.
pub fn run_stress(
    config: &StressConfig,
    mut on_case: impl FnMut(&StressOutcome),
) -> Vec<StressOutcome> {
    config
        .cases
        .iter()
        .map(|case| {
            let start = Instant::now();
            let outcome = match catch_unwind(AssertUnwindSafe(|| run_case(case))) {
                Ok(outcome) => outcome,
                Err(panic) => {
                    let message = panic
                        .downcast_ref::<String>()
                        .cloned()
                        .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                        .unwrap_or_else(|| "unknown panic".into());
                    StressOutcome {
                        status: CaseStatus::Panicked(message),
                        ..StressOutcome::not_run(case)
                    }
                }
            };
            let outcome = StressOutcome {
                seconds: start.elapsed().as_secs_f64(),
                ..outcome
            };
            on_case(&outcome);
            outcome
        })
        .collect()
}

/// The object of a case: basis points, simulation points, per-point materials of each, scene.
struct CaseObject {
    basis_points: IntegrationPoints,
    basis_materials: Vec<MaterialSample>,
    simulation_points: IntegrationPoints,
    simulation_materials: Vec<MaterialSample>,
    scene: SceneSpec,
    /// Initial uniform velocity (m/s).
    velocity: Vector3<f64>,
}

fn material(youngs_modulus: f64, poisson_ratio: f64) -> MaterialSample {
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
        }),
    }
}

/// The beam scenes of DESIGN 4.1 ([`BeamTest::scene`]), the twist at its own rate.
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
fn case_object(case: &StressCase) -> Result<CaseObject, String> {
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
fn run_case(case: &StressCase) -> StressOutcome {
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

/// The outcomes as a Markdown table, with what each column means.
pub fn stress_markdown(outcomes: &[StressOutcome]) -> String {
    use std::fmt::Write as _;
    let mut md = String::from(
        "## Stress suite (reduced simulator)\n\n\
         growth = max_t (H_t − H_0 − W_t) / S: energy created, relative to the largest energy \
         exchanged (H = kinetic + elastic + gravity + penalty energies, W = work of moving pins); \
         0 means the energy never rose above its start (backward Euler only dissipates). min det F over all points and steps (< 0: inverted \
         material). ok = finished or stopped with a named error, all values finite, no panic.\n\n\
         | group | case | ν | dt | m | K | status | steps | unconverged | finite | growth | min det F | s | ok |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for o in outcomes {
        let c = &o.case;
        let reduced_only = |v: usize| match c.solver {
            StressSolver::Reduced => v.to_string(),
            StressSolver::Fem => "—".into(),
        };
        let status = match &o.status {
            CaseStatus::Finished => "finished".to_string(),
            CaseStatus::Error(e) => format!("error: {}", e.replace('|', "/")),
            CaseStatus::Panicked(e) => format!("PANIC: {}", e.replace('|', "/")),
        };
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} | {} | {} | {}/{} | {} | {} | {:.1e} | {:.3} | {:.1} | {} |",
            c.group,
            c.name,
            c.poisson_ratio,
            c.time_step,
            reduced_only(c.modes),
            reduced_only(c.kernels),
            status,
            o.steps_run,
            c.steps,
            o.unconverged_steps,
            if o.all_finite { "yes" } else { "NO" },
            o.max_energy_growth,
            o.min_det_f,
            o.seconds,
            if o.acceptable() { "yes" } else { "NO" }
        );
    }
    md
}

/// Runs one case on the FEM reference (P2, 2 cells per metre): finiteness, Newton convergence
/// and min det F at every quadrature point; no energy balance.
fn run_fem_case(case: &StressCase) -> StressOutcome {
    use fem_ref::{ElementOrder, FemMesh, FemModel, FemParams, FemSimulator, MassKind, TetMesh};

    let mut outcome = StressOutcome {
        min_det_f: f64::INFINITY,
        ..StressOutcome::not_run(case)
    };
    let object = match case_object(case) {
        Ok(object) => object,
        Err(e) => {
            return StressOutcome {
                status: CaseStatus::Error(format!("scene: {e}")),
                ..outcome
            };
        }
    };
    let setup = || -> Result<FemSimulator<StableNeoHookean>, String> {
        if !matches!(
            case.scene,
            StressScene::BeamBend | StressScene::BeamTwist { .. }
        ) {
            return Err("the FEM stress cases are beam scenes".into());
        }
        let tets = TetMesh::cuboid(BEAM_MIN, BEAM_MAX, [10, 2, 2]).map_err(|e| e.to_string())?;
        let elements = tets.tets().len();
        let model = FemModel::new(
            FemMesh::new(tets, ElementOrder::Quadratic),
            &vec![material(beam_material().youngs_modulus, case.poisson_ratio); elements],
            StableNeoHookean,
            MassKind::Consistent,
        )
        .map_err(|e| e.to_string())?;
        let scene = object
            .scene
            .fem_scene(model.mesh().nodes(), 1e4)
            .map_err(|e| e.to_string())?;
        let params = FemParams {
            time_step: case.time_step,
            ..Default::default()
        };
        FemSimulator::new(model, scene, params).map_err(|e| e.to_string())
    };
    let mut sim = match setup() {
        Ok(sim) => sim,
        Err(e) => {
            outcome.status = CaseStatus::Error(format!("FEM setup: {e}"));
            return outcome;
        }
    };
    for step in 1..=case.steps {
        match sim.step() {
            Ok(report) => {
                outcome.steps_run = step;
                outcome.unconverged_steps += usize::from(!report.converged());
            }
            Err(e) => {
                outcome.status = CaseStatus::Error(format!("FEM step {step}: {e}"));
                break;
            }
        }
        let x: Vec<f64> = sim
            .positions()
            .iter()
            .flat_map(|p| [p.x, p.y, p.z])
            .collect();
        if !x.iter().all(|v| v.is_finite()) {
            outcome.all_finite = false;
            break;
        }
        for f in sim.model().deformation_gradients(&x) {
            outcome.min_det_f = outcome.min_det_f.min(f.determinant());
        }
    }
    outcome
}
