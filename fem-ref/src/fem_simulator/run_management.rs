//! Running a [`FemSimulator`] through the trajectory cache: cache keys, cached runs,
//! checkpoints of long runs and resuming from them.

use std::ops::ControlFlow;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use hyperelastic::HyperelasticMaterial;

use crate::fem_model::FemModel;
use crate::run_checkpoint::RunCheckpoint;
use crate::run_keys::KeyInputs;
use crate::scene::FemScene;
use crate::trajectory_cache::{Trajectory, TrajectoryCache, TrajectoryCacheError, TrajectoryKey};

use super::{FemParams, FemRunError, FemSimulator, length_scale, penalized_floor};

/// What [`FemSimulator::run_cached`] tells its progress callback.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RunProgress {
    /// The run goes on from a checkpoint holding this many steps (reported once, before any
    /// step is computed).
    Resumed {
        /// Steps the checkpoint holds.
        steps_done: usize,
    },
    /// A step was computed.
    Stepped {
        /// The step (1-based): the steps done.
        step: usize,
    },
}

impl RunProgress {
    /// The steps done so far.
    pub fn steps_done(self) -> usize {
        match self {
            RunProgress::Resumed { steps_done } => steps_done,
            RunProgress::Stepped { step } => step,
        }
    }
}

/// What [`FemSimulator::run_cached`] returns.
#[derive(Debug)]
pub struct CachedRun {
    /// The trajectory (frames 0..=steps).
    pub trajectory: Trajectory,
    /// Whether it was read from the cache whole (nothing computed).
    pub from_cache: bool,
    /// Steps taken from a checkpoint of an earlier, stopped run (0 when it started afresh).
    pub resumed_steps: usize,
    /// The first checkpoint that could not be written or removed: the run went on, and only
    /// the work since the last good save was at risk.
    pub checkpoint_error: Option<TrajectoryCacheError>,
}

impl<M: HyperelasticMaterial> FemSimulator<M> {
    /// The cache key of `steps` steps from the rest state: a hash of the mesh, element order,
    /// mass kind, material model and per-element parameters, gravity, Dirichlet node sets,
    /// floor, time step, Newton options and `steps`. Moving Dirichlet targets are closures and
    /// cannot be hashed: `scene_label` must name them uniquely (e.g. "twist 2160 deg/s to 720
    /// deg about y = z = 0.5").
    pub fn trajectory_key(&self, scene_label: &str, steps: usize) -> TrajectoryKey {
        self.key_inputs().builder(scene_label, steps).finish()
    }

    /// The cache key of a run of `steps` steps some of whose steps were split
    /// ([`FemParams::failed_step_halvings`]): [`Self::trajectory_key`]'s inputs and the
    /// splitting depth.
    pub fn split_trajectory_key(&self, scene_label: &str, steps: usize) -> TrajectoryKey {
        self.key_inputs().split_key(scene_label, steps)
    }

    /// The key the checkpoint of a run of `steps` steps is saved under
    /// ([`TrajectoryCache::checkpoint_path`]): [`Self::split_trajectory_key`] where the run may
    /// split steps, [`Self::trajectory_key`] otherwise.
    pub fn checkpoint_key(&self, scene_label: &str, steps: usize) -> TrajectoryKey {
        self.key_inputs().keys(scene_label, steps).checkpoint()
    }

