#![doc = include_str!("../README.md")]

pub mod contact;
pub mod model;
pub mod multibody;
pub mod quadrature;
pub mod scene;
mod scene_error;
pub mod step;
pub mod terms;

pub use contact::body_contact::{BodyContactModel, BodyContactParams};
pub use contact::collider::{
    Collider, ColliderShape, Keyframe, SignedDistance, chain_defect, collider_poses,
};
pub use contact::mesh_collider::MeshShape;
pub use model::deformation_map::{DeformationMap, DeformationMapError};
pub use model::projected_dilatation::{
    INVERSION_BARRIER_START, ProjectedDilatationError, ProjectedDilatationParams,
};
pub use model::reduced_coordinates::ReducedLayout;
pub use model::reduced_model::{ReducedModel, ReducedModelError};
pub use model::skinning_field::SkinningField;
pub use multibody::{
    Body, MultiBodyError, MultiBodyReport, MultiBodySimulator, MultiBodyStepError,
};
pub use quadrature::automatic_quadrature::QuadratureChoice;
pub use quadrature::cubature::{
    CubatureBudget, CubatureError, CubatureParams, CubatureReport, CubatureStop, optimize_cubature,
};
pub use quadrature::elastic_cost::{ElasticCost, PlannedRun};
pub use quadrature::rule::{ElasticQuadrature, QuadratureError, QuadratureReport, QuadratureRule};
pub use scene::{
    Floor, FloorContact, PenaltyParams, PinModulus, PinTarget, PinnedRegion, Scene, TargetFunction,
};
pub use scene_error::SceneError;
pub use step::hessian_tangent::HessianTangent;
pub use step::incremental_potential::IncrementalPotential;
pub use step::simulator::{ReducedState, SimulationParams, Simulator, StateError, StepError};
pub use terms::{
    NitscheError, NitscheInterface, NitscheParams, NitscheReport, StepTerm, TermCheckError,
    TermCheckParams, TermCheckReport, TermPoint, check_term,
};
