//! One FEM step as the Newton solver's objective, over the free degrees of freedom.

use std::sync::{Mutex, PoisonError};

use hyperelastic::HyperelasticMaterial;
use optimize::NewtonObjective;

use crate::sparse_system::NumericFactor;

use super::{FemSimulator, StepProblem};

/// One step's minimization problem for [`optimize::minimize`]: x holds every node (Dirichlet
/// nodes at their targets), the gradient and the sparse Hessian only the free DOFs.
pub(super) struct StepObjective<'a, M: HyperelasticMaterial> {
    sim: &'a FemSimulator<M>,
    problem: StepProblem<'a>,
    /// Where the last exact Hessian was assembled, for the definite one a failed
    /// factorization falls back to ([`HessianTangent::fallback`]).
    exact_at: Mutex<Option<Vec<f64>>>,
}

impl<'a, M: HyperelasticMaterial> StepObjective<'a, M> {
    pub(super) fn new(sim: &'a FemSimulator<M>, problem: StepProblem<'a>) -> Self {
        StepObjective {
            sim,
            problem,
            exact_at: Mutex::new(None),
        }
    }
}

impl<M: HyperelasticMaterial> NewtonObjective for StepObjective<'_, M> {
    type Hessian = Vec<f64>;
    type Factor = NumericFactor;

    fn energy(&self, x: &[f64]) -> f64 {
        self.sim.energy(&self.problem, x)
    }

    fn gradient(&self, x: &[f64]) -> Vec<f64> {
        self.sim.free_part(&self.sim.gradient(&self.problem, x))
    }

    fn gradient_and_hessian(&self, x: &[f64], gradient: Option<Vec<f64>>) -> (Vec<f64>, Vec<f64>) {
        let gradient = gradient.unwrap_or_else(|| self.gradient(x));
        let tangent = self.sim.params.tangent;
        if tangent.fallback().is_some() {
            *self.exact_at.lock().unwrap_or_else(PoisonError::into_inner) = Some(x.to_vec());
        }
        (
            gradient,
            self.sim.hessian(&self.problem, x, tangent.first_try()),
        )
    }

    fn factor(&self, values: Vec<f64>) -> Option<Self::Factor> {
        let factor = self.sim.system.factorize(&values);
        if factor.is_some() {
            return factor;
        }
        let fallback = self.sim.params.tangent.fallback()?;
        let x = self
            .exact_at
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .take()?;
        let definite = self.sim.hessian(&self.problem, &x, fallback);
        self.sim.system.factorize(&definite)
    }

    fn solve(&self, factor: &Self::Factor, gradient: &[f64]) -> Vec<f64> {
        self.sim.solve(factor, gradient)
    }

    fn step_norm(&self, step: &[f64]) -> f64 {
        self.sim.step_norm(step)
    }

    fn directional_derivative(&self, gradient: &[f64], step: &[f64]) -> f64 {
        self.sim
            .free_part(step)
            .iter()
            .zip(gradient)
            .map(|(s, g)| s * g)
            .sum()
    }
}
