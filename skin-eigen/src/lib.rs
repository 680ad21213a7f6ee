//! Skinning eigenmodes from RKPM shape functions (paper Sec. 3.2, Prop. 1, Eqs. 14-15;
//! DESIGN 3.4-3.5).
//!
//! From `rkpm-core` shape functions at integration points and `hyperelastic` Lamé parameters:
//! assemble the K×K mass matrix 𝓜 and weight-space Hessian H_w, solve `H_w c = λ𝓜c` for the
//! m + 1 smallest pairs, drop the constant mode, and wrap the rest as a [`SkinningBasis`] that
//! evaluates `W(X)` and `∇W(X)` anywhere (constant handle first) and saves/loads itself.
//!
//! Status: the dense eigen path (K up to a few thousand). The iterative solver for larger K
//! is not built yet.

pub mod assembly;
pub mod basis_builder;
pub mod generalized_eigen;
pub mod skinning_basis;

pub use assembly::{AssemblyError, WeightSpaceMatrices, assemble_weight_space_matrices};
pub use basis_builder::{BasisError, BasisParams, BasisReport, PhaseTimings, build_basis};
pub use generalized_eigen::{EigenError, EigenParams, EigenSolution, solve_skinning_modes};
pub use skinning_basis::{
    BASIS_FORMAT_VERSION, BasisFileError, BasisMetadata, SkinningBasis, SkinningWeights,
};
