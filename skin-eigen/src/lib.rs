//! Skinning eigenmodes from RKPM shape functions (paper Sec. 3.2, Prop. 1, Eqs. 14-15;
//! DESIGN 3.4-3.5).
//!
//! From `rkpm-core` shape functions at integration points and `hyperelastic` Lamé parameters:
//! assemble the K×K mass matrix 𝓜 and weight-space Hessian H_w, solve `H_w c = λ𝓜c` for the
//! m + 1 smallest pairs, drop the constant mode, and wrap the rest as a [`SkinningBasis`] that
//! evaluates `W(X)` and `∇W(X)` anywhere (constant handle first) and saves/loads itself.
//!
//! Two solver paths: dense (K up to a few thousand: [`assemble_weight_space_matrices`] +
//! [`solve_skinning_modes`]) and sparse iterative for larger K
//! ([`assemble_sparse_weight_space_matrices`] + [`solve_skinning_modes_iteratively`]);
//! [`build_basis`] picks by K (see [`EigenSolverChoice`]).
//!
//! For exactly held regions (issue 25), [`build_basis_with_regions`] adds one weight per region
//! and computes the modes among the weights that vanish on the regions
//! ([`solve_constrained_modes`]).

pub mod assembly;
pub mod basis_builder;
pub mod generalized_eigen;
pub mod region_constraints;
pub mod skinning_basis;
pub mod sparse_assembly;
pub mod subspace_iteration;

pub use assembly::{AssemblyError, WeightSpaceMatrices, assemble_weight_space_matrices};
pub use basis_builder::{
    AssembledMatrices, BasisError, BasisParams, BasisReport, DENSE_SOLVER_MAX_KERNELS,
    EigenSolverChoice, HeldRegionsReport, PhaseTimings, build_basis, build_basis_with_regions,
};
pub use generalized_eigen::{EigenError, EigenParams, EigenSolution, solve_skinning_modes};
pub use region_constraints::{
    ConstrainedModes, RegionConstraintParams, RegionError, solve_constrained_modes,
};
pub use skinning_basis::{
    BASIS_FORMAT_VERSION, BasisFileError, BasisMetadata, SkinningBasis, SkinningWeights,
};
pub use sparse_assembly::{SparseWeightSpaceMatrices, assemble_sparse_weight_space_matrices};
pub use subspace_iteration::{SubspaceParams, solve_skinning_modes_iteratively};
