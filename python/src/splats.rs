//! `freeform.Splats`: a 3DGS file's vertex table.

use std::path::PathBuf;

use freeform::SplatTable;
use numpy::ndarray::{Array1, Array2, Array3};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray3};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::arrays::points_array;
use crate::errors::{self};

/// The vertex table of a 3DGS PLY file (binary little-endian), kept byte for byte: what a
/// deformation rewrites (centres, scales, rotations, higher SH) is typed, the rest is carried.
#[pyclass(module = "freeform._native", name = "Splats", frozen)]
pub(crate) struct PySplats {
    pub(crate) inner: SplatTable,
}

#[pymethods]
impl PySplats {
    /// Reads a 3DGS PLY file.
    #[staticmethod]
    fn read(path: PathBuf) -> PyResult<Self> {
        SplatTable::read(&path)
            .map(|inner| PySplats { inner })
            .map_err(|e| errors::splat_error(&e))
    }

    /// Writes the table (atomically).
    fn write(&self, path: PathBuf) -> PyResult<()> {
        self.inner.write(&path).map_err(|e| errors::splat_error(&e))
    }

    /// Splat centres `(n, 3)` (file units, m for a simulated scene).
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        points_array(py, &self.inner.positions())
    }

    /// Covariances `Σ = R diag(exp(2 s)) Rᵀ` `(n, 3, 3)` (file units²).
    #[getter]
    fn covariances<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray3<f64>> {
        let c = self.inner.covariances();
        Array3::from_shape_fn((c.len(), 3, 3), |(i, r, k)| c[i][(r, k)]).into_pyarray(py)
    }

    /// Covariances packed `(n, 6)` as `(xx, xy, xz, yy, yz, zz)`, the upper triangle that 3DGS
    /// rasterizers take (file units²).
    #[getter]
    fn packed_covariances<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        const UPPER: [(usize, usize); 6] = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)];
        let c = self.inner.covariances();
        Array2::from_shape_fn((c.len(), 6), |(i, k)| c[i][UPPER[k]]).into_pyarray(py)
    }

    /// The property names of a splat, in file order.
    #[getter]
    fn properties(&self) -> Vec<String> {
        self.inner
            .property_names()
            .into_iter()
            .map(str::to_string)
            .collect()
    }

    /// The values `(n,)` of property `name` (e.g. `opacity`, `f_dc_0`).
    fn column<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyArray1<f64>>> {
        self.inner
            .column(name)
            .map(|c| Array1::from(c).into_pyarray(py))
            .ok_or_else(|| PyValueError::new_err(format!("the splats have no property {name:?}")))
    }

    fn __len__(&self) -> usize {
        self.inner.len()
    }

    fn __repr__(&self) -> String {
        format!("Splats({} splats)", self.inner.len())
    }
}
