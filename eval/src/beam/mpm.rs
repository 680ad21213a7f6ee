//! The MPM baseline on the beam (Tables 1 and 5, issue 22): particles on the beam grid at
//! `particles_per_cell` per axis per grid cell, the test's scene on those particles (pinned and
//! twisted regions by particle velocity enforcement), tracers at the FEM vertices' rest
//! positions (those in a constrained region moved onto its target like the region's
//! particles, the others with the grid velocity), scored by the metrics of DESIGN 4.3. A run
//! that stops (a tracer left the material, an instability) is reported with its reason and
//! not scored. Trajectories are cached under
//! `<cache>/mpm/`: a Bend run at Δx = 0.05 m takes more than 80 min on 2 cores.

use std::path::Path;
use std::time::Instant;

use artifact::{load_framed, save_framed};
use baselines::mpm::{MpmError, MpmMaterial, MpmParams, MpmSimulator, MpmTimings};
use fem_ref::trajectory_key_builder;
use nalgebra::Vector3;
use rkpm_core::sample_box_grid;
use serde::{Deserialize, Serialize};

use crate::EvalError;
use crate::beam::study::beam_length_scale;
use crate::beam::{BEAM_MAX, BEAM_MIN, BEAM_TIME_STEP, BeamTest, beam_material};
use crate::fem_reference::FemRun;
use crate::metrics::{per_frame_mse, trajectory_errors};
use crate::progress::Progress;

/// Cache file kind and format version of an MPM beam trajectory.
const MPM_CACHE_MAGIC: &[u8] = b"FFMPMTR1";
const MPM_CACHE_VERSION: u32 = 3;

/// How the MPM baseline is run on the beam.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MpmStudyConfig {
    /// Grid spacings Δx to run (m). Default [0.1, 0.05].
    pub spacings: Vec<f64>,
    /// Particles per grid cell along each axis (2 → 8 per cell). Default 2.
    pub particles_per_cell: usize,
    /// Substep Δt (s). Default 1e-4, the paper's.
    pub time_step: f64,
    /// Elastic model. Default fixed corotated (warp-mpm's).
    pub material: MpmMaterial,
}

impl Default for MpmStudyConfig {
    fn default() -> Self {
        MpmStudyConfig {
            spacings: vec![0.1, 0.05],
            particles_per_cell: 2,
            time_step: 1e-4,
            material: MpmMaterial::FixedCorotated,
        }
    }
}

/// One particle-method run of one test, scored against the FEM.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ParticleBaselineRow {
    /// "mpm".
    pub method: String,
    /// Bend or Twist.
    pub test: BeamTest,
    /// Grid spacing Δx (m).
    pub spacing: f64,
    /// Particles.
    pub particles: usize,
    /// Substeps per 0.01 s frame.
    pub substeps_per_step: usize,
    /// Normalized MSE against the FEM at its vertices (tracers); `None` for a failed run.
    pub mse: Option<f64>,
    /// Normalized max error; `None` for a failed run.
    pub max: Option<f64>,
    /// Normalized MSE of each frame 1..T (empty for a failed run).
    pub per_frame_mse: Vec<f64>,
    /// Largest distance of a particle in a constrained region from its target over the run
    /// (m): how well particle velocity enforcement holds the regions (the tracers in them are
    /// put on target like the particles).
    pub max_pin_deviation: f64,
    /// Why the run stopped early, if it did.
    pub failure: Option<String>,
    /// Frames (0.01 s steps) completed.
    pub steps_completed: usize,
    /// Wall time per 0.01 s of simulated time (ms).
    pub ms_per_step: f64,
    /// Share of the time in stress / P2G / grid / G2P.
    pub split: [f64; 4],
    /// Loaded from the cache.
    pub cached: bool,
}

/// A scored MPM run and its tracer positions per frame (frame 0 = rest; fewer frames than
/// asked for when the run stopped early).
pub struct MpmBeamRun {
    /// The scores and timings.
    pub row: ParticleBaselineRow,
    /// Tracer (FEM vertex) positions per frame (m).
    pub frames: Vec<Vec<Vector3<f64>>>,
}

/// What the cache keeps of a run.
#[derive(Serialize, Deserialize)]
struct CachedMpmRun {
    failure: Option<String>,
    max_pin_deviation: f64,
    frames: Vec<Vec<[f64; 3]>>,
    timings: MpmTimings,
    particles: usize,
    seconds: f64,
}

