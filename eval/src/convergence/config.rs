//! What the convergence study runs ([`ConvergenceConfig`]).

use std::path::PathBuf;

use fem_ref::ElementOrder;
use freeform::PressureSpaceParams;
use serde::{Deserialize, Serialize};

use crate::convergence::options::{BoundaryTreatment, ConvergenceTest, VolumetricTerm};
use crate::fem_reference::FemResolution;
use crate::reduced_settings::ReducedSettings;

/// What the study runs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ConvergenceConfig {
    /// Tests.
    pub tests: Vec<ConvergenceTest>,
    /// Poisson ratios of the beam (E and ρ stay the beam's).
    pub poisson_ratios: Vec<f64>,
    /// Modes m.
    pub modes: Vec<usize>,
    /// Kernel counts K.
    pub kernels: Vec<usize>,
    /// Boundary treatments.
    pub treatments: Vec<BoundaryTreatment>,
    /// Volumetric terms.
    pub volumetric: Vec<VolumetricTerm>,
    /// The pressure space of [`VolumetricTerm::Projected`].
    pub pressure: PressureSpaceParams,
    /// Neumann-mode fractions whose inf-sup constants the static projected rows report.
    pub inf_sup_fractions: Vec<f64>,
    /// Everything else of the reduced runs (`modes`, `kernels` and `pins` are set per run).
    pub settings: ReducedSettings,
    /// Gravity of the static Bend as a fraction of the Bend's 9.8 m/s² (small: linear).
    pub static_gravity_scale: f64,
    /// Steps of the dynamic tests; `None` for Table 1's (300 Bend, 30 Twist).
    pub steps: Option<usize>,
    /// The FEM reference (static and dynamic).
    pub fem: FemResolution,
    /// Coarse FEM runs of the dynamic Bend at ν = 0.45 placed beside FreeForm in the plot.
    pub coarse_fem: Vec<FemResolution>,
    /// Check, per kernel count, that the basis grid is a converged integration pool: the
    /// first 2m eigenvalues with the same kernels on twice the points move by at most
    /// [`crate::convergence::POOL_TOLERANCE`] (default true).
    #[serde(default)]
    pub pool_check: bool,
    /// The static Bend's FEM reference, when not `fem` (a static solve costs seconds where a
    /// dynamic reference costs hours, so it can be much finer). `None` (default): `fem`.
    #[serde(default)]
    pub static_fem: Option<FemResolution>,
    /// A finer FEM at which the static reference is solved again, to measure the reference's
    /// own error (its MSE against the finer solution at its nodes and its tip's change): a
    /// static row whose MSE is below it is within the reference's error. `None` (default):
    /// not checked.
    #[serde(default)]
    pub static_reference_check: Option<FemResolution>,
    /// s of [`BoundaryTreatment::Nitsche`]'s `β = 2 s C` (default 2; ≥ 1 keeps the held body
    /// definite).
    #[serde(default = "default_nitsche_factor")]
    pub nitsche_stabilization_factor: f64,
    /// Cache folder (FEM trajectories, cubatures).
    pub cache_dir: PathBuf,
}

fn default_nitsche_factor() -> f64 {
    reduced_sim::NitscheParams::default().stabilization_factor
}

impl ConvergenceConfig {
    /// The static Bend's reference: `static_fem`, else `fem`.
    pub fn static_reference_resolution(&self) -> FemResolution {
        self.static_fem.unwrap_or(self.fem)
    }

    /// The whole study: the three tests at ν = 0.3 / 0.45 / 0.49, m = 8 … 64, K = 1000 and
    /// 2000, every treatment, every simulation point with Hessian reuse, the P2 res 6 reference
    /// of the dynamic tests and P1 / P2 res 2–4 beside it, the static Bend against P2 res 10
    /// (checked against P2 res 12).
    pub fn full(cache_dir: PathBuf) -> Self {
        let coarse = |order, cells_per_metre| FemResolution {
            order,
            cells_per_metre,
        };
        ConvergenceConfig {
            tests: vec![
                ConvergenceTest::StaticBend,
                ConvergenceTest::Bend,
                ConvergenceTest::Twist,
            ],
            poisson_ratios: vec![0.3, 0.45, 0.49],
            modes: vec![8, 12, 16, 24, 32, 48, 64],
            kernels: vec![1000, 2000],
            treatments: vec![
                BoundaryTreatment::Penalty,
                BoundaryTreatment::ExactInset,
                BoundaryTreatment::Weighted,
                BoundaryTreatment::Nitsche,
            ],
            volumetric: vec![VolumetricTerm::Pointwise, VolumetricTerm::Projected],
            pressure: PressureSpaceParams::default(),
            inf_sup_fractions: vec![0.5, 1.0, 2.0, 3.0, 5.0],
            settings: ReducedSettings {
                hessian_reuse: reduced_sim::SimulationParams::HESSIAN_REUSE,
                ..ReducedSettings::default()
            },
            static_gravity_scale: 1e-3,
            steps: None,
            fem: FemResolution::GROUND_TRUTH,
            coarse_fem: vec![
                coarse(ElementOrder::Linear, 2),
                coarse(ElementOrder::Linear, 3),
                coarse(ElementOrder::Linear, 4),
                coarse(ElementOrder::Quadratic, 2),
                coarse(ElementOrder::Quadratic, 3),
                coarse(ElementOrder::Quadratic, 4),
            ],
            pool_check: true,
            static_fem: Some(FemResolution {
                order: ElementOrder::Quadratic,
                cells_per_metre: 10,
            }),
            static_reference_check: Some(FemResolution {
                order: ElementOrder::Quadratic,
                cells_per_metre: 12,
            }),
            nitsche_stabilization_factor: default_nitsche_factor(),
            cache_dir,
        }
    }

    /// A minutes-long version: the static Bend at ν = 0.45, m = 8 / 16 / 32, K = 1000, every
    /// treatment and volumetric term, against P2 res 8 (checked against P2 res 10).
    pub fn quick(cache_dir: PathBuf) -> Self {
        ConvergenceConfig {
            tests: vec![ConvergenceTest::StaticBend],
            poisson_ratios: vec![0.45],
            modes: vec![8, 16, 32],
            kernels: vec![1000],
            steps: Some(100),
            fem: FemResolution {
                order: ElementOrder::Quadratic,
                cells_per_metre: 4,
            },
            coarse_fem: Vec::new(),
            static_fem: Some(FemResolution {
                order: ElementOrder::Quadratic,
                cells_per_metre: 8,
            }),
            static_reference_check: Some(FemResolution {
                order: ElementOrder::Quadratic,
                cells_per_metre: 10,
            }),
            ..ConvergenceConfig::full(cache_dir)
        }
    }
}
