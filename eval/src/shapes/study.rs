//! The shapes study behind Tables 2 and 7 (design §4.2): for every closed mesh, normalized so its
//! largest bounding-box side is L = 1 m, our basis and the Simplicits network (m = 32) on the
//! same grid of integration points, a tetrahedralization for the FEM reference, and the three
//! boundary conditions of [`crate::shapes::boundary`] run by all three solvers. Reduced runs are
//! scored at the FEM mesh's vertices.
//!
//! A shape that cannot be read, sampled, meshed or given a basis is reported with the reason,
//! as is a boundary condition that fails on a shape (e.g. a region that selects no FEM node);
//! the study goes on. FEM trajectories and trained networks are cached, so a rerun (or a run
//! after an interruption) only computes what is missing; a cached-only study
//! ([`ShapeStudyConfig::cached_only`]) computes none of it and scores what the cache holds.

use fem_ref::{FillReducingOrdering, TetMesh, tetrahedralize};
use hyperelastic::{LameParameters, MaterialField, MaterialSample, StableNeoHookean};
use nalgebra::Vector3;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, PoisonError};
use std::time::Instant;

use baselines::{SIMPLICITS_FORMAT_VERSION, SimplicitsParams, TrainedSimplicits};
use reduced_sim::{QuadratureRule, SimulationParams, SkinningField};
use rkpm_core::{
    CoverageReport, GridSamplingParams, IntegrationPoints, TriangleMesh, read_triangle_mesh,
    sample_grid,
};
use serde::{Deserialize, Serialize};
use skin_eigen::{SkinningBasis, build_basis};

use crate::EvalError;
use crate::beam::reduced::{ReducedSettings, median_kernel_radius};
use crate::beam::simplicits::train_cached_simplicits;
use crate::model_cache::{load_cached, model_path};
use crate::reduced_run::{ReducedProblem, run_reduced};
use crate::shapes::boundary::{ShapeBoundary, ShapeBoundaryParams};
use crate::shapes::catalog::{
    DEFAULT_SHAPE_YOUNGS_MODULUS, MaterialClass, SHAPE_DENSITY, SHAPE_POISSON_RATIO,
    ShapeCollection, catalog_entry,
};
use crate::shapes::reference::{
    ConditionLattice, FemMeshSummary, ShapeFemParams, mesh_for_fem, mesh_through,
};
use freeform::failure_chain;
use freeform::fem_reference::{FemProblem, FemRun, cached_fem, run_fem};
use freeform::metrics::trajectory_errors;
use freeform::scene::SceneSpec;
use freeform::terminal_progress::{BarProgress, TerminalProgress};
use freeform::{PinHold, Simulation};

