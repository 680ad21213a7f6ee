//! Newton's method with an Armijo backtracking line search and a lagged-factor convergence
//! check.
//!
//! Each iteration k (x the unknowns, g the gradient, H the Hessian, ‖·‖ the objective's
//! scale-invariant step norm):
//!
//! 1. With the factorization of the last H: `Δx = −H_{k−1}⁻¹ g(x)`; if `‖Δx‖ < tol`, take the
//!    full step and stop (converged without assembling a new Hessian).
//! 2. Assemble and factor `H(x)`, `Δx = −H⁻¹ g`; if `‖Δx‖ < tol`, take the full step and stop.
//! 3. Halve α from 1 until `E(x + αΔx) ≤ E(x) + c α gᵀΔx` (Armijo); if no α within the cut
//!    budget decreases E, stop with [`NewtonStop::LineSearchStalled`].
//!
//! Reaching the iteration cap stops with [`NewtonStop::IterationLimit`]; the last iterate is
//! kept either way, and the report says why it stopped.
//!
//! With [`HessianReuse::WhileContracting`], step 1 goes further: when the lagged step is not yet
//! converged but is at most `contraction` times the previous step, it is taken (with the same
//! line search) instead of assembling a new Hessian (a chord step), and
//! [`minimize_reusing`] carries the factor from one solve to the next (e.g. across time
//! steps). Convergence is tested exactly as without reuse, so the converged point meets the
//! same tolerance; it is reached by more, cheaper iterations.

use std::time::Instant;

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// What [`minimize`] needs from an objective E(x).
///
/// The gradient may live in a smaller space than x (e.g. only the free DOFs of a FEM with
/// Dirichlet nodes): the solver only hands it back to the objective ([`Self::solve`],
/// [`Self::directional_derivative`]); steps always live in x's space.
pub trait NewtonObjective {
    /// The assembled Hessian (dense matrix, sparse values, …).
    type Hessian;
    /// Its factorization (e.g. a Cholesky factor).
    type Factor;

    /// E(x); may be non-finite, which the line search rejects.
    fn energy(&self, x: &[f64]) -> f64;

    /// ∇E(x).
    fn gradient(&self, x: &[f64]) -> Vec<f64>;

    /// The Hessian at x with the gradient at x. `gradient` is the gradient at x when the solver
    /// already has it (return it, or recompute it: the values must be the same); `None` asks
    /// for it (an objective may compute both in one pass).
    fn gradient_and_hessian(
        &self,
        x: &[f64],
        gradient: Option<Vec<f64>>,
    ) -> (Vec<f64>, Self::Hessian);

    /// Factors the Hessian, or `None` when it is not positive definite.
    fn factor(&self, hessian: Self::Hessian) -> Option<Self::Factor>;

    /// The Newton step `Δx = −H⁻¹ g` in x's space.
    fn solve(&self, factor: &Self::Factor, gradient: &[f64]) -> Vec<f64>;

    /// The scale-invariant size of a step, compared with [`NewtonParams::tolerance`] (for the
    /// simulators: the root-mean-square distance the step moves the mass, over L).
    fn step_norm(&self, step: &[f64]) -> f64;

    /// The largest fraction α ≤ 1 of `step` the objective can take from x (default 1): an
    /// objective with a barrier returns where its first constraint would come too close, so the
    /// line search (which starts at α) and the converged last step never leave the feasible
    /// set.
    fn max_step(&self, _x: &[f64], _step: &[f64]) -> f64 {
        1.0
    }

    /// `gᵀΔx`, the slope of E along the step (default: the dot product, for a gradient in x's
    /// space).
    fn directional_derivative(&self, gradient: &[f64], step: &[f64]) -> f64 {
        gradient.iter().zip(step).map(|(g, s)| g * s).sum()
    }
}

