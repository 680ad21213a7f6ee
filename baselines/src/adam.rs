//! Adam (Kingma & Ba 2015) on a flat parameter vector, with PyTorch's defaults.

use serde::{Deserialize, Serialize};

/// Adam's constants.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct AdamParams {
    /// Learning rate (Simplicits: 1e-3).
    pub learning_rate: f64,
    /// First-moment decay (default 0.9).
    pub beta1: f64,
    /// Second-moment decay (default 0.999).
    pub beta2: f64,
    /// Denominator guard (default 1e-8).
    pub epsilon: f64,
}

impl Default for AdamParams {
    fn default() -> Self {
        AdamParams {
            learning_rate: 1e-3,
            beta1: 0.9,
            beta2: 0.999,
            epsilon: 1e-8,
        }
    }
}

/// Adam's state for one parameter vector.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Adam {
    params: AdamParams,
    first: Vec<f64>,
    second: Vec<f64>,
    steps: u64,
}

impl Adam {
    /// Fresh state for `len` parameters.
    pub fn new(len: usize, params: AdamParams) -> Self {
        Adam {
            params,
            first: vec![0.0; len],
            second: vec![0.0; len],
            steps: 0,
        }
    }

    /// Steps taken so far.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// One update: `m ← β₁m + (1−β₁)g`, `v ← β₂v + (1−β₂)g²`,
    /// `θ ← θ − lr · m̂ / (√v̂ + ε)` with the bias corrections `m̂ = m/(1−β₁ᵗ)`, `v̂ = v/(1−β₂ᵗ)`.
    ///
    /// # Panics
    /// If `parameters` or `gradient` do not have the length the state was made for.
    pub fn step(&mut self, parameters: &mut [f64], gradient: &[f64]) {
        assert_eq!(parameters.len(), self.first.len(), "parameter count");
        assert_eq!(gradient.len(), self.first.len(), "gradient length");
        self.steps += 1;
        let AdamParams {
            learning_rate,
            beta1,
            beta2,
            epsilon,
        } = self.params;
        let t = self.steps as i32;
        let (c1, c2) = (1.0 - beta1.powi(t), 1.0 - beta2.powi(t));
        for (((p, g), m), v) in parameters
            .iter_mut()
            .zip(gradient)
            .zip(&mut self.first)
            .zip(&mut self.second)
        {
            *m = beta1 * *m + (1.0 - beta1) * g;
            *v = beta2 * *v + (1.0 - beta2) * g * g;
            *p -= learning_rate * (*m / c1) / ((*v / c2).sqrt() + epsilon);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_step_moves_every_parameter_by_the_learning_rate_against_its_gradient_sign() {
        // With bias correction, step 1 is lr · g/|g| (up to ε).
        let mut adam = Adam::new(3, AdamParams::default());
        let mut p = vec![1.0, -2.0, 0.5];
        adam.step(&mut p, &[4.0, -0.01, 0.0]);
        assert!((p[0] - (1.0 - 1e-3)).abs() < 1e-10);
        assert!((p[1] - (-2.0 + 1e-3)).abs() < 1e-9);
        assert_eq!(p[2], 0.5);
    }

    #[test]
    fn adam_minimizes_an_ill_scaled_quadratic() {
        let scales = [1.0, 100.0, 1e-2];
        let mut p = vec![3.0, -2.0, 5.0];
        let mut adam = Adam::new(
            3,
            AdamParams {
                learning_rate: 0.05,
                ..AdamParams::default()
            },
        );
        for _ in 0..3000 {
            let g: Vec<f64> = p.iter().zip(&scales).map(|(x, s)| 2.0 * s * x).collect();
            adam.step(&mut p, &g);
        }
        assert!(p.iter().all(|x| x.abs() < 0.05), "{p:?}");
        assert_eq!(adam.steps(), 3000);
    }
}
