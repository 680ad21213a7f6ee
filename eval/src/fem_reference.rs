//! The FEM ground truth (DESIGN 3.8): one cached FEM run of any tetrahedral mesh and scene
//! ([`run_fem`]), and the beam's: P2 tetrahedra at 6 elements per metre, the configuration the
//! fem-ref convergence study chose (Bend tip within ≈ 0.3% of the Richardson limit at t = 1 s).

use optimize::NewtonParams;
use std::ops::ControlFlow;
use std::path::Path;

use fem_ref::{
    CachedRun, ElementOrder, FemMesh, FemModel, FemParams, FemScene, FemSimulator,
    FillReducingOrdering, MassKind, PointInterpolation, RunProgress, TetMesh, TrajectoryCache,
};
use hyperelastic::{HessianTangent, StableNeoHookean};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use hyperelastic::MaterialSample;

use reduced_sim::{DeformationMap, SkinningField};

use crate::EvalError;
use crate::beam::{BEAM_MAX, BEAM_MIN, BEAM_TIME_STEP, BeamTest, beam_material};
use crate::metrics::{TrajectoryErrors, basis_fitting_residual, per_frame_mse, trajectory_errors};
use crate::progress::Progress;
use freeform::scene::SceneSpec;

/// Resolution and element order of a FEM beam run.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FemResolution {
    /// P1 or P2.
    pub order: ElementOrder,
    /// Elements across the 1 m side (the mesh has 5r × r × r cubes of 6 tetrahedra).
    pub cells_per_metre: usize,
}

impl FemResolution {
    /// The ground truth: P2 at 6 cells per metre (27 378 DOFs).
    pub const GROUND_TRUTH: FemResolution = FemResolution {
        order: ElementOrder::Quadratic,
        cells_per_metre: 6,
    };

    /// "P2 res 6".
    pub fn label(&self) -> String {
        let p = match self.order {
            ElementOrder::Linear => 1,
            ElementOrder::Quadratic => 2,
        };
        format!("P{p} res {}", self.cells_per_metre)
    }
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

/// Runs (or loads from `cache_dir`) `steps` steps of `test` at `resolution` with the Newton
/// options `newton` (the defaults for the ground truth).
///
/// # Errors
/// [`EvalError`] for a failed step, an unusable cache or an empty region.
pub fn run_fem_beam(
    test: BeamTest,
    resolution: FemResolution,
    newton: NewtonParams,
    steps: usize,
    cache_dir: &Path,
    progress: &Progress,
) -> Result<FemRun, EvalError> {
    run_fem_beam_with(
        test,
        resolution,
        beam_material(),
        newton,
        steps,
        cache_dir,
        progress,
    )
}

/// [`run_fem_beam`] with another material than the beam's (the pin sweep's Poisson ratios).
///
/// # Errors
/// As [`run_fem_beam`].
pub fn run_fem_beam_with(
    test: BeamTest,
    resolution: FemResolution,
    material: MaterialSample,
    newton: NewtonParams,
    steps: usize,
    cache_dir: &Path,
    progress: &Progress,
) -> Result<FemRun, EvalError> {
    let scene = test.scene();
    let problem = beam_problem(&scene, resolution, material, newton, steps)?;
    let label = if material == beam_material() {
        format!("{} {}", test.name(), resolution.label())
    } else {
        format!(
            "{} {} ν={}",
            test.name(),
            resolution.label(),
            material.poisson_ratio
        )
    };
    run_fem(&problem, &label, cache_dir, progress)
}

/// The beam's FEM problem for `scene` (a [`BeamTest::scene`]) at `resolution`.
fn beam_problem(
    scene: &SceneSpec,
    resolution: FemResolution,
    material: MaterialSample,
    newton: NewtonParams,
    steps: usize,
) -> Result<FemProblem<'_>, EvalError> {
    let r = resolution.cells_per_metre;
    let tets = TetMesh::cuboid(BEAM_MIN, BEAM_MAX, [5 * r, r, r]).map_err(EvalError::FemBox)?;
    Ok(FemProblem {
        tets,
        order: resolution.order,
        material,
        scene,
        time_step: BEAM_TIME_STEP,
        newton,
        tangent: HessianTangent::ProjectedPsd,
        ordering: FillReducingOrdering::default(),
        failed_step_halvings: 0,
        steps,
    })
}

