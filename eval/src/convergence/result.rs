//! What the convergence study measures: one [`ConvergenceRow`] per (test, ν, K, m, treatment,
//! volumetric term), the coarse FEM points, the references it refused.

use freeform::metrics::trajectory_errors;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::EvalError;
use crate::beam_scenario::beam_length_scale;
use crate::convergence::static_reference::{StaticReference, field_errors, tip_index};

use crate::convergence::options::{BoundaryTreatment, ConvergenceTest, VolumetricTerm};

/// One (test, ν, K, m, treatment) result.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ConvergenceRow {
    /// The test.
    pub test: ConvergenceTest,
    /// Poisson ratio.
    pub nu: f64,
    /// Modes m.
    pub m: usize,
    /// Kernels K.
    pub kernels: usize,
    /// Boundary treatment.
    pub treatment: BoundaryTreatment,
    /// Volumetric term.
    pub volumetric: VolumetricTerm,
    /// Pressure functions P of the projected term (0 for the pointwise one).
    pub pressure_functions: usize,
    /// Whether this is the library's default treatment and volumetric term.
    pub default: bool,
    /// Normalized MSE against the FEM, `mean |x − x*|² / L²` over the output points (and frames).
    pub mse: f64,
    /// Relative L2 error of the displacements, `sqrt(Σ|u − u*|² / Σ|u*|²)` over points (and
    /// frames).
    pub relative_error: f64,
    /// Tip error: `max_t |x_tip − x*_tip| / max_t |u*_tip|` at the node nearest the tip corner
    /// (5, 1, 1).
    pub tip_error: f64,
    /// Static Bend: `u_tip,y / u*_tip,y − 1` (+ too soft, − too stiff); NaN for dynamic tests.
    pub tip_ratio: f64,
    /// Largest distance of an FEM node in a constrained region from its target (m); for
    /// [`BoundaryTreatment::Nitsche`], whose held part is prescribed, the interface samples'
    /// largest distance from their targets.
    pub held_drift: f64,
    /// Milliseconds per step (the static solve's for the static test).
    pub ms_per_step: f64,
    /// Normalized MSE of the L2 projection of the FEM field onto the subspace (static only).
    pub best_l2: Option<f64>,
    /// Normalized MSE of the energy projection of the FEM field onto the subspace with the
    /// held nodes tied (static only; module docs).
    pub best_energy: Option<f64>,
    /// Static projected rows: the discrete inf-sup constant β of the pressure space with each
    /// candidate count of Neumann modes ([`crate::convergence::ConvergenceConfig::inf_sup_fractions`]).
    pub inf_sup: Vec<(usize, f64)>,
    /// Why the run stopped, when it did (then the errors are NaN).
    pub failure: Option<String>,
}

impl ConvergenceRow {
    /// A row of `test` at `nu` with `treatment` and `volumetric` before it is measured: NaN
    /// scores, no failure, m, K and the pressure functions 0, not the default.
    pub(crate) fn unmeasured(
        test: ConvergenceTest,
        nu: f64,
        treatment: BoundaryTreatment,
        volumetric: VolumetricTerm,
    ) -> Self {
        ConvergenceRow {
            test,
            nu,
            m: 0,
            kernels: 0,
            treatment,
            volumetric,
            pressure_functions: 0,
            default: false,
            mse: f64::NAN,
            relative_error: f64::NAN,
            tip_error: f64::NAN,
            tip_ratio: f64::NAN,
            held_drift: f64::NAN,
            ms_per_step: f64::NAN,
            best_l2: None,
            best_energy: None,
            inf_sup: Vec::new(),
            failure: None,
        }
    }

    /// Scores the static displacements `ours` (m) at the reference's nodes: the MSE, the
    /// relative error, the tip error and the tip's ratio.
    pub(crate) fn score_static(&mut self, ours: &[Vector3<f64>], reference: &StaticReference) {
        let (mse, relative) = field_errors(ours, &reference.displacements);
        self.mse = mse;
        self.relative_error = relative;
        let tip = reference.tip;
        let exact_tip = reference.displacements[tip];
        self.tip_error = (ours[tip] - exact_tip).norm() / exact_tip.norm();
        self.tip_ratio = ours[tip].y / exact_tip.y - 1.0;
    }

    /// Scores `frames` (frame 0 the rest state) against the FEM's `reference` frames at its
    /// `vertices`: the MSE, the relative error and the tip error.
    ///
    /// # Errors
    /// [`EvalError::Metrics`] for frames that do not match the reference.
    pub(crate) fn score_frames(
        &mut self,
        frames: &[Vec<Vector3<f64>>],
        reference: &[Vec<Vector3<f64>>],
        vertices: &[Vector3<f64>],
    ) -> Result<(), EvalError> {
        let errors = trajectory_errors(&frames[1..], &reference[1..], beam_length_scale())?;
        self.mse = errors.normalized_mse;
        let (mut error, mut size) = (0.0, 0.0);
        let tip = tip_index(vertices);
        let (mut tip_error, mut tip_size): (f64, f64) = (0.0, 0.0);
        for (ours, theirs) in frames.iter().zip(reference) {
            for ((a, b), rest) in ours.iter().zip(theirs).zip(vertices) {
                error += (a - b).norm_squared();
                size += (b - rest).norm_squared();
            }
            tip_error = tip_error.max((ours[tip] - theirs[tip]).norm());
            tip_size = tip_size.max((theirs[tip] - vertices[tip]).norm());
        }
        self.relative_error = (error / size).sqrt();
        self.tip_error = tip_error / tip_size;
        Ok(())
    }
}

/// A coarse FEM's dynamic Bend at ν = 0.45.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CoarseFemRow {
    /// "P2 res 4".
    pub resolution: String,
    /// Normalized MSE against the reference.
    pub mse: f64,
    /// Seconds per step as run (or as cached).
    pub ms_per_step: f64,
}

/// The study's results.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ConvergenceStudy {
    /// One row per run.
    pub rows: Vec<ConvergenceRow>,
    /// The coarse FEM points.
    pub coarse_fem: Vec<CoarseFemRow>,
    /// References that failed their own check, and so scored nothing.
    pub refused_references: Vec<String>,
    /// Per kernel count: whether the basis's integration pool is converged
    /// ([`crate::convergence::ConvergenceConfig::pool_check`]).
    #[serde(default)]
    pub pool_checks: Vec<crate::convergence::PoolCheckRow>,
    /// Per ν: the static reference's own error against a finer FEM
    /// ([`crate::convergence::ConvergenceConfig::static_reference_check`]).
    #[serde(default)]
    pub static_reference_checks: Vec<StaticReferenceCheck>,
}

/// The static reference's own error at one ν, measured against a finer FEM.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StaticReferenceCheck {
    /// Poisson ratio.
    pub nu: f64,
    /// The reference, "P2 res 6".
    pub resolution: String,
    /// The finer FEM, "P2 res 8".
    pub finer: String,
    /// Normalized MSE of the reference against the finer solution at the reference's nodes:
    /// static rows below it are within the reference's own error.
    pub mse: f64,
    /// `u_tip,y / u'_tip,y − 1` (− the reference is stiffer than the finer FEM).
    pub tip_change: f64,
}
