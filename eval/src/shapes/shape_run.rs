//! One shape, stage by stage: its basis and the baseline's network, its FEM mesh and points,
//! then per boundary condition the reference (and its convergence check) and each method's
//! scores. Every failure of a condition ends up in its row; the shape goes on.

use fem_ref::{FillReducingOrdering, TetMesh, tetrahedralize};
use hyperelastic::{LameParameters, MaterialSample};
use nalgebra::Vector3;
use std::path::Path;
use std::time::Instant;

use baselines::{SIMPLICITS_FORMAT_VERSION, SimplicitsField, SimplicitsParams, TrainedSimplicits};
use rkpm_core::{
    CoverageReport, GridSamplingParams, IntegrationPoints, TriangleMesh, read_triangle_mesh,
    sample_grid,
};
use skin_eigen::{SkinningBasis, build_basis};

use crate::EvalError;
use crate::beam_protocol::reduced::median_kernel_radius;
use crate::model_cache::{load_cached, model_path};
use crate::reduced_settings::ReducedSettings;
use crate::shapes::boundary::ShapeBoundary;
use crate::shapes::boundary_run::BoundaryRun;
use crate::shapes::config::ShapeStudyConfig;
use crate::shapes::reference::{ConditionLattice, FemMeshSummary, mesh_for_fem, mesh_through};
use crate::shapes::result::{FemRunSummary, MethodScores, ShapeResult, ShapeRow};
use crate::shapes::stage::{ShapeStage, ShapeWork};
use crate::simplicits_cache::train_cached_simplicits;
use freeform::failure_chain;
use freeform::fem_reference::{FemProblem, FemRun, cached_fem, run_fem};
use freeform::metrics::trajectory_errors;
use freeform::scene::SceneSpec;
use freeform::terminal_progress::{BarProgress, TerminalProgress};
use freeform::{PinHold, PressureSpace};

/// The body of [`crate::shapes::study`]'s shape run, filling `result` as it goes so that what
/// was measured before a failure stays; `work` says whether that is everything, one stage of
/// the shape's work ([`ShapeStage`]) or the references' estimates.
pub(crate) fn run_shape_into(
    path: &Path,
    config: &ShapeStudyConfig,
    work: ShapeWork,
    progress: &TerminalProgress,
    result: &mut ShapeResult,
) -> Result<(), EvalError> {
    let surface = read_triangle_mesh(path)?.normalized().0;
    let length = surface.bounding_box().largest_side();
    let material = result.material();
    let lame = material.lame_parameters().map_err(EvalError::Material)?;
    let settings = &config.settings;

    let fem_only = matches!(
        work,
        ShapeWork::Stage(ShapeStage::Reference | ShapeStage::Check) | ShapeWork::Estimate
    );
    let basis = if fem_only {
        None
    } else {
        let basis_start = Instant::now();
        let basis_points = sample_on(&surface, settings.basis_points, "basis points")?;
        let lames = vec![lame; basis_points.len()];
        result.basis_points = basis_points.len();
        if work == ShapeWork::Stage(ShapeStage::Train) {
            baseline_network(config, &basis_points, &lames, material, progress, result)?;
            return Ok(());
        }
        let (ours, _, _) = build_basis(&basis_points, &lames, &settings.basis_params())
            .map_err(EvalError::Basis)?;
        result.basis_seconds = Some(basis_start.elapsed().as_secs_f64());
        let simplicits =
            baseline_network(config, &basis_points, &lames, material, progress, result)?;
        Some((ours, basis_points, lames, simplicits))
    };

    let (lattice_mesh, report) = mesh_for_fem(&surface, &config.fem)?;
    // Islands the lattice cut off from the body would fall freely in the FEM reference.
    let (tets, summary) = FemMeshSummary::largest_piece(&lattice_mesh, &report, length);
    result.fem_mesh = Some(summary);
    let points = match &basis {
        Some(_) => Some(sample_on(
            &surface,
            settings.simulation_points,
            "simulation points",
        )?),
        None => None,
    };
    let mut meshes = ShapeMeshes {
        surface: &surface,
        length,
        tets,
        cells: summary.cells_across,
        finer_cells: (1.5 * length / report.cell_size).round() as usize,
        finer: None,
    };
    let shape = ShapeInputs {
        config,
        progress,
        work,
        name: &result.name,
        youngs_modulus: result.youngs_modulus,
        material,
        reduced: basis.as_ref().zip(points.as_ref()).map(
            |((ours, basis_points, lames, simplicits), points)| ReducedInputs {
                points,
                ours,
                basis_points,
                lames,
                simplicits: simplicits.as_ref(),
            },
        ),
    };
    let mut fem_seconds = 0.0;
    for &boundary in &config.boundaries {
        let row = run_row(&shape, &mut meshes, boundary, &mut fem_seconds);
        result.rows.push(row);
    }
    result.fem_seconds = Some(fem_seconds);
    Ok(())
}

