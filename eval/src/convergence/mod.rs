//! The convergence study: does the beam error fall as m grows? For each boundary treatment,
//! Poisson ratio ν, kernel count K and mode count m, a linear static Bend against a static FEM
//! (with the best approximations the subspace allows beside it) and the dynamic Bend and Twist
//! of Table 1 against the cached FEM references.
//!
//! Static diagnostics, at the FEM nodes N with the LBS displacement `u_h = P z` of the basis:
//!
//! ```text
//! best_l2:      z = argmin |P z − u*|²                         (L2 projection onto V_m)
//! best_energy:  z = argmin (P z − u*)ᵀ K (P z − u*) + τ |P z − u*|² + κ Σ_{i held} |P_i z − u*_i|²,
//!               τ = 1e-8 tr(PᵀKP)/tr(PᵀP),  κ = 1e4 tr(PᵀKP)/tr(PᵀP)
//! ```
//!
//! with K the FEM's stiffness at rest and the held nodes (where u* = 0) tied by κ, so the
//! projection holds the region as the Galerkin solution must (without κ it would add the rigid
//! motion that fits u* best, which the clamp forbids; τ fixes what κ leaves free). For a
//! conforming, exactly integrated model with exact held regions the Galerkin solution is this
//! projection (Ritz), so the gap between the two is what quadrature, penalty and locking cost.

//!
//! Files: `options.rs` (what varies besides m, K and ν), `config.rs` (what the study runs),
//! `result.rs` (what it measures), `nitsche_row.rs` (the static Bend held by symmetric
//! Nitsche on the free part), `pool_check.rs` (whether the basis's integration pool is
//! converged), `static_reference.rs` (the static reference, its own error against a finer FEM, and the
//! projections), `study.rs` (the run), `table.rs` (the Markdown).

mod config;
mod nitsche_row;
mod options;
mod pool_check;
mod result;
mod static_reference;
mod study;
mod table;
#[cfg(test)]
mod tests;

pub use config::ConvergenceConfig;
pub use options::{BoundaryTreatment, ConvergenceTest, VolumetricTerm};
pub use pool_check::{POOL_TOLERANCE, PoolCheckRow};
pub use result::{CoarseFemRow, ConvergenceRow, ConvergenceStudy, StaticReferenceCheck};
pub use study::run_convergence;
pub use table::convergence_table;
