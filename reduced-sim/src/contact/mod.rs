//! Contact: kinematic colliders (analytic shapes and meshes on keyframed paths) with their
//! signed distances, IPC's log barrier, and the contact between bodies of a multibody scene.

pub mod body_contact;
pub mod collider;
pub(crate) mod friction_smoothing;
pub(crate) mod log_barrier;
pub mod mesh_collider;
pub(crate) mod signed_distance;