/// What the study runs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShapeStudyConfig {
    /// Surface files (OBJ/STL/PLY), in table order.
    pub meshes: Vec<PathBuf>,
    /// Modes, kernels, basis and simulation points, Newton tolerance, pin penalty (default
    /// m = 32, K = 1000, 20 000 basis points, 5000 simulation points).
    pub settings: ReducedSettings,
    /// The boundary conditions' sizes, speeds and step count.
    pub boundary: ShapeBoundaryParams,
    /// The FEM reference's mesh.
    pub fem: ShapeFemParams,
    /// The Simplicits baseline's training options (`modes` is set from `settings`), or `None`
    /// to leave it out.
    pub simplicits: Option<SimplicitsParams>,
    /// Young's modulus of a file not in [`crate::shapes::catalog`] (Pa, default 10⁵).
    pub default_youngs_modulus: f64,
    /// Shapes run at the same time (default 1). Each holds one FEM system (≤ 1 GB at the
    /// default resolution); the solvers already use every core, so more jobs mainly fill the
    /// serial phases.
    pub jobs: usize,
    /// Cache folder (FEM trajectories under `fem/`, networks under `simplicits/`).
    pub cache_dir: PathBuf,
    /// The quality gate of the FEM reference: a row is scored only when the
    /// reference's tet mesh keeps the surface's volume within this fraction (default 0.03).
    #[serde(default = "default_reference_volume_gate")]
    pub max_reference_volume_error: f64,
    /// Check each reference's convergence: run the FEM again on the lattice 1.5×
    /// finer and measure how much the trajectory changes at the reference's vertices (default
    /// false: it multiplies the FEM time by about 5).
    #[serde(default)]
    pub check_convergence: bool,
    /// Also run every (shape, boundary condition) with its regions held exactly, shrunk by this
    /// many median kernel radii (a basis per condition, [`PinHold::Exact`]); `None` leaves it
    /// out.
    #[serde(default)]
    pub exact_pins: Option<f64>,
    /// The quadrature Simplicits is simulated with; `None` (default): FreeForm's
    /// (`settings.quadrature`). `Some(QuadratureRule::Full)` keeps the baseline on every point
    /// while FreeForm runs on a cubature: Simplicits' own cubature is coarser (about 320 of
    /// the 20 000 basis-grid points on the shared shapes) and costs it accuracy on stiff ones.
    #[serde(default)]
    pub simplicits_quadrature: Option<QuadratureRule>,
    /// The boundary conditions run on every shape (default all three, in the paper's column
    /// order). Table 2's and 7's averages of a condition left out cover no shape.
    #[serde(default = "all_boundaries")]
    pub boundaries: Vec<ShapeBoundary>,
    /// Score only what the cache holds (default false): a FEM reference or convergence check
    /// that is not cached is not computed, and its row says so ([`EvalError::NotCached`]); a
    /// shape whose Simplicits network is not cached (or not readable) is not trained, and
    /// reported. For reading the tables of work spread over several runs while they go on.
    #[serde(default)]
    pub cached_only: bool,
}

fn default_reference_volume_gate() -> f64 {
    0.03
}

fn all_boundaries() -> Vec<ShapeBoundary> {
    ShapeBoundary::ALL.to_vec()
}

impl ShapeStudyConfig {
    /// The paper's configuration (design §4.2): m = 32, K = 1000, Simplicits trained for 10 000
    /// steps, FEM P2.
    pub fn full(meshes: Vec<PathBuf>, cache_dir: PathBuf) -> Self {
        ShapeStudyConfig {
            meshes,
            settings: ReducedSettings {
                modes: 32,
                ..ReducedSettings::default()
            },
            boundary: ShapeBoundaryParams::default(),
            fem: ShapeFemParams::default(),
            simplicits: Some(SimplicitsParams::default()),
            default_youngs_modulus: DEFAULT_SHAPE_YOUNGS_MODULUS,
            jobs: 1,
            cache_dir,
            // The shapes' held regions (a slab, small balls) are thinner than the beam's
            // 1.5-radius inset: the whole region is held.
            exact_pins: Some(0.0),
            max_reference_volume_error: default_reference_volume_gate(),
            check_convergence: false,
            simplicits_quadrature: None,
            boundaries: all_boundaries(),
            cached_only: false,
        }
    }

    /// A seconds-per-shape version: m = 6, K = 120 on 3000 basis points, 1000 simulation
    /// points, 10 steps, FEM P2 on a 6-cell lattice, Simplicits trained for 30 steps.
    pub fn quick(meshes: Vec<PathBuf>, cache_dir: PathBuf) -> Self {
        let full = ShapeStudyConfig::full(meshes, cache_dir);
        ShapeStudyConfig {
            settings: ReducedSettings {
                modes: 6,
                kernels: 120,
                basis_points: 3000,
                simulation_points: 1000,
                ..full.settings
            },
            boundary: ShapeBoundaryParams {
                steps: 10,
                ..full.boundary
            },
            fem: ShapeFemParams {
                first_cells_across: 6,
                max_cells_across: 6,
                ..full.fem
            },
            simplicits: Some(SimplicitsParams {
                steps: 30,
                ..SimplicitsParams::default()
            }),
            // Its 120 kernels are too wide for the inset regions to keep points.
            exact_pins: None,
            ..full
        }
    }
}

