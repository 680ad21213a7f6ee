//! Lamé parameters and their conversion from engineering constants.

use serde::{Deserialize, Serialize};

/// Invalid material parameters.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum MaterialParameterError {
    /// Young's modulus must be positive and finite.
    #[error("Young's modulus E = {value} Pa must be positive and finite")]
    InvalidYoungsModulus {
        /// The value given (Pa).
        value: f64,
    },
    /// Poisson ratio must lie in (-1, 0.5).
    #[error("Poisson ratio ν = {value} must lie strictly between -1 and 0.5")]
    InvalidPoissonRatio {
        /// The value given.
        value: f64,
    },
    /// Lamé pair out of the stable range (μ > 0, bulk modulus λ + 2μ/3 > 0, both finite).
    #[error("Lamé parameters λ = {lambda} Pa, μ = {mu} Pa need μ > 0 and λ + 2μ/3 > 0")]
    InvalidLamePair {
        /// First Lamé parameter (Pa).
        lambda: f64,
        /// Shear modulus (Pa).
        mu: f64,
    },
}

/// Lamé parameters (λ, μ) of one material point, in Pa.
///
/// Postcondition of every constructor: μ > 0 and λ + 2μ/3 > 0 (positive shear and bulk
/// moduli), so linear elasticity is positive definite on strains and `λ + μ > 0`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct LameParameters {
    lambda: f64,
    mu: f64,
}

impl LameParameters {
    /// From a Lamé pair.
    ///
    /// # Errors
    /// [`MaterialParameterError::InvalidLamePair`] unless μ > 0, λ + 2μ/3 > 0, both finite.
    pub fn new(lambda: f64, mu: f64) -> Result<Self, MaterialParameterError> {
        let ok = lambda.is_finite() && mu.is_finite() && mu > 0.0 && lambda + 2.0 * mu / 3.0 > 0.0;
        if ok {
            Ok(LameParameters { lambda, mu })
        } else {
            Err(MaterialParameterError::InvalidLamePair { lambda, mu })
        }
    }

    /// From Young's modulus E (Pa) and Poisson ratio ν:
    /// `μ = E / (2(1+ν))`, `λ = E ν / ((1+ν)(1-2ν))` (design §3.4).
    ///
    /// # Errors
    /// [`MaterialParameterError::InvalidYoungsModulus`] unless E > 0 and finite;
    /// [`MaterialParameterError::InvalidPoissonRatio`] unless -1 < ν < 0.5.
    pub fn from_young_poisson(
        youngs_modulus: f64,
        poisson_ratio: f64,
    ) -> Result<Self, MaterialParameterError> {
        if !(youngs_modulus.is_finite() && youngs_modulus > 0.0) {
            return Err(MaterialParameterError::InvalidYoungsModulus {
                value: youngs_modulus,
            });
        }
        if !(poisson_ratio > -1.0 && poisson_ratio < 0.5) {
            return Err(MaterialParameterError::InvalidPoissonRatio {
                value: poisson_ratio,
            });
        }
        let (e, nu) = (youngs_modulus, poisson_ratio);
        Self::new(
            e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)),
            e / (2.0 * (1.0 + nu)),
        )
    }

    /// First Lamé parameter λ (Pa).
    pub fn lambda(&self) -> f64 {
        self.lambda
    }

    /// Shear modulus μ (Pa).
    pub fn mu(&self) -> f64 {
        self.mu
    }

    /// Young's modulus `E = μ(3λ + 2μ)/(λ + μ)` (Pa): bounded by 3μ as ν → 1/2, where λ + 2μ
    /// grows without bound.
    pub fn youngs_modulus(&self) -> f64 {
        self.mu * (3.0 * self.lambda + 2.0 * self.mu) / (self.lambda + self.mu)
    }

    /// The P-wave modulus λ + 2μ (Pa).
    pub fn p_wave_modulus(&self) -> f64 {
        self.lambda + 2.0 * self.mu
    }

    /// `λ + 4μ`, the weight of the weight-space Hessian in Prop. 1 (Pa).
    pub fn weight_space_hessian_modulus(&self) -> f64 {
        self.lambda + 4.0 * self.mu
    }

    /// Both parameters multiplied by `factor > 0` (the same material with `E` scaled).
    pub fn scaled(&self, factor: f64) -> Self {
        LameParameters {
            lambda: self.lambda * factor,
            mu: self.mu * factor,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn young_poisson_conversion_matches_textbook_values() {
        let p = LameParameters::from_young_poisson(5e6, 0.45).unwrap();
        assert!((p.mu() - 5e6 / 2.9).abs() < 1e-6);
        assert!((p.lambda() - 5e6 * 0.45 / (1.45 * 0.1)).abs() < 1e-4);
    }

    #[test]
    fn invalid_parameters_are_rejected_with_the_value() {
        assert_eq!(
            LameParameters::from_young_poisson(-1.0, 0.3),
            Err(MaterialParameterError::InvalidYoungsModulus { value: -1.0 })
        );
        assert_eq!(
            LameParameters::from_young_poisson(1.0, 0.5),
            Err(MaterialParameterError::InvalidPoissonRatio { value: 0.5 })
        );
        assert!(LameParameters::from_young_poisson(1.0, f64::NAN).is_err());
        assert!(LameParameters::from_young_poisson(f64::INFINITY, 0.3).is_err());
        assert!(LameParameters::new(-1.0, 1.0).is_err());
        assert!(LameParameters::new(1.0, 0.0).is_err());
        assert!(LameParameters::from_young_poisson(1.0, -0.99).is_ok());
    }
}
