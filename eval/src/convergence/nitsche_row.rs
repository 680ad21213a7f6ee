//! The static Bend held by symmetric Nitsche ([`reduced_sim::NitscheInterface`]): the held
//! region left out of the body, the basis and pressure space built on the free part alone (its
//! Neumann modes), and the clamp's plane held weakly with β from the reduced trace bound.

use freeform::scene::{Motion, Region, SceneSpec};
use freeform::{PinHold, PressureSpace, PressureSpaceParams, RunError, Simulation};
use hyperelastic::{MaterialField, MaterialSample, StableNeoHookean, Tangent};
use nalgebra::Vector3;
use reduced_sim::{DeformationMap, NitscheInterface, NitscheParams, PinTarget};
use rkpm_core::IntegrationPoints;
use skin_eigen::{SkinningBasis, WeightInterface, build_basis_with_interface};

use crate::EvalError;
use crate::beam_protocol::reduced::beam_simulation_points;
use crate::beam_scenario::{
    BEAM_MAX, BEAM_MIN, BEAM_TIME_STEP, BeamTest, beam_basis_grid, beam_grid_spacing,
};
use crate::convergence::result::ConvergenceRow;
use crate::convergence::static_reference::{StaticReference, field_errors};
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

/// The Bend's free-part basis under `settings` (its kernels and modes): the basis grid's
/// points outside the clamp, with weights that vanish weakly on the clamp's plane
/// ([`build_basis_with_interface`], stabilization factor `factor`).
///
/// # Errors
/// [`EvalError::Sampling`] / [`EvalError::Basis`] when the grid or the basis cannot be made.
pub(crate) fn free_part_basis(
    settings: &ReducedSettings,
    factor: f64,
) -> Result<SkinningBasis, EvalError> {
    let (grid, lame) = beam_basis_grid(settings.basis_points)?;
    let scene = BeamTest::Bend.scene();
    let free = free_part(&grid, &scene)?;
    let material = lame[0];
    let lame = vec![material; free.len()];
    let spacing = beam_grid_spacing(settings.basis_points);
    let mut interface = WeightInterface {
        samples: Vec::new(),
        areas: Vec::new(),
        normals: Vec::new(),
        material,
        stabilization_factor: factor,
    };
    for constraint in &scene.constraints {
        let plane = interface_samples(&constraint.region, spacing)
            .ok_or_else(|| EvalError::NitscheRegion(format!("{constraint:?}")))?;
        interface.samples.extend(plane.samples);
        interface.areas.extend(plane.areas);
        interface.normals.extend(plane.normals);
    }
    let (basis, _, _) =
        build_basis_with_interface(&free, &lame, &settings.basis_params(), &interface)
            .map_err(EvalError::Basis)?;
    Ok(basis)
}

/// The pressure space of the free part (its Neumann modes and the affine functions).
///
/// # Errors
/// As [`free_part_basis`].
pub(crate) fn free_part_pressure_space(
    settings: &ReducedSettings,
    params: &PressureSpaceParams,
) -> Result<PressureSpace, EvalError> {
    let (grid, lame) = beam_basis_grid(settings.basis_points)?;
    let scene = BeamTest::Bend.scene();
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

/// Fills `row` with the static Bend of `scene` (the clamp a half-space) held by Nitsche with
/// stabilization factor `factor` on the free-part `basis` (and `pressure`, if projected).
/// `held_drift` is the interface's largest gap from its target (the held part itself is
/// prescribed); the best approximations are not computed (the free-part basis does not reach
/// the held part's nodes).
///
/// # Errors
/// [`EvalError`] for points, a model, an interface or a static solve that fails.
#[allow(clippy::too_many_arguments)]
pub(crate) fn nitsche_static_row(
    row: &mut ConvergenceRow,
    basis: &SkinningBasis,
    pressure: Option<&PressureSpace>,
    settings: &ReducedSettings,
    material: MaterialSample,
    scene: &SceneSpec,
    reference: &StaticReference,
    factor: f64,
    cache_dir: &std::path::Path,
) -> Result<(), EvalError> {
    let points = free_part(&beam_simulation_points(scene, settings)?, scene)?;
    let free = free_scene(scene);
    let field = MaterialField::Uniform(material);
    let simulation = Simulation::new(basis, &points, &field, StableNeoHookean, &free)
        .with_params(settings.simulation_params(BEAM_TIME_STEP))
        .with_quadrature(settings.quadrature)
        .with_cache_dir(Some(cache_dir))
        .with_pin_hold(PinHold::Penalty)
        .with_pressure(pressure);
    let (mut simulator, _) = freeform::prepare_simulator(&simulation, 1, &[])?;
    let len = simulator.model().deformation_map().layout().len();
    let rest_stiffness = simulator
        .model()
        .elastic_hessian(&vec![0.0; len], Tangent::Exact);
    let spacing = beam_grid_spacing(settings.simulation_points);
    let lame = material.lame_parameters().map_err(EvalError::Material)?;
    let mut gaps = Vec::new();
    for constraint in &scene.constraints {
        let unsupported = || EvalError::NitscheRegion(format!("{constraint:?}"));
        if constraint.motion != Motion::Rest {
            return Err(unsupported());
        }
        let plane = interface_samples(&constraint.region, spacing).ok_or_else(unsupported)?;
        let (interface, _) = NitscheInterface::new(
            basis,
            &plane.samples,
            &plane.areas,
            &plane.normals,
            StableNeoHookean,
            lame,
            PinTarget::Rest,
            rest_stiffness.as_ref(),
            &NitscheParams {
                stabilization_factor: factor,
            },
        )?;
        simulator.add_term(Box::new(interface));
        gaps.push(DeformationMap::new(basis, &plane.samples).map_err(EvalError::OutputMap)?);
    }
    let start = std::time::Instant::now();
    simulator
        .solve_static(0.0)
        .map_err(|e| EvalError::Run(RunError::Static(e)))?;
    let seconds = start.elapsed().as_secs_f64();
    let z = &simulator.state().z;
    let held = |x: &Vector3<f64>| scene.constraints.iter().any(|c| c.region.contains(x));
    let free_nodes: Vec<usize> = (0..reference.nodes.len())
        .filter(|&i| !held(&reference.nodes[i]))
        .collect();
    let at: Vec<Vector3<f64>> = free_nodes.iter().map(|&i| reference.nodes[i]).collect();
    let map = DeformationMap::new(basis, &at).map_err(EvalError::OutputMap)?;
    let mut ours = vec![Vector3::zeros(); reference.nodes.len()];
    for (&i, u) in free_nodes.iter().zip(map.displacements(z)) {
        ours[i] = u;
    }
    let (mse, relative) = field_errors(&ours, &reference.displacements);
    row.mse = mse;
    row.relative_error = relative;
    let tip = reference.tip;
    let exact_tip = reference.displacements[tip];
    row.tip_error = (ours[tip] - exact_tip).norm() / exact_tip.norm();
    row.tip_ratio = ours[tip].y / exact_tip.y - 1.0;
    row.held_drift = gaps
        .iter()
        .flat_map(|map| map.displacements(z))
        .map(|u| u.norm())
        .fold(0.0, f64::max);
    row.ms_per_step = 1e3 * seconds;
    Ok(())
}