/// A method's scores on one (shape, boundary condition).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct MethodScores {
    /// Normalized MSE against the FEM (design §4.3).
    pub mse: f64,
    /// Normalized max error.
    pub max: f64,
    /// Basis fitting residual of the FEM trajectory (Table 7).
    pub fitting_residual: f64,
    /// Wall time per step (ms).
    pub ms_per_step: f64,
    /// Points the elastic energy is integrated on (all simulation points, or a cubature's).
    pub quadrature_points: usize,
    /// Steps whose Newton solve did not converge.
    pub unconverged_steps: usize,
    /// Largest distance of a constrained integration point from its target (m): how far the
    /// penalty lets held and pulled regions drift (exact pins: of the exactly held points).
    pub max_pin_deviation: f64,
}

/// The FEM run of one (shape, boundary condition).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FemRunSummary {
    /// FEM nodes in each constrained region (a region held by one or two nodes is a hinge).
    pub region_nodes: Vec<usize>,
    /// Largest vertex displacement over the run over L: the scale the errors compare with.
    pub max_displacement: f64,
    /// Free DOFs.
    pub dofs: usize,
    /// Seconds per step of the run that produced the trajectory.
    pub seconds_per_step: f64,
    /// Newton iterations per step.
    pub iterations_per_step: f64,
    /// Unconverged steps.
    pub unconverged_steps: usize,
    /// Loaded from the cache.
    pub cached: bool,
}

impl FemRunSummary {
    /// What a table reports of `fem`, a run of `length` (m) across.
    fn of(fem: &FemRun, length: f64) -> Self {
        FemRunSummary {
            region_nodes: fem.region_nodes.clone(),
            max_displacement: fem.max_vertex_displacement() / length,
            dofs: fem.dofs,
            seconds_per_step: fem.seconds_per_step,
            iterations_per_step: fem.iterations_per_step,
            unconverged_steps: fem.unconverged_steps,
            cached: fem.cached,
        }
    }
}

/// One (shape, boundary condition).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShapeRow {
    /// Which condition.
    pub boundary: ShapeBoundary,
    /// The FEM reference, if it ran.
    pub fem: Option<FemRunSummary>,
    /// Our scores, if the run finished.
    pub ours: Option<MethodScores>,
    /// Simplicits' scores, if it was trained and the run finished.
    pub simplicits: Option<MethodScores>,
    /// Our scores with the regions held exactly (inset), if that ran and finished.
    #[serde(default)]
    pub exact: Option<MethodScores>,
    /// Why the exact run is missing when it was asked for (e.g. an inset that leaves a region
    /// without points).
    #[serde(default)]
    pub exact_error: Option<String>,
    /// How the exact basis's compact kernels were widened to reach every point in a thin part
    /// (`BasisReport::coverage`), when the exact basis was built.
    #[serde(default)]
    pub exact_kernel_coverage: Option<CoverageReport>,
    /// With [`ShapeStudyConfig::check_convergence`]: the normalized MSE (the table's metric)
    /// between this reference and the one on the 1.5× finer lattice, at this reference's
    /// vertices inside the finer mesh.
    #[serde(default)]
    pub reference_change: Option<f64>,
    /// The convergence check's finer reference, when it ran (its DOFs and seconds a step:
    /// the check's cost, which the shape's `fem_seconds` leaves out).
    #[serde(default)]
    pub reference_check: Option<FemRunSummary>,
    /// Why the convergence check could not be made, when it was asked for.
    #[serde(default)]
    pub reference_check_error: Option<String>,
    /// This row's own FEM mesh when it is not the shape's ([`ShapeResult::fem_mesh`]): on the
    /// lattice whose vertex planes are the held slabs' faces
    /// ([`ShapeFemParams::clamp_on_lattice_plane`],
    /// [`ShapeFemParams::pull_slabs_on_lattice_planes`]) or refined along the pulled regions'
    /// edges ([`ShapeFemParams::refine_pulled_patch_edges`],
    /// [`ShapeFemParams::refine_pulled_slab_faces`]). `None`: the shape's mesh.
    #[serde(default)]
    pub fem_mesh: Option<FemMeshSummary>,
    /// Reduced integration points in each constrained region.
    pub region_points: Vec<usize>,
    /// Why something is missing.
    pub error: Option<String>,
}

