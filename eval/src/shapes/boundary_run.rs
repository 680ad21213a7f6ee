//! One boundary condition of one shape, ready to run any skinning field on and score against
//! the FEM reference.

use std::path::Path;

use hyperelastic::{MaterialField, MaterialSample, StableNeoHookean};
use reduced_sim::{QuadratureRule, SimulationParams, SkinningField};
use rkpm_core::IntegrationPoints;

use crate::EvalError;
use crate::reduced_run::{ReducedProblem, run_reduced};
use crate::shapes::result::MethodScores;
use freeform::fem_reference::FemRun;
use freeform::scene::SceneSpec;
use freeform::terminal_progress::TerminalProgress;
use freeform::{PinHold, PressureSpace, Simulation};

/// One boundary condition of one shape, ready to run any skinning field on.
pub(crate) struct BoundaryRun<'a> {
    pub(crate) points: &'a IntegrationPoints,
    pub(crate) material: MaterialSample,
    pub(crate) scene: &'a SceneSpec,
    pub(crate) params: SimulationParams,
    /// Where the elastic energy is integrated (the paper's setting: every point).
    pub(crate) quadrature: QuadratureRule,
    /// The projected volumetric term's pressure space (`None`: the material's own at every
    /// point, the paper's setting).
    pub(crate) pressure: Option<&'a PressureSpace>,
    /// Where an optimized cubature is cached.
    pub(crate) cache_dir: &'a Path,
    pub(crate) fem: &'a FemRun,
    pub(crate) steps: usize,
    pub(crate) length: f64,
    pub(crate) label: &'a str,
    pub(crate) progress: &'a TerminalProgress,
}

impl BoundaryRun<'_> {
    /// Simulates `field` (labelled `method`, its regions held by `pin_hold`) at the FEM
    /// vertices and scores it; also returns the integration points in each constrained region.
    pub(crate) fn score<B: SkinningField + ?Sized>(
        &self,
        field: &B,
        method: &str,
        pin_hold: PinHold,
    ) -> Result<(MethodScores, Vec<usize>), EvalError> {
        let run = run_reduced(
            &ReducedProblem {
                simulation: Simulation::new(
                    field,
                    self.points,
                    &MaterialField::Uniform(self.material),
                    StableNeoHookean,
                    self.scene,
                )
                .with_params(self.params)
                .with_quadrature(self.quadrature)
                .with_cache_dir(Some(self.cache_dir))
                .with_pin_hold(pin_hold)
                .with_pressure(self.pressure),
                output_points: self.fem.vertices(),
                steps: self.steps,
            },
            &format!("{method} {}", self.label),
            self.progress,
        )?;
        let scores = self.fem.score(field, &run.frames, self.length)?;
        let scores = MethodScores {
            mse: scores.errors.normalized_mse,
            max: scores.errors.normalized_max,
            fitting_residual: scores.fitting_residual,
            ms_per_step: run.report.ms_per_step,
            quadrature_points: run.report.quadrature.points,
            unconverged_steps: run.report.unconverged_steps,
            max_pin_deviation: match pin_hold {
                PinHold::Penalty => run.report.max_pin_deviation,
                PinHold::Exact { .. } | PinHold::Weighted { .. } => run.report.max_held_deviation,
            },
        };
        Ok((scores, run.report.region_points))
    }
}
