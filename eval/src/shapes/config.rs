//! What the shapes study runs ([`ShapeStudyConfig`]): the meshes, the reduced settings, the
//! boundary conditions, the FEM reference's mesh, the baseline, the quality gate.

use std::path::PathBuf;

use baselines::SimplicitsParams;
use reduced_sim::QuadratureRule;
use serde::{Deserialize, Serialize};

use crate::reduced_settings::ReducedSettings;
use crate::shapes::boundary::{ShapeBoundary, ShapeBoundaryParams};
use crate::shapes::catalog::DEFAULT_SHAPE_YOUNGS_MODULUS;
use crate::shapes::reference::ShapeFemParams;

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
    /// many median kernel radii (a basis per condition, [`freeform::PinHold::Exact`]); `None` leaves it
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
    /// that is not cached is not computed, and its row says so ([`crate::EvalError::NotCached`]); a
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