/// Everything measured on one shape.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShapeResult {
    /// File name.
    pub name: String,
    /// What it depicts (catalog) or the file stem.
    pub title: String,
    /// Its collection.
    pub collection: ShapeCollection,
    /// Its material class (`None`: not catalogued, `default_youngs_modulus` used).
    pub class: Option<MaterialClass>,
    /// Young's modulus used (Pa).
    pub youngs_modulus: f64,
    /// Grid points the bases were built on.
    pub basis_points: usize,
    /// Our basis build time, sampling included (s).
    pub basis_seconds: Option<f64>,
    /// Simplicits training time of the run that produced the network (s).
    pub training_seconds: Option<f64>,
    /// The FEM reference's mesh.
    pub fem_mesh: Option<FemMeshSummary>,
    /// Wall time of the three FEM runs that produced the trajectories (s).
    pub fem_seconds: Option<f64>,
    /// One row per boundary condition that was attempted.
    pub rows: Vec<ShapeRow>,
    /// Why the shape could not be run at all.
    pub error: Option<String>,
}

impl ShapeResult {
    /// The tet mesh `row`'s reference ran on: the row's own ([`ShapeRow::fem_mesh`]) or else
    /// the shape's.
    pub fn reference_mesh(&self, row: &ShapeRow) -> Option<FemMeshSummary> {
        row.fem_mesh.or(self.fem_mesh)
    }

    /// Why `row`'s FEM reference cannot be trusted, or `None` when it passes the quality gate:
    /// the tet mesh it ran on ([`Self::reference_mesh`]) keeps the surface's volume within
    /// `max_volume_error` (relative), its every step converged, and, when the convergence check
    /// ran, the 1.5× finer reference changes it by less than a tenth of the smaller of the
    /// methods' MSEs.
    pub fn untrusted_reference(&self, row: &ShapeRow, max_volume_error: f64) -> Option<String> {
        let Some(mesh) = self.reference_mesh(row) else {
            return Some("no FEM mesh".into());
        };
        if !(mesh.relative_volume_error.abs() <= max_volume_error) {
            return Some(format!(
                "the FEM mesh has {:+.1}% of the surface's volume (gate ±{:.0}%)",
                100.0 * mesh.relative_volume_error,
                100.0 * max_volume_error
            ));
        }
        match &row.fem {
            None => return Some("no FEM run".into()),
            Some(fem) if fem.unconverged_steps > 0 => {
                return Some(format!(
                    "the FEM run left {} steps unconverged",
                    fem.unconverged_steps
                ));
            }
            Some(_) => {}
        }
        if let Some(why) = &row.reference_check_error {
            return Some(format!("the convergence check did not finish: {why}"));
        }
        let smallest = [row.ours, row.simplicits]
            .iter()
            .flatten()
            .map(|s| s.mse)
            .fold(f64::INFINITY, f64::min);
        match row.reference_change {
            Some(change) if !(change < 0.1 * smallest) => Some(format!(
                "the 1.5× finer reference changes it by {change:.2e} (MSE), not below a tenth of \
                 the smallest method error {smallest:.2e}"
            )),
            _ => None,
        }
    }
}

/// Everything Tables 2 and 7 print.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShapeStudy {
    /// What was run.
    pub config: ShapeStudyConfig,
    /// One result per mesh, in the order of `config.meshes`.
    pub shapes: Vec<ShapeResult>,
    /// Wall time of the whole study (s).
    pub seconds: f64,
}

impl ShapeStudy {
    /// The file names of `config.meshes` that have no result in `shapes`, in table order: none
    /// for the study [`run_shape_study`] returns, the shapes still to come in the one it hands
    /// to `on_shape`.
    pub fn unfinished(&self) -> Vec<String> {
        let mut finished: Vec<&str> = self.shapes.iter().map(|s| s.name.as_str()).collect();
        self.config
            .meshes
            .iter()
            .map(|path| mesh_name(path))
            .filter(|name| match finished.iter().position(|f| f == name) {
                Some(i) => {
                    finished.swap_remove(i);
                    false
                }
                None => true,
            })
            .collect()
    }
}