/// Runs (or loads) MPM on `test` for `steps` frames at grid spacing `spacing`, with tracers at
/// `reference`'s vertices, and scores it.
///
/// # Errors
/// [`EvalError::Mpm`] from the solver (the CFL refusal, an unstable run),
/// [`EvalError::Sampling`] / [`EvalError::Scene`] for particles or regions that cannot be
/// built, [`EvalError::Metrics`] for a trajectory that cannot be scored.
pub fn run_mpm_beam(
    test: BeamTest,
    spacing: f64,
    config: &MpmStudyConfig,
    steps: usize,
    reference: &FemRun,
    cache_dir: &Path,
    progress: &Progress,
) -> Result<MpmBeamRun, EvalError> {
    let particles = sample_box_grid(
        BEAM_MIN,
        BEAM_MAX,
        spacing / config.particles_per_cell.max(1) as f64,
    )
    .map_err(|source| EvalError::Sampling {
        what: "MPM particles",
        source,
    })?;
    let scene = test.scene();
    let params = MpmParams {
        grid_spacing: spacing,
        time_step: config.time_step,
        material: config.material,
        ..MpmParams::default()
    };
    let vertices = reference.vertices();
    let mut key = trajectory_key_builder();
    key.str("mpm beam")
        .u64(MPM_CACHE_VERSION as u64)
        .str(&scene.label())
        // The run's own options only: not the list of spacings it came from.
        .str(&format!(
            "{params:?} particles_per_cell={}",
            config.particles_per_cell
        ))
        .u64(particles.len() as u64)
        .u64(steps as u64)
        .f64s(&[BEAM_TIME_STEP]);
    for v in vertices {
        key.f64s(v.as_slice());
    }
    let path = cache_dir
        .join("mpm")
        .join(format!("mpm-{}.bin", key.finish().hex()));
    let label = format!("MPM {} Δx = {spacing} m", test.name());
    let cached: Option<CachedMpmRun> = match load_framed(&path, MPM_CACHE_MAGIC, MPM_CACHE_VERSION)
    {
        Ok(run) => run,
        Err(e) => {
            progress.status(format!("ignoring a damaged cache entry: {e}"));
            None
        }
    };
    let (run, was_cached) = match cached {
        Some(run) if run.frames.len() == steps + 1 || run.failure.is_some() => {
            progress.status(format!(
                "{label}: loaded from the cache ({})",
                path.display()
            ));
            (run, true)
        }
        _ => {
            let reduced_scene = scene.reduced_scene(particles.positions())?;
            let tracer_regions = scene.reduced_scene(vertices)?.pins;
            let mut sim =
                MpmSimulator::new(&particles, &[beam_material()], &reduced_scene, params)?
                    .with_tracers(vertices, &tracer_regions)?;
            let bar = progress.bar(steps, format!("{label} ({} particles)", particles.len()));
            let start = Instant::now();
            let mut frames = vec![vertices.iter().map(|v| [v.x, v.y, v.z]).collect()];
            let mut failure = None;
            let mut max_pin_deviation: f64 = 0.0;
            for _ in 0..steps {
                if let Err(e) = sim.advance(BEAM_TIME_STEP) {
                    let at = match e {
                        MpmError::TracerLost { tracer, .. } => {
                            format!(
                                " (tracer at rest position {:?} m)",
                                vertices[tracer].as_slice()
                            )
                        }
                        _ => String::new(),
                    };
                    failure = Some(format!("{e}{at}"));
                    break;
                }
                max_pin_deviation = max_pin_deviation.max(sim.max_pin_deviation());
                frames.push(
                    sim.tracer_positions()
                        .iter()
                        .map(|v| [v.x, v.y, v.z])
                        .collect(),
                );
                bar.inc(1);
            }
            bar.finish_and_clear();
            let run = CachedMpmRun {
                failure,
                max_pin_deviation,
                frames,
                timings: *sim.timings(),
                particles: particles.len(),
                seconds: start.elapsed().as_secs_f64(),
            };
            if let Err(e) = save_framed(&path, MPM_CACHE_MAGIC, MPM_CACHE_VERSION, &run) {
                progress.status(format!("warning: {label} not cached: {e}"));
            }
            (run, false)
        }
    };
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
    let t = &run.timings;
    let total = t.total().max(f64::MIN_POSITIVE);
    if let Some(why) = &run.failure {
        progress.status(format!(
            "{label}: not scored, stopped after {completed} steps: {why}"
        ));
    }
    let row = ParticleBaselineRow {
        method: "mpm".into(),
        test,
        spacing,
        particles: run.particles,
        substeps_per_step: t.substeps / completed.max(1),
        mse: scores.map(|s| s.normalized_mse),
        max: scores.map(|s| s.normalized_max),
        per_frame_mse: per_frame,
        max_pin_deviation: run.max_pin_deviation,
        failure: run.failure.clone(),
        steps_completed: completed,
        ms_per_step: 1e3 * run.seconds / completed.max(1) as f64,
        split: [
            t.stress / total,
            t.particle_to_grid / total,
            t.grid_update / total,
            t.grid_to_particle / total,
        ],
        cached: was_cached,
    };
    Ok(MpmBeamRun { row, frames })
}
