//! The FEM reference of a scene (feature `fem`; design §3.8): one tetrahedral P1/P2 run of a
//! [`SceneSpec`] with one material, run or loaded from a content-keyed cache ([`run_fem`],
//! [`cached_fem`]), and the scores of a reduced trajectory against it ([`FemRun::score`],
//! design §4.3).

use std::ops::ControlFlow;
use std::path::Path;

use fem_ref::{
    CachedRun, ElementOrder, FemMesh, FemModel, FemParams, FemScene, FemSimulator,
    FillReducingOrdering, MassKind, PointInterpolation, RunProgress, TetMesh, TrajectoryCache,
};
use hyperelastic::{HessianTangent, MaterialSample, StableNeoHookean};
use nalgebra::Vector3;
use optimize::NewtonParams;
use reduced_sim::{DeformationMap, SkinningField};
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::metrics::{
    MetricsError, TrajectoryErrors, basis_fitting_residual, per_frame_mse, trajectory_errors,
};
use crate::progress::Progress;
use crate::scene::{SceneSpec, SceneSpecError};

/// A FEM reference could not be built, run, loaded or scored.
#[derive(Debug, Error)]
pub enum FemReferenceError {
    /// The FEM model could not be built.
    #[error("building the FEM model failed")]
    Model(#[source] fem_ref::FemModelError),
    /// The FEM simulator refused the scene.
    #[error("setting up the FEM simulator failed")]
    Setup(#[source] fem_ref::FemSetupError),
    /// The FEM run failed or its cache could not be used.
    #[error("the FEM reference failed")]
    Run(#[source] fem_ref::FemRunError),
    /// The scene cannot be applied to the mesh (e.g. a region that holds no node).
    #[error(transparent)]
    Scene(#[from] SceneSpecError),
    /// Points to read the solution at lie outside the mesh.
    #[error(transparent)]
    PointLocation(#[from] fem_ref::PointLocationError),
    /// A skinning field cannot be evaluated at the mesh's vertices.
    #[error("evaluating the skinning field at the output points failed")]
    OutputMap(#[source] reduced_sim::DeformationMapError),
    /// The trajectories cannot be compared.
    #[error(transparent)]
    Metrics(#[from] MetricsError),
}

/// A FEM trajectory.
#[derive(Clone, Debug)]
pub struct FemRun {
    /// The element mesh; its tet mesh's vertices are where metrics are evaluated.
    pub mesh: FemMesh,
    /// Node positions per frame, frame 0 = rest (m).
    pub frames: Vec<Vec<Vector3<f64>>>,
    /// Seconds per step of the run that produced it (also when loaded from the cache).
    pub seconds_per_step: f64,
    /// Mean Newton iterations per step.
    pub iterations_per_step: f64,
    /// Steps whose Newton solve did not converge.
    pub unconverged_steps: usize,
    /// Newton iterations of each step (`step_iterations[t - 1]` produced frame t).
    pub step_iterations: Vec<usize>,
    /// Whether each step's Newton solve converged (`step_converged[t - 1]` for frame t).
    pub step_converged: Vec<bool>,
    /// Free degrees of freedom.
    pub dofs: usize,
    /// Whether it came from the cache.
    pub cached: bool,
    /// Nodes held in each constrained region of the scene (a region held by one or two nodes
    /// is a hinge).
    pub region_nodes: Vec<usize>,
    /// How deep an unconverged step was allowed to split ([`FemProblem::failed_step_halvings`]).
    pub failed_step_halvings: usize,
}

/// What one FEM reference run needs, known before its numeric work ([`FemProblem::estimate`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ReferenceEstimate {
    /// Free degrees of freedom.
    pub dofs: usize,
    /// Stored entries of one Cholesky factor.
    pub factor_nonzeros: usize,
    /// Bytes the factors need: two factors and the factorization's workspace (the run's
    /// largest allocation).
    pub factor_bytes: u64,
    /// Whether that fits in the memory available where the estimate was made (the smaller of
    /// the machine's and its cgroup's).
    pub fits_here: bool,
}

/// Everything one FEM reference run needs.
pub struct FemProblem<'a> {
    /// The tetrahedral mesh (m).
    pub tets: TetMesh,
    /// P1 or P2 elements on it.
    pub order: ElementOrder,
    /// One homogeneous material.
    pub material: MaterialSample,
    /// What acts on the object (Dirichlet on the nodes in each region).
    pub scene: &'a SceneSpec,
    /// Backward Euler step (s).
    pub time_step: f64,
    /// Newton options (`NewtonParams::default()` for a reference).
    pub newton: NewtonParams,
    /// The element tangent of Newton's Hessian ([`HessianTangent::ProjectedPsd`] for the
    /// references so far; the converged states do not depend on it).
    pub tangent: HessianTangent,
    /// Elimination order of the sparse Cholesky factorization (round-off only; not part of
    /// the cache key).
    pub ordering: FillReducingOrdering,
    /// How deep a step that does not converge whole is split into backward-Euler half steps
    /// ([`FemParams::failed_step_halvings`]; 0 for the beam's references).
    pub failed_step_halvings: usize,
    /// Steps to run.
    pub steps: usize,
}

impl FemProblem<'_> {
    /// The P1/P2 simulator of this problem (Stable Neo-Hookean, consistent mass, floor
    /// penalty factor 1e4) at its rest state, and the node count of each Dirichlet region.
    ///
    /// # Errors
    /// [`FemReferenceError::Model`] / [`FemReferenceError::Setup`] for a model or scene that cannot be
    /// built (e.g. a region that selects no node).
    pub fn simulator(
        &self,
    ) -> Result<(FemSimulator<StableNeoHookean>, Vec<usize>), FemReferenceError> {
        let parts = self.parts()?;
        let region_nodes = parts.region_nodes();
        let sim = FemSimulator::new(parts.model, parts.scene, parts.params)
            .map_err(FemReferenceError::Setup)?;
        Ok((sim, region_nodes))
    }

    /// What this problem's run needs, from the symbolic analysis alone (no numeric work): its
    /// free DOFs and the memory of its Cholesky factors, and whether that fits in the memory
    /// available here ([`fem_ref::FactorMemoryLimit::Available`]).
    ///
    /// # Errors
    /// As [`Self::simulator`], except that factors too large for this machine give an estimate
    /// with `fits_here: false`.
    pub fn estimate(&self) -> Result<ReferenceEstimate, FemReferenceError> {
        match self.simulator() {
            Ok((sim, _)) => Ok(ReferenceEstimate {
                dofs: sim.free_dofs(),
                factor_nonzeros: sim.factor_nonzeros(),
                factor_bytes: sim.factor_memory_bytes(),
                fits_here: true,
            }),
            Err(FemReferenceError::Setup(fem_ref::FemSetupError::FactorTooLarge {
                dofs,
                factor_nonzeros,
                bytes,
                ..
            })) => Ok(ReferenceEstimate {
                dofs,
                factor_nonzeros,
                factor_bytes: bytes,
                fits_here: false,
            }),
            Err(e) => Err(e),
        }
    }

    /// What [`Self::simulator`] builds the simulator from.
    fn parts(&self) -> Result<SimulatorParts, FemReferenceError> {
        let elements = self.tets.tets().len();
        let mesh = FemMesh::new(self.tets.clone(), self.order);
        let model = FemModel::new(
            mesh,
            &vec![self.material; elements],
            StableNeoHookean,
            MassKind::Consistent,
        )
        .map_err(FemReferenceError::Model)?;
        let scene = self.scene.fem_scene(model.mesh().nodes(), 1e4)?;
        let params = FemParams {
            time_step: self.time_step,
            newton: self.newton,
            tangent: self.tangent,
            ordering: self.ordering,
            failed_step_halvings: self.failed_step_halvings,
            ..FemParams::default()
        };
        Ok(SimulatorParts {
            model,
            scene,
            params,
        })
    }
}

/// A [`FemProblem`]'s model, scene and options: [`FemSimulator::new`]'s inputs.
struct SimulatorParts {
    model: FemModel<StableNeoHookean>,
    scene: FemScene,
    params: FemParams,
}

impl SimulatorParts {
    /// Nodes held in each Dirichlet region.
    fn region_nodes(&self) -> Vec<usize> {
        self.scene.dirichlet.iter().map(|r| r.nodes.len()).collect()
    }
}

/// Runs (or loads from `<cache_dir>/fem/`, keyed by the mesh, material, scene and options)
/// `problem`, showing a bar labelled `FEM <label>`.
///
/// # Errors
/// [`FemReferenceError::Model`] / [`FemReferenceError::Setup`] for a model or scene that cannot be built
/// (e.g. a region that selects no node), [`FemReferenceError::Run`] for a failed step or an unusable
/// cache.
pub fn run_fem(
    problem: &FemProblem<'_>,
    label: &str,
    cache_dir: &Path,
    progress: &dyn Progress,
) -> Result<FemRun, FemReferenceError> {
    let parts = problem.parts()?;
    let region_nodes = parts.region_nodes();
    let cache = TrajectoryCache::new(cache_dir.join("fem"));
    let solved = match load_solved(&parts, problem, &cache)? {
        Some(solved) => solved,
        None => {
            // Another process (here or on a machine sharing the cache) may be computing the
            // same run: wait for it and load its trajectory instead of computing it again.
            let _lock = lock_run(&parts, problem, &cache, label, progress)?;
            match load_solved(&parts, problem, &cache)? {
                Some(solved) => solved,
                None => step_through(
                    parts,
                    problem.steps,
                    &problem.scene.label(),
                    &cache,
                    label,
                    progress,
                )?,
            }
        }
    };
    Ok(fem_run(
        solved,
        region_nodes,
        problem,
        label,
        &cache,
        progress,
    ))
}

/// The lock of `problem`'s run in `cache` (`<checkpoint file>.lock`, [`artifact::KeyLock`]),
/// waiting while another process holds it; `None` when the run has no key (its scene is
/// refused, which the run then reports).
fn lock_run(
    parts: &SimulatorParts,
    problem: &FemProblem<'_>,
    cache: &TrajectoryCache,
    label: &str,
    progress: &dyn Progress,
) -> Result<Option<artifact::KeyLock>, FemReferenceError> {
    let Some(key) = FemSimulator::checkpoint_key_for(
        &parts.model,
        &parts.scene,
        &parts.params,
        problem.steps,
        &problem.scene.label(),
    ) else {
        return Ok(None);
    };
    let mut path = cache.path(key).into_os_string();
    path.push(".lock");
    artifact::KeyLock::acquire(
        Path::new(&path),
        &artifact::KeyLockParams::default(),
        |owner| {
            progress.status(&format!(
                "FEM {label}: waiting for {owner}, which is computing it in the same cache"
            ));
        },
    )
    .map(Some)
    .map_err(|e| FemReferenceError::Run(fem_ref::FemRunError::Cache(e.into())))
}

/// [`run_fem`]'s trajectory when `<cache_dir>/fem/` holds it, else `None`: nothing is computed
/// (a checkpoint of an unfinished run is not a trajectory).
///
/// # Errors
/// As [`run_fem`], but for a failed step (no step is taken).
pub fn cached_fem(
    problem: &FemProblem<'_>,
    label: &str,
    cache_dir: &Path,
    progress: &dyn Progress,
) -> Result<Option<FemRun>, FemReferenceError> {
    let parts = problem.parts()?;
    let region_nodes = parts.region_nodes();
    let cache = TrajectoryCache::new(cache_dir.join("fem"));
    Ok(load_solved(&parts, problem, &cache)?
        .map(|solved| fem_run(solved, region_nodes, problem, label, &cache, progress)))
}

/// `problem`'s trajectory from `cache`, if it is there. Found before the simulator is built:
/// its symbolic factorization would be a fifth of a warm-cache Table 2.
fn load_solved(
    parts: &SimulatorParts,
    problem: &FemProblem<'_>,
    cache: &TrajectoryCache,
) -> Result<Option<Solved>, FemReferenceError> {
    let cached_trajectory = FemSimulator::load_cached(
        &parts.model,
        &parts.scene,
        &parts.params,
        problem.steps,
        &problem.scene.label(),
        cache,
    )
    .map_err(|e| FemReferenceError::Run(fem_ref::FemRunError::Cache(e)))?;
    let Some(trajectory) = cached_trajectory else {
        return Ok(None);
    };
    Ok(Some(Solved {
        dofs: parts
            .scene
            .free_dofs(parts.model.mesh().nodes().len())
            .map_err(FemReferenceError::Setup)?,
        mesh: parts.model.mesh().clone(),
        run: CachedRun {
            trajectory,
            from_cache: true,
            resumed_steps: 0,
            checkpoint_error: None,
        },
        split_steps: 0,
    }))
}

/// The [`FemRun`] of a `solved` `problem`, with a status line saying how it was had.
fn fem_run(
    solved: Solved,
    region_nodes: Vec<usize>,
    problem: &FemProblem<'_>,
    label: &str,
    cache: &TrajectoryCache,
    progress: &dyn Progress,
) -> FemRun {
    let steps = problem.steps;
    let Solved {
        mesh,
        run,
        dofs,
        split_steps,
    } = solved;
    let (trajectory, cached) = (run.trajectory, run.from_cache);
    let seconds_per_step = trajectory.seconds / steps.max(1) as f64;
    let iterations_per_step =
        trajectory.iterations.iter().sum::<usize>() as f64 / steps.max(1) as f64;
    if cached {
        progress.status(&format!(
            "FEM {label}: loaded from the cache ({})",
            cache.dir().display()
        ));
    } else {
        // A line per computed reference, also where bars are hidden (parallel shapes, stderr
        // not a terminal): long tables show where their time goes.
        let mut split = match split_steps {
            0 => String::new(),
            n => format!(", {n} split in halves"),
        };
        if run.resumed_steps > 0 {
            split += &format!(", the first {} from a checkpoint", run.resumed_steps);
        }
        progress.status(&format!(
            "FEM {label}: {steps} steps on {dofs} DOFs in {:.0} s ({seconds_per_step:.2} s per \
             step, {iterations_per_step:.1} Newton iterations per step{split})",
            trajectory.seconds
        ));
    }
    let frames = trajectory
        .frames
        .iter()
        .map(|f| f.iter().map(|p| Vector3::from(*p)).collect())
        .collect();
    FemRun {
        mesh,
        frames,
        seconds_per_step,
        iterations_per_step,
        unconverged_steps: trajectory.converged.iter().filter(|c| !**c).count(),
        step_iterations: trajectory.iterations.clone(),
        step_converged: trajectory.converged.clone(),
        dofs,
        cached,
        region_nodes,
        failed_step_halvings: problem.failed_step_halvings,
    }
}

/// A reference's trajectory with the mesh it lives on and how it was had.
struct Solved {
    mesh: FemMesh,
    run: CachedRun,
    /// Free DOFs of the system.
    dofs: usize,
    /// Steps split into backward-Euler halves to converge.
    split_steps: usize,
}

/// Builds the simulator from `parts` and runs it `steps` steps through `cache` (resuming from a
/// checkpoint), showing a bar labelled `FEM <label>`.
fn step_through(
    parts: SimulatorParts,
    steps: usize,
    label_of_scene: &str,
    cache: &TrajectoryCache,
    label: &str,
    progress: &dyn Progress,
) -> Result<Solved, FemReferenceError> {
    let mut sim = FemSimulator::new(parts.model, parts.scene, parts.params)
        .map_err(FemReferenceError::Setup)?;
    let dofs = sim.free_dofs();
    progress.begin(steps, &format!("FEM {label} ({dofs} DOFs)"));
    let run = sim
        .run_cached(steps, label_of_scene, cache, |event| {
            match event {
                RunProgress::Resumed { steps_done } => {
                    progress.resume_at(steps_done);
                    progress.status(&format!(
                        "FEM {label}: resuming at step {steps_done} of {steps} from its checkpoint"
                    ));
                }
                RunProgress::Stepped { .. } => progress.advance(),
            }
            ControlFlow::Continue(())
        })
        .map_err(FemReferenceError::Run)?;
    progress.finish();
    if let Some(e) = &run.checkpoint_error {
        progress.status(&format!("FEM {label}: a checkpoint was not saved: {e}"));
    }
    Ok(Solved {
        mesh: sim.model().mesh().clone(),
        run,
        dofs,
        split_steps: sim.split_steps(),
    })
}

/// How well a method's trajectory matches a FEM run (design §4.3).
#[derive(Clone, Debug, PartialEq)]
pub struct FieldScores {
    /// Normalized MSE and max error.
    pub errors: TrajectoryErrors,
    /// Normalized MSE of each frame 1..T (their mean is `errors.normalized_mse`).
    pub per_frame_mse: Vec<f64>,
    /// Basis fitting residual of the FEM trajectory through the method's deformation map.
    pub fitting_residual: f64,
}

/// A FEM run some of whose Newton solves stopped unconverged: its frames are not a reference,
/// and no table scores against it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize, thiserror::Error)]
#[error(
    "the FEM reference's Newton solve did not converge at frame(s) {} of {steps} (cap {iteration_cap} \
     iterations{}): not a reference, not scored",
    list(frames),
    match step_halvings {
        0 => String::new(),
        n => format!(", steps split into halves {n} deep"),
    }
)]
pub struct UnconvergedReference {
    /// The frames (= 1-based steps) whose Newton solve did not converge.
    pub frames: Vec<usize>,
    /// Steps in the run.
    pub steps: usize,
    /// The Newton iteration cap the run used.
    pub iteration_cap: usize,
    /// How deep the run split a step that did not converge whole (0: not at all).
    #[serde(default)]
    pub step_halvings: usize,
}

fn list(frames: &[usize]) -> String {
    frames
        .iter()
        .map(usize::to_string)
        .collect::<Vec<_>>()
        .join(", ")
}

impl FemRun {
    /// The largest Newton iteration count of any step (0 for a run of no steps).
    pub fn max_iterations(&self) -> usize {
        self.step_iterations.iter().copied().max().unwrap_or(0)
    }

    /// The frames (1-based steps) whose Newton solve did not converge.
    pub fn unconverged_frames(&self) -> Vec<usize> {
        self.step_converged
            .iter()
            .enumerate()
            .filter(|(_, c)| !**c)
            .map(|(i, _)| i + 1)
            .collect()
    }

    /// `Ok` when every step converged, so the run may serve as a reference; otherwise which
    /// frames did not (`iteration_cap` is the cap the run used, for the message).
    ///
    /// # Errors
    /// [`UnconvergedReference`] naming the unconverged frames.
    pub fn check_converged(&self, iteration_cap: usize) -> Result<(), UnconvergedReference> {
        let frames = self.unconverged_frames();
        if frames.is_empty() {
            Ok(())
        } else {
            Err(UnconvergedReference {
                frames,
                steps: self.step_converged.len(),
                iteration_cap,
                step_halvings: self.failed_step_halvings,
            })
        }
    }

    /// Rest positions of the tet mesh's vertices (m).
    pub fn vertices(&self) -> &[Vector3<f64>] {
        self.mesh.tet_mesh().vertices()
    }

    /// The largest vertex displacement `|x_t − x_0|` over all frames (m).
    pub fn max_vertex_displacement(&self) -> f64 {
        let n = self.vertices().len();
        self.frames
            .iter()
            .flat_map(|f| {
                f[..n]
                    .iter()
                    .zip(&self.frames[0])
                    .map(|(x, x0)| (x - x0).norm())
            })
            .fold(0.0, f64::max)
    }

    /// Vertex positions per frame (frame 0 = rest).
    pub fn vertex_frames(&self) -> Vec<Vec<Vector3<f64>>> {
        let n = self.vertices().len();
        self.frames.iter().map(|f| f[..n].to_vec()).collect()
    }

    /// Scores `frames` (positions at this run's vertices, frame 0 = rest, as many frames as this
    /// run) of a method whose deformation map is `field`, over frames 1..T with length scale
    /// `length` (design §4.3): normalized MSE and max error, and the basis fitting residual of
    /// this trajectory through `field`.
    ///
    /// # Errors
    /// [`FemReferenceError::Metrics`] for mismatched or non-finite frames or a singular fit,
    /// [`FemReferenceError::OutputMap`] if `field` cannot be evaluated at the vertices.
    pub fn score<B: SkinningField + ?Sized>(
        &self,
        field: &B,
        frames: &[Vec<Vector3<f64>>],
        length: f64,
    ) -> Result<FieldScores, FemReferenceError> {
        let reference = self.vertex_frames();
        let errors = trajectory_errors(&frames[1..], &reference[1..], length)?;
        let per_frame_mse = per_frame_mse(&frames[1..], &reference[1..], length)?;
        let map =
            DeformationMap::new(field, self.vertices()).map_err(FemReferenceError::OutputMap)?;
        let fitting_residual = basis_fitting_residual(&map, &reference[1..], length)?;
        Ok(FieldScores {
            errors,
            per_frame_mse,
            fitting_residual,
        })
    }

    /// Positions per frame of arbitrary rest points inside the mesh, interpolated from the
    /// elements.
    ///
    /// # Errors
    /// [`FemReferenceError::PointLocation`] if a point lies outside the mesh.
    pub fn frames_at(
        &self,
        points: &[Vector3<f64>],
    ) -> Result<Vec<Vec<Vector3<f64>>>, FemReferenceError> {
        let interpolation = PointInterpolation::new(&self.mesh, points)?;
        Ok(self
            .frames
            .iter()
            .map(|f| interpolation.interpolate(f))
            .collect())
    }

    /// This run's frames interpolated at those of `points` (rest positions, m) that lie inside
    /// its mesh, with their indices (points outside are skipped, e.g. the vertices of a coarser
    /// mesh of the same shape whose boundary sticks out).
    pub fn frames_inside(&self, points: &[Vector3<f64>]) -> (Vec<usize>, Vec<Vec<Vector3<f64>>>) {
        let (interpolation, inside) = PointInterpolation::inside(&self.mesh, points);
        let frames = self
            .frames
            .iter()
            .map(|f| interpolation.interpolate(f))
            .collect();
        (inside, frames)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_unconverged_reference_names_its_frames_cap_and_split_depth() {
        let why = |step_halvings| {
            UnconvergedReference {
                frames: vec![28, 31],
                steps: 40,
                iteration_cap: 60,
                step_halvings,
            }
            .to_string()
        };
        assert!(
            why(0).contains("frame(s) 28, 31 of 40 (cap 60 iterations): not a reference"),
            "{}",
            why(0)
        );
        assert!(
            why(2).contains("(cap 60 iterations, steps split into halves 2 deep)"),
            "{}",
            why(2)
        );
    }
}
