#![doc = include_str!("../README.md")]

pub mod element;
pub mod factor_memory;
pub mod fem_model;
pub mod fem_params;
pub mod fem_setup_error;
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
