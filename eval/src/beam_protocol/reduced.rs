//! FreeForm on the beam: build the skinning basis on a grid of the beam, simulate a beam test
//! on a (coarser) grid of integration points, record positions at given output points.

use std::path::Path;
use std::time::Instant;

use freeform::scene::SceneSpec;
use freeform::{PinHold, PressureSpace, PressureSpaceParams, Simulation};
use hyperelastic::{MaterialField, MaterialSample, StableNeoHookean};
use nalgebra::Vector3;
use reduced_sim::SkinningField;
use rkpm_core::{IntegrationPoints, Kernels, place_kernels};
use skin_eigen::{BasisError, BasisReport, SkinningBasis, build_basis};

use crate::EvalError;
use crate::beam_scenario::{BEAM_TIME_STEP, BeamTest, beam_basis_grid, beam_material};
use crate::reduced_run::{ReducedProblem, ReducedRun, run_reduced};
use crate::reduced_settings::ReducedSettings;
use freeform::terminal_progress::TerminalProgress;

/// A beam basis and what building it cost.
pub struct BeamBasis {
    /// The basis.
    pub basis: SkinningBasis,
    /// Its build report (per-phase seconds).
    pub report: BasisReport,
    /// Wall time including grid sampling (s).
    pub seconds: f64,
}

