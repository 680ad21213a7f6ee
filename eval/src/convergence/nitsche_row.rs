//! The beam held by symmetric Nitsche ([`reduced_sim::NitscheInterface`]): the held regions
//! left out of the body, the basis (weights held weakly on the regions' planes) and the
//! pressure space (Neumann modes) built on the free part alone, and each plane held weakly at
//! its region's target with β from the reduced trace bound, its traction the body's projected
//! stress when the term is projected; the static Bend and the dynamic tests.

use freeform::scene::{Constraint, Region, SceneSpec};
use freeform::{PinHold, PressureSpace, PressureSpaceParams, RunError, Simulation};
use hyperelastic::{MaterialField, MaterialSample, StableNeoHookean};
use nalgebra::Vector3;
use reduced_sim::{DeformationMap, NitscheInterface, NitscheParams, PinTarget, Simulator};
use rkpm_core::IntegrationPoints;
use skin_eigen::{SkinningBasis, WeightInterface, build_basis_with_interfaces};

use crate::EvalError;
use crate::beam_protocol::reduced::beam_simulation_points;
use crate::beam_scenario::{
    BEAM_MAX, BEAM_MIN, BEAM_TIME_STEP, BeamTest, beam_basis_grid, beam_grid_spacing,
};
use crate::convergence::result::ConvergenceRow;
use crate::convergence::static_reference::StaticReference;
use crate::reduced_settings::ReducedSettings;

/// `scene` without its constraints: the free part's own scene (gravity and the rest kept).
fn free_scene(scene: &SceneSpec) -> SceneSpec {
    SceneSpec {
        constraints: Vec::new(),
        ..scene.clone()
    }
}

/// The points of `points` outside every constraint region of `scene`.
fn free_part(
    points: &IntegrationPoints,
    scene: &SceneSpec,
) -> Result<IntegrationPoints, EvalError> {
    let (positions, volumes): (Vec<Vector3<f64>>, Vec<f64>) = points
        .positions()
        .iter()
        .zip(points.volumes())
        .filter(|(x, _)| !scene.constraints.iter().any(|c| c.region.contains(x)))
        .map(|(x, v)| (*x, *v))
        .unzip();
    IntegrationPoints::new(positions, volumes).map_err(|source| EvalError::Sampling {
        what: "free-part points",
        source,
    })
}

/// `test`'s free-part basis under `settings` (its kernels and modes): the basis grid's points
/// outside its constraints, with weights that vanish weakly on their planes and a region
/// handle for every plane but the first ([`build_basis_with_interfaces`], stabilization factor
/// `factor`).
///
/// # Errors
/// [`EvalError::Sampling`] / [`EvalError::Basis`] when the grid or the basis cannot be made.
pub(crate) fn free_part_basis(
    test: BeamTest,
    settings: &ReducedSettings,
    factor: f64,
) -> Result<SkinningBasis, EvalError> {
    let (grid, lame) = beam_basis_grid(settings.basis_points)?;
    let scene = test.scene();
    let free = free_part(&grid, &scene)?;
    let material = lame[0];
    let lame = vec![material; free.len()];
    let spacing = beam_grid_spacing(settings.basis_points);
    let interfaces = scene
        .constraints
        .iter()
        .map(|constraint| {
            let plane = interface_samples(&constraint.region, spacing)
                .ok_or_else(|| EvalError::NitscheRegion(format!("{constraint:?}")))?;
            Ok(WeightInterface {
                samples: plane.samples,
                areas: plane.areas,
                normals: plane.normals,
                material,
                stabilization_factor: factor,
            })
        })
        .collect::<Result<Vec<_>, EvalError>>()?;
    let (basis, _, _) =
        build_basis_with_interfaces(&free, &lame, &settings.basis_params(), &interfaces)
            .map_err(EvalError::Basis)?;
    Ok(basis)
}

/// The pressure space of `test`'s free part (its Neumann modes, and the affine functions when
/// `params` asks).
///
/// # Errors
/// As [`free_part_basis`].
pub(crate) fn free_part_pressure_space(
    test: BeamTest,
    settings: &ReducedSettings,
    params: &PressureSpaceParams,
) -> Result<PressureSpace, EvalError> {
    let (grid, lame) = beam_basis_grid(settings.basis_points)?;
    let scene = test.scene();
    let free = free_part(&grid, &scene)?;
    let lame = vec![lame[0]; free.len()];
    PressureSpace::build(
        &free_scene(&scene),
        PinHold::Penalty,
        &free,
        &lame,
        settings.basis_params(),
        params,
        None,
    )
    .map_err(EvalError::Basis)
}