/// The Simplicits network of the shape (trained and cached, or with
/// [`ShapeStudyConfig::cached_only`] only loaded), or `None` when the study leaves it out;
/// records its training time in `result`.
///
/// # Errors
/// From training; [`EvalError::NotCached`] for a cached-only study without the network.
fn baseline_network(
    config: &ShapeStudyConfig,
    basis_points: &IntegrationPoints,
    lames: &[LameParameters],
    material: MaterialSample,
    progress: &TerminalProgress,
    result: &mut ShapeResult,
) -> Result<Option<SimplicitsField>, EvalError> {
    let Some(params) = &config.simplicits else {
        return Ok(None);
    };
    let params = SimplicitsParams {
        modes: config.settings.modes,
        ..*params
    };
    let model = model_path(
        &config.cache_dir,
        "simplicits",
        "simplicits shape",
        SIMPLICITS_FORMAT_VERSION,
        &format!("{params:?}"),
        basis_points,
        &material,
    );
    let trained = if config.cached_only {
        // Nothing is trained: a network the cache lacks, or holds damaged, is reported.
        let label = format!("Simplicits m = {}", params.modes);
        load_cached(&model, &label, progress, |path| {
            TrainedSimplicits::load(path)
        })
        .ok_or_else(|| EvalError::NotCached {
            what: format!("{label} (a readable network)"),
        })?
    } else {
        train_cached_simplicits(basis_points, lames, &params, &model, progress)?.trained
    };
    result.training_seconds = Some(trained.report.seconds);
    Ok(Some(trained.field))
}

/// What every boundary condition of one shape shares.
struct ShapeInputs<'a> {
    config: &'a ShapeStudyConfig,
    progress: &'a TerminalProgress,
    /// Everything, one stage, or the estimates.
    work: ShapeWork,
    name: &'a str,
    youngs_modulus: f64,
    material: MaterialSample,
    /// What the reduced runs need (none in the FEM-only stages).
    reduced: Option<ReducedInputs<'a>>,
}

/// The bases and points the reduced runs of a shape share.
struct ReducedInputs<'a> {
    /// The simulation's integration points.
    points: &'a IntegrationPoints,
    ours: &'a SkinningBasis,
    basis_points: &'a IntegrationPoints,
    lames: &'a [LameParameters],
    simplicits: Option<&'a SimplicitsField>,
}

/// The shape's FEM meshes: its own and, built when the first condition on it needs one for the
/// convergence check, the 1.5× finer one.
struct ShapeMeshes<'a> {
    surface: &'a TriangleMesh,
    length: f64,
    tets: TetMesh,
    cells: usize,
    finer_cells: usize,
    finer: Option<TetMesh>,
}