/// Builds the beam's skinning basis for `settings` (modes, kernels, basis points).
///
/// # Errors
/// [`EvalError::Basis`] from the builder (e.g. m ≥ K).
pub fn build_beam_basis(settings: &ReducedSettings) -> Result<BeamBasis, EvalError> {
    let start = Instant::now();
    let (grid, lame) = beam_basis_grid(settings.basis_points)?;
    let (basis, report, _) =
        build_basis(&grid, &lame, &settings.basis_params()).map_err(EvalError::Basis)?;
    Ok(BeamBasis {
        basis,
        report,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// Exact holding for `settings`' beam basis: each region shrunk by `inset_radii` (default
/// [`crate::reduced_settings::EXACT_INSET_KERNEL_RADII`]) times the median radius of the kernels placed on the basis
/// grid.
///
/// # Errors
/// [`EvalError::Sampling`] / [`EvalError::Basis`] when the grid or the kernels cannot be made.
pub fn exact_pin_hold(settings: &ReducedSettings, inset_radii: f64) -> Result<PinHold, EvalError> {
    let (grid, _) = beam_basis_grid(settings.basis_points)?;
    let kernels = place_kernels(grid.positions(), &settings.basis_params().kernels)
        .map_err(|e| EvalError::Basis(BasisError::Kernels(e)))?;
    Ok(PinHold::Exact {
        inset: inset_radii * median_kernel_radius(&kernels),
    })
}

/// The beam's basis for `test` under `settings`: [`build_beam_basis`] for the penalty; for
/// exact holding, built for the test's held regions at the basis grid's and the simulation's
/// points ([`PinHold::build_basis`]; no output points are passed: the box's kernels as placed
/// reach its FEM vertices, and a vertex they did not reach would fail the run by name).
///
/// # Errors
/// [`EvalError::Basis`] from the builder, [`EvalError::Scene`] for a held region that holds no
/// point.
pub fn build_beam_basis_for(
    test: BeamTest,
    settings: &ReducedSettings,
) -> Result<BeamBasis, EvalError> {
    if settings.pins == PinHold::Penalty {
        return build_beam_basis(settings);
    }
    let start = Instant::now();
    let (grid, lame) = beam_basis_grid(settings.basis_points)?;
    let points = beam_simulation_points(&test.scene(), settings)?;
    let (basis, report) = settings.pins.build_basis(
        &test.scene(),
        &grid,
        &lame,
        points.positions(),
        &[],
        settings.basis_params(),
    )?;
    Ok(BeamBasis {
        basis,
        report,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// The beam's simulation points in `scene` under `settings`: the sampling's grid or random
/// points, with the cells a weighted hold's regions cut split into their parts when the hold
/// asks ([`PinHold::simulation_points`]).
///
/// # Errors
/// [`EvalError::Sampling`] when the points cannot be sampled.
pub fn beam_simulation_points(
    scene: &SceneSpec,
    settings: &ReducedSettings,
) -> Result<IntegrationPoints, EvalError> {
    let points = settings
        .simulation_sampling
        .beam_points(settings.simulation_points)?;
    Ok(settings.pins.simulation_points(scene, points).0)
}

/// The median radius (m) of `kernels`: the length exact holding's inset is measured in.
pub(crate) fn median_kernel_radius(kernels: &Kernels) -> f64 {
    let mut radii = kernels.radii().to_vec();
    radii.sort_by(f64::total_cmp);
    radii[radii.len() / 2]
}

/// Simulates `steps` steps of `test` with `basis` (ours, or any other skinning field) on about
/// `settings.simulation_points` points placed by `settings.simulation_sampling`, recording
/// positions at `output_points` (rest positions, m) every step.
///
/// # Errors
/// [`EvalError`] for a failed setup or step.
pub fn run_reduced_beam<B: SkinningField + ?Sized>(
    test: BeamTest,
    basis: &B,
    settings: &ReducedSettings,
    output_points: &[Vector3<f64>],
    steps: usize,
    progress: &TerminalProgress,
) -> Result<ReducedRun, EvalError> {
    run_reduced_beam_with(
        test,
        basis,
        settings,
        beam_material(),
        None,
        output_points,
        steps,
        progress,
    )
}

/// [`run_reduced_beam`] with a material (the beam's is [`beam_material`]; the pin sweep varies
/// its Poisson ratio) and a cache folder for the cubature (`None`: optimized every run). With
/// `settings.pressure`, the volumetric term is projected onto [`beam_pressure_space`].
///
/// # Errors
/// As [`run_reduced_beam`].
#[allow(clippy::too_many_arguments)]
pub fn run_reduced_beam_with<B: SkinningField + ?Sized>(
    test: BeamTest,
    basis: &B,
    settings: &ReducedSettings,
    material: MaterialSample,
    cache_dir: Option<&Path>,
    output_points: &[Vector3<f64>],
    steps: usize,
    progress: &TerminalProgress,
) -> Result<ReducedRun, EvalError> {
    let pressure = settings
        .pressure
        .map(|params| beam_pressure_space(test, settings, &params))
        .transpose()?;
    run_reduced_beam_with_pressure(
        test,
        basis,
        settings,
        material,
        pressure.as_ref(),
        cache_dir,
        output_points,
        steps,
        progress,
    )
}

/// [`run_reduced_beam_with`] with the locking-free volumetric term over `pressure`
/// ([`freeform::Simulation::pressure`]; `None` is [`run_reduced_beam_with`]).
///
/// # Errors
/// As [`run_reduced_beam`].
#[allow(clippy::too_many_arguments)]
pub fn run_reduced_beam_with_pressure<B: SkinningField + ?Sized>(
    test: BeamTest,
    basis: &B,
    settings: &ReducedSettings,
    material: MaterialSample,
    pressure: Option<&PressureSpace>,
    cache_dir: Option<&Path>,
    output_points: &[Vector3<f64>],
    steps: usize,
    progress: &TerminalProgress,
) -> Result<ReducedRun, EvalError> {
    let points = beam_simulation_points(&test.scene(), settings)?;
    run_reduced(
        &ReducedProblem {
            simulation: Simulation::new(
                basis,
                &points,
                &MaterialField::Uniform(material),
                StableNeoHookean,
                &test.scene(),
            )
            .with_params(settings.simulation_params(BEAM_TIME_STEP))
            .with_quadrature(settings.quadrature)
            .with_cache_dir(cache_dir)
            .with_pin_hold(settings.pins)
            .with_pressure(pressure),
            output_points,
            steps,
        },
        &format!("FreeForm {} m={}", test.name(), settings.modes),
        progress,
    )
}

/// The pressure space of `test`'s beam under `settings` (its hold, kernels and modes) on the
/// basis grid ([`PressureSpace::build`]).
///
/// # Errors
/// [`EvalError::Sampling`] / [`EvalError::Basis`] when the grid or the Neumann basis cannot be
/// made.
pub fn beam_pressure_space(
    test: BeamTest,
    settings: &ReducedSettings,
    params: &PressureSpaceParams,
) -> Result<PressureSpace, EvalError> {
    let (grid, lame) = beam_basis_grid(settings.basis_points)?;
    PressureSpace::build(
        &test.scene(),
        settings.pins,
        &grid,
        &lame,
        settings.basis_params(),
        params,
        None,
    )
    .map_err(EvalError::Basis)
}
