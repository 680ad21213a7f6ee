//! Tables 2 and 7 (design §4.2): every mesh of a folder under its boundary conditions, ours and
//! Simplicits against a FEM reference of the same mesh.
//!
//! - [`catalog`]: the shared meshes' names and materials; [`boundary`]: the boundary
//!   conditions on any shape; [`reference`](mod@reference): the FEM mesh of a shape;
//! - [`config`]: what the study runs; [`result`]: what it measures;
//! - [`study`]: the run over the shapes, `shape_run` one shape stage by stage,
//!   `boundary_run` one condition's reduced runs;
//! - [`stage`]: the stages a workflow engine runs as tasks, [`tasks`]: their plan and
//!   receipts, [`shard`]: their raw rows, [`merge`]: shards into one study,
//!   [`rendered_import`]: shards from tables rendered before shards existed;
//! - [`tables`]: the rendering.

pub mod boundary;
pub(crate) mod boundary_run;
pub mod catalog;
pub mod config;
pub mod merge;
pub mod reference;
pub mod rendered_import;
pub mod result;
pub(crate) mod shape_run;
pub mod shard;
pub mod stage;
pub mod study;
pub mod tables;
pub mod tasks;