/// Whether Newton may keep stepping with an older Hessian factorization.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HessianReuse {
    /// A new Hessian for every iteration whose lagged step does not pass the convergence test
    /// (default; the setting of the paper's tables).
    #[default]
    Never,
    /// Take the step of the last factorization while its norm is at most `contraction` times
    /// the previous step's (the first step of a solve always may), with the Armijo line search;
    /// assemble a new Hessian when it does not contract or the line search stalls.
    WhileContracting {
        /// Required ratio of successive step norms, in (0, 1) (e.g. 0.5).
        contraction: f64,
    },
}

/// Options of [`minimize`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct NewtonParams {
    /// Iteration cap (default 20).
    pub max_iterations: usize,
    /// Converged when the objective's step norm of a Newton step falls below this (default
    /// 1e-6; for the simulators, the step moves the mass by less than `tolerance · L` root mean
    /// square, L the largest rest bounding-box side).
    pub tolerance: f64,
    /// Armijo sufficient-decrease constant c in `E(x + αΔx) ≤ E(x) + c α gᵀΔx` (default 1e-4).
    pub armijo: f64,
    /// Step halvings allowed per iteration before the line search gives up (default 30).
    pub max_line_search_cuts: usize,
    /// Whether to keep stepping with an older Hessian (default [`HessianReuse::Never`]).
    #[serde(default)]
    pub hessian_reuse: HessianReuse,
}

impl Default for NewtonParams {
    fn default() -> Self {
        NewtonParams {
            max_iterations: 20,
            tolerance: 1e-6,
            armijo: 1e-4,
            max_line_search_cuts: 30,
            hessian_reuse: HessianReuse::Never,
        }
    }
}

/// Why Newton stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NewtonStop {
    /// The step norm fell below the tolerance.
    #[serde(alias = "Converged")]
    Converged,
    /// `max_iterations` reached first.
    #[serde(alias = "IterationLimit")]
    IterationLimit,
    /// The line search found no decrease within `max_line_search_cuts` halvings.
    #[serde(alias = "LineSearchStalled")]
    LineSearchStalled,
}

/// Seconds spent in each part of a solve.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct NewtonTimings {
    /// Gradients and Hessians.
    pub assembly: f64,
    /// Factorizations and solves.
    pub solve: f64,
    /// Energy evaluations of the line search.
    pub line_search: f64,
}

impl NewtonTimings {
    /// Sum of the parts (s).
    pub fn total(&self) -> f64 {
        self.assembly + self.solve + self.line_search
    }
}

/// What one solve did.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct NewtonReport {
    /// Newton iterations performed (each ends in a convergence test).
    pub iterations: usize,
    /// Hessians assembled and factored (an iteration whose lagged-Hessian step already passes
    /// the convergence test assembles none).
    pub hessian_assemblies: usize,
    /// The last convergence measure (the objective's step norm; ∞ before the first).
    pub residual: f64,
    /// Step halvings of the line search over all iterations (the last try of a stalled
    /// search is not a cut).
    pub line_search_cuts: usize,
    /// Steps taken along an older factorization ([`HessianReuse::WhileContracting`]).
    #[serde(default)]
    pub lagged_steps: usize,
    /// Why Newton stopped.
    pub stop: NewtonStop,
    /// The final E.
    pub energy: f64,
    /// Time per part.
    pub timings: NewtonTimings,
}

impl NewtonReport {
    /// True when Newton met its tolerance.
    pub fn converged(&self) -> bool {
        self.stop == NewtonStop::Converged
    }

    /// The report of a problem solved again after this solve (a retry, a re-lagged contact
    /// set): `second`'s outcome (stop, residual, energy), with the iterations, assemblies,
    /// cuts, chord steps and time of both.
    pub fn followed_by(&self, second: &NewtonReport) -> NewtonReport {
        NewtonReport {
            iterations: self.iterations + second.iterations,
            hessian_assemblies: self.hessian_assemblies + second.hessian_assemblies,
            line_search_cuts: self.line_search_cuts + second.line_search_cuts,
            lagged_steps: self.lagged_steps + second.lagged_steps,
            timings: NewtonTimings {
                assembly: self.timings.assembly + second.timings.assembly,
                solve: self.timings.solve + second.timings.solve,
                line_search: self.timings.line_search + second.timings.line_search,
            },
            ..*second
        }
    }
}