/// The name a shape goes by in the tables: its file name.
fn mesh_name(path: &Path) -> String {
    path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into(),
    )
}

/// The closed meshes (`.obj`, `.stl`, `.ply`) directly in `dir`, sorted by name; with `only`,
/// just the one whose file name or stem is `only`.
///
/// # Errors
/// [`EvalError::Io`] if `dir` cannot be read; [`EvalError::InvalidInput`] if it holds no mesh or
/// nothing matches `only`.
pub fn mesh_files(dir: &Path, only: Option<&str>) -> Result<Vec<PathBuf>, EvalError> {
    let entries = std::fs::read_dir(dir).map_err(|e| EvalError::io(dir, e))?;
    let mut files: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.is_file()
                && p.extension().is_some_and(|x| {
                    matches!(x.to_ascii_lowercase().to_str(), Some("obj" | "stl" | "ply"))
                })
        })
        .collect();
    files.sort();
    if files.is_empty() {
        return Err(EvalError::InvalidInput(format!(
            "{}: no .obj, .stl or .ply file in this folder",
            dir.display()
        )));
    }
    let Some(only) = only else {
        return Ok(files);
    };
    let matching: Vec<PathBuf> = files
        .iter()
        .filter(|p| {
            p.file_name().is_some_and(|n| n == only) || p.file_stem().is_some_and(|s| s == only)
        })
        .cloned()
        .collect();
    if matching.is_empty() {
        let names: Vec<String> = files
            .iter()
            .filter_map(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
            .collect();
        return Err(EvalError::InvalidInput(format!(
            "--only {only}: no such mesh in {} (there are: {})",
            dir.display(),
            names.join(", ")
        )));
    }
    Ok(matching)
}

/// Runs the study, `config.jobs` shapes at a time. As each shape finishes, `on_shape` sees it
/// and the study so far (every finished shape, in table order; [`ShapeStudy::unfinished`] names
/// the rest), one call at a time, so it may write the tables of a long run as it goes.
///
/// # Errors
/// None from a shape (those are reported in its [`ShapeResult`]); [`EvalError::InvalidInput`] for
/// `jobs = 0` or no meshes.
pub fn run_shape_study(
    config: &ShapeStudyConfig,
    progress: &TerminalProgress,
    on_shape: impl Fn(&ShapeResult, &ShapeStudy) + Sync,
) -> Result<ShapeStudy, EvalError> {
    if config.jobs == 0 || config.meshes.is_empty() {
        return Err(EvalError::InvalidInput(format!(
            "the shape study needs at least one job and one mesh (jobs = {}, {} meshes)",
            config.jobs,
            config.meshes.len()
        )));
    }
    let start = Instant::now();
    // Parallel shapes print status lines only: their bars would draw over each other.
    let progress = if config.jobs > 1 {
        progress.without_bars()
    } else {
        *progress
    };
    let progress = &progress;
    let next = AtomicUsize::new(0);
    let results: Mutex<Vec<Option<ShapeResult>>> = Mutex::new(vec![None; config.meshes.len()]);
    std::thread::scope(|scope| {
        for _ in 0..config.jobs.min(config.meshes.len()) {
            scope.spawn(|| {
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    let Some(path) = config.meshes.get(i) else {
                        break;
                    };
                    let result = run_shape(path, config, progress);
                    // Held through `on_shape`: one call at a time, each seeing its own shape.
                    let mut slots = results.lock().unwrap_or_else(PoisonError::into_inner);
                    let so_far = ShapeStudy {
                        config: config.clone(),
                        shapes: slots
                            .iter()
                            .enumerate()
                            .filter_map(
                                |(j, slot)| if j == i { Some(&result) } else { slot.as_ref() },
                            )
                            .cloned()
                            .collect(),
                        seconds: start.elapsed().as_secs_f64(),
                    };
                    on_shape(&result, &so_far);
                    slots[i] = Some(result);
                }
            });
        }
    });
    let shapes = results
        .into_inner()
        .unwrap_or_else(PoisonError::into_inner)
        .into_iter()
        .zip(&config.meshes)
        .map(|(slot, path)| {
            slot.unwrap_or_else(|| {
                let mut r = ShapeResult::new(path, config);
                r.error = Some("the worker running this shape stopped (a bug)".into());
                r
            })
        })
        .collect();
    Ok(ShapeStudy {
        config: config.clone(),
        shapes,
        seconds: start.elapsed().as_secs_f64(),
    })
}

