//! One reduced simulation of any skinning field and any material on any scene (Eqs. 1-2): the
//! loop every caller shares, from a user's program to the paper's tables. It builds the model
//! and the scene, steps, and hands every frame to an observer (record positions, write files,
//! advance a progress bar) while it keeps timings and convergence counts.

use std::path::Path;
use std::time::Instant;

use hyperelastic::{HyperelasticMaterial, MaterialField};
use optimize::NewtonReport;
use reduced_sim::quadrature::automatic_quadrature::cubature_if_it_pays;
use reduced_sim::quadrature::cubature::CubatureCacheFile;
use reduced_sim::{
    CubatureError, CubatureParams, PinnedRegion, PlannedRun, QuadratureChoice, QuadratureReport,
    QuadratureRule, ReducedModel, ReducedModelError, SceneError, SimulationParams, Simulator,
    SkinningField, StepError,
};
use rkpm_core::IntegrationPoints;
use thiserror::Error;

use crate::pin_hold::PinHold;
use crate::placement::Placement;
use crate::pressure_space::PressureSpace;
use crate::scene::{SceneSpec, SceneSpecError};
use crate::step_loop::{StepStatistics, run_steps};

/// Everything one reduced run needs: made by [`Simulation::new`] with the library's defaults
/// and changed by its `with_…` methods (or by assigning a field), so that a new option does
/// not break a caller: `Simulation::new(&basis, &points, &material, StableNeoHookean,
/// &scene).with_quadrature(QuadratureRule::PAPER)` (the crate docs run one end to end).
#[non_exhaustive]
pub struct Simulation<'a, B: SkinningField + ?Sized, M> {
    /// The skinning field (an RKPM eigenbasis, or a baseline's network).
    pub field: &'a B,
    /// Integration points (rest positions in m, volumes in m³).
    pub points: &'a IntegrationPoints,
    /// E, ν, ρ over the object, sampled at the integration points.
    pub material: &'a MaterialField,
    /// The energy density Ψ(F) (e.g. [`hyperelastic::StableNeoHookean`]).
    pub material_model: M,
    /// What acts on the object.
    pub scene: &'a SceneSpec,
    /// Time step, Newton, tangent and penalty options.
    pub params: SimulationParams,
    /// Where the elastic energy is integrated ([`QuadratureRule::Full`], every point, is the
    /// paper's setting; a cubature makes the step cost independent of the point count).
    pub quadrature: QuadratureRule,
    /// Where an optimized cubature is cached by content (`<dir>/cubature/`), or `None` to
    /// optimize it every run.
    pub cache_dir: Option<&'a Path>,
    /// How the constrained regions are held ([`PinHold::Penalty`] by default; exact holding
    /// needs `field` built for [`PinHold::basis_regions`]).
    pub pin_hold: PinHold,
    /// The pressure space of a locking-free volumetric term
    /// ([`reduced_sim::ReducedModel::with_projected_dilatation`]); `None` (the paper's setting)
    /// integrates the material's own volumetric term at every point.
    pub pressure: Option<&'a PressureSpace>,
    /// Where the object starts in the world and how fast ([`Placement`]: its constraints'
    /// targets move with it); `None` (the default) starts it at rest where it was made.
    pub placement: Option<Placement>,
}

impl<'a, B: SkinningField + ?Sized, M> Simulation<'a, B, M> {
    /// A run of `field` on `points` with `material` and `material_model` in `scene`, with the
    /// defaults: [`SimulationParams::default`] (h = 0.01 s), [`QuadratureRule::default`] (an
    /// optimized cubature), no cache, pins by the penalty ([`PinHold::Penalty`], the hold of a
    /// basis built without regions: give [`Simulation::with_pin_hold`] the hold `field` was
    /// built for) and the material's own volumetric term at every point (no pressure space).
    pub fn new(
        field: &'a B,
        points: &'a IntegrationPoints,
        material: &'a MaterialField,
        material_model: M,
        scene: &'a SceneSpec,
    ) -> Self {
        Simulation {
            field,
            points,
            material,
            material_model,
            scene,
            params: SimulationParams::default(),
            quadrature: QuadratureRule::default(),
            cache_dir: None,
            pin_hold: PinHold::Penalty,
            pressure: None,
            placement: None,
        }
    }

