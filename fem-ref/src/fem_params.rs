//! The options of a FEM simulation.

use std::time::Duration;

use hyperelastic::HessianTangent;
use optimize::NewtonParams;
use serde::{Deserialize, Serialize};

use crate::factor_memory::FactorMemoryLimit;
use crate::fill_reducing_ordering::FillReducingOrdering;

/// Options of a FEM simulation.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FemParams {
    /// Time step h (s, default 0.01).
    pub time_step: f64,
    /// Newton options (the workspace's one solver, [`optimize::minimize`]); its convergence
    /// test is `sqrt(Δxᵀ M Δx / mass) / L < tolerance`, L the largest rest bounding-box side:
    /// the same scale-invariant test as the reduced simulator. With
    /// [`optimize::HessianReuse::WhileContracting`] the sparse Cholesky factor is carried from step to
    /// step (chord steps while they contract, at most [`crate::FEM_FACTOR_MAX_AGE`] steps), and a
    /// step that does not converge that way is solved again with fresh Hessians; the default,
    /// [`optimize::HessianReuse::Never`], factors afresh every iteration.
    pub newton: NewtonParams,
    /// Element tangent (default PSD-projected, the references' setting; `Exact` is only safe
    /// while the system stays positive definite, and a failed factorization is then reported;
    /// `ExactWhenDefinite` assembles the exact Hessian and the projected one only when the
    /// exact one fails to factor, which converges in fewer iterations at large rotations;
    /// `ExactElseAbsolute` falls back to the absolute-eigenvalue tangent instead: on the
    /// Twist beam 182 instead of 189 Newton iterations, on the soft skull's Fix side sag (10
    /// cells, 65k P2 DOFs, steps 1–33) 398 instead of 276, one step 151 instead of 42; always
    /// projected took 416 there).
    pub tangent: HessianTangent,
    /// Elimination order of the sparse Cholesky factorization (default: nested dissection or
    /// minimum degree, whichever leaves the smaller factor).
    /// Only round-off depends on it, so it is not part of [`crate::FemSimulator::trajectory_key`].
    #[serde(default)]
    pub ordering: FillReducingOrdering,
    /// The most memory the sparse Cholesky factors may take (default
    /// [`FactorMemoryLimit::Available`]: what the operating system reports available at
    /// setup); a larger need is refused at setup. Not part of the trajectory key.
    #[serde(default)]
    pub factor_memory: FactorMemoryLimit,
    /// How deep a step whose Newton solve does not converge (iteration cap, stalled line
    /// search, a failed factorization or a non-finite value) is split: the step of h is taken
    /// again from its start as two backward-Euler steps of h/2, each of which may be split
    /// again, at most this many halvings deep (default 0: the step is kept unconverged and
    /// reported so, the first tables' setting). Frames stay at multiples of h; a step that
    /// still fails at the deepest level is reported unconverged (or its error returned).
    /// Not part of [`crate::FemSimulator::trajectory_key`]: a trajectory whose every step converged
    /// whole is what any depth computes, and [`crate::FemSimulator::run_cached`] stores one that
    /// needed a split under its own key ([`crate::FemSimulator::split_trajectory_key`]).
    #[serde(default)]
    pub failed_step_halvings: usize,
    /// How often [`crate::FemSimulator::run_cached`] saves the run so far
    /// ([`crate::RunCheckpoint`]; default [`DEFAULT_CHECKPOINT_INTERVAL`], `None`: only when
    /// the caller stops the run): after the first whole step at least this long after the
    /// last save, and at least ten times as long as the last save took, so that saving the
    /// frames of a large mesh never costs more than a tenth of the run. Not part of the
    /// trajectory key.
    #[serde(default = "default_checkpoint_interval")]
    pub checkpoint_interval: Option<Duration>,
}

/// [`FemParams::checkpoint_interval`]'s default: a killed run loses at most about five
/// minutes.
pub const DEFAULT_CHECKPOINT_INTERVAL: Duration = Duration::from_secs(300);

fn default_checkpoint_interval() -> Option<Duration> {
    Some(DEFAULT_CHECKPOINT_INTERVAL)
}

impl Default for FemParams {
    fn default() -> Self {
        FemParams {
            time_step: 0.01,
            newton: NewtonParams::default(),
            tangent: HessianTangent::ProjectedPsd,
            ordering: FillReducingOrdering::default(),
            factor_memory: FactorMemoryLimit::default(),
            failed_step_halvings: 0,
            checkpoint_interval: default_checkpoint_interval(),
        }
    }
}
