//! The stress over a set of points of a deformed object (Sec. 9.3, Fig. 1's stress field): at
//! each point the Cauchy stress `σ = J⁻¹ P Fᵀ` of its material at its deformation gradient, the
//! principal stresses and the von Mises stress, as written into the VTK frames.

use hyperelastic::{HyperelasticMaterial, LameParameters, StressSample};
use nalgebra::Matrix3;
use thiserror::Error;

/// Stress at every point of a set (integration points or output vertices), in their order.
#[derive(Clone, Debug, PartialEq)]
pub struct StressField {
    /// One sample per point (Pa). An inverted point (det F ≤ 0), whose Cauchy stress is not
    /// defined, holds zeros and is listed in [`StressField::inverted`].
    pub samples: Vec<StressSample>,
    /// Points with det F ≤ 0, ascending.
    pub inverted: Vec<usize>,
}

/// The inputs of a stress field do not fit together.
#[derive(Debug, Error, PartialEq)]
pub enum StressFieldError {
    /// One Lamé pair per deformation gradient is needed.
    #[error("{gradients} deformation gradients but {lame} Lamé parameter pairs")]
    Length {
        /// Deformation gradients given.
        gradients: usize,
        /// Lamé pairs given.
        lame: usize,
    },
}

impl StressField {
    /// The stress of `material` at each point i, with Lamé parameters `lame[i]` and
    /// deformation gradient `deformation_gradients[i]` (e.g.
    /// [`reduced_sim::DeformationMap::deformation_gradients`]).
    ///
    /// # Errors
    /// [`StressFieldError::Length`] when the two slices differ in length.
    pub fn new<M: HyperelasticMaterial>(
        material: &M,
        lame: &[LameParameters],
        deformation_gradients: &[Matrix3<f64>],
    ) -> Result<Self, StressFieldError> {
        if lame.len() != deformation_gradients.len() {
            return Err(StressFieldError::Length {
                gradients: deformation_gradients.len(),
                lame: lame.len(),
            });
        }
        let mut inverted = Vec::new();
        let samples = deformation_gradients
            .iter()
            .zip(lame)
            .enumerate()
            .map(|(i, (f, lame))| {
                StressSample::new(material, lame, f).unwrap_or_else(|_| {
                    inverted.push(i);
                    StressSample {
                        cauchy: Matrix3::zeros(),
                        principal: nalgebra::Vector3::zeros(),
                        von_mises: 0.0,
                    }
                })
            })
            .collect();
        Ok(StressField { samples, inverted })
    }

    /// Points in the field.
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    /// Whether the field has no point.
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    /// The largest von Mises stress over the points (Pa; 0 for an empty field).
    pub fn max_von_mises(&self) -> f64 {
        self.samples.iter().map(|s| s.von_mises).fold(0.0, f64::max)
    }
}
