//! The MPM baseline on the beam (Tables 1 and 5): particles on the beam grid at
//! `particles_per_cell` per axis per grid cell, the test's scene on those particles (pinned and
//! twisted regions by particle velocity enforcement), tracers at the FEM vertices' rest
//! positions (those in a constrained region moved onto its target like the region's
//! particles, the others with the grid velocity), scored by the metrics of design §4.3. A run
//! that stops (a tracer left the material, an instability) is reported with its reason and
//! not scored. Trajectories are cached under
//! `<cache>/mpm/`: a Bend run at Δx = 0.05 m takes more than 80 min on 2 cores.

use std::path::Path;
use std::time::Instant;

use baselines::mpm::{MpmError, MpmMaterial, MpmParams, MpmSimulator, MpmTimings};
use fem_ref::trajectory_key_builder;
use nalgebra::Vector3;
use rkpm_core::{IntegrationPoints, sample_box_grid};
use serde::{Deserialize, Serialize};

use crate::EvalError;
use crate::beam_scenario::{BEAM_MAX, BEAM_MIN, BEAM_TIME_STEP, BeamTest, beam_material};
use crate::particle_baselines::particle_baseline::{
    ParticleBeamRun, ParticleMethod, ParticleTrajectory, as_arrays, load_cached_run, record_frames,
    score_particle_run, store_cached_run,
};
use freeform::fem_reference::FemRun;
use freeform::scene::SceneSpec;
use freeform::terminal_progress::TerminalProgress;

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
    progress: &TerminalProgress,
) -> Result<ParticleBeamRun, EvalError> {
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
    let cached = load_cached_run(
        &path,
        MPM_CACHE_MAGIC,
        MPM_CACHE_VERSION,
        &label,
        progress,
        |run: &CachedMpmRun| run.frames.len() == steps + 1 || run.failure.is_some(),
    );
    let (run, was_cached) = match cached {
        Some(run) => (run, true),
        None => {
            let run = simulate_mpm(
                &particles, &scene, params, vertices, steps, &label, progress,
            )?;
            store_cached_run(
                &path,
                MPM_CACHE_MAGIC,
                MPM_CACHE_VERSION,
                &label,
                progress,
                &run,
            );
            (run, false)
        }
    };
    let t = run.timings;
    let total = t.total().max(f64::MIN_POSITIVE);
    score_particle_run(
        ParticleTrajectory {
            method: ParticleMethod::Mpm,
            test,
            spacing,
            particles: run.particles,
            frames: run.frames,
            failure: run.failure,
            max_pin_deviation: run.max_pin_deviation,
            seconds: run.seconds,
            setup_seconds: 0.0,
            substeps: t.substeps,
            split: vec![
                ("stress".into(), t.stress / total),
                ("particle to grid".into(), t.particle_to_grid / total),
                ("grid".into(), t.grid_update / total),
                ("grid to particle".into(), t.grid_to_particle / total),
            ],
            iterations: None,
            cached: was_cached,
        },
        reference,
        progress,
    )
}

/// MPM on `scene` for `steps` frames from `particles`, with tracers at `vertices`: what the
/// cache keeps (a failed run is a run with its `failure`).
///
/// # Errors
/// [`EvalError::Mpm`] / [`EvalError::Scene`] when the simulator or its regions cannot be set up.
fn simulate_mpm(
    particles: &IntegrationPoints,
    scene: &SceneSpec,
    params: MpmParams,
    vertices: &[Vector3<f64>],
    steps: usize,
    label: &str,
    progress: &TerminalProgress,
) -> Result<CachedMpmRun, EvalError> {
    let reduced_scene = scene.reduced_scene(particles.positions())?;
    let tracer_regions = scene.reduced_scene(vertices)?.pins;
    let mut sim = MpmSimulator::new(particles, &[beam_material()], &reduced_scene, params)?
        .with_tracers(vertices, &tracer_regions)?;
    let start = Instant::now();
    let recorded = record_frames(
        vertices,
        steps,
        format!("{label} ({} particles)", particles.len()),
        progress,
        || {
            sim.advance(BEAM_TIME_STEP).map_err(|e| match e {
                MpmError::TracerLost { tracer, .. } => format!(
                    "{e} (tracer at rest position {:?} m)",
                    vertices[tracer].as_slice()
                ),
                _ => e.to_string(),
            })?;
            Ok((as_arrays(sim.tracer_positions()), sim.max_pin_deviation()))
        },
    );
    Ok(CachedMpmRun {
        failure: recorded.failure,
        max_pin_deviation: recorded.max_pin_deviation,
        frames: recorded.frames,
        timings: *sim.timings(),
        particles: particles.len(),
        seconds: start.elapsed().as_secs_f64(),
    })
}
