//! `freeform.IntegrationPoints`: points with their volumes.

use numpy::ndarray::Array1;
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::prelude::*;
use rkpm_core::IntegrationPoints;

use crate::arrays::{Points, points_array, points_of};
use crate::errors::{self};

/// Integration points x_i (m) with their volumes v_i (m³).
#[pyclass(module = "freeform._native", name = "IntegrationPoints", frozen)]
pub(crate) struct PyIntegrationPoints {
    pub(crate) inner: IntegrationPoints,
}

#[pymethods]
impl PyIntegrationPoints {
    /// Integration points from an `(n, 3)` array of positions (m) and `n` volumes (m³).
    #[new]
    fn new(positions: Points<'_>, volumes: Vec<f64>) -> PyResult<Self> {
        let positions = points_of(&positions, "positions")?;
        IntegrationPoints::new(positions, volumes)
            .map(|inner| PyIntegrationPoints { inner })
            .map_err(|e| errors::raise::<errors::GeometryError>(&e))
    }

    /// `(n, 3)` positions (m).
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        points_array(py, self.inner.positions())
    }

    /// `(n,)` volumes (m³).
    #[getter]
    fn volumes<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        Array1::from(self.inner.volumes().to_vec()).into_pyarray(py)
    }

    fn __len__(&self) -> usize {
        self.inner.len()
    }

    fn __repr__(&self) -> String {
        let volume: f64 = self.inner.volumes().iter().sum();
        format!(
            "IntegrationPoints({} points, volume {volume:.6} m³)",
            self.inner.len()
        )
    }
}
