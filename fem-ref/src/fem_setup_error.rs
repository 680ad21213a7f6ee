//! Why a FEM simulation cannot be set up.

use thiserror::Error;

/// The scene does not fit the model, or the system cannot be set up.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum FemSetupError {
    /// A Dirichlet node index is out of range.
    #[error("Dirichlet region {region} names node {node}, but the mesh has {nodes} nodes")]
    NodeOutOfRange {
        /// Region.
        region: usize,
        /// Bad index.
        node: usize,
        /// Node count.
        nodes: usize,
    },
    /// Gravity or the floor is not finite, or the floor normal is zero.
    #[error("invalid scene: {0}")]
    InvalidScene(String),
    /// Every node is fixed.
    #[error("every node is fixed by Dirichlet conditions: nothing to solve")]
    NothingFree,
    /// The time step is not finite and positive.
    #[error("the time step must be finite and positive, got {0} s")]
    InvalidTimeStep(f64),
    /// The sparse symbolic analysis failed (out of memory).
    #[error("sparse symbolic analysis failed: {0}")]
    Symbolic(String),
    /// The sparse Cholesky factors would need more memory than [`crate::FemParams::factor_memory`]
    /// allows (found by the symbolic analysis, before any numeric work).
    #[error(
        "the FEM's Cholesky factors of {dofs} DOFs ({factor_nonzeros} nonzeros) need {:.1} GB, \
         more than the {:.1} GB allowed (FemParams::factor_memory)",
        *.bytes as f64 / 1e9,
        *.limit as f64 / 1e9
    )]
    FactorTooLarge {
        /// Free DOFs.
        dofs: usize,
        /// Nonzeros of one factor.
        factor_nonzeros: usize,
        /// Bytes needed: two factors (a carried or previous one and the fresh one) and the
        /// factorization's workspace.
        bytes: u64,
        /// The limit (bytes).
        limit: u64,
    },
}
