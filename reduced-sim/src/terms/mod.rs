//! The terms of a step's incremental potential besides inertia and elasticity (design §3.7),
//! each a [`StepTerm`]: gravity, the pin penalty, the floor, the colliders (by penalty or IPC's
//! barrier) and the lagged friction, and any term a user adds
//! ([`crate::Simulator::add_term`]), checked against central differences by [`check_term`];
//! the exactly held regions eliminated from Newton (`held_regions.rs`); and the scene's terms
//! built and summed in one place (`scene_terms.rs`).

pub(crate) mod collider_term;
pub(crate) mod floor_term;
pub(crate) mod friction_term;
pub(crate) mod gravity_term;
pub(crate) mod held_regions;
pub(crate) mod nitsche_params;
pub(crate) mod nitsche_pressure;
pub mod nitsche_term;
pub(crate) mod pin_penalty;
pub(crate) mod pinned_points;
pub(crate) mod scene_terms;
pub mod step_term;
pub mod term_check;

pub use nitsche_params::{NitscheError, NitscheParams, NitscheReport};
pub use nitsche_term::NitscheInterface;
pub use step_term::{StepTerm, TermPoint};
pub use term_check::{TermCheckError, TermCheckParams, TermCheckReport, check_term};
