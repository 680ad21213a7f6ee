//! Reduced-order implicit elastodynamics on any skinning basis (paper Eqs. 1-2, DESIGN 3.7).
//!
//! - [`SkinningField`]: the basis trait (weights and weight gradients at points); the RKPM
//!   eigenbasis [`skin_eigen::SkinningBasis`] implements it, the neural baseline will too.
//! - [`DeformationMap`]: the LBS map `x_i(z)`, `F_i(z)` at fixed rest points, precomputed once
//!   (integration points, or output points such as FEM vertices and splat centers).
//! - [`ReducedModel`]: integration points with volumes and materials, and the constant reduced
//!   mass matrix; [`ReducedModel::elastic_energy`] with its gradient and Hessian.
//! - [`Scene`]: gravity, pinned/moving regions, a floor; [`PenaltyParams`] for their stiffness;
//!   [`Scene::held`] regions are held exactly instead (with a basis built for them).
//! - [`Simulator`]: backward Euler, each step minimized by the workspace's one Newton solver
//!   ([`optimize::minimize`]); one [`optimize::NewtonReport`] per step.
//! - [`Collider`]: kinematic shapes on keyframed paths (sphere, box, capsule, closed triangle
//!   mesh [`MeshShape`]) that push and rub the object.
//! - [`MultiBodySimulator`]: several objects, each a [`Simulator`], in contact through samples
//!   on their surfaces ([`BodyContactParams`]: penalty or IPC barrier, friction); objects in
//!   contact are solved together, the others alone.
//!
//! Units: SI throughout (m, s, kg, Pa, J). z is dimensionless (its translation entries are m).
//!
//! ```no_run
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! use hyperelastic::StableNeoHookean;
//! use nalgebra::Vector3;
//! use reduced_sim::{PinTarget, PinnedRegion, ReducedModel, Scene, SimulationParams, Simulator};
//! # let (basis, points, materials): (skin_eigen::SkinningBasis, rkpm_core::IntegrationPoints,
//! #     Vec<hyperelastic::MaterialSample>) = todo!();
//! let model = ReducedModel::new(&basis, &points, &materials, StableNeoHookean)?;
//! let pinned = model.points_where(|x| x.x <= 0.5);
//! let scene = Scene {
//!     gravity: Some(Vector3::new(0.0, -9.8, 0.0)),
//!     pins: vec![PinnedRegion { points: pinned, target: PinTarget::Rest }],
//!     floor: None,
//!     held: Vec::new(),
//!     colliders: Vec::new(),
//! };
//! let mut sim = Simulator::new(model, &scene, SimulationParams::default())?;
//! for _ in 0..100 {
//!     let report = sim.step()?;
//!     assert!(report.converged());
//! }
//! # Ok(()) }
//! ```

#[cfg(test)]
mod analytic_field;
pub mod body_contact;
pub mod collider;
mod contact_friction;
pub mod cubature;
mod cubature_gram;
pub mod deformation_map;
pub mod elastic_energy;
mod held_regions;
pub mod hessian_tangent;
pub mod incremental_potential;
mod log_barrier;
pub mod mesh_collider;
pub mod multibody;
pub mod quadrature;
pub mod reduced_coordinates;
pub mod reduced_model;
pub mod scene;
mod scene_terms;
pub mod simulator;
pub mod skinning_field;

pub use body_contact::{BodyContactModel, BodyContactParams};
pub use collider::{
    Collider, ColliderShape, Keyframe, SignedDistance, chain_defect, collider_poses,
};
pub use cubature::{CubatureError, CubatureParams, CubatureReport, optimize_cubature};
pub use deformation_map::{DeformationMap, DeformationMapError};
pub use hessian_tangent::HessianTangent;
pub use incremental_potential::IncrementalPotential;
pub use mesh_collider::MeshShape;
pub use multibody::{
    Body, MultiBodyError, MultiBodyReport, MultiBodySimulator, MultiBodyStepError,
};
pub use quadrature::{ElasticQuadrature, QuadratureError, QuadratureReport, QuadratureRule};
pub use reduced_coordinates::ReducedLayout;
pub use reduced_model::{ReducedModel, ReducedModelError};
pub use scene::{
    Floor, FloorContact, PenaltyParams, PinModulus, PinTarget, PinnedRegion, Scene, TargetFunction,
};
pub use scene_terms::SceneError;
pub use simulator::{ReducedState, SimulationParams, Simulator, StateError, StepError};
pub use skinning_field::SkinningField;