/// A factorization carried from one solve into the next similar one (the next time step, for
/// [`minimize_reusing`]), with the solves it has been carried across since it was assembled.
#[derive(Debug)]
pub struct CarriedFactor<F> {
    factor: F,
    age: usize,
}

impl<F> CarriedFactor<F> {
    /// For a solve that may use a factorization carried across fewer than `max_age` solves:
    /// `carried`'s factorization and age, or none (age 0) when there is none or it is older.
    pub fn usable(carried: Option<Self>, max_age: usize) -> (Option<F>, usize) {
        match carried {
            Some(carried) if carried.age < max_age => (Some(carried.factor), carried.age),
            _ => (None, 0),
        }
    }

    /// What to carry after a solve that began with a factorization of age `age` and left
    /// `factor`: one solve older, or of age 1 when the solve (`report`) assembled a Hessian.
    pub fn after(factor: Option<F>, age: usize, report: &NewtonReport) -> Option<Self> {
        factor.map(|factor| CarriedFactor {
            factor,
            age: if report.hessian_assemblies > 0 {
                1
            } else {
                age + 1
            },
        })
    }
}

/// The solve cannot go on; x is left at the last accepted iterate.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum NewtonError {
    /// A NaN or infinity appeared.
    #[error("non-finite {quantity} at Newton iteration {iteration}")]
    NonFinite {
        /// Iteration where it appeared (0 = the starting energy).
        iteration: usize,
        /// What was non-finite ("energy", "gradient", "Newton step").
        quantity: &'static str,
    },
    /// The Hessian was not positive definite (a static solve with free rigid motions, or an
    /// exact tangent that is indefinite).
    #[error("the Newton system is not positive definite at iteration {iteration}")]
    NotPositiveDefinite {
        /// Iteration.
        iteration: usize,
    },
}

/// Minimizes `objective` from `x` in place (the steps of the module docs).
///
/// Postcondition: on `Ok`, `x` is the last accepted iterate (the converged point when
/// `report.converged()`), and `report.energy = E(x)` up to the final full step of a converged
/// solve, whose energy change is below the tolerance's order.
///
/// # Errors
/// [`NewtonError::NonFinite`] for a non-finite starting energy, gradient or Newton step;
/// [`NewtonError::NotPositiveDefinite`] when a Hessian cannot be factored.
pub fn minimize<O: NewtonObjective>(
    objective: &O,
    x: &mut Vec<f64>,
    params: &NewtonParams,
) -> Result<NewtonReport, NewtonError> {
    minimize_reusing(objective, x, params, &mut None)
}

/// [`minimize`] starting from the factorization in `factor` (left by an earlier solve of a
/// similar objective, e.g. the previous time step) and leaving its last one there. A carried
/// factor is only used by the lagged convergence test, and, with
/// [`HessianReuse::WhileContracting`], for chord steps; a step along it is always checked by the
/// same tolerance and line search.
///
/// # Errors
/// As [`minimize`]; `factor` is then emptied.
pub fn minimize_reusing<O: NewtonObjective>(
    objective: &O,
    x: &mut Vec<f64>,
    params: &NewtonParams,
    factor: &mut Option<O::Factor>,
) -> Result<NewtonReport, NewtonError> {
    let (report, last) = solve(objective, x, params, factor.take())?;
    *factor = last;
    Ok(report)
}

