//! A scene file's material: one value over the object, or regions with their own.

use hyperelastic::{MaterialField, MaterialSample};
use serde::{Deserialize, Serialize};

/// Material (SI units): one value over the object, or parts of it with their own
/// (`[[material.regions]]`, e.g. the shells of a layered sphere).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialSpec {
    /// Young's modulus E (Pa).
    pub youngs_modulus: f64,
    /// Poisson ratio ν, in (-1, 0.5).
    pub poisson_ratio: f64,
    /// Density ρ (kg/m³).
    pub density: f64,
    /// Parts of the object (by rest position) with their own material; where regions overlap
    /// the later one wins (default none: uniform).
    #[serde(default)]
    pub regions: Vec<MaterialRegion>,
}

/// A part of the object with its own material.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialRegion {
    /// Where (rest positions, m).
    pub region: crate::Region,
    /// Young's modulus E (Pa).
    pub youngs_modulus: f64,
    /// Poisson ratio ν, in (-1, 0.5).
    pub poisson_ratio: f64,
    /// Density ρ (kg/m³).
    pub density: f64,
}

impl MaterialSpec {
    /// The material at rest position `x` (m): the last region containing x, else the base.
    pub fn at(&self, x: &nalgebra::Vector3<f64>) -> MaterialSample {
        self.regions
            .iter()
            .rev()
            .find(|r| r.region.contains(x))
            .map_or(self.base(), |r| MaterialSample {
                youngs_modulus: r.youngs_modulus,
                poisson_ratio: r.poisson_ratio,
                density: r.density,
            })
    }

    /// The base material (outside every region).
    pub fn base(&self) -> MaterialSample {
        MaterialSample {
            youngs_modulus: self.youngs_modulus,
            poisson_ratio: self.poisson_ratio,
            density: self.density,
        }
    }

    /// The material as a field over the object: uniform without regions.
    pub fn field(&self) -> MaterialField {
        if self.regions.is_empty() {
            MaterialField::Uniform(self.base())
        } else {
            let spec = self.clone();
            MaterialField::Function(std::sync::Arc::new(move |x| spec.at(x)))
        }
    }
}

impl MaterialSpec {
    /// The first problem as (field, what is wrong): E or ν out of range, a density that is not
    /// positive, an invalid region.
    pub fn defect(&self) -> Option<(String, String)> {
        let samples = std::iter::once(("material".to_string(), self.base())).chain(
            self.regions.iter().enumerate().map(|(i, r)| {
                (
                    format!("material.regions[{i}]"),
                    MaterialSample {
                        youngs_modulus: r.youngs_modulus,
                        poisson_ratio: r.poisson_ratio,
                        density: r.density,
                    },
                )
            }),
        );
        for (name, sample) in samples {
            if let Err(e) = sample.lame_parameters() {
                return Some((name, e.to_string()));
            }
            if !(sample.density > 0.0 && sample.density.is_finite()) {
                return Some((
                    format!("{name}.density"),
                    format!("{} must be positive", sample.density),
                ));
            }
        }
        self.regions.iter().enumerate().find_map(|(i, r)| {
            let defect = r.region.defect()?;
            Some((format!("material.regions[{i}].region"), defect))
        })
    }
}
