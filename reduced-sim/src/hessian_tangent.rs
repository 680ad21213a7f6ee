//! Which material tangent the Newton Hessian of a step uses.
//!
//! Projected Newton clamps each point's negative tangent eigenvalues to zero
//! ([`Tangent::ProjectedPsd`]), which keeps every Hessian positive semidefinite but makes it
//! *stiffer* than the true one wherever the material is compressed or buckling. The Newton
//! step then falls short of the minimum and the solve converges only linearly: the armadillo
//! of the container example, landing on a floor alone, took 8.0 Hessians a step at a steady
//! 0.72 contraction per iteration. The exact tangent converges quadratically, but its Hessian
//! can be indefinite far from equilibrium. [`HessianTangent::ExactWhenDefinite`] takes the
//! exact Hessian of the whole step (inertia included, which usually makes it definite) and
//! projects only when Cholesky fails on it, the "projection on demand" of Longva et al.,
//! *Pitfalls of Projection* (2023): the armadillo took 3.8 Hessians a step, the container
//! example 12.3 instead of 14.7.
//!
//! Against the converged FEM on the beam (`eval/examples/fast_step.rs --exact-when-definite`,
//! 2026-11-24): Bend is unchanged (one Hessian a step either way, MSE equal to 3 digits); Twist,
//! with its large rotations, takes 3.4 instead of 6.8 Hessians a step at m = 16 (every point,
//! fresh Hessians: 125 → 46 ms/step) and 3.7 instead of 7.8 at m = 32 on the cubature (one
//! unconverged step → none), the MSE equal to 4 digits (the two trajectories 1e-11 apart).
//! Hence the default; [`HessianTangent::ProjectedPsd`] stays the paper's setting.
//! [`HessianTangent::ExactElseAbsolute`] falls back to the absolute-eigenvalue tangent (Chen et
//! al. 2024) instead of the projected one; it is not measured on the reduced simulator (on the
//! FEM references it did not pay: `fem_ref::FemParams::tangent`).

pub use hyperelastic::HessianTangent;

/// A step objective made of incremental potentials (one object's, or a group's side by side)
/// whose tangents a retry in the paper's setting switches
/// ([`crate::simulator::solve_step`]).
pub(crate) trait StepTangents {
    /// The potentials' tangents, in order.
    fn tangents(&self) -> Vec<HessianTangent>;
    /// Sets them, in the same order.
    fn set_tangents(&mut self, tangents: &[HessianTangent]);
}
