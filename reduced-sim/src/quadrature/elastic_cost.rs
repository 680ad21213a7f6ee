//! The predicted elastic work of a run integrated on every point, which
//! [`crate::QuadratureRule::Automatic`] weighs against what a cubature's training costs.
//!
//! A step of the simulator evaluates the elastic energy and gradient once per Newton iteration
//! and line-search trial, and assembles the elastic Hessian when it is not reused. Both scale
//! with the quadrature's points, so the time one of each takes on the full model at rest,
//! measured on this machine, predicts the elastic part of a run ([`PlannedRun`]):
//!
//! ```text
//! T_run ≈ steps · (gradient_passes_per_step · t_gradient + hessians_per_step · t_hessian)
//! ```
//!
//! The counts per step are estimates for the default Newton and Hessian-reuse settings, one
//! for a single body and one for several bodies in contact (which take many more Newton
//! iterations); the measurements behind them are in `results/RESULTS.md` ("The quadrature that
//! pays for itself").

use std::time::Instant;

use hyperelastic::{HyperelasticMaterial, Tangent};

use crate::model::reduced_model::ReducedModel;

/// A run whose elastic work is predicted: its steps and the elastic evaluations each makes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlannedRun {
    /// Steps of the run.
    pub steps: usize,
    /// Elastic energy-and-gradient passes per step: Newton iterations and line-search trials.
    pub gradient_passes_per_step: f64,
    /// Elastic Hessian assemblies per step.
    pub hessians_per_step: f64,
}

impl PlannedRun {
    /// `steps` steps of one body (alone, on a floor or against colliders): 8 gradient passes
    /// and 1 Hessian per step.
    pub fn single_body(steps: usize) -> Self {
        PlannedRun {
            steps,
            gradient_passes_per_step: 8.0,
            hessians_per_step: 1.0,
        }
    }

    /// `steps` steps of one of several bodies in contact with each other: 40 gradient passes
    /// and 10 Hessians per step.
    pub fn multibody(steps: usize) -> Self {
        PlannedRun {
            steps,
            gradient_passes_per_step: 40.0,
            hessians_per_step: 10.0,
        }
    }
}

/// Measured time of one elastic evaluation of each kind on a model's quadrature.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ElasticCost {
    /// One elastic energy and gradient at rest (s): the faster of two passes.
    pub gradient_seconds: f64,
    /// One elastic Hessian at rest, PSD-projected material tangents (s): the faster of two.
    pub hessian_seconds: f64,
}

impl ElasticCost {
    /// Times the evaluations on `model` (on its elastic quadrature if it has one) at rest.
    pub fn measure<M: HyperelasticMaterial>(model: &ReducedModel<M>) -> Self {
        let z = model.deformation_map().layout().rest();
        let gradient_seconds = (0..2)
            .map(|_| {
                let start = Instant::now();
                std::hint::black_box(model.elastic_energy(&z));
                std::hint::black_box(model.elastic_gradient(&z));
                start.elapsed().as_secs_f64()
            })
            .fold(f64::INFINITY, f64::min);
        let hessian_seconds = (0..2)
            .map(|_| {
                let start = Instant::now();
                std::hint::black_box(model.elastic_hessian(&z, Tangent::ProjectedPsd));
                start.elapsed().as_secs_f64()
            })
            .fold(f64::INFINITY, f64::min);
        ElasticCost {
            gradient_seconds,
            hessian_seconds,
        }
    }

    /// Predicted elastic time of `run` on this quadrature (s):
    /// `steps · (gradient_passes_per_step · t_gradient + hessians_per_step · t_hessian)`.
    pub fn run(&self, run: &PlannedRun) -> f64 {
        run.steps as f64
            * (run.gradient_passes_per_step * self.gradient_seconds
                + run.hessians_per_step * self.hessian_seconds)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn run_cost_is_steps_times_the_weighted_evaluations() {
        let cost = ElasticCost {
            gradient_seconds: 0.002,
            hessian_seconds: 0.01,
        };
        let run = PlannedRun {
            steps: 100,
            gradient_passes_per_step: 8.0,
            hessians_per_step: 1.0,
        };
        assert!((cost.run(&run) - 100.0 * (8.0 * 0.002 + 0.01)).abs() < 1e-12);
        assert_eq!(cost.run(&PlannedRun { steps: 0, ..run }), 0.0);
        assert!(cost.run(&PlannedRun::multibody(100)) > cost.run(&PlannedRun::single_body(100)));
    }
}
