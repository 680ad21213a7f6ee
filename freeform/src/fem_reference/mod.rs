//! The FEM reference of a scene (feature `fem`; design §3.8): one tetrahedral P1/P2 run of a
//! [`SceneSpec`] with one material, run or loaded from a content-keyed cache ([`run_fem`],
//! [`cached_fem`]), and the scores of a reduced trajectory against it ([`FemRun::score`],
//! design §4.3).

use std::ops::ControlFlow;
use std::path::Path;

use fem_ref::{
    CachedRun, ElementOrder, FemMesh, FemModel, FemParams, FemScene, FemSimulator,
    FillReducingOrdering, MassKind, RunProgress, TetMesh, TrajectoryCache,
};
use hyperelastic::{HessianTangent, MaterialSample, StableNeoHookean};
use nalgebra::Vector3;
use optimize::NewtonParams;
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::metrics::MetricsError;
use crate::progress::Progress;
use crate::scene::{SceneSpec, SceneSpecError};

mod scores;
pub use scores::{FieldScores, UnconvergedReference};

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
