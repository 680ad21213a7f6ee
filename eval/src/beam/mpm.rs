//! The MPM baseline on the beam (Tables 1 and 5, issue 22): particles on the beam grid at
//! `particles_per_cell` per axis per grid cell, the test's scene on those particles (pinned and
//! twisted regions by particle velocity enforcement), tracers at the FEM vertices' rest
//! positions, scored by the metrics of DESIGN 4.3. Trajectories are cached under
//! `<cache>/mpm/`: a Bend run at Δx = 0.05 m takes most of an hour on 2 cores.

use std::path::Path;
use std::time::Instant;

use artifact::{load_framed, save_framed};
use baselines::mpm::{MpmMaterial, MpmParams, MpmSimulator, MpmTimings};
use fem_ref::trajectory_key_builder;
use nalgebra::Vector3;
use rkpm_core::sample_box_grid;
use serde::{Deserialize, Serialize};

use crate::EvalError;
use crate::beam::study::{beam_length_scale, region_drift};
use crate::beam::{BEAM_MAX, BEAM_MIN, BEAM_TIME_STEP, BeamTest, beam_material};
use crate::fem_reference::FemRun;
use crate::metrics::trajectory_errors;
use crate::progress::Progress;

/// Cache file kind and format version of an MPM beam trajectory.
const MPM_CACHE_MAGIC: &[u8] = b"FFMPMTR1";
const MPM_CACHE_VERSION: u32 = 1;

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
    /// Normalized MSE against the FEM at its vertices (tracers).
    pub mse: f64,
    /// Normalized max error.
    pub max: f64,
    /// Largest distance of an FEM vertex (tracer) in a constrained region from its target (m).
    pub region_drift: f64,
    /// Wall time per 0.01 s of simulated time (ms).
    pub ms_per_step: f64,
    /// Share of the time in stress / P2G / grid / G2P.
    pub split: [f64; 4],
    /// Loaded from the cache.
    pub cached: bool,
}

/// What the cache keeps of a run.
#[derive(Serialize, Deserialize)]
struct CachedMpmRun {
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
) -> Result<ParticleBaselineRow, EvalError> {
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
        .str(&format!("{params:?} {config:?}"))
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
        Some(run) if run.frames.len() == steps + 1 => {
            progress.status(format!(
                "{label}: loaded from the cache ({})",
                path.display()
            ));
            (run, true)
        }
        _ => {
            let reduced_scene = scene.reduced_scene(particles.positions())?;
            let mut sim =
                MpmSimulator::new(&particles, &[beam_material()], &reduced_scene, params)?
                    .with_tracers(vertices)?;
            let bar = progress.bar(steps, format!("{label} ({} particles)", particles.len()));
            let start = Instant::now();
            let mut frames = vec![vertices.iter().map(|v| [v.x, v.y, v.z]).collect()];
            for _ in 0..steps {
                sim.advance(BEAM_TIME_STEP)?;
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
    let errors = trajectory_errors(&frames[1..], &truth[1..], beam_length_scale())?;
    let t = &run.timings;
    let total = t.total().max(f64::MIN_POSITIVE);
    Ok(ParticleBaselineRow {
        method: "mpm".into(),
        test,
        spacing,
        particles: run.particles,
        substeps_per_step: t.substeps / steps.max(1),
        mse: errors.normalized_mse,
        max: errors.normalized_max,
        region_drift: region_drift(test, vertices, &frames),
        ms_per_step: 1e3 * run.seconds / steps.max(1) as f64,
        split: [
            t.stress / total,
            t.particle_to_grid / total,
            t.grid_update / total,
            t.grid_to_particle / total,
        ],
        cached: was_cached,
    })
}