impl ShapeResult {
    /// An empty result for `path`: name, collection and material from the catalog.
    fn new(path: &Path, config: &ShapeStudyConfig) -> Self {
        let name = mesh_name(path);
        let entry = catalog_entry(&name);
        ShapeResult {
            title: entry.map_or_else(
                || {
                    path.file_stem()
                        .map_or(name.clone(), |s| s.to_string_lossy().into())
                },
                |e| e.title.into(),
            ),
            collection: entry.map_or(ShapeCollection::Other, |e| e.collection),
            class: entry.map(|e| e.class),
            youngs_modulus: entry
                .map_or(config.default_youngs_modulus, |e| e.class.youngs_modulus()),
            name,
            basis_points: 0,
            basis_seconds: None,
            training_seconds: None,
            fem_mesh: None,
            fem_seconds: None,
            rows: Vec::new(),
            error: None,
        }
    }

    /// The shape's material.
    pub fn material(&self) -> MaterialSample {
        MaterialSample {
            youngs_modulus: self.youngs_modulus,
            poisson_ratio: SHAPE_POISSON_RATIO,
            density: SHAPE_DENSITY,
        }
    }
}

/// Runs one shape; every failure ends up in the result.
fn run_shape(path: &Path, config: &ShapeStudyConfig, progress: &TerminalProgress) -> ShapeResult {
    let mut result = ShapeResult::new(path, config);
    let start = Instant::now();
    progress.status(format!(
        "{}: E = {:e} Pa ({})",
        result.name,
        result.youngs_modulus,
        result.class.map_or("not catalogued", MaterialClass::name)
    ));
    if let Err(e) = run_shape_into(path, config, progress, &mut result) {
        result.error = Some(failure_chain(&e));
    }
    progress.status(format!(
        "{}: done in {:.1} s{}",
        result.name,
        start.elapsed().as_secs_f64(),
        result
            .error
            .as_ref()
            .map_or(String::new(), |e| format!(" ({e})"))
    ));
    result
}

