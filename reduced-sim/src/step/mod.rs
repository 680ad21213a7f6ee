//! One time step: the backward-Euler incremental potential, the material tangent of its
//! Hessian, and the simulator that minimizes it step after step.

pub(crate) mod deformation_cache;
pub mod hessian_tangent;
pub mod incremental_potential;
pub mod simulator;
