//! What the shapes study measures: per (shape, boundary condition) a [`ShapeRow`] with each
//! method's [`MethodScores`] and the FEM run's [`FemRunSummary`]; per shape a [`ShapeResult`];
//! the whole [`ShapeStudy`], which Tables 2 and 7 render.

use std::path::Path;

use hyperelastic::MaterialSample;
use rkpm_core::CoverageReport;
use serde::{Deserialize, Serialize};

use crate::shapes::boundary::ShapeBoundary;
use crate::shapes::catalog::{
    MaterialClass, SHAPE_DENSITY, SHAPE_POISSON_RATIO, ShapeCollection, catalog_entry,
};
use crate::shapes::config::ShapeStudyConfig;
use crate::shapes::reference::FemMeshSummary;
use freeform::fem_reference::{FemRun, ReferenceEstimate};

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
    pub(crate) fn of(fem: &FemRun, length: f64) -> Self {
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
    /// ([`crate::shapes::reference::ShapeFemParams::clamp_on_lattice_plane`],
    /// [`crate::shapes::reference::ShapeFemParams::pull_slabs_on_lattice_planes`]) or refined along the pulled regions'
    /// edges ([`crate::shapes::reference::ShapeFemParams::refine_pulled_patch_edges`],
    /// [`crate::shapes::reference::ShapeFemParams::refine_pulled_slab_faces`]). `None`: the shape's mesh.
    #[serde(default)]
    pub fem_mesh: Option<FemMeshSummary>,
    /// What the reference needs (DOFs, factor memory), when estimated
    /// ([`crate::shapes::study::estimate_references`]; no run or score made).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference_estimate: Option<ReferenceEstimate>,
    /// What the convergence check's finer reference needs, when estimated.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub check_estimate: Option<ReferenceEstimate>,
    /// Reduced integration points in each constrained region.
    pub region_points: Vec<usize>,
    /// Why something is missing.
    pub error: Option<String>,
}

impl ShapeRow {
    /// The row of `boundary` before anything is measured: no runs, no scores, no errors.
    pub fn new(boundary: ShapeBoundary) -> Self {
        ShapeRow {
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
            reference_estimate: None,
            check_estimate: None,
            region_points: Vec::new(),
            error: None,
        }
    }
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
    /// for the study [`crate::shapes::study::run_shape_study`] returns, the shapes still to come in the one it hands
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

impl ShapeStudy {
    /// The rows of shapes in `shapes` that no run attempted, as "name (Condition)" in table
    /// order: none for a study one process ran (every shape it finished has a row for every
    /// condition, or failed as a whole), the rows no shard held in one
    /// [`crate::shapes::merge::merge_shards`] put together.
    pub fn unfinished_rows(&self) -> Vec<String> {
        self.shapes
            .iter()
            .filter(|s| s.error.is_none())
            .flat_map(|s| {
                self.config
                    .boundaries
                    .iter()
                    .filter(|&&b| !s.rows.iter().any(|r| r.boundary == b))
                    .map(|b| format!("{} ({})", s.name, b.title()))
            })
            .collect()
    }
}

/// The name a shape goes by in the tables (and in `--only`, plans and shards): its file name.
pub fn mesh_name(path: &Path) -> String {
    path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into(),
    )
}

impl ShapeResult {
    /// An empty result for `path`: name, collection and material from the catalog.
    pub(crate) fn new(path: &Path, config: &ShapeStudyConfig) -> Self {
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
