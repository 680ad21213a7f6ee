//! Tables 2 and 7 (design §4.2): every mesh of a folder under Drop and Fix side, ours and
//! Simplicits against a FEM reference of the same mesh.
//!
//! - [`catalog`]: the shared meshes' names and materials; [`boundary`]: the two boundary
//!   conditions on any shape; [`reference`](mod@reference): the FEM mesh of a shape; [`study`]: the run;
//!   [`tables`]: the rendering.

pub mod boundary;
pub mod catalog;
pub mod reference;
pub mod study;
pub mod tables;