/// Samples of an interface: rest positions (m), areas (m²) and the free part's outward unit
/// normals.
struct InterfaceSamples {
    samples: Vec<Vector3<f64>>,
    areas: Vec<f64>,
    normals: Vec<Vector3<f64>>,
}

/// Midpoint samples of the beam's cross-section on a half-space region's plane, `spacing`
/// apart (m); `None` for other regions.
fn interface_samples(region: &Region, spacing: f64) -> Option<InterfaceSamples> {
    let (axis, value, sign) = match *region {
        Region::Below { axis, value } => (axis, value, -1.0),
        Region::Above { axis, value } => (axis, value, 1.0),
        Region::Ball { .. } => return None,
    };
    let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
    let extent = BEAM_MAX - BEAM_MIN;
    let (na, nb) = (
        (extent[a] / spacing).round().max(1.0) as usize,
        (extent[b] / spacing).round().max(1.0) as usize,
    );
    let (ha, hb) = (extent[a] / na as f64, extent[b] / nb as f64);
    let samples: Vec<Vector3<f64>> = (0..na * nb)
        .map(|k| {
            let mut x = Vector3::zeros();
            x[axis] = value;
            x[a] = BEAM_MIN[a] + ((k % na) as f64 + 0.5) * ha;
            x[b] = BEAM_MIN[b] + ((k / na) as f64 + 0.5) * hb;
            x
        })
        .collect();
    let mut normal = Vector3::zeros();
    normal[axis] = sign;
    let count = samples.len();
    Some(InterfaceSamples {
        samples,
        areas: vec![ha * hb; count],
        normals: vec![normal; count],
    })
}

/// What a Nitsche-held beam runs with: the free-part basis and pressure space, the settings
/// (points, quadrature, Newton), the material and s of `β = 2sC`.
pub(crate) struct NitscheBeam<'a> {
    pub(crate) basis: &'a SkinningBasis,
    pub(crate) pressure: Option<&'a PressureSpace>,
    pub(crate) settings: &'a ReducedSettings,
    pub(crate) material: MaterialSample,
    pub(crate) factor: f64,
    pub(crate) cache_dir: &'a std::path::Path,
}

/// One constraint's interface: its region and motion, and the basis at its samples.
struct HeldInterface {
    constraint: Constraint,
    samples: Vec<Vector3<f64>>,
    map: DeformationMap,
}

impl HeldInterface {
    /// The samples' largest distance from their targets at `z` and time `t` (m).
    fn gap(&self, z: &[f64], t: f64) -> f64 {
        self.map
            .positions(z)
            .iter()
            .zip(&self.samples)
            .map(|(x, x0)| (x - self.constraint.motion.at(x0, t)).norm())
            .fold(0.0, f64::max)
    }
}

impl NitscheBeam<'_> {
    /// The simulator of `scene`'s free part for a run of `steps` steps, with one Nitsche
    /// interface per constraint (half-spaces only).
    fn simulator(
        &self,
        scene: &SceneSpec,
        steps: usize,
    ) -> Result<(Simulator<StableNeoHookean>, Vec<HeldInterface>), EvalError> {
        let settings = self.settings;
        let points = free_part(&beam_simulation_points(scene, settings)?, scene)?;
        let free = free_scene(scene);
        let field = MaterialField::Uniform(self.material);
        let simulation = Simulation::new(self.basis, &points, &field, StableNeoHookean, &free)
            .with_params(settings.simulation_params(BEAM_TIME_STEP))
            .with_quadrature(settings.quadrature)
            .with_cache_dir(Some(self.cache_dir))
            .with_pin_hold(PinHold::Penalty)
            .with_pressure(self.pressure);
        let (mut simulator, _) = freeform::prepare_simulator(&simulation, steps, &[])?;
        let spacing = beam_grid_spacing(settings.simulation_points);
        let lame = self
            .material
            .lame_parameters()
            .map_err(EvalError::Material)?;
        let mut interfaces = Vec::new();
        for constraint in &scene.constraints {
            let plane = interface_samples(&constraint.region, spacing)
                .ok_or_else(|| EvalError::NitscheRegion(format!("{constraint:?}")))?;
            let target = constraint
                .motion
                .target_function()
                .map_or(PinTarget::Rest, PinTarget::Moving);
            let pressure_values = self
                .pressure
                .map(|space| space.values(&plane.samples))
                .transpose()
                .map_err(|e| EvalError::Basis(e.into()))?;
            let (interface, _) = NitscheInterface::on_model(
                self.basis,
                simulator.model(),
                &plane.samples,
                &plane.areas,
                &plane.normals,
                lame,
                target,
                pressure_values.as_ref(),
                &NitscheParams {
                    stabilization_factor: self.factor,
                },
            )?;
            simulator.add_term(Box::new(interface));
            interfaces.push(HeldInterface {
                constraint: constraint.clone(),
                map: DeformationMap::new(self.basis, &plane.samples)
                    .map_err(EvalError::OutputMap)?,
                samples: plane.samples,
            });
        }
        Ok((simulator, interfaces))
    }
}