/// The body of [`run_shape`], filling `result` as it goes so that what was measured before a
/// failure stays.
fn run_shape_into(
    path: &Path,
    config: &ShapeStudyConfig,
    progress: &TerminalProgress,
    result: &mut ShapeResult,
) -> Result<(), EvalError> {
    let surface = read_triangle_mesh(path)?.normalized().0;
    let length = surface.bounding_box().largest_side();
    let material = result.material();
    let lame = material.lame_parameters().map_err(EvalError::Material)?;
    let settings = &config.settings;

    let basis_start = Instant::now();
    let basis_points = sample_on(&surface, settings.basis_points, "basis points")?;
    let lames = vec![lame; basis_points.len()];
    let (ours, _, _) =
        build_basis(&basis_points, &lames, &settings.basis_params()).map_err(EvalError::Basis)?;
    result.basis_points = basis_points.len();
    result.basis_seconds = Some(basis_start.elapsed().as_secs_f64());

    let simplicits = match &config.simplicits {
        Some(params) => {
            let params = SimplicitsParams {
                modes: settings.modes,
                ..*params
            };
            let model = model_path(
                &config.cache_dir,
                "simplicits",
                "simplicits shape",
                SIMPLICITS_FORMAT_VERSION,
                &format!("{params:?}"),
                &basis_points,
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
                train_cached_simplicits(&basis_points, &lames, &params, &model, progress)?.trained
            };
            result.training_seconds = Some(trained.report.seconds);
            Some(trained.field)
        }
        None => None,
    };

    let (lattice_mesh, report) = mesh_for_fem(&surface, &config.fem)?;
    // Islands the lattice cut off from the body would fall freely in the FEM reference.
    let (tets, summary) = FemMeshSummary::largest_piece(&lattice_mesh, &report, length);
    result.fem_mesh = Some(summary);
    let points = sample_on(&surface, settings.simulation_points, "simulation points")?;
    let cells = summary.cells_across;
    let finer_cells = (1.5 * length / report.cell_size).round() as usize;
    // The largest piece of the lattice mesh at `cells` across, on a condition's own lattice.
    let lattice_mesh = |cells: usize, condition: &ConditionLattice| -> Result<TetMesh, EvalError> {
        let params = config.fem.lattice_through(cells, length, condition);
        let (mesh, report) = tetrahedralize(&surface, &params).map_err(EvalError::FemMesh)?;
        Ok(FemMeshSummary::largest_piece(&mesh, &report, length).0)
    };
    // The shape's finer mesh, built when the first condition on the shape's mesh needs it (on
    // graded lattices every condition has a lattice of its own).
    let mut shape_finer: Option<TetMesh> = None;

    let mut fem_seconds = 0.0;
    for &boundary in &config.boundaries {
        let mut row = ShapeRow {
            boundary,
            fem: None,
            ours: None,
            simplicits: None,
            exact: None,
            exact_error: None,
            exact_kernel_coverage: None,
            reference_change: None,
            reference_check: None,
            reference_check_error: None,
            fem_mesh: None,
            region_points: Vec::new(),
            error: None,
        };
        let scene = boundary.scene(&surface, tets.vertices(), &config.boundary);
        let label = format!("{} {}", result.name, boundary.title());
        // The reference on its own lattice (the held slabs' faces on vertex planes, the pulled
        // patches' edges refined), if asked. (Finer by 1.5× the cells of its own mesh, which
        // may be finer than the shape's when its lattice at the shape's cells loses volume.)
        let condition = config.fem.condition_lattice(boundary, &scene);
        let aligned = (!condition.is_plain()).then(|| {
            let (tets, summary, cells) =
                mesh_through(&surface, &config.fem, cells, length, &condition)?;
            row.fem_mesh = Some(summary);
            let finer_cells = (1.5 * cells as f64).round() as usize;
            let finer = config
                .check_convergence
                .then(|| lattice_mesh(finer_cells, &condition))
                .transpose()?;
            Ok::<_, EvalError>((tets, finer))
        });
        let aligned = match aligned.transpose() {
            Ok(aligned) => aligned,
            Err(e) => {
                row.error = Some(failure_chain(&e));
                result.rows.push(row);
                continue;
            }
        };
        if aligned.is_none() && config.check_convergence && shape_finer.is_none() {
            match lattice_mesh(finer_cells, &ConditionLattice::default()) {
                Ok(mesh) => shape_finer = Some(mesh),
                Err(e) => {
                    row.error = Some(failure_chain(&e));
                    result.rows.push(row);
                    continue;
                }
            }
        }
        let (tets, finer) = match &aligned {
            Some((tets, finer)) => (tets, finer.as_ref()),
            None => (&tets, shape_finer.as_ref()),
        };
        let problem = |tets: &TetMesh| FemProblem {
            tets: tets.clone(),
            order: config.fem.order,
            material,
            scene: &scene,
            time_step: config.boundary.time_step,
            newton: config.fem.newton_for(boundary, result.youngs_modulus),
            tangent: config.fem.tangent,
            ordering: FillReducingOrdering::default(),
            failed_step_halvings: config.fem.failed_step_halvings,
            steps: config.boundary.steps,
        };
        let outcome = reference_run(&problem(tets), &label, config, progress).and_then(|fem| {
            fem_seconds += fem.seconds_per_step * config.boundary.steps as f64;
            row.fem = Some(FemRunSummary::of(&fem, length));
            fem.check_converged(config.fem.newton.max_iterations)?;
            if let Some(finer) = finer {
                let label = format!("{label} finer");
                let change =
                    reference_run(&problem(finer), &label, config, progress).and_then(|fine| {
                        row.reference_check = Some(FemRunSummary::of(&fine, length));
                        reference_change(&fem, &fine, length, config)
                    });
                match change {
                    Ok(change) => row.reference_change = Some(change),
                    Err(e) => row.reference_check_error = Some(failure_chain(&e)),
                }
            }
            let run = BoundaryRun {
                points: &points,
                material,
                scene: &scene,
                params: settings.simulation_params(config.boundary.time_step),
                quadrature: settings.quadrature,
                cache_dir: &config.cache_dir,
                fem: &fem,
                steps: config.boundary.steps,
                length,
                label: &label,
                progress,
            };
            let (scores, region_points) = run.score(&ours, "FreeForm", PinHold::Penalty)?;
            row.ours = Some(scores);
            row.region_points = region_points;
            if let Some(radii) = config.exact_pins {
                match run_exact(&run, &ours, &basis_points, &lames, settings, radii) {
                    Ok((scores, coverage)) => {
                        row.exact = Some(scores);
                        row.exact_kernel_coverage = Some(coverage);
                    }
                    Err(e) => row.exact_error = Some(failure_chain(&e)),
                }
            }
            if let Some(net) = &simplicits {
                let baseline = BoundaryRun {
                    quadrature: config.simplicits_quadrature.unwrap_or(run.quadrature),
                    ..run
                };
                row.simplicits = Some(baseline.score(net, "Simplicits", PinHold::Penalty)?.0);
            }
            Ok(())
        });
        if let Err(e) = outcome {
            row.error = Some(failure_chain(&e));
        }
        result.rows.push(row);
    }
    result.fem_seconds = Some(fem_seconds);
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

/// One boundary condition of one shape, ready to run any skinning field on.
struct BoundaryRun<'a> {
    points: &'a IntegrationPoints,
    material: MaterialSample,
    scene: &'a SceneSpec,
    params: SimulationParams,
    /// Where the elastic energy is integrated (the paper's setting: every point).
    quadrature: QuadratureRule,
    /// Where an optimized cubature is cached.
    cache_dir: &'a Path,
    fem: &'a FemRun,
    steps: usize,
    length: f64,
    label: &'a str,
    progress: &'a TerminalProgress,
}

