//! The particle baselines on the beam, run or loaded from the cache through one path: the MPM
//! ([`mpm`]) and SPH ([`sph`]) runners, what a run reports ([`particle_baseline`]) and the one
//! choice of baseline and options the beam study and the bench make per run
//! ([`particle_config`]).

pub mod mpm;
pub mod particle_baseline;
pub mod particle_config;
pub mod sph;
