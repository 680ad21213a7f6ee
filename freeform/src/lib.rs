//! FreeForm as a library: everything a program needs to simulate its own shapes with
//! skinning eigenmodes of RKPM kernels, without the paper's experiments or the CLI.
//!
//! - [`geometry`]: a closed mesh, a point cloud or a 3DGS file ([`Geometry::read`]) → integration
//!   points ([`Geometry::integration_points`]).
//! - Bases: [`skin_eigen::build_basis`] on those points ([`skin_eigen::SkinningBasis`] saves and
//!   loads itself); any [`reduced_sim::SkinningField`] runs.
//! - [`scene`]: what acts on the object ([`SceneSpec`]: gravity, pinned and moving regions, a
//!   floor), translated for the reduced simulator and for the FEM reference alike;
//!   [`scene_file`]: the same as a TOML/JSON file with geometry, material, basis and time;
//!   [`pin_hold`]: whether the reduced simulator holds the regions by a penalty or exactly.
//! - [`runner`]: one loop ([`run`]) for any skinning field and any
//!   [`hyperelastic::HyperelasticMaterial`], handing every frame to the caller.
//! - [`frames`]: per-frame PLY and VTK ([`FrameWriter`]), with the stress of
//!   [`stress_field`] ([`StressField`]: Cauchy, principal, von Mises) when asked; [`splats`]: 3DGS files deformed
//!   (`Σ' = F Σ Fᵀ`) in their own layout ([`SplatTable`]); [`simulate`]: a scene file end to
//!   end.
//! - [`progress`]: progress reported through a trait ([`Progress`]), not a terminal type.
//!
//! Units: SI throughout (m, s, kg, Pa).
//!
//! ```no_run
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! use freeform::{FloorSpec, Geometry, SceneSpec, Simulation, run};
//! use hyperelastic::{MaterialField, MaterialSample, StableNeoHookean};
//! use nalgebra::Vector3;
//!
//! let geometry = Geometry::read("data/meshes/spot.obj".as_ref())?.normalized();
//! let points = geometry.integration_points(5000)?;
//! let material = MaterialSample { youngs_modulus: 1e5, poisson_ratio: 0.45, density: 1000.0 };
//! let lame = vec![material.lame_parameters()?; points.len()];
//! let params = skin_eigen::BasisParams::default().with_modes(16).with_kernels(400);
//! let (basis, _, _) = skin_eigen::build_basis(&points, &lame, &params)?;
//! let scene = SceneSpec {
//!     gravity: Some(Vector3::new(0.0, -9.8, 0.0)),
//!     floor: Some(FloorSpec { normal: Vector3::y(), offset: -0.5, friction: 0.3 }),
//!     ..Default::default()
//! };
//! let simulation = Simulation {
//!     field: &basis,
//!     points: &points,
//!     material: &MaterialField::Uniform(material),
//!     material_model: StableNeoHookean,
//!     scene: &scene,
//!     params: Default::default(),
//!     quadrature: Default::default(), // every point; QuadratureRule::Cubature(..) is faster
//!     cache_dir: None,
//!     pin_hold: Default::default(), // the penalty; PinHold::Exact needs a basis built for it
//! };
//! let report = run(&simulation, 100, |_frame| Ok(()))?;
//! println!("{:.2} ms per step", report.ms_per_step);
//! # Ok(()) }
//! ```

pub mod collider_frames;
pub mod frames;
pub mod geometry;
pub mod object_scene;
pub mod pin_hold;
pub mod progress;
pub mod runner;
pub mod scene;
pub mod scene_file;
pub mod simulate;
pub mod spherical_harmonics;
pub mod splat_preview;
pub mod splats;
pub mod stress_field;

pub use collider_frames::ColliderFrames;
pub use frames::FrameWriter;
pub use geometry::{Geometry, GeometryError};
pub use object_scene::{ObjectSpec, ObjectSummary, ObjectsFile, ObjectsReport, simulate_objects};
pub use pin_hold::{HeldBasisError, PinHold};
pub use progress::{Progress, Silent};
pub use runner::{Frame, ObserverResult, RunError, RunReport, Simulation, run};
pub use scene::{Constraint, FloorSpec, Motion, Region, SceneSpec, SceneSpecError};
pub use scene_file::{
    BasisSpec, BoxSpec, GeometrySpec, MaterialRegion, MaterialSpec, SceneFile, SceneFileError,
    SimulationSpec,
};
pub use simulate::{SimulateError, SimulateReport, StressSummary, simulate_scene_file};
pub use splat_preview::{
    Camera, PreviewError, PreviewImage, PreviewParams, PreviewSplat, point_splats, preview_splats,
    render_preview,
};
pub use splats::{SplatFileError, SplatTable};
pub use stress_field::{StressField, StressFieldError};
