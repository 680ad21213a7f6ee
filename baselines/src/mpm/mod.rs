//! The Material Point Method baseline of Tables 1 and 5 (design §3.10): explicit MPM with APIC
//! transfers and quadratic B-spline weights, as warp-mpm (PhysGaussian's solver) runs it.
//!
//! - [`QuadraticStencil`]: the 3 × 3 × 3 node weights and gradients of a point;
//! - [`MpmMaterial`]: fixed corotated (warp-mpm's default) or the project's stable
//!   Neo-Hookean, as Kirchhoff stress;
//! - [`BackgroundGrid`]: the per-substep node block and its slab colouring (a deterministic
//!   parallel scatter);
//! - [`MpmSimulator`]: particles, tracers, substeps, the CFL check.
//!
//! ```
//! use baselines::mpm::{MpmParams, MpmSimulator};
//! use hyperelastic::MaterialSample;
//! use nalgebra::Vector3;
//! use reduced_sim::Scene;
//! use rkpm_core::sample_box_grid;
//!
//! // A 0.2 m jelly cube, 8 particles per 0.05 m cell, falling for 0.01 s.
//! let points = sample_box_grid(Vector3::zeros(), Vector3::repeat(0.2), 0.025)?;
//! let material = MaterialSample { youngs_modulus: 1e5, poisson_ratio: 0.3, density: 1000.0 };
//! let scene = Scene { gravity: Some(Vector3::new(0.0, -9.8, 0.0)), ..Scene::default() };
//! let params = MpmParams { grid_spacing: 0.05, time_step: 1e-4, ..MpmParams::default() };
//! let mut sim = MpmSimulator::new(&points, &[material], &scene, params)?;
//! assert_eq!(sim.advance(0.01)?, 100);
//! let v = sim.linear_momentum() / sim.masses().iter().sum::<f64>();
//! assert!((v.y + 0.098).abs() < 1e-9); // free fall: v = g t
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod constitutive;
pub mod grid;
pub mod quadratic_stencil;
pub mod simulator;

pub use constitutive::{MpmMaterial, fixed_corotated_energy_density};
pub use grid::{BackgroundGrid, GridLayout, SLAB_CELLS};
pub use quadratic_stencil::{QuadraticStencil, apic_inertia};
pub use simulator::{
    MpmError, MpmParams, MpmSimulator, MpmTimings, p_wave_speed, stable_time_step,
};