/// Fresh steps a cached beam reference is timed over ([`time_fem_beam`]).
pub const FEM_TIMING_STEPS: usize = 10;

/// Seconds per step of the first `steps` steps of `test` at `resolution` (the beam's material),
/// run fresh in this process, nothing read from or written to the cache: the FEM's cost
/// measured beside the method it is compared with, whatever machine or solver produced a
/// cached trajectory.
///
/// # Errors
/// [`EvalError`] for a model that cannot be built or a failed step.
pub fn time_fem_beam(
    test: BeamTest,
    resolution: FemResolution,
    newton: NewtonParams,
    steps: usize,
) -> Result<f64, EvalError> {
    let scene = test.scene();
    let (mut sim, _) =
        beam_problem(&scene, resolution, beam_material(), newton, steps)?.simulator()?;
    let start = std::time::Instant::now();
    for step in 1..=steps {
        sim.step()
            .map_err(|source| EvalError::Fem(fem_ref::FemRunError::Step { step, source }))?;
    }
    Ok(start.elapsed().as_secs_f64() / steps.max(1) as f64)
}

/// Seconds per step of the beam reference `run` (of `test` at `resolution`) as timed in this
/// process, and the steps timed: the run's own when it was computed now, [`FEM_TIMING_STEPS`]
/// fresh steps ([`time_fem_beam`]) when it came from the cache, whose time is of whatever
/// machine and solver produced it.
///
/// # Errors
/// As [`time_fem_beam`].
pub fn beam_seconds_per_step_here(
    run: &FemRun,
    test: BeamTest,
    resolution: FemResolution,
    newton: NewtonParams,
    steps: usize,
) -> Result<(f64, usize), EvalError> {
    if !run.cached {
        return Ok((run.seconds_per_step, steps));
    }
    let timed = FEM_TIMING_STEPS.min(steps);
    Ok((time_fem_beam(test, resolution, newton, timed)?, timed))
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
    /// [`EvalError::FemModel`] / [`EvalError::FemSetup`] for a model or scene that cannot be
    /// built (e.g. a region that selects no node).
    pub fn simulator(&self) -> Result<(FemSimulator<StableNeoHookean>, Vec<usize>), EvalError> {
        let parts = self.parts()?;
        let region_nodes = parts.region_nodes();
        let sim = FemSimulator::new(parts.model, parts.scene, parts.params)
            .map_err(EvalError::FemSetup)?;
        Ok((sim, region_nodes))
    }

    /// What [`Self::simulator`] builds the simulator from.
    fn parts(&self) -> Result<SimulatorParts, EvalError> {
        let elements = self.tets.tets().len();
        let mesh = FemMesh::new(self.tets.clone(), self.order);
        let model = FemModel::new(
            mesh,
            &vec![self.material; elements],
            StableNeoHookean,
            MassKind::Consistent,
        )
        .map_err(EvalError::FemModel)?;
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
/// [`EvalError::FemModel`] / [`EvalError::FemSetup`] for a model or scene that cannot be built
/// (e.g. a region that selects no node), [`EvalError::Fem`] for a failed step or an unusable
/// cache.
pub fn run_fem(
    problem: &FemProblem<'_>,
    label: &str,
    cache_dir: &Path,
    progress: &Progress,
) -> Result<FemRun, EvalError> {
    let parts = problem.parts()?;
    let region_nodes = parts.region_nodes();
    let cache = TrajectoryCache::new(cache_dir.join("fem"));
    let solved = match load_solved(&parts, problem, &cache)? {
        Some(solved) => solved,
        None => step_through(
            parts,
            problem.steps,
            &problem.scene.label(),
            &cache,
            label,
            progress,
        )?,
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

/// [`run_fem`]'s trajectory when `<cache_dir>/fem/` holds it, else `None`: nothing is computed
/// (a checkpoint of an unfinished run is not a trajectory).
///
/// # Errors
/// As [`run_fem`], but for a failed step (no step is taken).
pub fn cached_fem(
    problem: &FemProblem<'_>,
    label: &str,
    cache_dir: &Path,
    progress: &Progress,
) -> Result<Option<FemRun>, EvalError> {
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
) -> Result<Option<Solved>, EvalError> {
    let cached_trajectory = FemSimulator::load_cached(
        &parts.model,
        &parts.scene,
        &parts.params,
        problem.steps,
        &problem.scene.label(),
        cache,
    )
    .map_err(|e| EvalError::Fem(fem_ref::FemRunError::Cache(e)))?;
    let Some(trajectory) = cached_trajectory else {
        return Ok(None);
    };
    Ok(Some(Solved {
        dofs: parts
            .scene
            .free_dofs(parts.model.mesh().nodes().len())
            .map_err(EvalError::FemSetup)?,
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
    progress: &Progress,
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
        progress.status(format!(
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
        progress.status(format!(
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
    progress: &Progress,
) -> Result<Solved, EvalError> {
    let mut sim =
        FemSimulator::new(parts.model, parts.scene, parts.params).map_err(EvalError::FemSetup)?;
    let dofs = sim.free_dofs();
    let bar = progress.bar(steps, format!("FEM {label} ({dofs} DOFs)"));
    let run = sim
        .run_cached(steps, label_of_scene, cache, |event| {
            match event {
                RunProgress::Resumed { steps_done } => {
                    bar.resume_at(steps_done as u64);
                    progress.status(format!(
                        "FEM {label}: resuming at step {steps_done} of {steps} from its checkpoint"
                    ));
                }
                RunProgress::Stepped { .. } => bar.inc(1),
            }
            ControlFlow::Continue(())
        })
        .map_err(EvalError::Fem)?;
    bar.finish_and_clear();
    if let Some(e) = &run.checkpoint_error {
        progress.status(format!("FEM {label}: a checkpoint was not saved: {e}"));
    }
    Ok(Solved {
        mesh: sim.model().mesh().clone(),
        run,
        dofs,
        split_steps: sim.split_steps(),
    })
}

/// How well a method's trajectory matches a FEM run (DESIGN 4.3).
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
    /// `length` (DESIGN 4.3): normalized MSE and max error, and the basis fitting residual of
    /// this trajectory through `field`.
    ///
    /// # Errors
    /// [`EvalError::Metrics`] for mismatched or non-finite frames or a singular fit,
    /// [`EvalError::OutputMap`] if `field` cannot be evaluated at the vertices.
    pub fn score<B: SkinningField + ?Sized>(
        &self,
        field: &B,
        frames: &[Vec<Vector3<f64>>],
        length: f64,
    ) -> Result<FieldScores, EvalError> {
        let reference = self.vertex_frames();
        let errors = trajectory_errors(&frames[1..], &reference[1..], length)?;
        let per_frame_mse = per_frame_mse(&frames[1..], &reference[1..], length)?;
        let map = DeformationMap::new(field, self.vertices()).map_err(EvalError::OutputMap)?;
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
    /// [`EvalError::PointLocation`] if a point lies outside the mesh.
    pub fn frames_at(&self, points: &[Vector3<f64>]) -> Result<Vec<Vec<Vector3<f64>>>, EvalError> {
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

    /// A run served from the cache (found before the simulator is built) reports what the
    /// computed run did: the same frames, mesh, free DOFs, held nodes and iterations.
    #[test]
    fn a_reference_from_the_cache_matches_the_computed_one_field_for_field() {
        let dir = test_support::fixtures::scratch_dir("eval-fem-run-cache");
        let run = || {
            run_fem_beam(
                BeamTest::Bend,
                FemResolution {
                    order: ElementOrder::Quadratic,
                    cells_per_metre: 1,
                },
                NewtonParams::default(),
                2,
                &dir,
                &Progress {
                    quiet: true,
                    hide_bars: true,
                },
            )
            .unwrap()
        };
        let computed = run();
        let cached = run();
        assert!(!computed.cached && cached.cached);
        assert!(computed.dofs > 0 && computed.region_nodes.iter().all(|&n| n > 0));
        assert_eq!(cached.dofs, computed.dofs);
        assert_eq!(cached.region_nodes, computed.region_nodes);
        assert_eq!(cached.mesh.nodes(), computed.mesh.nodes());
        assert_eq!(cached.frames, computed.frames);
        assert_eq!(cached.step_iterations, computed.step_iterations);
        assert_eq!(cached.step_converged, computed.step_converged);
        assert_eq!(cached.seconds_per_step, computed.seconds_per_step);
    }

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
