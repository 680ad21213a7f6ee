//! Newton's method with a backtracking line search for one implicit step, and its report
//! (DESIGN 3.7).

use std::time::Instant;

use faer::Side;
use faer::linalg::solvers::{Llt, Solve};
use hyperelastic::{HyperelasticMaterial, Tangent};
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::incremental_potential::IncrementalPotential;

/// Options of the Newton solve of one step.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct NewtonParams {
    /// Iteration cap (default 20).
    pub max_iterations: usize,
    /// Convergence tolerance on the Newton step, scale-invariant (default 1e-6): converged when
    /// `sqrt(Δzᵀ M_z Δz / mass) / L < tolerance`, i.e. the step moves the object's mass by less
    /// than `tolerance · L` (root mean square), L the largest rest bounding-box side.
    pub tolerance: f64,
    /// Armijo sufficient-decrease constant c in `E(z + αΔz) ≤ E(z) + c α ∇Eᵀ Δz`
    /// (default 1e-4).
    pub armijo: f64,
    /// Step halvings allowed per iteration before the line search gives up (default 30).
    pub max_line_search_cuts: usize,
    /// Material tangent used in the Hessian (default PSD-projected, which keeps the Newton
    /// system positive definite).
    pub tangent: Tangent,
}

impl Default for NewtonParams {
    fn default() -> Self {
        NewtonParams {
            max_iterations: 20,
            tolerance: 1e-6,
            armijo: 1e-4,
            max_line_search_cuts: 30,
            tangent: Tangent::ProjectedPsd,
        }
    }
}

/// Why Newton stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum NewtonStop {
    /// The step norm fell below the tolerance.
    Converged,
    /// `max_iterations` reached first.
    IterationLimit,
    /// The line search found no decrease within `max_line_search_cuts` halvings.
    LineSearchStalled,
}

/// Seconds spent in each part of a step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StepTimings {
    /// Gradient and Hessian of E (elastic products, scene terms, inertia).
    pub assembly: f64,
    /// Cholesky factorization and solve.
    pub solve: f64,
    /// Energy evaluations of the line search.
    pub line_search: f64,
}

impl StepTimings {
    /// Sum of the parts (s).
    pub fn total(&self) -> f64 {
        self.assembly + self.solve + self.line_search
    }
}

/// What one step did.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct StepReport {
    /// Newton iterations performed (each ends in a convergence test).
    pub iterations: usize,
    /// Hessians assembled and factored (an iteration whose lagged-Hessian step already passes
    /// the convergence test assembles none).
    pub hessian_assemblies: usize,
    /// The last convergence measure `sqrt(Δzᵀ M_z Δz / mass) / L` (dimensionless).
    pub residual: f64,
    /// Total step halvings of the line search over all iterations.
    pub line_search_cuts: usize,
    /// Why Newton stopped.
    pub stop: NewtonStop,
    /// Final incremental potential E (J, up to a constant).
    pub energy: f64,
    /// Time per part.
    pub timings: StepTimings,
}

impl StepReport {
    /// True when Newton met its tolerance.
    pub fn converged(&self) -> bool {
        self.stop == NewtonStop::Converged
    }
}

/// A step failed; the simulator's state is left as it was before the step.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum StepError {
    /// A NaN or infinity appeared.
    #[error("non-finite {quantity} at Newton iteration {iteration}")]
    NonFinite {
        /// Iteration where it appeared (0 = before the first solve).
        iteration: usize,
        /// What was non-finite ("energy", "gradient", "Hessian", "Newton step").
        quantity: &'static str,
    },
    /// The Newton system was not positive definite (a static solve with free rigid motions,
    /// or an exact tangent that is indefinite).
    #[error("the Newton system is not positive definite at iteration {iteration}")]
    NotPositiveDefinite {
        /// Iteration.
        iteration: usize,
    },
    /// The time step is not finite and positive.
    #[error("the time step must be finite and positive, got {0} s")]
    InvalidTimeStep(f64),
}