impl ShapeMeshes<'_> {
    /// The largest piece of the lattice mesh at `cells` across, on a condition's own lattice.
    fn lattice_mesh(
        &self,
        config: &ShapeStudyConfig,
        cells: usize,
        condition: &ConditionLattice,
    ) -> Result<TetMesh, EvalError> {
        let params = config.fem.lattice_through(cells, self.length, condition);
        let (mesh, report) = tetrahedralize(self.surface, &params).map_err(EvalError::FemMesh)?;
        Ok(FemMeshSummary::largest_piece(&mesh, &report, self.length).0)
    }
}

/// The row of one boundary condition: its meshes, reference, check and scores; a failure is
/// recorded in the row.
fn run_row(
    shape: &ShapeInputs<'_>,
    meshes: &mut ShapeMeshes<'_>,
    boundary: ShapeBoundary,
    fem_seconds: &mut f64,
) -> ShapeRow {
    let config = shape.config;
    let mut row = ShapeRow::new(boundary);
    let scene = boundary.scene(meshes.surface, meshes.tets.vertices(), &config.boundary);
    let label = format!("{} {}", shape.name, boundary.title());
    // The reference on its own lattice (the held slabs' faces on vertex planes, the pulled
    // patches' edges refined), if asked. (Finer by 1.5× the cells of its own mesh, which
    // may be finer than the shape's when its lattice at the shape's cells loses volume.)
    let condition = config.fem.condition_lattice(boundary, &scene);
    let aligned = (!condition.is_plain()).then(|| {
        let (tets, summary, cells) = mesh_through(
            meshes.surface,
            &config.fem,
            meshes.cells,
            meshes.length,
            &condition,
        )?;
        row.fem_mesh = Some(summary);
        let finer_cells = (1.5 * cells as f64).round() as usize;
        let finer = config
            .check_convergence
            .then(|| meshes.lattice_mesh(config, finer_cells, &condition))
            .transpose()?;
        Ok::<_, EvalError>((tets, finer))
    });
    let aligned = match aligned.transpose() {
        Ok(aligned) => aligned,
        Err(e) => {
            row.error = Some(failure_chain(&e));
            return row;
        }
    };
    if aligned.is_none() && config.check_convergence && meshes.finer.is_none() {
        match meshes.lattice_mesh(config, meshes.finer_cells, &ConditionLattice::default()) {
            Ok(mesh) => meshes.finer = Some(mesh),
            Err(e) => {
                row.error = Some(failure_chain(&e));
                return row;
            }
        }
    }
    let (tets, finer) = match &aligned {
        Some((tets, finer)) => (tets, finer.as_ref()),
        None => (&meshes.tets, meshes.finer.as_ref()),
    };
    let problem = |tets: &TetMesh| FemProblem {
        tets: tets.clone(),
        order: config.fem.order,
        material: shape.material,
        scene: &scene,
        time_step: config.boundary.time_step,
        newton: config.fem.newton_for(boundary, shape.youngs_modulus),
        tangent: config.fem.tangent,
        ordering: FillReducingOrdering::default(),
        failed_step_halvings: config.fem.failed_step_halvings,
        steps: config.boundary.steps,
    };
    match shape.work {
        ShapeWork::Estimate => {
            match problem(tets).estimate() {
                Ok(estimate) => row.reference_estimate = Some(estimate),
                Err(e) => row.error = Some(failure_chain(&e)),
            }
            if let Some(finer) = finer {
                match problem(finer).estimate() {
                    Ok(estimate) => row.check_estimate = Some(estimate),
                    Err(e) => row.reference_check_error = Some(failure_chain(&e)),
                }
            }
            return row;
        }
        ShapeWork::Stage(ShapeStage::Reference) => {
            match reference_run(&problem(tets), &label, config, shape.progress) {
                Ok(fem) => row.fem = Some(FemRunSummary::of(&fem, meshes.length)),
                Err(e) => row.error = Some(failure_chain(&e)),
            }
            return row;
        }
        ShapeWork::Stage(ShapeStage::Check) => {
            if let Some(finer) = finer {
                let label = format!("{label} finer");
                match reference_run(&problem(finer), &label, config, shape.progress) {
                    Ok(fine) => row.reference_check = Some(FemRunSummary::of(&fine, meshes.length)),
                    Err(e) => row.reference_check_error = Some(failure_chain(&e)),
                }
            }
            return row;
        }
        _ => {}
    }
    let outcome = reference_run(&problem(tets), &label, config, shape.progress).and_then(|fem| {
        *fem_seconds += fem.seconds_per_step * config.boundary.steps as f64;
        row.fem = Some(FemRunSummary::of(&fem, meshes.length));
        fem.check_converged(config.fem.newton.max_iterations)?;
        if let Some(finer) = finer {
            let label = format!("{label} finer");
            let change =
                reference_run(&problem(finer), &label, config, shape.progress).and_then(|fine| {
                    row.reference_check = Some(FemRunSummary::of(&fine, meshes.length));
                    reference_change(&fem, &fine, meshes.length, config)
                });
            match change {
                Ok(change) => row.reference_change = Some(change),
                Err(e) => row.reference_check_error = Some(failure_chain(&e)),
            }
        }
        score_row(shape, &scene, &fem, meshes.length, &label, &mut row)
    });
    if let Err(e) = outcome {
        row.error = Some(failure_chain(&e));
    }
    row
}

