//! What the particle baselines of Tables 1 and 5 (MPM and SPH) report on the
//! beam, and how a run of either is scored against the FEM.

use std::path::Path;

use artifact::{load_framed, save_framed};
use nalgebra::Vector3;
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

use crate::EvalError;
use crate::beam_scenario::{BeamTest, beam_length_scale};
use crate::report::paper;
use freeform::fem_reference::FemRun;
use freeform::metrics::{per_frame_mse, trajectory_errors};
use freeform::terminal_progress::TerminalProgress;

/// Which particle method.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ParticleMethod {
    /// Explicit APIC MPM (warp-mpm's scheme).
    Mpm,
    /// Implicit corotated SPH (Kugelstadt et al. 2021, SPlisHSPlasH's).
    Sph,
}

impl ParticleMethod {
    /// "MPM" or "SPH".
    pub fn label(self) -> &'static str {
        match self {
            ParticleMethod::Mpm => "MPM",
            ParticleMethod::Sph => "SPH",
        }
    }

    /// "mpm" or "sph" (JSON, CSV).
    pub fn key(self) -> &'static str {
        match self {
            ParticleMethod::Mpm => "mpm",
            ParticleMethod::Sph => "sph",
        }
    }

    /// The name of the method's spacing: the MPM grid's Δx, the SPH particles' spacing.
    pub fn spacing_name(self) -> &'static str {
        match self {
            ParticleMethod::Mpm => "Δx",
            ParticleMethod::Sph => "spacing",
        }
    }

    /// The paper's Table 1 MSE of this method on `test` (its m = 9 row).
    pub fn paper_mse(self, test: &str) -> Option<f64> {
        match self {
            ParticleMethod::Mpm => paper::table1_mpm(test),
            ParticleMethod::Sph => paper::table1_sph(test),
        }
    }

    /// The paper's Table 5 time per 0.01 s (ms, GPU).
    pub fn paper_ms(self) -> f64 {
        match self {
            ParticleMethod::Mpm => paper::TABLE5_MPM_MS,
            ParticleMethod::Sph => paper::TABLE5_SPH_MS,
        }
    }
}

/// One particle-method run of one test, scored against the FEM.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ParticleBaselineRow {
    /// MPM or SPH.
    pub method: ParticleMethod,
    /// Bend or Twist.
    pub test: BeamTest,
    /// MPM: grid spacing Δx; SPH: particle spacing (m).
    pub spacing: f64,
    /// Particles.
    pub particles: usize,
    /// Solver steps per 0.01 s frame (MPM substeps; SPH 1).
    pub substeps_per_step: usize,
    /// Normalized MSE against the FEM at its vertices; `None` for a failed run.
    pub mse: Option<f64>,
    /// Normalized max error; `None` for a failed run.
    pub max: Option<f64>,
    /// Normalized MSE of each frame 1..T (empty for a failed run).
    pub per_frame_mse: Vec<f64>,
    /// Largest distance of a particle in a constrained region from its target over the run
    /// (m): how well the method holds the regions (the FEM vertices in them are put on
    /// target like the particles).
    pub max_pin_deviation: f64,
    /// Why the run stopped early, if it did.
    pub failure: Option<String>,
    /// Frames (0.01 s steps) completed.
    pub steps_completed: usize,
    /// Wall time per 0.01 s of simulated time (ms).
    pub ms_per_step: f64,
    /// Share of the stepping time per phase, (phase, share).
    pub split: Vec<(String, f64)>,
    /// Iterations of the method's inner solver per step, if it has one (SPH: the volume
    /// solve's conjugate-gradient iterations).
    pub iterations_per_step: Option<f64>,
    /// Seconds of setup before the first step (SPH: neighbourhoods and the factorization).
    pub setup_seconds: f64,
    /// Loaded from the cache.
    pub cached: bool,
}

/// A scored particle run and its positions at the FEM vertices per frame (frame 0 = rest;
/// fewer frames than asked for when the run stopped early).
pub struct ParticleBeamRun {
    /// The scores and timings.
    pub row: ParticleBaselineRow,
    /// FEM vertex positions per frame (m).
    pub frames: Vec<Vec<Vector3<f64>>>,
}

/// A finished (or stopped) particle run as the caches keep it, before scoring.
pub(crate) struct ParticleTrajectory {
    pub(crate) method: ParticleMethod,
    pub(crate) test: BeamTest,
    pub(crate) spacing: f64,
    pub(crate) particles: usize,
    pub(crate) frames: Vec<Vec<[f64; 3]>>,
    pub(crate) failure: Option<String>,
    pub(crate) max_pin_deviation: f64,
    /// Seconds of the steps.
    pub(crate) seconds: f64,
    pub(crate) setup_seconds: f64,
    pub(crate) substeps: usize,
    pub(crate) split: Vec<(String, f64)>,
    pub(crate) iterations: Option<usize>,
    pub(crate) cached: bool,
}