    fn key_inputs(&self) -> KeyInputs<'_, M> {
        KeyInputs {
            model: &self.model,
            scene: &self.scene,
            floor: self.floor.as_ref(),
            params: &self.params,
        }
    }

    /// The trajectory [`Self::run_cached`] would load from `cache` for the simulator
    /// `FemSimulator::new(model.clone(), scene.clone(), *params)` at rest, found without
    /// building it: no fill-reducing ordering, no symbolic factorization (seconds at 100k DOFs,
    /// a fifth of a warm-cache Table 2). `None` when the run must be computed, or when `new`
    /// would refuse the scene (it then names why).
    ///
    /// # Errors
    /// [`TrajectoryCacheError`]: the cache could not be read.
    pub fn load_cached(
        model: &FemModel<M>,
        scene: &FemScene,
        params: &FemParams,
        steps: usize,
        scene_label: &str,
        cache: &TrajectoryCache,
    ) -> Result<Option<Trajectory>, TrajectoryCacheError> {
        let Ok(floor) = penalized_floor(model, scene, length_scale(model)) else {
            return Ok(None);
        };
        let inputs = KeyInputs {
            model,
            scene,
            floor: floor.as_ref(),
            params,
        };
        inputs.keys(scene_label, steps).load(cache)
    }

    /// The key [`Self::checkpoint_key`] gives the simulator `FemSimulator::new(model.clone(),
    /// scene.clone(), *params)`, found without building it: what several processes computing
    /// the same run lock on. `None` when `new` would refuse the scene.
    pub fn checkpoint_key_for(
        model: &FemModel<M>,
        scene: &FemScene,
        params: &FemParams,
        steps: usize,
        scene_label: &str,
    ) -> Option<TrajectoryKey> {
        let floor = penalized_floor(model, scene, length_scale(model)).ok()?;
        let inputs = KeyInputs {
            model,
            scene,
            floor: floor.as_ref(),
            params,
        };
        Some(inputs.keys(scene_label, steps).checkpoint())
    }

    /// `steps` steps from the current state, recording all node positions per frame (frame 0 =
    /// the current state) — or the cached trajectory when `cache` holds one. A fresh run is
    /// stored. `progress` hears [`RunProgress::Stepped`] after each computed step, and
    /// [`RunProgress::Resumed`] once before the first when the run resumes from a checkpoint;
    /// returning [`ControlFlow::Break`] stops the run there ([`FemRunError::Stopped`]).
    ///
    /// A run is stored under [`Self::trajectory_key`], or under
    /// [`Self::split_trajectory_key`] when it split a step
    /// ([`FemParams::failed_step_halvings`]). With splitting allowed, a trajectory under the
    /// first key is taken only when every step converged (it is then what splitting computes
    /// too); one with unconverged steps was run without splitting and is run again.
    ///
    /// While it runs, the run so far is saved every [`FemParams::checkpoint_interval`] and
    /// when it is stopped ([`crate::RunCheckpoint`], under the key it may finish under); a
    /// later call for the same run goes on from there and the checkpoint is deleted once the
    /// trajectory is stored. Without Hessian reuse ([`optimize::HessianReuse::Never`], every shape and
    /// beam reference) the resumed trajectory is bit for bit the uninterrupted one; with
    /// reuse the carried factorization is not saved, so it differs within the Newton
    /// tolerance.
    ///
    /// Only meaningful from the rest state at t = 0 (what the key describes).
    ///
    /// # Errors
    /// [`FemRunError`]: a step failed (nothing is stored; the last checkpoint stays), the run
    /// was stopped, a checkpoint under its key does not fit it, or the cache could not be
    /// read or written (the computed trajectory is still returned inside the error).
    pub fn run_cached(
        &mut self,
        steps: usize,
        scene_label: &str,
        cache: &TrajectoryCache,
        mut progress: impl FnMut(RunProgress) -> ControlFlow<()>,
    ) -> Result<CachedRun, FemRunError> {
        let keys = self.key_inputs().keys(scene_label, steps);
        if let Some(trajectory) = keys.load(cache).map_err(FemRunError::Cache)? {
            return Ok(CachedRun {
                trajectory,
                from_cache: true,
                resumed_steps: 0,
                checkpoint_error: None,
            });
        }
        let checkpoint_key = keys.checkpoint();
        let split_before = self.split_steps;
        let mut trajectory = match cache
            .load_checkpoint(checkpoint_key)
            .map_err(FemRunError::Cache)?
        {
            Some(checkpoint) => {
                self.resume(checkpoint, steps, cache.checkpoint_path(checkpoint_key))?
            }
            None => Trajectory {
                times: vec![self.time],
                frames: vec![self.frame()],
                iterations: Vec::with_capacity(steps),
                converged: Vec::with_capacity(steps),
                seconds: 0.0,
            },
        };
        let resumed_steps = trajectory.frames.len() - 1;
        if resumed_steps > 0
            && resumed_steps < steps
            && progress(RunProgress::Resumed {
                steps_done: resumed_steps,
            })
            .is_break()
        {
            return Err(FemRunError::Stopped {
                step: resumed_steps,
                steps,
                checkpoint: cache.checkpoint_path(checkpoint_key),
            });
        }
        let seconds_before = trajectory.seconds;
        let start = Instant::now();
        let mut last_save = (Instant::now(), Duration::ZERO);
        let mut checkpoint_error = None;
        for step in resumed_steps + 1..=steps {
            let report = self
                .step()
                .map_err(|source| FemRunError::Step { step, source })?;
            trajectory.times.push(self.time);
            trajectory.frames.push(self.frame());
            trajectory.iterations.push(report.iterations);
            trajectory.converged.push(report.converged());
            let stopped = progress(RunProgress::Stepped { step }).is_break();
            let due = self
                .params
                .checkpoint_interval
                .is_some_and(|interval| last_save.0.elapsed() >= interval.max(10 * last_save.1));
            if step == steps || !(stopped || due) {
                continue;
            }
            trajectory.seconds = seconds_before + start.elapsed().as_secs_f64();
            let saving = Instant::now();
            let checkpoint = RunCheckpoint {
                trajectory: trajectory.clone(),
                velocities: self.v.clone(),
                split_steps: self.split_steps - split_before,
            };
            let saved = cache.store_checkpoint(checkpoint_key, &checkpoint);
            last_save = (Instant::now(), saving.elapsed());
            if stopped {
                return Err(match saved {
                    Ok(checkpoint) => FemRunError::Stopped {
                        step,
                        steps,
                        checkpoint,
                    },
                    Err(e) => FemRunError::Cache(e),
                });
            }
            if let Err(e) = saved {
                checkpoint_error.get_or_insert(e);
            }
        }
        trajectory.seconds = seconds_before + start.elapsed().as_secs_f64();
        let key = match keys.split {
            Some(split_key) if self.split_steps > split_before => split_key,
            _ => keys.whole,
        };
        if let Err(e) = cache.store(key, &trajectory) {
            return Err(FemRunError::CacheWrite {
                error: e,
                trajectory: Box::new(trajectory),
            });
        }
        if let Err(e) = cache.remove_checkpoint(checkpoint_key) {
            checkpoint_error.get_or_insert(e);
        }
        Ok(CachedRun {
            trajectory,
            from_cache: false,
            resumed_steps,
            checkpoint_error,
        })
    }

    /// The current node positions as one trajectory frame.
    fn frame(&self) -> Vec<[f64; 3]> {
        self.x.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
    }

    /// Sets the state to a checkpoint's last frame and returns its trajectory so far.
    fn resume(
        &mut self,
        checkpoint: RunCheckpoint,
        steps: usize,
        path: PathBuf,
    ) -> Result<Trajectory, FemRunError> {
        let nodes = self.x.len() / 3;
        let mismatch = checkpoint.mismatch(nodes, steps).or_else(|| {
            (checkpoint.trajectory.frames[0] != self.frame()
                || checkpoint.trajectory.times[0] != self.time)
                .then(|| "its first frame is not this simulator's state".to_string())
        });
        if let Some(reason) = mismatch {
            return Err(FemRunError::CheckpointMismatch { path, reason });
        }
        let RunCheckpoint {
            trajectory,
            velocities,
            split_steps,
        } = checkpoint;
        let last = trajectory
            .frames
            .last()
            .expect("a checkpoint holds frame 0");
        self.x = last.iter().flatten().copied().collect();
        self.v = velocities;
        self.time = *trajectory.times.last().expect("as many times as frames");
        self.split_steps += split_steps;
        self.carried = None;
        Ok(trajectory)
    }
}
