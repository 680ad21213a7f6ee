//! One Newton solver for the workspace (DESIGN 2, 3.7, 3.8): minimizes any objective that
//! owns its energy, gradient, Hessian assembly, factorization and solve, with an Armijo
//! backtracking line search and a convergence test that first tries the last factorization
//! (a lagged-Hessian step: gradient only, no assembly).
//!
//! Both simulators use it: `reduced-sim` for the reduced backward-Euler step (dense Cholesky
//! of a 12(m+1)-square Hessian) and `fem-ref` for the FEM reference (sparse Cholesky on the
//! free DOFs). A user's own solver plugs in by implementing [`NewtonObjective`].
//!
//! - [`mod@nnls`]: non-negative least squares (Lawson–Hanson), for cubature weights.
//! - [`NewtonObjective`]: what an objective provides.
//! - [`minimize`]: the solver; [`NewtonParams`] in, [`NewtonReport`] out, [`NewtonError`]
//!   when it cannot go on; [`minimize_reusing`] carries the Hessian factorization from one
//!   solve to the next ([`HessianReuse`]).

pub mod newton;
pub mod nnls;
mod subset_cholesky;

pub use newton::{
    CarriedFactor, HessianReuse, NewtonError, NewtonObjective, NewtonParams, NewtonReport,
    NewtonStop, NewtonTimings, minimize, minimize_reusing,
};
pub use nnls::{NnlsError, NnlsParams, NnlsSolution, NnlsWarmStart, nnls, nnls_normal};