fn solve<O: NewtonObjective>(
    objective: &O,
    x: &mut Vec<f64>,
    params: &NewtonParams,
    carried: Option<O::Factor>,
) -> Result<(NewtonReport, Option<O::Factor>), NewtonError> {
    let mut timings = NewtonTimings::default();
    let mut energy = objective.energy(x);
    if !energy.is_finite() {
        return Err(NewtonError::NonFinite {
            iteration: 0,
            quantity: "energy",
        });
    }
    let mut report = NewtonReport {
        iterations: 0,
        hessian_assemblies: 0,
        residual: f64::INFINITY,
        line_search_cuts: 0,
        lagged_steps: 0,
        stop: NewtonStop::IterationLimit,
        energy,
        timings,
    };
    let non_finite_gradient = |iteration| NewtonError::NonFinite {
        iteration,
        quantity: "gradient",
    };
    let mut factor: Option<O::Factor> = carried;
    // Norm of the last step taken (∞ before the first), for the contraction test.
    let mut previous_residual = f64::INFINITY;
    for iteration in 1..=params.max_iterations {
        report.iterations = iteration;
        // The lagged-Hessian convergence test: gradient only, no new Hessian if it passes.
        let mut known_gradient = None;
        if let Some(f) = &factor {
            let t = Instant::now();
            let gradient = objective.gradient(x);
            timings.assembly += t.elapsed().as_secs_f64();
            if !gradient.iter().all(|g| g.is_finite()) {
                return Err(non_finite_gradient(iteration));
            }
            let t = Instant::now();
            let step = objective.solve(f, &gradient);
            timings.solve += t.elapsed().as_secs_f64();
            // A non-finite lagged step (a solve that could not be had) is no step.
            let residual = if step.iter().all(|s| s.is_finite()) {
                objective.step_norm(&step)
            } else {
                f64::INFINITY
            };
            if residual.is_finite() && residual < params.tolerance {
                report.residual = residual;
                let alpha = objective.max_step(x, &step).min(1.0);
                apply(x, &step, alpha);
                report.stop = NewtonStop::Converged;
                break;
            }
            if let HessianReuse::WhileContracting { contraction } = params.hessian_reuse
                && residual.is_finite()
                && residual <= contraction * previous_residual
            {
                let t = Instant::now();
                let accepted = line_search(objective, x, energy, &gradient, &step, params);
                timings.line_search += t.elapsed().as_secs_f64();
                if let Some((trial, e, cuts)) = accepted {
                    // A chord step: no new Hessian this iteration.
                    report.line_search_cuts += cuts;
                    report.lagged_steps += 1;
                    report.residual = residual;
                    previous_residual = residual;
                    *x = trial;
                    energy = e;
                    continue;
                }
                // No decrease along the old factor's step: a new Hessian decides.
            }
            known_gradient = Some(gradient);
        }
        let t = Instant::now();
        let (gradient, hessian) = objective.gradient_and_hessian(x, known_gradient);
        timings.assembly += t.elapsed().as_secs_f64();
        report.hessian_assemblies += 1;
        if !gradient.iter().all(|g| g.is_finite()) {
            return Err(non_finite_gradient(iteration));
        }
        let t = Instant::now();
        let f = objective
            .factor(hessian)
            .ok_or(NewtonError::NotPositiveDefinite { iteration })?;
        let step = objective.solve(&f, &gradient);
        factor = Some(f);
        timings.solve += t.elapsed().as_secs_f64();
        if !step.iter().all(|s| s.is_finite()) {
            return Err(NewtonError::NonFinite {
                iteration,
                quantity: "Newton step",
            });
        }
        let residual = objective.step_norm(&step);
        report.residual = residual;
        previous_residual = residual;
        if residual < params.tolerance {
            // Within tolerance: take the full step (quadratically small) and stop.
            let alpha = objective.max_step(x, &step).min(1.0);
            apply(x, &step, alpha);
            report.stop = NewtonStop::Converged;
            break;
        }
        let t = Instant::now();
        let accepted = line_search(objective, x, energy, &gradient, &step, params);
        timings.line_search += t.elapsed().as_secs_f64();
        match accepted {
            Some((trial, e, cuts)) => {
                report.line_search_cuts += cuts;
                *x = trial;
                energy = e;
            }
            None => {
                report.line_search_cuts += params.max_line_search_cuts;
                report.stop = NewtonStop::LineSearchStalled;
                break;
            }
        }
    }
    report.energy = energy;
    report.timings = timings;
    Ok((report, factor))
}