/// Minimizes E from `z` in place. `step_norm(Δz)` is the scale-invariant convergence measure.
pub(crate) fn minimize<M: HyperelasticMaterial>(
    potential: &IncrementalPotential<'_, M>,
    z: &mut Vec<f64>,
    params: &NewtonParams,
    step_norm: impl Fn(&[f64]) -> f64,
) -> Result<StepReport, StepError> {
    let mut timings = StepTimings::default();
    let mut energy = potential.energy(z);
    if !energy.is_finite() {
        return Err(StepError::NonFinite {
            iteration: 0,
            quantity: "energy",
        });
    }
    let mut report = StepReport {
        iterations: 0,
        hessian_assemblies: 0,
        residual: f64::INFINITY,
        line_search_cuts: 0,
        stop: NewtonStop::IterationLimit,
        energy,
        timings,
    };
    // The factorization of the last Hessian: at later iterations the convergence test first
    // tries the step it gives (a lagged-Hessian Newton step, gradient only); a new Hessian is
    // assembled only when that step is not yet below the tolerance.
    let mut factor: Option<Llt<f64>> = None;
    for iteration in 1..=params.max_iterations {
        report.iterations = iteration;
        if let Some(llt) = &factor {
            let t = Instant::now();
            let gradient = potential.gradient(z);
            timings.assembly += t.elapsed().as_secs_f64();
            let t = Instant::now();
            let step = newton_step(llt, &gradient);
            timings.solve += t.elapsed().as_secs_f64();
            let residual = step_norm(&step);
            if residual.is_finite() && residual < params.tolerance {
                report.residual = residual;
                apply(z, &step, 1.0);
                report.stop = NewtonStop::Converged;
                break;
            }
        }
        let t = Instant::now();
        let (gradient, hessian) = potential.derivatives(z);
        timings.assembly += t.elapsed().as_secs_f64();
        report.hessian_assemblies += 1;
        if !gradient.iter().all(|g| g.is_finite()) {
            return Err(StepError::NonFinite {
                iteration,
                quantity: "gradient",
            });
        }
        let t = Instant::now();
        let llt = hessian
            .llt(Side::Lower)
            .map_err(|_| StepError::NotPositiveDefinite { iteration })?;
        let step = newton_step(&llt, &gradient);
        factor = Some(llt);
        timings.solve += t.elapsed().as_secs_f64();
        if !step.iter().all(|s| s.is_finite()) {
            return Err(StepError::NonFinite {
                iteration,
                quantity: "Newton step",
            });
        }
        let residual = step_norm(&step);
        report.residual = residual;
        if residual < params.tolerance {
            // Within tolerance: take the full step (quadratically small) and stop.
            apply(z, &step, 1.0);
            report.stop = NewtonStop::Converged;
            break;
        }
        let t = Instant::now();
        let slope: f64 = gradient.iter().zip(&step).map(|(g, s)| g * s).sum();
        let mut alpha = 1.0;
        let mut accepted = None;
        for _ in 0..=params.max_line_search_cuts {
            let mut trial = z.clone();
            apply(&mut trial, &step, alpha);
            let e = potential.energy(&trial);
            if e.is_finite() && e <= energy + params.armijo * alpha * slope {
                accepted = Some((trial, e));
                break;
            }
            alpha *= 0.5;
            report.line_search_cuts += 1;
        }
        timings.line_search += t.elapsed().as_secs_f64();
        match accepted {
            Some((trial, e)) => {
                *z = trial;
                energy = e;
            }
            None => {
                report.line_search_cuts -= 1;
                report.stop = NewtonStop::LineSearchStalled;
                break;
            }
        }
    }
    report.energy = energy;
    report.timings = timings;
    Ok(report)
}

/// `-H⁻¹ g` from a Cholesky factor of H.
fn newton_step(llt: &Llt<f64>, gradient: &[f64]) -> Vec<f64> {
    let mut step = faer::Mat::<f64>::from_fn(gradient.len(), 1, |i, _| -gradient[i]);
    llt.solve_in_place(step.as_mut());
    (0..gradient.len()).map(|i| step[(i, 0)]).collect()
}

/// `z += α Δz`.
fn apply(z: &mut [f64], step: &[f64], alpha: f64) {
    for (a, s) in z.iter_mut().zip(step) {
        *a += alpha * s;
    }
}