impl BoundaryRun<'_> {
    /// Simulates `field` (labelled `method`, its regions held by `pin_hold`) at the FEM
    /// vertices and scores it; also returns the integration points in each constrained region.
    fn score<B: SkinningField + ?Sized>(
        &self,
        field: &B,
        method: &str,
        pin_hold: PinHold,
    ) -> Result<(MethodScores, Vec<usize>), EvalError> {
        let run = run_reduced(
            &ReducedProblem {
                simulation: Simulation::new(
                    field,
                    self.points,
                    &MaterialField::Uniform(self.material),
                    StableNeoHookean,
                    self.scene,
                )
                .with_params(self.params)
                .with_quadrature(self.quadrature)
                .with_cache_dir(Some(self.cache_dir))
                .with_pin_hold(pin_hold),
                output_points: self.fem.vertices(),
                steps: self.steps,
            },
            &format!("{method} {}", self.label),
            self.progress,
        )?;
        let scores = self.fem.score(field, &run.frames, self.length)?;
        let scores = MethodScores {
            mse: scores.errors.normalized_mse,
            max: scores.errors.normalized_max,
            fitting_residual: scores.fitting_residual,
            ms_per_step: run.report.ms_per_step,
            quadrature_points: run.report.quadrature.points,
            unconverged_steps: run.report.unconverged_steps,
            max_pin_deviation: match pin_hold {
                PinHold::Penalty => run.report.max_pin_deviation,
                PinHold::Exact { .. } | PinHold::Weighted { .. } => run.report.max_held_deviation,
            },
        };
        Ok((scores, run.report.region_points))
    }
}
