//! The beam's FEM ground truth (design §3.8): P2 tetrahedra at 6 elements per metre, the
//! configuration the fem-ref convergence study chose (Bend tip within ≈ 0.3% of the Richardson
//! limit at t = 1 s), run through the library's cached FEM reference
//! ([`freeform::fem_reference::run_fem`]).

use optimize::NewtonParams;
use std::path::Path;

use fem_ref::{ElementOrder, FillReducingOrdering, TetMesh};
use freeform::fem_reference::{FemProblem, FemRun, run_fem};
use freeform::scene::SceneSpec;
use freeform::terminal_progress::{BarProgress, TerminalProgress};
use hyperelastic::{HessianTangent, MaterialSample};
use serde::{Deserialize, Serialize};

use crate::EvalError;
use crate::beam_scenario::{BEAM_MAX, BEAM_MIN, BEAM_TIME_STEP, BeamTest, beam_material};

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
    progress: &TerminalProgress,
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
    progress: &TerminalProgress,
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
    Ok(run_fem(
        &problem,
        &label,
        cache_dir,
        &BarProgress::new(*progress),
    )?)
}

/// [`run_fem_beam_with`] under [`NewtonParams::default`], checked: `Ok(Err(why))` when a step
/// did not converge (the reference must not be scored; `why` names the test, ν and the step).
///
/// # Errors
/// As [`run_fem_beam`].
pub fn converged_fem_beam(
    test: BeamTest,
    resolution: FemResolution,
    material: MaterialSample,
    steps: usize,
    cache_dir: &Path,
    progress: &TerminalProgress,
) -> Result<Result<FemRun, String>, EvalError> {
    let newton = NewtonParams::default();
    let fem = run_fem_beam_with(
        test, resolution, material, newton, steps, cache_dir, progress,
    )?;
    Ok(match fem.check_converged(newton.max_iterations) {
        Ok(()) => Ok(fem),
        Err(why) => Err(format!(
            "ν = {}, {}: {why}",
            material.poisson_ratio,
            test.name()
        )),
    })
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
                &TerminalProgress {
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
}
