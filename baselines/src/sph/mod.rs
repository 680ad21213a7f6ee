//! The SPH solid baseline of Tables 1 and 5 (design §3.10): the implicit corotated SPH of
//! Kugelstadt et al. 2021 with zero-energy mode control, as SPlisHSPlasH runs it.
//!
//! - [`CubicSplineKernel`]: W and ∇W;
//! - [`CorrectedGradients`]: rest neighbourhoods and the corrected gradients that make F
//!   exact for affine motions;
//! - [`SphElasticity`]: the stretching, volume and zero-energy-mode energies and gradients;
//! - [`RestVolume`]: the volumes the energies are integrated with;
//! - [`StretchingSystem`]: the constant matrix of the stretching solve, factored once;
//! - [`ParticleInterpolation`]: particle displacements carried to other points (probes);
//! - [`SphSimulator`]: the step.
//!
//! ```
//! use baselines::sph::{SphParams, SphSimulator};
//! use hyperelastic::MaterialSample;
//! use nalgebra::Vector3;
//! use reduced_sim::Scene;
//! use rkpm_core::sample_box_grid;
//!
//! // A 0.2 m jelly cube of 0.05 m particles falling for 0.05 s: no elastic force acts on a
//! // rigid drop, so v = g t.
//! let points = sample_box_grid(Vector3::zeros(), Vector3::repeat(0.2), 0.05)?;
//! let material = MaterialSample { youngs_modulus: 1e5, poisson_ratio: 0.3, density: 1000.0 };
//! let scene = Scene { gravity: Some(Vector3::new(0.0, -9.8, 0.0)), ..Scene::default() };
//! let mut sim = SphSimulator::new(&points, &[material], &scene, SphParams::default())?;
//! for _ in 0..5 {
//!     sim.step()?;
//! }
//! let v = sim.linear_momentum() / sim.masses().iter().sum::<f64>();
//! assert!((v.y + 0.49).abs() < 1e-9);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod conjugate_gradients;
pub mod corrected_gradients;
pub mod cubic_spline;
pub mod elasticity;
pub mod interpolation;
pub mod rest_volume;
pub mod simulator;
pub mod stretching_system;

pub use corrected_gradients::CorrectedGradients;
pub use cubic_spline::CubicSplineKernel;
pub use elasticity::{SphElasticity, VolumeHessian};
pub use interpolation::ParticleInterpolation;
pub use rest_volume::RestVolume;
pub use simulator::{SphError, SphParams, SphSimulator, SphTimings, particle_spacing};
pub use stretching_system::StretchingSystem;
