//! One particle baseline with its options — the choice the beam study and the bench make per
//! run, and the one place that dispatches to the MPM or the SPH runner.

use std::path::Path;

use crate::EvalError;
use crate::beam_scenario::{BEAM_TIME_STEP, BeamTest};
use crate::particle_baselines::mpm::{MpmStudyConfig, run_mpm_beam};
use crate::particle_baselines::particle_baseline::{ParticleBeamRun, ParticleMethod};
use crate::particle_baselines::sph::{SphStudyConfig, run_sph_beam};
use freeform::fem_reference::FemRun;
use freeform::terminal_progress::TerminalProgress;

/// SPH's implicit step per particle, in MPM particle substeps' worth of time: a coarse weight
/// that only orders the runs (measured on the beam: an SPH particle step 8.6 µs at 5 000
/// particles and 23 µs at 40 000, an MPM particle substep 0.7 µs, i.e. 12–32×).
const SPH_STEP_COST: f64 = 50.0;

/// MPM or SPH, with its options.
#[derive(Clone, Copy, Debug)]
pub enum ParticleConfig<'a> {
    /// The MPM baseline.
    Mpm(&'a MpmStudyConfig),
    /// The SPH baseline.
    Sph(&'a SphStudyConfig),
}

impl ParticleConfig<'_> {
    /// Which method.
    pub fn method(&self) -> ParticleMethod {
        match self {
            ParticleConfig::Mpm(_) => ParticleMethod::Mpm,
            ParticleConfig::Sph(_) => ParticleMethod::Sph,
        }
    }

    /// The spacings the study runs (m).
    pub fn spacings(&self) -> &[f64] {
        match self {
            ParticleConfig::Mpm(c) => &c.spacings,
            ParticleConfig::Sph(c) => &c.spacings,
        }
    }

    /// A relative cost of one 0.01 s frame at `spacing` (particles on the 5 m beam's unit
    /// volume × solver steps per frame, SPH's weighted by `SPH_STEP_COST`), to run the cheap
    /// ones first.
    pub fn cost_per_frame(&self, spacing: f64) -> f64 {
        match self {
            ParticleConfig::Mpm(c) => {
                (c.particles_per_cell.max(1) as f64 / spacing).powi(3)
                    * (BEAM_TIME_STEP / c.time_step)
            }
            ParticleConfig::Sph(c) => SPH_STEP_COST * c.substeps as f64 / spacing.powi(3),
        }
    }

    /// Runs (or loads) the method on `test` for `steps` frames at `spacing`, scored against
    /// `reference` ([`run_mpm_beam`], [`run_sph_beam`]).
    ///
    /// # Errors
    /// The runner's.
    pub fn run(
        &self,
        test: BeamTest,
        spacing: f64,
        steps: usize,
        reference: &FemRun,
        cache_dir: &Path,
        progress: &TerminalProgress,
    ) -> Result<ParticleBeamRun, EvalError> {
        match self {
            ParticleConfig::Mpm(c) => {
                run_mpm_beam(test, spacing, c, steps, reference, cache_dir, progress)
            }
            ParticleConfig::Sph(c) => {
                run_sph_beam(test, spacing, c, steps, reference, cache_dir, progress)
            }
        }
    }
}
