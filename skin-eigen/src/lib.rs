#![doc = include_str!("../README.md")]

pub mod assembly;
pub mod basis_builder;
mod build_point_weights;
pub mod generalized_eigen;
pub mod held_material;
pub mod interface_weights;
pub mod pool_convergence;
pub mod region_constraints;
pub mod region_weight;
pub mod shared_shape_functions;
pub mod skinning_basis;
pub mod sparse_assembly;
pub mod subspace_iteration;
pub mod weighted_basis;

pub use assembly::{AssemblyError, WeightSpaceMatrices, assemble_weight_space_matrices};
pub use basis_builder::{
    AssembledMatrices, BasisError, BasisParams, BasisReport, BasisStage, DENSE_SOLVER_MAX_KERNELS,
    EigenSolverChoice, HeldRegionsReport, PhaseTimings, build_basis, build_basis_observed,
    build_basis_with_regions,
};
pub use generalized_eigen::{
    EigenError, EigenParams, EigenSolution, largest_eigenvalue_on_range, solve_skinning_modes,
};
pub use held_material::HeldMaterial;
pub use interface_weights::{
    WeightInterface, build_basis_with_interface, build_basis_with_interfaces,
};
pub use pool_convergence::{PoolConvergence, pool_convergence};
pub use region_constraints::{
    ConstrainedModes, RegionConstraintParams, RegionError, solve_constrained_modes,
};
pub use region_weight::{HeldRegionShape, RegionWeight, RegionWeightError};
pub use shared_shape_functions::{
    KernelShapeFunctions, build_basis_keeping_shape_functions, build_basis_sharing,
};
pub use skinning_basis::{
    BASIS_FORMAT_VERSION, BasisFileError, BasisMetadata, SkinningBasis, SkinningWeights,
};
pub use sparse_assembly::{SparseWeightSpaceMatrices, assemble_sparse_weight_space_matrices};
pub use subspace_iteration::{SubspaceParams, solve_skinning_modes_iteratively};
pub use weighted_basis::{build_weighted_basis, build_weighted_basis_sharing};
