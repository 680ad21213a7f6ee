//! The beam protocol every beam experiment (Tables 1, 3-6, the bench, the pin sweep, the
//! convergence study) shares, built on [`crate::beam_scenario`]:
//!
//! - [`study_config`]: a beam study's settings (m, tests, steps, FEM, baselines);
//! - [`reduced`]: the beam's basis and reduced runs;
//! - [`evaluation`]: the FEM references and a skinning field scored against them;
//! - [`failed_row`]: a run that failed, named in the tables in place of its row;
//! - [`preamble`]: the settings preamble of the beam tables.

pub mod evaluation;
pub mod failed_row;
pub mod preamble;
pub mod reduced;
pub mod study_config;
