//! Material values attached to points: Young's modulus, Poisson ratio and density, constant or
//! a function of rest position (heterogeneous objects such as the layered sphere of Sec. 9.2),
//! and their one conversion to Lamé parameters ([`MaterialSample::lame_parameters`]) that the
//! basis builder, the reduced model, the FEM and the baselines all use.

use std::fmt;
use std::sync::Arc;

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::lame_parameters::{LameParameters, MaterialParameterError};

/// Elastic and inertial parameters at one point.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct MaterialSample {
    /// Young's modulus E (Pa).
    pub youngs_modulus: f64,
    /// Poisson ratio ν (dimensionless, in (-1, 0.5)).
    pub poisson_ratio: f64,
    /// Mass density ρ (kg/m³).
    pub density: f64,
}

impl MaterialSample {
    /// The Lamé parameters λ = Eν / ((1 + ν)(1 − 2ν)), μ = E / (2(1 + ν)) (Pa), the one place
    /// E and ν are converted.
    ///
    /// # Errors
    /// [`MaterialParameterError`] for E not positive and finite or ν outside (−1, 0.5).
    pub fn lame_parameters(&self) -> Result<LameParameters, MaterialParameterError> {
        LameParameters::from_young_poisson(self.youngs_modulus, self.poisson_ratio)
    }
}

/// Lamé parameters of per-point material samples (e.g. from [`MaterialField::sample`]).
///
/// # Errors
/// The first invalid sample's [`MaterialParameterError`], with its index.
pub fn lame_parameters_of(
    samples: &[MaterialSample],
) -> Result<Vec<LameParameters>, (usize, MaterialParameterError)> {
    samples
        .iter()
        .enumerate()
        .map(|(i, s)| s.lame_parameters().map_err(|e| (i, e)))
        .collect()
}

/// A material as a function of rest position X (m).
pub type MaterialFunction = Arc<dyn Fn(&Vector3<f64>) -> MaterialSample + Send + Sync>;

/// A material over the object: one value everywhere, or a function of rest position X (m).
#[derive(Clone)]
pub enum MaterialField {
    /// The same material at every point.
    Uniform(MaterialSample),
    /// `f(X)` evaluated at each integration point.
    Function(MaterialFunction),
}

impl MaterialField {
    /// The material at each of `positions` (one sample per point).
    pub fn sample(&self, positions: &[Vector3<f64>]) -> Vec<MaterialSample> {
        match self {
            MaterialField::Uniform(m) => vec![*m; positions.len()],
            MaterialField::Function(f) => positions.iter().map(|p| f(p)).collect(),
        }
    }
}

impl fmt::Debug for MaterialField {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MaterialField::Uniform(m) => f.debug_tuple("Uniform").field(m).finish(),
            MaterialField::Function(_) => f.write_str("Function(..)"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn function_field_is_evaluated_per_point() {
        let soft = MaterialSample {
            youngs_modulus: 1e5,
            poisson_ratio: 0.45,
            density: 1000.0,
        };
        let field = MaterialField::Function(Arc::new(move |x: &Vector3<f64>| MaterialSample {
            youngs_modulus: if x.x < 0.5 {
                soft.youngs_modulus
            } else {
                100.0 * soft.youngs_modulus
            },
            ..soft
        }));
        let samples = field.sample(&[Vector3::new(0.2, 0.0, 0.0), Vector3::new(0.8, 0.0, 0.0)]);
        assert_eq!(samples[0].youngs_modulus, 1e5);
        assert_eq!(samples[1].youngs_modulus, 1e7);
    }
}