/// The positions at time `t` of `points` (rest, m): a held point at its constraint's target,
/// a free one where `map` (the free points' basis) puts it at `z`.
struct PointPositions {
    /// Per point, the constraint holding it (index into `scene.constraints`), if any.
    held: Vec<Option<usize>>,
    /// The basis at the free points, in order.
    map: DeformationMap,
}

impl PointPositions {
    fn new(
        basis: &SkinningBasis,
        scene: &SceneSpec,
        points: &[Vector3<f64>],
    ) -> Result<Self, EvalError> {
        let held: Vec<Option<usize>> = points
            .iter()
            .map(|x| scene.constraints.iter().position(|c| c.region.contains(x)))
            .collect();
        let free: Vec<Vector3<f64>> = points
            .iter()
            .zip(&held)
            .filter(|(_, h)| h.is_none())
            .map(|(x, _)| *x)
            .collect();
        let map = DeformationMap::new(basis, &free).map_err(EvalError::OutputMap)?;
        Ok(PointPositions { held, map })
    }

    fn at(&self, scene: &SceneSpec, rest: &[Vector3<f64>], z: &[f64], t: f64) -> Vec<Vector3<f64>> {
        let mut free = self.map.positions(z).into_iter();
        rest.iter()
            .zip(&self.held)
            .map(|(x, held)| match held {
                Some(c) => scene.constraints[*c].motion.at(x, t),
                None => free.next().unwrap_or(*x),
            })
            .collect()
    }
}

/// Fills `row` with the static Bend of `scene` (its clamp a half-space at rest) held by
/// Nitsche. `held_drift` is the interface's largest gap from its target (the held part itself
/// is prescribed); the best approximations are not computed (the free-part basis does not
/// reach the held part's nodes).
///
/// # Errors
/// [`EvalError`] for points, a model, an interface or a static solve that fails.
pub(crate) fn nitsche_static_row(
    row: &mut ConvergenceRow,
    beam: &NitscheBeam<'_>,
    scene: &SceneSpec,
    reference: &StaticReference,
) -> Result<(), EvalError> {
    let (mut simulator, interfaces) = beam.simulator(scene, 1)?;
    let start = std::time::Instant::now();
    simulator
        .solve_static(0.0)
        .map_err(|e| EvalError::Run(RunError::Static(e)))?;
    let seconds = start.elapsed().as_secs_f64();
    let z = &simulator.state().z;
    let positions = PointPositions::new(beam.basis, scene, &reference.nodes)?;
    let ours: Vec<Vector3<f64>> = positions
        .at(scene, &reference.nodes, z, 0.0)
        .iter()
        .zip(&reference.nodes)
        .map(|(x, x0)| x - x0)
        .collect();
    row.score_static(&ours, reference);
    row.held_drift = interfaces.iter().map(|i| i.gap(z, 0.0)).fold(0.0, f64::max);
    row.ms_per_step = 1e3 * seconds;
    Ok(())
}

/// Fills `row` with `test` (its constraints half-spaces) held by Nitsche, `steps` steps scored
/// against the FEM's `reference` frames at its `vertices` (frame 0 the rest state).
/// `held_drift` is the interfaces' largest gap from their targets over the run.
///
/// # Errors
/// [`EvalError`] for points, a model, an interface or a step that fails.
pub(crate) fn nitsche_dynamic_row(
    row: &mut ConvergenceRow,
    beam: &NitscheBeam<'_>,
    test: BeamTest,
    vertices: &[Vector3<f64>],
    reference: &[Vec<Vector3<f64>>],
    steps: usize,
) -> Result<(), EvalError> {
    let scene = test.scene();
    let (mut simulator, interfaces) = beam.simulator(&scene, steps)?;
    let positions = PointPositions::new(beam.basis, &scene, vertices)?;
    let mut frames = vec![vertices.to_vec()];
    let mut gap: f64 = 0.0;
    let mut stepping = 0.0;
    for step in 1..=steps {
        let start = std::time::Instant::now();
        simulator
            .step()
            .map_err(|source| EvalError::Run(RunError::Step { step, source }))?;
        stepping += start.elapsed().as_secs_f64();
        let state = simulator.state();
        frames.push(positions.at(&scene, vertices, &state.z, state.time));
        for interface in &interfaces {
            gap = gap.max(interface.gap(&state.z, state.time));
        }
    }
    row.score_frames(&frames, reference, vertices)?;
    row.held_drift = gap;
    row.ms_per_step = 1e3 * stepping / steps.max(1) as f64;
    Ok(())
}
