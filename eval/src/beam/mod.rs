//! Tables 1, 5 and 6 on the beam of design §4.1 ([`crate::beam_scenario`]): [`study`] runs ours,
//! Simplicits and the particle baselines against the FEM at each m; [`tables`] renders them.

pub mod study;
pub mod tables;
