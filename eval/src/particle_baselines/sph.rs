//! The SPH baseline on the beam (Tables 1 and 5): particles on the beam at the
//! study's spacing, the test's scene on those particles (pinned and twisted regions as
//! prescribed particle positions), one implicit step per 0.01 s frame (the paper's Δt; more on
//! request), the
//! FEM vertices' positions from the particles' displacements by the linear interpolant of
//! `baselines::sph::ParticleInterpolation` (those in a pinned or twisted region put on its
//! target, like the region's particles), scored by the metrics of design §4.3. A run that stops
//! is reported with its reason and not scored. Trajectories are cached under `<cache>/sph/`.

use std::path::Path;

use baselines::sph::{SphParams, SphSimulator, SphTimings};
use fem_ref::trajectory_key_builder;
use rkpm_core::sample_box_grid;
use serde::{Deserialize, Serialize};

use crate::EvalError;
use crate::beam_scenario::{BEAM_MAX, BEAM_MIN, BEAM_TIME_STEP, BeamTest, beam_material};
use crate::particle_baselines::particle_baseline::{
    ParticleBeamRun, ParticleMethod, ParticleTrajectory, as_arrays, load_cached_run, record_frames,
    score_particle_run, store_cached_run,
};
use freeform::fem_reference::FemRun;
use freeform::terminal_progress::TerminalProgress;

/// Cache file kind and format version of an SPH beam trajectory.
const SPH_CACHE_MAGIC: &[u8] = b"FFSPHTR1";
const SPH_CACHE_VERSION: u32 = 1;

/// How the SPH baseline is run on the beam.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SphStudyConfig {
    /// Particle spacings to run (m). Default [0.1, 0.05] (5 000 and 40 000 particles).
    pub spacings: Vec<f64>,
    /// The solver's options; its time step must be the beam's frame (0.01 s, the paper's)
    /// divided by `substeps`. Default [`SphParams::default`].
    pub params: SphParams,
    /// Steps per 0.01 s frame. Default 1 (the paper: Δt = 0.01 s); SPlisHSPlasH's own beam
    /// scene for this solver takes Δt = 2 ms, i.e. 5.
    #[serde(default = "one")]
    pub substeps: usize,
}

fn one() -> usize {
    1
}

impl SphStudyConfig {
    /// This configuration with `substeps` steps per frame (the time step set to match).
    pub fn with_substeps(self, substeps: usize) -> Self {
        SphStudyConfig {
            params: SphParams {
                time_step: BEAM_TIME_STEP / substeps.max(1) as f64,
                ..self.params
            },
            substeps: substeps.max(1),
            ..self
        }
    }
}

impl Default for SphStudyConfig {
    fn default() -> Self {
        SphStudyConfig {
            spacings: vec![0.1, 0.05],
            params: SphParams::default(),
            substeps: 1,
        }
    }
}

/// What the cache keeps of a run.
#[derive(Serialize, Deserialize)]
struct CachedSphRun {
    failure: Option<String>,
    max_pin_deviation: f64,
    frames: Vec<Vec<[f64; 3]>>,
    timings: SphTimings,
    particles: usize,
}

/// Runs (or loads) SPH on `test` for `steps` frames at particle spacing `spacing`, read at
/// `reference`'s vertices, and scores it.
///
/// # Errors
/// [`EvalError::Sph`] from the solver's setup (a time step other than the frame's, invalid
/// options, a probe outside the body), [`EvalError::Sampling`] / [`EvalError::Scene`] for
/// particles or regions that cannot be built, [`EvalError::Metrics`] for a trajectory that
/// cannot be scored.
pub fn run_sph_beam(
    test: BeamTest,
    spacing: f64,
    config: &SphStudyConfig,
    steps: usize,
    reference: &FemRun,
    cache_dir: &Path,
    progress: &TerminalProgress,
) -> Result<ParticleBeamRun, EvalError> {
    let params = config.params;
    let substeps = config.substeps.max(1);
    if (params.time_step * substeps as f64 - BEAM_TIME_STEP).abs() > 1e-12 {
        return Err(EvalError::Sph(baselines::sph::SphError::InvalidParameter(
            format!(
                "time_step = {} s with {substeps} steps per frame: the beam study's frames are \
                 {BEAM_TIME_STEP} s (use `SphStudyConfig::with_substeps`)",
                params.time_step
            ),
        )));
    }
    let particles =
        sample_box_grid(BEAM_MIN, BEAM_MAX, spacing).map_err(|source| EvalError::Sampling {
            what: "SPH particles",
            source,
        })?;
    let scene = test.scene();
    let vertices = reference.vertices();
    let mut key = trajectory_key_builder();
    key.str("sph beam")
        .u64(SPH_CACHE_VERSION as u64)
        .str(&scene.label())
        .str(&format!("{params:?} substeps={substeps}"))
        .u64(particles.len() as u64)
        .u64(steps as u64)
        .f64s(&[spacing]);
    for v in vertices {
        key.f64s(v.as_slice());
    }
    let path = cache_dir
        .join("sph")
        .join(format!("sph-{}.bin", key.finish().hex()));
    let label = format!("SPH {} spacing {spacing} m", test.name());
    let cached = load_cached_run(
        &path,
        SPH_CACHE_MAGIC,
        SPH_CACHE_VERSION,
        &label,
        progress,
        |run: &CachedSphRun| run.frames.len() == steps + 1 || run.failure.is_some(),
    );
    let (run, was_cached) = match cached {
        Some(run) => (run, true),
        None => {
            let reduced_scene = scene.reduced_scene(particles.positions())?;
            let probe_regions = scene.reduced_scene(vertices)?.pins;
            progress.status(format!(
                "{label}: neighbourhoods and factorization ({} particles)",
                particles.len()
            ));
            let mut sim =
                SphSimulator::new(&particles, &[beam_material()], &reduced_scene, params)?
                    .with_probes(vertices, &probe_regions)?;
            let recorded = record_frames(
                vertices,
                steps,
                format!("{label} ({} particles)", particles.len()),
                progress,
                || {
                    for _ in 0..substeps {
                        sim.step().map_err(|e| e.to_string())?;
                    }
                    Ok((as_arrays(sim.probe_positions()), sim.max_pin_deviation()))
                },
            );
            let run = CachedSphRun {
                failure: recorded.failure,
                max_pin_deviation: recorded.max_pin_deviation,
                frames: recorded.frames,
                timings: *sim.timings(),
                particles: particles.len(),
            };
            store_cached_run(
                &path,
                SPH_CACHE_MAGIC,
                SPH_CACHE_VERSION,
                &label,
                progress,
                &run,
            );
            (run, false)
        }
    };
    let t = run.timings;
    let total = t.stepping().max(f64::MIN_POSITIVE);
    score_particle_run(
        ParticleTrajectory {
            method: ParticleMethod::Sph,
            test,
            spacing,
            particles: run.particles,
            frames: run.frames,
            failure: run.failure,
            max_pin_deviation: run.max_pin_deviation,
            seconds: t.stepping(),
            setup_seconds: t.setup,
            substeps: t.steps,
            split: vec![
                ("stretching".into(), t.stretching / total),
                ("volume".into(), t.volume / total),
                ("advection and probes".into(), t.advection / total),
            ],
            iterations: Some(t.volume_iterations),
            cached: was_cached,
        },
        reference,
        progress,
    )
}
