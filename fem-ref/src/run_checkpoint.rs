//! A FEM run saved part way (design §3.8): the frames computed so far and the state to go on
//! from, so that an hours-long reference that is stopped or killed resumes where it was
//! instead of starting over ([`crate::FemSimulator::run_cached`]).
//!
//! The file is `<dir>/fem-<key>.partial` beside the finished trajectory's `fem-<key>.traj`,
//! under the key the run may finish under (the split key where the run may split steps, whose
//! hash holds the splitting depth; the whole-step key otherwise). It is replaced atomically at
//! each save and deleted once the finished trajectory is stored. Deleting it is always safe:
//! the run then starts over.

use std::path::PathBuf;

use artifact::{load_framed, save_framed};
use serde::{Deserialize, Serialize};

use crate::trajectory_cache::{Trajectory, TrajectoryCache, TrajectoryCacheError, TrajectoryKey};

/// Version of the checkpoint file format.
pub const CHECKPOINT_FORMAT_VERSION: u32 = 1;
const MAGIC: &[u8; 6] = b"FFPART";

/// A FEM run's progress after a whole step: what [`Trajectory`] holds so far and the state
/// the next step needs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunCheckpoint {
    /// Frames 0..=k and the reports of steps 1..=k; `seconds` is the wall time spent on them
    /// (s), over every sitting so far.
    pub trajectory: Trajectory,
    /// Flat node velocities at frame k (m/s), `3 × nodes`.
    pub velocities: Vec<f64>,
    /// Steps 1..=k taken as halves ([`crate::FemParams::failed_step_halvings`]).
    pub split_steps: usize,
}

impl RunCheckpoint {
    /// Steps done (k).
    pub fn steps_done(&self) -> usize {
        self.trajectory.frames.len().saturating_sub(1)
    }

    /// Why this checkpoint cannot be the start of a run of `steps` steps on `nodes` nodes
    /// (the key matched, so only a damaged or hand-made file gets here).
    pub(crate) fn mismatch(&self, nodes: usize, steps: usize) -> Option<String> {
        let t = &self.trajectory;
        let done = self.steps_done();
        if t.frames.is_empty() || done > steps {
            return Some(format!(
                "{} frames for a run of {steps} steps",
                t.frames.len()
            ));
        }
        if t.times.len() != t.frames.len()
            || t.iterations.len() != done
            || t.converged.len() != done
        {
            return Some(format!(
                "{} frames, {} times, {} iteration counts, {} convergence flags",
                t.frames.len(),
                t.times.len(),
                t.iterations.len(),
                t.converged.len()
            ));
        }
        if let Some(f) = t.frames.iter().position(|f| f.len() != nodes) {
            return Some(format!(
                "frame {f} has {} nodes, the mesh {nodes}",
                t.frames[f].len()
            ));
        }
        if self.velocities.len() != 3 * nodes {
            return Some(format!(
                "{} velocity components for {nodes} nodes",
                self.velocities.len()
            ));
        }
        let finite = t.frames.iter().flatten().flatten().all(|c| c.is_finite())
            && self.velocities.iter().all(|c| c.is_finite())
            && t.times.iter().all(|c| c.is_finite());
        (!finite).then(|| "non-finite positions, velocities or times".to_string())
    }
}

impl TrajectoryCache {
    /// The checkpoint file of a run stored under `key` when finished.
    pub fn checkpoint_path(&self, key: TrajectoryKey) -> PathBuf {
        self.dir().join(format!("fem-{}.partial", key.hex()))
    }

    /// The checkpoint under `key`, or `None` when there is none.
    ///
    /// # Errors
    /// [`TrajectoryCacheError`] when the file exists but cannot be read or decoded.
    pub fn load_checkpoint(
        &self,
        key: TrajectoryKey,
    ) -> Result<Option<RunCheckpoint>, TrajectoryCacheError> {
        load_framed(&self.checkpoint_path(key), MAGIC, CHECKPOINT_FORMAT_VERSION)
            .map_err(Into::into)
    }

    /// Stores a checkpoint atomically (a reader sees the previous one or this one, never a
    /// torn file); returns its path.
    ///
    /// # Errors
    /// [`TrajectoryCacheError::Io`].
    pub fn store_checkpoint(
        &self,
        key: TrajectoryKey,
        checkpoint: &RunCheckpoint,
    ) -> Result<PathBuf, TrajectoryCacheError> {
        let path = self.checkpoint_path(key);
        save_framed(&path, MAGIC, CHECKPOINT_FORMAT_VERSION, checkpoint)?;
        Ok(path)
    }

    /// Deletes the checkpoint under `key` (nothing to do when there is none).
    ///
    /// # Errors
    /// [`TrajectoryCacheError::Io`].
    pub fn remove_checkpoint(&self, key: TrajectoryKey) -> Result<(), TrajectoryCacheError> {
        let path = self.checkpoint_path(key);
        match std::fs::remove_file(&path) {
            Ok(()) => Ok(()),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
            Err(source) => Err(TrajectoryCacheError::Io { path, source }),
        }
    }
}
