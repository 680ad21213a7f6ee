//! What a program that simulates its own object needs, in one import:
//! `use freeform::prelude::*;` (the README's example). Each item is also at its own path.

pub use hyperelastic::{MaterialField, MaterialSample, StableNeoHookean};
pub use nalgebra::Vector3;
pub use reduced_sim::{QuadratureRule, SimulationParams};
pub use skin_eigen::{BasisParams, SkinningBasis};

pub use crate::frames::FrameWriter;
pub use crate::geometry::Geometry;
pub use crate::material_basis::build_basis;
pub use crate::pin_hold::PinHold;
pub use crate::runner::{Frame, RunReport, Simulation, run};
pub use crate::scene::{Constraint, FloorSpec, Motion, Region, SceneSpec};
pub use crate::simulate::simulate_scene_file;