    /// With time step, Newton, tangent and penalty options `params`.
    pub fn with_params(self, params: SimulationParams) -> Self {
        Simulation { params, ..self }
    }

    /// With the elastic energy integrated by `quadrature`.
    pub fn with_quadrature(self, quadrature: QuadratureRule) -> Self {
        Simulation { quadrature, ..self }
    }

    /// With optimized cubatures cached under `cache_dir` (`None`: optimized every run).
    pub fn with_cache_dir(self, cache_dir: Option<&'a Path>) -> Self {
        Simulation { cache_dir, ..self }
    }

    /// With the constrained regions held by `pin_hold`.
    pub fn with_pin_hold(self, pin_hold: PinHold) -> Self {
        Simulation { pin_hold, ..self }
    }

    /// With the locking-free volumetric term on `pressure` (`None`: the material's own).
    pub fn with_pressure(self, pressure: Option<&'a PressureSpace>) -> Self {
        Simulation { pressure, ..self }
    }

    /// Starting from `placement` (`None`: at rest where it was made).
    pub fn with_placement(self, placement: Option<Placement>) -> Self {
        Simulation { placement, ..self }
    }
}

/// The state after frame `index`, handed to the observer of [`run`].
pub struct Frame<'a, M: HyperelasticMaterial> {
    /// 0 for the rest state, then the step number.
    pub index: usize,
    /// Simulated time t = index · h (s).
    pub time: f64,
    /// The simulator, to read the reduced coordinates z (`state().z`, length 12m) and
    /// anything else (pin deviation, energies).
    pub simulator: &'a Simulator<M>,
    /// The Newton solve of this step (`None` for frame 0).
    pub step: Option<&'a NewtonReport>,
}

/// Timings and convergence of one run.
#[derive(Clone, Debug, PartialEq)]
pub struct RunReport {
    /// Steps taken.
    pub steps: usize,
    /// Wall time per step, Newton solve only (ms).
    pub ms_per_step: f64,
    /// Hessian/gradient assembly per step (ms).
    pub ms_assembly_per_step: f64,
    /// Factorization and back-substitution per step (ms).
    pub ms_solve_per_step: f64,
    /// Line search per step (ms).
    pub ms_line_search_per_step: f64,
    /// Mean Newton iterations per step.
    pub iterations_per_step: f64,
    /// Mean Hessians assembled and factored per step (below 1 with Hessian reuse).
    pub hessians_per_step: f64,
    /// Steps whose Newton solve stopped unconverged (the run goes on; the caller decides).
    pub unconverged_steps: usize,
    /// Largest distance of a constrained integration point from its target over the run (m).
    pub max_pin_deviation: f64,
    /// The same for the exactly held points alone ([`PinHold::Exact`]'s inset regions; 0
    /// without them).
    pub max_held_deviation: f64,
    /// The deepest penetration of an integration point into the floor or a collider over the
    /// run (m; 0 without contact).
    pub max_penetration: f64,
    /// The mechanical energy at the start and at the end (J,
    /// [`reduced_sim::Simulator::mechanical_energy`]).
    pub energy: [f64; 2],
    /// The largest rise of that energy over one step (J; 0 when it only fell): backward Euler
    /// and friction only take energy out, moving pins and colliders may put it in.
    pub max_energy_rise: f64,
    /// Model and scene setup, quadrature included (s).
    pub setup_seconds: f64,
    /// The elastic quadrature the run used (kind, points, cubature report).
    pub quadrature: QuadratureReport,
    /// Integration points simulated.
    pub simulation_points: usize,
    /// Integration points in each region of the reduced scene: those kept by the penalty, then
    /// the exactly held ones.
    pub region_points: Vec<usize>,
}

