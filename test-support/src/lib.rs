//! Test helpers shared by the workspace's test suites (`publish = false`, dev-only).
//!
//! - [`fixtures`]: paths to the test data (`data/` in the repository), resolved from
//!   `CARGO_MANIFEST_DIR` so tests run from any working directory.
//! - [`finite_difference`]: central-difference checkers for gradients and Jacobians.
//! - [`strategies`]: proptest strategies for the workspace's common inputs.
//!
//! Tests must call these instead of copying helpers around (DESIGN section 2).

pub mod finite_difference;
pub mod fixtures;
pub mod strategies;
