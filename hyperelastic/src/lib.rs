//! Hyperelastic constitutive models shared by every solver (DESIGN 3.6): energy density
//! Ψ(F), first Piola-Kirchhoff stress P = ∂Ψ/∂F, the 9×9 tangent ∂P/∂F and its positive
//! semi-definite projection, per-point Lamé parameters, and Cauchy stress.
//!
//! - [`StableNeoHookean`]: the paper's material (Eq. 16), with an analytic eigensystem for the
//!   PSD projection.
//! - [`LinearElastic`]: small-strain elasticity (the Simplicits loss ramp).
//!
//! Conventions: f64, SI units (Pa), `vec(F)` column-major (see [`determinant`]).
//!
//! ```
//! use hyperelastic::{HyperelasticMaterial, LameParameters, StableNeoHookean};
//! use nalgebra::Matrix3;
//! let params = LameParameters::from_young_poisson(5e6, 0.45)?;
//! let f = Matrix3::new(1.1, 0.1, 0.0, 0.0, 0.95, 0.0, 0.0, 0.0, 1.0);
//! let psi = StableNeoHookean.energy_density(&params, &f); // J/m³
//! assert!(psi > 0.0);
//! # Ok::<(), hyperelastic::MaterialParameterError>(())
//! ```

pub mod cauchy_stress;
pub mod determinant;
pub mod hessian_tangent;
pub mod lame_parameters;
pub mod linear_elastic;
pub mod material;
#[cfg(any(test, feature = "checks"))]
pub mod material_checks;
pub mod material_sample;
pub mod polar_rotation;
pub mod psd_projection;
pub mod signed_svd;
pub mod stable_neo_hookean;

pub use cauchy_stress::{
    CauchyStressError, StressSample, cauchy_stress, principal_stresses, von_mises_stress,
};
pub use determinant::{Matrix9, cofactor, determinant_hessian};
pub use hessian_tangent::HessianTangent;
pub use lame_parameters::{LameParameters, MaterialParameterError};
pub use linear_elastic::LinearElastic;
pub use material::{HyperelasticMaterial, Tangent};
#[cfg(any(test, feature = "checks"))]
pub use material_checks::{
    MaterialCheckError, MaterialCheckParams, MaterialCheckReport, check_material,
};
pub use material_sample::{MaterialField, MaterialFunction, MaterialSample, lame_parameters_of};
pub use polar_rotation::polar_rotation;
pub use psd_projection::{absolute_eigenvalues, project_to_psd};
pub use signed_svd::SignedSvd;
pub use stable_neo_hookean::StableNeoHookean;
