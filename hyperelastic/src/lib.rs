#![doc = include_str!("../README.md")]

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
pub use material::{HyperelasticMaterial, Tangent, VolumetricPart};
#[cfg(any(test, feature = "checks"))]
pub use material_checks::{
    MaterialCheckError, MaterialCheckParams, MaterialCheckReport, check_material,
};
pub use material_sample::{MaterialField, MaterialFunction, MaterialSample, lame_parameters_of};
pub use polar_rotation::polar_rotation;
pub use psd_projection::{absolute_eigenvalues, project_to_psd};
pub use signed_svd::SignedSvd;
pub use stable_neo_hookean::StableNeoHookean;