/// A run could not start or stopped.
#[derive(Debug, Error)]
pub enum RunError {
    /// The reduced model cannot be built (invalid material, singular mass matrix, ...).
    #[error("building the reduced model failed")]
    Model(#[source] ReducedModelError),
    /// The elastic quadrature cannot be built (a subset larger than the model, a failed
    /// cubature optimization).
    #[error("building the elastic quadrature failed")]
    Quadrature(#[source] CubatureError),
    /// The scene does not fit these points (e.g. a region that holds no integration point).
    #[error(transparent)]
    Scene(#[from] SceneSpecError),
    /// The simulator refused the scene (e.g. a penalty that is not positive).
    #[error("setting up the simulator failed")]
    Simulator(#[source] SceneError),
    /// The placement's state does not fit the simulator (a non-finite pose or velocity).
    #[error("placing the object failed")]
    Placement(#[source] reduced_sim::StateError),
    /// A step failed (non-finite energy, a Hessian that is not positive definite, ...).
    #[error("step {step} failed")]
    Step {
        /// The step (1-based).
        step: usize,
        /// Why.
        #[source]
        source: StepError,
    },
    /// The pressure space could not be evaluated at the integration points.
    #[error("evaluating the pressure space")]
    PressureSpace(#[source] rkpm_core::ShapeFunctionError),
    /// The projected volumetric term could not be set up.
    #[error("setting up the projected volumetric term")]
    Dilatation(#[source] reduced_sim::ProjectedDilatationError),
    /// The static solve of [`static_equilibrium`] failed.
    #[error("the static solve failed")]
    Static(#[source] StepError),
    /// The observer stopped the run (e.g. a frame could not be written).
    #[error("frame {frame}: the observer stopped the run")]
    Observer {
        /// The frame it was handed.
        frame: usize,
        /// Why.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
}

/// The reduced model of `simulation` on every point, with its projected volumetric term when it
/// has a pressure space (the quadrature not applied yet).
fn reduced_model<B, M>(simulation: &Simulation<'_, B, M>) -> Result<ReducedModel<M>, RunError>
where
    B: SkinningField + ?Sized,
    M: HyperelasticMaterial + Clone,
{
    let points = simulation.points;
    let model = ReducedModel::new(
        simulation.field,
        points,
        &simulation.material.sample(points.positions()),
        simulation.material_model.clone(),
    )
    .map_err(RunError::Model)?;
    match simulation.pressure {
        None => Ok(model),
        Some(space) => model
            .with_projected_dilatation(
                space
                    .values(points.positions())
                    .map_err(RunError::PressureSpace)?,
                space.dilatation_params(),
            )
            .map_err(RunError::Dilatation),
    }
}

/// Steps an automatic quadrature runs on every point before it decides, for a run of `steps`
/// steps: a twentieth of them, at least 3 (the first is not counted in the prediction).
fn warmup_steps(steps: usize) -> usize {
    (steps / 20).max(3)
}

/// A reduced simulator at rest and what the run reports about it.
struct Prepared<M: HyperelasticMaterial> {
    simulator: Simulator<M>,
    /// The quadrature it integrates with.
    quadrature: QuadratureReport,
    /// The points each constrained region selected (penalized regions, then held ones).
    region_points: Vec<usize>,
    /// A [`QuadratureRule::Automatic`] choice left to be made after the warm-up steps.
    pending: Option<PendingCubature>,
}

/// The automatic quadrature's choice, left for after the warm-up steps: its options and the
/// cache file it looked in (to save a trained cubature or note a training over budget there).
struct PendingCubature {
    params: CubatureParams,
    cache: Option<CubatureCacheFile>,
}

/// The reduced simulator of `simulation` at its start for the run `planned`; an automatic
/// quadrature with no cached cubature is left to be chosen after the warm-up steps when
/// `online`.
fn simulator<B, M>(
    simulation: &Simulation<'_, B, M>,
    planned: PlannedRun,
    online: bool,
    extra_pins: &[PinnedRegion],
) -> Result<Prepared<M>, RunError>
where
    B: SkinningField + ?Sized,
    M: HyperelasticMaterial + Clone,
{
    let planned_steps = planned.steps;
    let model = reduced_model(simulation)?;
    let cache_dir = simulation.cache_dir;
    let (model, quadrature, pending) = match simulation.quadrature {
        QuadratureRule::Automatic(params)
            if online && planned_steps > warmup_steps(planned_steps) =>
        {
            let cache = cache_dir.map(|dir| CubatureCacheFile::new(&model, &params, dir));
            match cache.as_ref().and_then(CubatureCacheFile::load) {
                Some((cubature, report)) => {
                    let report = QuadratureReport {
                        kind: "cubature".to_string(),
                        points: cubature.len(),
                        cubature: Some(report),
                        choice: Some(QuadratureChoice::cached(planned_steps, 0.0)),
                    };
                    let model = model
                        .with_elastic_quadrature(cubature)
                        .map_err(|e| RunError::Quadrature(e.into()))?;
                    (model, report, None)
                }
                None => {
                    let report = QuadratureReport {
                        kind: QuadratureRule::Full.name().to_string(),
                        points: model.elastic_point_count(),
                        cubature: None,
                        choice: None,
                    };
                    (model, report, Some(PendingCubature { params, cache }))
                }
            }
        }
        rule => {
            let (model, report) = rule
                .apply_for_run(model, cache_dir, Some(&planned))
                .map_err(RunError::Quadrature)?;
            (model, report, None)
        }
    };
    let mut scene = simulation
        .pin_hold
        .reduced_scene(simulation.scene, model.rest_positions())?;
    scene.pins.extend_from_slice(extra_pins);
    let region_points = scene
        .pins
        .iter()
        .chain(&scene.held)
        .map(|p| p.points.len())
        .collect();
    let placement = simulation.placement;
    if let Some(placement) = &placement {
        scene = placement.place(scene);
    }
    let layout = model.deformation_map().layout();
    let mut simulator =
        Simulator::new(model, &scene, simulation.params).map_err(RunError::Simulator)?;
    if let Some(placement) = placement {
        simulator
            .set_state(placement.state(&layout))
            .map_err(RunError::Placement)?;
    }
    Ok(Prepared {
        simulator,
        quadrature,
        region_points,
        pending,
    })
}

/// The reduced simulator of `simulation` at rest, for a caller that steps it itself (the
/// Python bindings, an interactive tool): what [`run`] steps, with the quadrature chosen up
/// front for a run of `planned_steps` steps ([`QuadratureRule::apply_for_run`]), and the report
/// of that quadrature. `extra_pins` are penalized like the scene's constraints and follow them
/// (indices of `simulation.points`, e.g. from a mask a caller computed).
///
/// # Errors
/// [`RunError`] for a model, pressure space, quadrature or scene that cannot be built (an
/// extra pin's index out of range is a [`RunError::Simulator`]).
pub fn prepare_simulator<B, M>(
    simulation: &Simulation<'_, B, M>,
    planned_steps: usize,
    extra_pins: &[PinnedRegion],
) -> Result<(Simulator<M>, QuadratureReport), RunError>
where
    B: SkinningField + ?Sized,
    M: HyperelasticMaterial + Clone,
{
    prepare_simulator_for(
        simulation,
        PlannedRun::single_body(planned_steps),
        extra_pins,
    )
}

/// [`prepare_simulator`] for the run `planned` (e.g. [`PlannedRun::multibody`] for one of
/// several objects in contact, whose automatic quadrature weighs their costlier steps).
///
/// # Errors
/// As [`prepare_simulator`].
pub fn prepare_simulator_for<B, M>(
    simulation: &Simulation<'_, B, M>,
    planned: PlannedRun,
    extra_pins: &[PinnedRegion],
) -> Result<(Simulator<M>, QuadratureReport), RunError>
where
    B: SkinningField + ?Sized,
    M: HyperelasticMaterial + Clone,
{
    let prepared = simulator(simulation, planned, false, extra_pins)?;
    Ok((prepared.simulator, prepared.quadrature))
}

/// The static equilibrium of [`static_equilibrium`].
#[derive(Clone, Debug)]
pub struct StaticEquilibrium {
    /// Reduced coordinates z at equilibrium (12 per handle).
    pub z: Vec<f64>,
    /// The Newton solve.
    pub newton: NewtonReport,
    /// Wall time of the solve alone (s).
    pub solve_seconds: f64,
    /// Largest penalized point's distance from its target (m), if any region is penalized.
    pub max_pin_deviation: Option<f64>,
    /// Largest exactly held point's distance from its target (m), if any region is held.
    pub max_held_deviation: Option<f64>,
}

/// The static equilibrium of `simulation` under its loads and the constraint targets at time
/// `time` (s): the potential without inertia minimized from rest
/// ([`reduced_sim::Simulator::solve_static`]).
///
/// # Errors
/// [`RunError`] for a model, quadrature or scene that cannot be built, and
/// [`RunError::Static`] for a solve that fails.
pub fn static_equilibrium<B, M>(
    simulation: &Simulation<'_, B, M>,
    time: f64,
) -> Result<StaticEquilibrium, RunError>
where
    B: SkinningField + ?Sized,
    M: HyperelasticMaterial + Clone,
{
    // A static solve costs about what one step does.
    let mut sim = simulator(simulation, PlannedRun::single_body(1), false, &[])?.simulator;
    let start = Instant::now();
    let newton = sim.solve_static(time).map_err(RunError::Static)?;
    Ok(StaticEquilibrium {
        z: sim.state().z.clone(),
        newton,
        solve_seconds: start.elapsed().as_secs_f64(),
        max_pin_deviation: sim.max_pin_deviation(),
        max_held_deviation: sim.max_held_deviation(),
    })
}

/// The discrete inf-sup constants of `simulation`'s pressure space truncated to its first
/// `neumann_modes[k]` Neumann modes ([`reduced_sim::ReducedModel::inf_sup_constants`]), on the
/// coordinates Newton solves for (all but the held regions' handles), every point integrated.
/// `None` without a pressure space, or when nothing is projected (the material's modulus all
/// kept pointwise, [`crate::PressureSpaceParams::retained_shear_multiple`]).
///
/// # Errors
/// [`RunError`] for a model or pressure space that cannot be built.
pub fn pressure_inf_sup<B, M>(
    simulation: &Simulation<'_, B, M>,
    neumann_modes: &[usize],
) -> Result<Option<Vec<f64>>, RunError>
where
    B: SkinningField + ?Sized,
    M: HyperelasticMaterial + Clone,
{
    let Some(space) = simulation.pressure else {
        return Ok(None);
    };
    let model = reduced_model(simulation)?;
    let layout = model.deformation_map().layout();
    let held = match simulation.pin_hold {
        PinHold::Penalty => 0,
        PinHold::Exact { .. } | PinHold::Weighted { .. } => simulation.scene.constraints.len(),
    };
    let n4 = layout.block_len();
    let free: Vec<usize> = (0..layout.len()).filter(|i| (i % n4) / 4 >= held).collect();
    let base = space.functions() - space.neumann_modes();
    let sizes: Vec<usize> = neumann_modes
        .iter()
        .map(|&n| base + n.min(space.neumann_modes()))
        .collect();
    Ok(model.inf_sup_constants(&free, &sizes))
}

/// What [`run`] hands each frame to: return `Err` to stop the run.
pub type ObserverResult = Result<(), Box<dyn std::error::Error + Send + Sync>>;

/// Runs `steps` backward-Euler steps of `simulation`, calling `observe` with frame 0 (rest)
/// and after every step. Only the steps are timed, not the observer.
///
/// # Errors
/// [`RunError`] naming the stage; frames handed to the observer before the error stay its own.
pub fn run<B, M>(
    simulation: &Simulation<'_, B, M>,
    steps: usize,
    mut observe: impl FnMut(&Frame<'_, M>) -> ObserverResult,
) -> Result<RunReport, RunError>
where
    B: SkinningField + ?Sized,
    M: HyperelasticMaterial + Clone,
{
    let start = Instant::now();
    let points = simulation.points;
    let Prepared {
        simulator: mut sim,
        mut quadrature,
        region_points,
        mut pending,
    } = simulator(simulation, PlannedRun::single_body(steps), true, &[])?;
    let mut setup_seconds = start.elapsed().as_secs_f64();
    let warmup = warmup_steps(steps);
    let mut first_step_elastic = 0.0;

    let mut notify = |sim: &Simulator<M>, index: usize, step: Option<&NewtonReport>| {
        observe(&Frame {
            index,
            time: sim.state().time,
            simulator: sim,
            step,
        })
        .map_err(|source| RunError::Observer {
            frame: index,
            source,
        })
    };
    notify(&sim, 0, None)?;
    let mut statistics = StepStatistics::new(&sim);
    run_steps(
        &mut sim,
        steps,
        &mut statistics,
        |step, source| RunError::Step { step, source },
        |sim, step, report, statistics| {
            notify(sim, step, Some(report))?;
            if step == 1 {
                first_step_elastic = statistics.elastic_seconds();
            }
            if step == warmup
                && let Some(PendingCubature { params, cache }) = pending.take()
            {
                // The automatic quadrature: the rest of the run on every point, predicted from
                // the elastic part (assembly and line search) of the warm-up steps after the
                // first, which always assembles a Hessian that later steps may carry.
                let choosing = Instant::now();
                let rest = steps - warmup;
                let per_step =
                    (statistics.elastic_seconds() - first_step_elastic) / (warmup - 1) as f64;
                let predicted = per_step * rest as f64;
                let outcome =
                    cubature_if_it_pays(sim.model(), &params, cache.as_ref(), rest, predicted)
                        .map_err(RunError::Quadrature)?;
                if let Some((cubature, report)) = outcome.cubature {
                    quadrature.kind = "cubature".to_string();
                    quadrature.points = cubature.len();
                    quadrature.cubature = Some(report);
                    sim.set_elastic_quadrature(cubature)
                        .map_err(|e| RunError::Quadrature(e.into()))?;
                }
                quadrature.choice = Some(outcome.choice);
                setup_seconds += choosing.elapsed().as_secs_f64();
            }
            Ok(())
        },
    )?;
    let s = &statistics;
    Ok(RunReport {
        steps,
        ms_per_step: 1e3 * s.per_step(s.stepping),
        ms_assembly_per_step: 1e3 * s.per_step(s.split[0]),
        ms_solve_per_step: 1e3 * s.per_step(s.split[1]),
        ms_line_search_per_step: 1e3 * s.per_step(s.split[2]),
        iterations_per_step: s.per_step(s.iterations as f64),
        hessians_per_step: s.per_step(s.hessians as f64),
        unconverged_steps: s.unconverged,
        max_pin_deviation: s.max_pin_deviation,
        max_held_deviation: s.max_held_deviation,
        max_penetration: s.max_penetration,
        energy: s.energy,
        max_energy_rise: s.max_energy_rise,
        setup_seconds,
        quadrature,
        simulation_points: points.len(),
        region_points,
    })
}
