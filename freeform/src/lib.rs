#![doc = include_str!("../README.md")]

// The method crates a program calls through this one, so that it depends on `freeform` alone.
pub use hyperelastic;
pub use nalgebra;
pub use reduced_sim;
pub use rkpm_core;
pub use skin_eigen;

/// The repository README's Rust snippet, compiled as a doctest so that it cannot drift.
#[cfg(doctest)]
#[doc = include_str!("../../README.md")]
pub struct RepositoryReadme;

pub mod cache_dir;
pub mod collider_frames;
pub mod failure_chain;
#[cfg(feature = "fem")]
pub mod fem_reference;
pub mod frames;
pub mod geometry;
pub mod material_basis;
pub mod material_spec;
pub mod metrics;
pub mod object_scene;
mod object_setup;
pub mod pin_hold;
pub mod placement;
pub mod prelude;
pub mod pressure_space;
pub mod progress;
pub mod recorded_run;
pub mod region_cells;
pub mod runner;
pub mod scene;
pub mod scene_file;
pub mod settings_vocabulary;
pub mod simulate;
pub mod simulate_error;
pub mod spherical_harmonics;
pub mod splat_preview;
pub mod splats;
mod step_loop;
pub mod stress_field;
pub mod stress_summary;
#[cfg(feature = "terminal")]
pub mod terminal_progress;

pub use cache_dir::default_cache_dir;
pub use collider_frames::ColliderFrames;
pub use failure_chain::failure_chain;
pub use frames::FrameWriter;
pub use geometry::{Geometry, GeometryError};
pub use material_basis::{BasisBuildError, build_basis};
pub use object_scene::{ObjectSpec, ObjectSummary, ObjectsFile, ObjectsReport, simulate_objects};
pub use pin_hold::{HeldBasisError, PinHold, WeightDistance};
pub use placement::Placement;
pub use pressure_space::{PressureSpace, PressureSpaceParams};
pub use progress::{Progress, Silent};
pub use recorded_run::{RecordError, RecordedRun, run_recorded};
pub use region_cells::{
    CellSplitReport, split_cells_at_regions, split_cells_at_regions_with_origins,
};
pub use runner::{
    Frame, ObserverResult, RunError, RunReport, Simulation, StaticEquilibrium, prepare_simulator,
    prepare_simulator_for, pressure_inf_sup, run, static_equilibrium,
};
pub use scene::{Constraint, FloorSpec, Motion, Region, SceneSpec, SceneSpecError};
pub use scene_file::{
    BasisSpec, BoxSpec, GeometrySpec, MaterialRegion, MaterialSpec, SceneFile, SceneFileError,
    SimulationSpec,
};
pub use simulate::{SimulateReport, simulate_scene_file};
pub use simulate_error::SimulateError;
pub use splat_preview::{
    Camera, PreviewError, PreviewImage, PreviewParams, PreviewSplat, point_splats, points_preview,
    preview_splats, render_preview,
};
pub use splats::{SplatFileError, SplatTable};
pub use stress_field::{StressField, StressFieldError};
pub use stress_summary::StressSummary;
