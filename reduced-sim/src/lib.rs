#![doc = include_str!("../README.md")]

#[cfg(test)]
mod analytic_field;
pub mod automatic_quadrature;
pub mod body_contact;
pub mod collider;
pub mod cubature;
mod cubature_gram;
pub mod deformation_map;
pub mod elastic_cost;
pub mod elastic_energy;
pub mod elastic_quadrature;
mod held_regions;
pub mod hessian_tangent;
pub mod incremental_potential;
mod log_barrier;
pub mod mesh_collider;
pub mod multibody;
pub mod projected_dilatation;
pub mod quadrature;
pub mod reduced_coordinates;
pub mod reduced_model;
pub mod scene;
mod scene_error;
mod scene_terms;
mod signed_distance;
pub mod simulator;
pub mod skinning_field;
pub mod terms;

pub use automatic_quadrature::QuadratureChoice;
pub use body_contact::{BodyContactModel, BodyContactParams};
pub use collider::{
    Collider, ColliderShape, Keyframe, SignedDistance, chain_defect, collider_poses,
};
pub use cubature::{
    CubatureBudget, CubatureError, CubatureParams, CubatureReport, optimize_cubature,
};
pub use deformation_map::{DeformationMap, DeformationMapError};
pub use elastic_cost::{ElasticCost, PlannedRun};
pub use hessian_tangent::HessianTangent;
pub use incremental_potential::IncrementalPotential;
pub use mesh_collider::MeshShape;
pub use multibody::{
    Body, MultiBodyError, MultiBodyReport, MultiBodySimulator, MultiBodyStepError,
};
pub use projected_dilatation::{ProjectedDilatationError, ProjectedDilatationParams};
pub use quadrature::{ElasticQuadrature, QuadratureError, QuadratureReport, QuadratureRule};
pub use reduced_coordinates::ReducedLayout;
pub use reduced_model::{ReducedModel, ReducedModelError};
pub use scene::{
    Floor, FloorContact, PenaltyParams, PinModulus, PinTarget, PinnedRegion, Scene, TargetFunction,
};
pub use scene_error::SceneError;
pub use simulator::{ReducedState, SimulationParams, Simulator, StateError, StepError};
pub use skinning_field::SkinningField;
pub use terms::{
    StepTerm, TermCheckError, TermCheckParams, TermCheckReport, TermPoint, check_term,
};
