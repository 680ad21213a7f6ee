//! Which material tangent the Newton Hessian of a step uses.
//!
//! Projected Newton clamps each point's negative tangent eigenvalues to zero
//! ([`hyperelastic::Tangent::ProjectedPsd`]), which keeps every Hessian positive semidefinite but makes it
//! *stiffer* than the true one wherever the material is compressed or buckling, so the solve
//! converges only linearly. [`HessianTangent::ExactWhenDefinite`] (the default) takes the exact
//! Hessian of the whole step (inertia included) and projects only when its Cholesky
//! factorization fails: the "projection on demand" of Longva et al., *Pitfalls of Projection*
//! (2023). [`HessianTangent::ProjectedPsd`] is the paper's setting;
//! [`HessianTangent::ExactElseAbsolute`] falls back to the absolute-eigenvalue tangent (Chen et
//! al. 2024) instead. The measurements behind the default are in `results/RESULTS.md` ("The
//! exact-when-definite tangent").

pub use hyperelastic::HessianTangent;

/// A step objective made of incremental potentials (one object's, or a group's side by side)
/// whose tangents a retry in the paper's setting switches
/// ([`crate::step::simulator::solve_step`]).
pub(crate) trait StepTangents {
    /// The potentials' tangents, in order.
    fn tangents(&self) -> Vec<HessianTangent>;
    /// Sets them, in the same order.
    fn set_tangents(&mut self, tangents: &[HessianTangent]);
}
