//! The beam experiments of design §4.1: a 5 m × 1 m × 1 m beam, E = 5 MPa, ν = 0.45,
//! ρ = 1000 kg/m³, h = 0.01 s; Bend (gravity, x ≤ 0.5 pinned, 300 steps) and Twist (x ≤ 0.5
//! pinned, x ≥ 4.5 rotated about the beam axis by min(2160°/s · t, 720°), 30 steps: 648° at
//! t = 0.30 s, before the twisted beam buckles).
//!
//! - [`study`]: Tables 1, 5, 6's run (ours and Simplicits against the FEM at each m);
//!   [`tables`]: their rendering; [`reduced`]: the beam's basis and integration points;
//!   [`simplicits`]: the Simplicits baseline trained (and cached) on the beam; [`mpm`]: the MPM
//!   baseline run (and cached) on the beam.

pub mod mpm;
pub mod particle_baseline;
pub mod particle_config;
pub mod reduced;
pub mod simplicits;
pub mod sph;
pub mod study;
pub mod tables;

pub use crate::beam_scenario::{
    BEAM_MAX, BEAM_MIN, BEAM_TIME_STEP, BeamTest, beam_basis_grid, beam_grid_spacing, beam_material,
};