/// Armijo backtracking from α = 1 along `step`: the accepted point, its energy and the
/// halvings it took, or `None` when no α ≥ 2^-max_cuts decreases E enough (then
/// `max_line_search_cuts` halvings were made).
fn line_search<O: NewtonObjective>(
    objective: &O,
    x: &[f64],
    energy: f64,
    gradient: &[f64],
    step: &[f64],
    params: &NewtonParams,
) -> Option<(Vec<f64>, f64, usize)> {
    let slope = objective.directional_derivative(gradient, step);
    let mut alpha = objective.max_step(x, step).min(1.0);
    for cuts in 0..=params.max_line_search_cuts {
        let mut trial = x.to_vec();
        apply(&mut trial, step, alpha);
        let e = objective.energy(&trial);
        if e.is_finite() && e <= energy + params.armijo * alpha * slope {
            return Some((trial, e, cuts));
        }
        alpha *= 0.5;
    }
    None
}

/// `x += α Δx`.
fn apply(x: &mut [f64], step: &[f64], alpha: f64) {
    for (a, s) in x.iter_mut().zip(step) {
        *a += alpha * s;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_carried_factor_ages_by_one_solve_resets_on_assembly_and_expires_at_the_cap() {
        let solved = |hessian_assemblies| NewtonReport {
            iterations: 1,
            hessian_assemblies,
            residual: 0.0,
            line_search_cuts: 0,
            lagged_steps: 0,
            stop: NewtonStop::Converged,
            energy: 0.0,
            timings: NewtonTimings::default(),
        };
        let carried = CarriedFactor::after(Some("L"), 0, &solved(1));
        let (factor, age) = CarriedFactor::usable(carried, 3);
        assert_eq!((factor, age), (Some("L"), 1));
        let older = CarriedFactor::after(factor, age, &solved(0));
        let (factor, age) = CarriedFactor::usable(older, 3);
        assert_eq!((factor, age), (Some("L"), 2));
        let oldest = CarriedFactor::after(factor, age, &solved(0));
        assert_eq!(CarriedFactor::usable(oldest, 3), (None, 0));
        assert!(CarriedFactor::<&str>::after(None, 2, &solved(0)).is_none());
    }

    #[test]
    fn a_followed_report_keeps_the_second_outcome_and_the_work_of_both() {
        let report = |iterations, stop, residual, seconds| NewtonReport {
            iterations,
            hessian_assemblies: iterations + 1,
            residual,
            line_search_cuts: 2 * iterations,
            lagged_steps: 3,
            stop,
            energy: residual * 10.0,
            timings: NewtonTimings {
                assembly: seconds,
                solve: 2.0 * seconds,
                line_search: 3.0 * seconds,
            },
        };
        let first = report(5, NewtonStop::IterationLimit, 1e-3, 0.5);
        let second = report(2, NewtonStop::Converged, 1e-9, 0.25);
        let both = first.followed_by(&second);
        assert_eq!(
            (
                both.iterations,
                both.hessian_assemblies,
                both.line_search_cuts
            ),
            (7, 9, 14)
        );
        assert_eq!(both.lagged_steps, 6);
        assert_eq!(
            (both.stop, both.residual, both.energy),
            (NewtonStop::Converged, 1e-9, 1e-8)
        );
        assert_eq!(
            (
                both.timings.assembly,
                both.timings.solve,
                both.timings.line_search
            ),
            (0.75, 1.5, 2.25)
        );
    }
}
