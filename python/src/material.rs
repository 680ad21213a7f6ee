//! `freeform.Material`: one material everywhere, or values given at points (each point of the
//! object takes the values of the nearest given point).

use std::sync::Arc;

use freeform::{MaterialRegion, MaterialSpec};
use hyperelastic::{LameParameters, MaterialField, MaterialSample};
use nalgebra::Vector3;
use numpy::ndarray::Array1;
use numpy::{IntoPyArray, PyArray1};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rkpm_core::SpatialIndex;

use crate::arrays::{Points, points_of};
use crate::errors::{self, SceneError};

/// Materials at points, looked up by the nearest point.
struct SampledMaterial {
    positions: Vec<Vector3<f64>>,
    samples: Vec<MaterialSample>,
    index: SpatialIndex,
}

impl SampledMaterial {
    /// The material of the given point nearest to `x`.
    fn at(&self, x: &Vector3<f64>) -> MaterialSample {
        let nearest = self.index.nearest(x, 1);
        self.samples[nearest.first().map_or(0, |&(i, _)| i)]
    }
}

/// A material: Young's modulus E (Pa), Poisson ratio ν and density ρ (kg/m³), the same
/// everywhere or given at points.
#[pyclass(module = "freeform._native", name = "Material", frozen)]
pub(crate) struct PyMaterial {
    kind: MaterialKind,
}

/// How a material varies over the object.
enum MaterialKind {
    /// One material everywhere.
    Uniform(MaterialSample),
    /// A base material with regions of their own (the scene file's `material.regions`).
    Regions(MaterialSpec),
    /// Values given at points.
    Sampled(Arc<SampledMaterial>),
}

/// The Lamé parameters of `field` at `positions` (m).
///
/// # Errors
/// `SceneError` where the material's values make no Lamé parameters.
pub(crate) fn lame_of(
    field: &MaterialField,
    positions: &[Vector3<f64>],
) -> PyResult<Vec<LameParameters>> {
    field
        .sample(positions)
        .iter()
        .map(|m| {
            m.lame_parameters()
                .map_err(|e| errors::raise::<SceneError>(&e))
        })
        .collect()
}

/// `sample`, refused unless its values make a material.
fn checked(sample: MaterialSample, what: &str) -> PyResult<MaterialSample> {
    sample
        .lame_parameters()
        .map_err(|e| SceneError::new_err(format!("{what}: {}", freeform::failure_chain(&e))))?;
    if !(sample.density.is_finite() && sample.density > 0.0) {
        return Err(SceneError::new_err(format!(
            "{what}: the density must be finite and positive, got {} kg/m³",
            sample.density
        )));
    }
    Ok(sample)
}

impl PyMaterial {
    /// The material as a field over the rest shape.
    pub(crate) fn field(&self) -> MaterialField {
        match &self.kind {
            MaterialKind::Uniform(m) => MaterialField::Uniform(*m),
            MaterialKind::Regions(spec) => spec.field(),
            MaterialKind::Sampled(sampled) => {
                let sampled = Arc::clone(sampled);
                MaterialField::Function(Arc::new(move |x: &Vector3<f64>| sampled.at(x)))
            }
        }
    }

    /// The Lamé parameters at `positions` (m).
    pub(crate) fn lame_at(&self, positions: &[Vector3<f64>]) -> PyResult<Vec<LameParameters>> {
        lame_of(&self.field(), positions)
    }

    /// The value of `pick` everywhere, or at each given point.
    fn values<'py>(
        &self,
        py: Python<'py>,
        pick: fn(&MaterialSample) -> f64,
    ) -> PyResult<Py<PyAny>> {
        Ok(match &self.kind {
            MaterialKind::Uniform(m) => pick(m).into_pyobject(py)?.into_any().unbind(),
            MaterialKind::Regions(spec) => {
                pick(&spec.base()).into_pyobject(py)?.into_any().unbind()
            }
            MaterialKind::Sampled(s) => {
                let values: Array1<f64> = s.samples.iter().map(pick).collect();
                let array: Bound<'py, PyArray1<f64>> = values.into_pyarray(py);
                array.into_any().unbind()
            }
        })
    }
}