/// Scores `run` against `reference` (design §4.3 metrics at the FEM vertices); a run that
/// stopped is reported and not scored.
///
/// # Errors
/// [`EvalError::Metrics`] for frames that cannot be compared.
pub(crate) fn score_particle_run(
    run: ParticleTrajectory,
    reference: &FemRun,
    progress: &TerminalProgress,
) -> Result<ParticleBeamRun, EvalError> {
    let frames: Vec<Vec<Vector3<f64>>> = run
        .frames
        .iter()
        .map(|f| f.iter().map(|p| Vector3::from(*p)).collect())
        .collect();
    let truth = reference.vertex_frames();
    let completed = frames.len() - 1;
    let (scores, per_frame) = match &run.failure {
        Some(_) => (None, Vec::new()),
        None => (
            Some(trajectory_errors(
                &frames[1..],
                &truth[1..],
                beam_length_scale(),
            )?),
            per_frame_mse(&frames[1..], &truth[1..], beam_length_scale())?,
        ),
    };
    if let Some(why) = &run.failure {
        progress.status(format!(
            "{} {} {} = {} m: not scored, stopped after {completed} steps: {why}",
            run.method.label(),
            run.test.name(),
            run.method.spacing_name(),
            run.spacing
        ));
    }
    let per_step = |x: usize| x as f64 / completed.max(1) as f64;
    let row = ParticleBaselineRow {
        method: run.method,
        test: run.test,
        spacing: run.spacing,
        particles: run.particles,
        substeps_per_step: run.substeps / completed.max(1),
        mse: scores.map(|s| s.normalized_mse),
        max: scores.map(|s| s.normalized_max),
        per_frame_mse: per_frame,
        max_pin_deviation: run.max_pin_deviation,
        failure: run.failure,
        steps_completed: completed,
        ms_per_step: 1e3 * run.seconds / completed.max(1) as f64,
        split: run.split,
        iterations_per_step: run.iterations.map(per_step),
        setup_seconds: run.setup_seconds,
        cached: run.cached,
    };
    Ok(ParticleBeamRun { row, frames })
}

/// A particle run from the cache at `path` (`magic`, `version`) when there is one that
/// `complete` accepts (all frames, or a recorded failure); a damaged entry is reported on
/// `progress` and ignored.
pub(crate) fn load_cached_run<T: DeserializeOwned>(
    path: &Path,
    magic: &[u8],
    version: u32,
    label: &str,
    progress: &TerminalProgress,
    complete: impl Fn(&T) -> bool,
) -> Option<T> {
    match load_framed::<T>(path, magic, version) {
        Ok(Some(run)) if complete(&run) => {
            progress.status(format!(
                "{label}: loaded from the cache ({})",
                path.display()
            ));
            Some(run)
        }
        Ok(_) => None,
        Err(e) => {
            progress.status(format!("ignoring a damaged cache entry: {e}"));
            None
        }
    }
}

/// Saves a particle run to the cache at `path`; a failure is reported on `progress`, not
/// returned (the run itself is not lost).
pub(crate) fn store_cached_run<T: Serialize>(
    path: &Path,
    magic: &[u8],
    version: u32,
    label: &str,
    progress: &TerminalProgress,
    run: &T,
) {
    if let Err(e) = save_framed(path, magic, version, run) {
        progress.status(format!("warning: {label} not cached: {e}"));
    }
}

/// The frames of a particle run: positions at the FEM vertices per frame (frame 0 = rest),
/// why it stopped (if it did) and the constrained particles' largest drift (m).
pub(crate) struct RecordedFrames {
    pub(crate) frames: Vec<Vec<[f64; 3]>>,
    pub(crate) failure: Option<String>,
    pub(crate) max_pin_deviation: f64,
}

/// Runs `steps` frames from the rest positions `rest`: `advance` moves the solver by one
/// 0.01 s frame and returns the vertices' positions and the pinned particles' drift, or why
/// it stopped (the recording stops there). Shows a progress bar labelled `label`.
pub(crate) fn record_frames(
    rest: &[Vector3<f64>],
    steps: usize,
    label: String,
    progress: &TerminalProgress,
    mut advance: impl FnMut() -> Result<(Vec<[f64; 3]>, f64), String>,
) -> RecordedFrames {
    let bar = progress.bar(steps, label);
    let mut recorded = RecordedFrames {
        frames: vec![as_arrays(rest)],
        failure: None,
        max_pin_deviation: 0.0,
    };
    for _ in 0..steps {
        match advance() {
            Ok((positions, drift)) => {
                recorded.max_pin_deviation = recorded.max_pin_deviation.max(drift);
                recorded.frames.push(positions);
            }
            Err(why) => {
                recorded.failure = Some(why);
                break;
            }
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    recorded
}

/// Positions as plain arrays (the caches' format).
pub(crate) fn as_arrays(positions: &[Vector3<f64>]) -> Vec<[f64; 3]> {
    positions.iter().map(|v| [v.x, v.y, v.z]).collect()
}
