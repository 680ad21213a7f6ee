//! Implicit reduced-order elastodynamics on any skinning basis (paper Eqs. 1-2, DESIGN 3.7).
//!
//! Will hold: the basis trait, the linear-blend-skinning deformation map, the reduced model
//! (integration points, reduced mass matrix) and the backward-Euler Newton integrator with
//! gravity, pin and floor terms. Not built yet (see the reduced-sim issue).