#[pymethods]
impl PyMaterial {
    /// One material everywhere: E (Pa), ν, ρ (kg/m³); with `regions` (a list of dicts with the
    /// scene file's `material.regions` keys: `region`, `youngs_modulus`, `poisson_ratio`,
    /// `density`), parts of the object by rest position have their own (the later region wins
    /// where they overlap).
    #[new]
    #[pyo3(signature = (youngs_modulus, poisson_ratio, density, regions = None))]
    fn new(
        py: Python<'_>,
        youngs_modulus: f64,
        poisson_ratio: f64,
        density: f64,
        regions: Option<Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let sample = MaterialSample {
            youngs_modulus,
            poisson_ratio,
            density,
        };
        let uniform = checked(sample, "the material")?;
        let kind = match regions {
            None => MaterialKind::Uniform(uniform),
            Some(regions) => {
                let json: String = py
                    .import("json")?
                    .call_method1("dumps", (regions,))?
                    .extract()?;
                let regions: Vec<MaterialRegion> = serde_json::from_str(&json)
                    .map_err(|e| SceneError::new_err(format!("material regions: {e}")))?;
                let spec = MaterialSpec {
                    youngs_modulus,
                    poisson_ratio,
                    density,
                    regions,
                };
                if let Some((field, problem)) = spec.defect() {
                    return Err(SceneError::new_err(format!("{field}: {problem}")));
                }
                MaterialKind::Regions(spec)
            }
        };
        Ok(PyMaterial { kind })
    }

    /// Values given at `positions` (`(n, 3)`, m): `youngs_modulus`, `poisson_ratio` and
    /// `density` each `(n,)` or one value; every point of an object takes the values of the
    /// nearest given position (so give them at the object's integration points, or densely).
    #[staticmethod]
    fn at_points(
        positions: Points<'_>,
        youngs_modulus: Vec<f64>,
        poisson_ratio: Vec<f64>,
        density: Vec<f64>,
    ) -> PyResult<Self> {
        let positions = points_of(&positions, "positions")?;
        let n = positions.len();
        if n == 0 {
            return Err(PyValueError::new_err(
                "a material at points needs at least one point",
            ));
        }
        let value = |values: &[f64], name: &str, i: usize| -> PyResult<f64> {
            match values.len() {
                1 => Ok(values[0]),
                len if len == n => Ok(values[i]),
                len => Err(PyValueError::new_err(format!(
                    "{name}: {len} values for {n} positions (give one or {n})"
                ))),
            }
        };
        let samples = (0..n)
            .map(|i| {
                let sample = MaterialSample {
                    youngs_modulus: value(&youngs_modulus, "youngs_modulus", i)?,
                    poisson_ratio: value(&poisson_ratio, "poisson_ratio", i)?,
                    density: value(&density, "density", i)?,
                };
                checked(sample, &format!("the material at point {i}"))
            })
            .collect::<PyResult<Vec<_>>>()?;
        let index = SpatialIndex::new(&positions);
        Ok(PyMaterial {
            kind: MaterialKind::Sampled(Arc::new(SampledMaterial {
                positions,
                samples,
                index,
            })),
        })
    }

    /// The number of regions with their own material (0 without).
    #[getter]
    fn regions(&self) -> usize {
        match &self.kind {
            MaterialKind::Regions(spec) => spec.regions.len(),
            _ => 0,
        }
    }

    /// Young's modulus E (Pa): a number (the base one with regions), or `(n,)` at the given
    /// points.
    #[getter]
    fn youngs_modulus(&self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        self.values(py, |m| m.youngs_modulus)
    }

    /// Poisson ratio ν: a number, or `(n,)` at the given points.
    #[getter]
    fn poisson_ratio(&self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        self.values(py, |m| m.poisson_ratio)
    }

    /// Density ρ (kg/m³): a number, or `(n,)` at the given points.
    #[getter]
    fn density(&self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        self.values(py, |m| m.density)
    }

    /// Whether the values were given at points.
    #[getter]
    fn per_point(&self) -> bool {
        matches!(self.kind, MaterialKind::Sampled(_))
    }

    fn __repr__(&self) -> String {
        match &self.kind {
            MaterialKind::Uniform(m) => format!(
                "Material(E = {} Pa, ν = {}, ρ = {} kg/m³)",
                m.youngs_modulus, m.poisson_ratio, m.density
            ),
            MaterialKind::Regions(spec) => format!(
                "Material(E = {} Pa, ν = {}, ρ = {} kg/m³, {} region(s))",
                spec.youngs_modulus,
                spec.poisson_ratio,
                spec.density,
                spec.regions.len()
            ),
            MaterialKind::Sampled(s) => format!("Material(at {} points)", s.positions.len()),
        }
    }
}
