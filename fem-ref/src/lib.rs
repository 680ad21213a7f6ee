//! Tetrahedral finite-element ground truth (DESIGN 3.8): the reference every table's error is
//! measured against.
//!
//! - [`TetMesh`]: validated linear tet meshes; [`TetMesh::cuboid`] for boxes;
//!   [`tetrahedralize`] for the solid inside a closed triangle surface.
//! - [`FemMesh`]: P1 (4-node) or P2 (10-node) elements on a tet mesh ([`ElementOrder`]).
//! - [`FemModel`]: per-element materials (the shared `hyperelastic` models), quadrature data,
//!   consistent or lumped mass ([`MassKind`]).
//! - [`FemSimulator`]: backward Euler with Newton, line search, exact Dirichlet conditions
//!   ([`FemScene`]), sparse Cholesky with the symbolic analysis done once.
//! - [`PointInterpolation`]: positions at arbitrary points inside the mesh (e.g. the beam's tip
//!   lattice).
//! - [`TrajectoryCache`]: trajectories on disk keyed by a hash of every input
//!   ([`FemSimulator::trajectory_key`], [`FemSimulator::run_cached`]; a stored run is found
//!   from the simulator's inputs alone by [`FemSimulator::load_cached`]); a run stopped or
//!   killed part way resumes from its [`RunCheckpoint`].
//!
//! Units: SI (m, s, kg, Pa). Positions are flat `[x0, y0, z0, x1, …]` where noted.

pub mod element;
pub mod factor_memory;
pub mod fem_model;
pub mod fem_simulator;
pub mod fill_reducing_ordering;
mod kuhn_bisection;
pub mod lattice_mesher;
pub mod point_interpolation;
pub mod run_checkpoint;
mod run_keys;
pub mod scene;
mod sparse_system;
pub mod tet_mesh;
pub mod trajectory_cache;

pub use element::{ElementOrder, FemMesh};
pub use factor_memory::FactorMemoryLimit;
pub use fem_model::{FemModel, FemModelError, MassKind};
pub use fem_simulator::{
    CachedRun, DEFAULT_CHECKPOINT_INTERVAL, FEM_FACTOR_MAX_AGE, FemParams, FemRunError,
    FemSetupError, FemSimulator, RunProgress, reusing_reference_newton,
};
pub use fill_reducing_ordering::FillReducingOrdering;
pub use lattice_mesher::{
    InteriorFeature, LatticeMesherError, LatticeMesherParams, LatticeMesherReport,
    LatticeRefinement, VolumeTarget, tetrahedralize, tetrahedralize_to_volume,
};
pub use point_interpolation::{PointInterpolation, PointLocationError};
pub use run_checkpoint::{CHECKPOINT_FORMAT_VERSION, RunCheckpoint};
pub use scene::{DirichletRegion, FemFloor, FemScene, NodeTarget, NodeTargetFunction};
pub use tet_mesh::{TetMesh, TetMeshError, TetQuality};
pub use trajectory_cache::{
    TRAJECTORY_FORMAT_VERSION, Trajectory, TrajectoryCache, TrajectoryCacheError, TrajectoryKey,
    trajectory_key_builder,
};