/// Scores ours (and the exact holding, and the baseline, when asked) against `fem` into `row`.
/// Ours holds the condition's regions as `settings.pins` says (a basis built for them when
/// held exactly) and integrates the volumetric term as `settings.pressure` says; the exact
/// holding's row shares that volumetric term; the baseline keeps the penalty and the
/// material's own volumetric term.
fn score_row(
    shape: &ShapeInputs<'_>,
    scene: &SceneSpec,
    fem: &FemRun,
    length: f64,
    label: &str,
    row: &mut ShapeRow,
) -> Result<(), EvalError> {
    let config = shape.config;
    let settings = &config.settings;
    let Some(reduced) = &shape.reduced else {
        return Ok(());
    };
    // Ours integrates over the sampled points, with the cells its held regions cut split when
    // its hold asks (`PinHold::simulation_points`); the exact holding and the baseline keep the
    // sampled ones.
    let (our_points, _) = settings
        .pins
        .simulation_points(scene, reduced.points.clone());
    // A basis built here for the held regions shares its shape functions with the pressure
    // space's Neumann modes on the same points.
    let (held_basis, shared) = match settings.pins {
        PinHold::Penalty => (None, None),
        hold => {
            let (basis, _, shared) = hold.build_basis_sharing(
                scene,
                reduced.basis_points,
                reduced.lames,
                our_points.positions(),
                fem.vertices(),
                settings.basis_params(),
            )?;
            (Some(basis), shared)
        }
    };
    let pressure = settings
        .pressure
        .as_ref()
        .map(|params| {
            PressureSpace::build(
                scene,
                settings.pins,
                reduced.basis_points,
                reduced.lames,
                settings.basis_params(),
                params,
                shared.as_ref(),
            )
        })
        .transpose()
        .map_err(EvalError::Basis)?;
    drop(shared);
    let run = BoundaryRun {
        points: reduced.points,
        material: shape.material,
        scene,
        params: settings.simulation_params(config.boundary.time_step),
        quadrature: settings.quadrature,
        pressure: pressure.as_ref(),
        cache_dir: &config.cache_dir,
        fem,
        steps: config.boundary.steps,
        length,
        label,
        progress: shape.progress,
    };
    let ours = held_basis.as_ref().unwrap_or(reduced.ours);
    let our_run = BoundaryRun {
        points: &our_points,
        ..run
    };
    let (scores, region_points) = our_run.score(ours, "FreeForm", settings.pins)?;
    row.ours = Some(scores);
    row.region_points = region_points;
    if let Some(radii) = config.exact_pins {
        match run_exact(
            &run,
            reduced.ours,
            reduced.basis_points,
            reduced.lames,
            settings,
            radii,
        ) {
            Ok((scores, coverage)) => {
                row.exact = Some(scores);
                row.exact_kernel_coverage = Some(coverage);
            }
            Err(e) => row.exact_error = Some(failure_chain(&e)),
        }
    }
    if let Some(net) = reduced.simplicits {
        let baseline = BoundaryRun {
            quadrature: config.simplicits_quadrature.unwrap_or(run.quadrature),
            pressure: None,
            ..run
        };
        row.simplicits = Some(baseline.score(net, "Simplicits", PinHold::Penalty)?.0);
    }
    Ok(())
}

