//! Tables 3 and 4 (design §4.4): how the basis is trained (coefficient ablations against our
//! eigenmodes and Simplicits) and how the simulation points are sampled (grid or random).
//!
//! - [`study`]: the run; [`coefficients`]: the Table 3 coefficient networks trained on the
//!   beam (cached); [`tables`]: the rendering.

pub mod coefficients;
pub mod study;
pub mod tables;