/// `problem`'s FEM run ([`run_fem`]), or with [`ShapeStudyConfig::cached_only`] its cached one.
///
/// # Errors
/// As [`run_fem`]; [`EvalError::NotCached`] for a cached-only run the cache does not hold.
fn reference_run(
    problem: &FemProblem<'_>,
    label: &str,
    config: &ShapeStudyConfig,
    progress: &TerminalProgress,
) -> Result<FemRun, EvalError> {
    let bars = BarProgress::new(*progress);
    if !config.cached_only {
        return Ok(run_fem(problem, label, &config.cache_dir, &bars)?);
    }
    cached_fem(problem, label, &config.cache_dir, &bars)?.ok_or_else(|| {
        progress.status(format!(
            "FEM {label}: not in the cache, not computed (cached only)"
        ));
        EvalError::NotCached {
            what: format!("FEM {label}"),
        }
    })
}

/// The normalized MSE between `coarse` and `fine` (the same problem's run on a finer mesh), at
/// the coarse vertices inside the finer mesh over frames 1..T.
///
/// # Errors
/// [`EvalError`] when a step of the finer run did not converge, or from the metric;
/// [`EvalError::InvalidInput`] when no coarse vertex lies inside the finer mesh.
fn reference_change(
    coarse: &FemRun,
    fine: &FemRun,
    length: f64,
    config: &ShapeStudyConfig,
) -> Result<f64, EvalError> {
    fine.check_converged(config.fem.newton.max_iterations)?;
    let (inside, fine_frames) = fine.frames_inside(coarse.vertices());
    if inside.is_empty() {
        return Err(EvalError::InvalidInput(
            "no vertex of the reference lies inside the finer mesh".into(),
        ));
    }
    let coarse_frames: Vec<Vec<Vector3<f64>>> = coarse
        .vertex_frames()
        .iter()
        .map(|f| inside.iter().map(|&i| f[i]).collect())
        .collect();
    Ok(trajectory_errors(&coarse_frames[1..], &fine_frames[1..], length)?.normalized_mse)
}

/// `run` with its regions held exactly: the inset from `radii` times the median radius of
/// `ours`' kernels, a basis built for the inset regions on `basis_points`, scored like ours;
/// with how that basis's kernels were widened.
fn run_exact(
    run: &BoundaryRun<'_>,
    ours: &SkinningBasis,
    basis_points: &IntegrationPoints,
    lames: &[LameParameters],
    settings: &ReducedSettings,
    radii: f64,
) -> Result<(MethodScores, CoverageReport), EvalError> {
    let hold = PinHold::Exact {
        inset: radii * median_kernel_radius(ours.kernels()),
    };
    let (basis, report) = hold.build_basis(
        run.scene,
        basis_points,
        lames,
        run.points.positions(),
        run.fem.vertices(),
        settings.basis_params(),
    )?;
    Ok((
        run.score(&basis, "FreeForm exact", hold)?.0,
        report.coverage,
    ))
}

/// A grid of about `target` points inside `surface`.
fn sample_on(
    surface: &TriangleMesh,
    target: usize,
    what: &'static str,
) -> Result<IntegrationPoints, EvalError> {
    sample_grid(
        surface,
        &GridSamplingParams {
            target_points: target,
        },
    )
    .map_err(|source| EvalError::Sampling { what, source })
}
