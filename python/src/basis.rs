//! `freeform.Basis` and `freeform.build_basis`: the skinning eigenmode basis.

use std::path::PathBuf;

use numpy::ndarray::Array3;
use numpy::{IntoPyArray, PyArray2, PyArray3};
use pyo3::exceptions::{PyFileNotFoundError, PyOSError};
use pyo3::prelude::*;
use skin_eigen::{BasisParams, BasisStage, SkinningBasis, SkinningWeights, build_basis_observed};

use crate::arrays::{Points, matrix_array, points_of};
use crate::errors::{self};
use crate::material::PyMaterial;
use crate::points::PyIntegrationPoints;
use crate::progress::PythonProgress;
use crate::threads::with_threads;

/// A skinning basis: m eigenmode weights plus the constant handle, evaluated anywhere in the
/// shape.
#[pyclass(module = "freeform._native", name = "Basis", frozen)]
pub(crate) struct PyBasis {
    pub(crate) inner: SkinningBasis,
}

impl PyBasis {
    /// W and ∇W at `points`, evaluated without the GIL.
    fn evaluate(&self, py: Python<'_>, points: &Points<'_>) -> PyResult<SkinningWeights> {
        let points = points_of(points, "points")?;
        let basis = &self.inner;
        py.detach(|| basis.evaluate(&points))
            .map_err(|e| errors::raise::<errors::BasisError>(&e))
    }
}

#[pymethods]
impl PyBasis {
    /// Modes m (the handles are m + 1 with the constant one).
    #[getter]
    fn modes(&self) -> usize {
        self.inner.modes()
    }

    /// Handles m + 1 (the constant handle first).
    #[getter]
    fn handles(&self) -> usize {
        self.inner.handles()
    }

    /// The m generalized eigenvalues of the modes, ascending.
    #[getter]
    fn eigenvalues(&self) -> Vec<f64> {
        self.inner.eigenvalues().to_vec()
    }

    /// Weights W at `points` (`(n, 3)`, m): `(n, m + 1)`, column 0 the constant handle (1).
    fn weights<'py>(
        &self,
        py: Python<'py>,
        points: Points<'py>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let evaluated = self.evaluate(py, &points)?;
        Ok(matrix_array(py, &evaluated.weights))
    }

    /// Weight gradients ∇W at `points` (`(n, 3)`, m): `(n, m + 1, 3)` (1/m).
    fn weight_gradients<'py>(
        &self,
        py: Python<'py>,
        points: Points<'py>,
    ) -> PyResult<Bound<'py, PyArray3<f64>>> {
        let evaluated = self.evaluate(py, &points)?;
        let g = &evaluated.gradients;
        let shape = (g[0].nrows(), self.inner.handles(), 3);
        Ok(Array3::from_shape_fn(shape, |(i, j, k)| g[k][(i, j)]).into_pyarray(py))
    }

    /// Writes the basis to `path` (the library's versioned binary format).
    fn save(&self, path: PathBuf) -> PyResult<()> {
        self.inner
            .save(&path)
            .map_err(|e| errors::raise::<PyOSError>(&e))
    }

    /// Reads a basis written by `save`.
    #[staticmethod]
    fn load(path: PathBuf) -> PyResult<Self> {
        if !path.is_file() {
            return Err(PyFileNotFoundError::new_err(format!(
                "{}: no such file",
                path.display()
            )));
        }
        SkinningBasis::load(&path)
            .map(|inner| PyBasis { inner })
            .map_err(|e| errors::raise::<errors::FileFormatError>(&e))
    }

    fn __repr__(&self) -> String {
        format!(
            "Basis({} modes, {} kernels)",
            self.inner.modes(),
            self.inner.kernels().len()
        )
    }
}

/// Builds the skinning basis of `points` (Sec. 4–5): `kernels` RKPM kernels, the `modes`
/// lowest generalized eigenmodes of the elastic Hessian at rest against the mass.
/// `threads`: the threads it may use (all cores when None); `progress`: a callable
/// `progress(label, done, total)` told as each of the three stages begins (`"basis: shape
/// functions"`, `"basis: assembly"`, `"basis: eigen solve"` with done 0, 1, 2 of 3) and once
/// more when it is built (`"basis"`, 3 of 3).
#[pyfunction]
#[pyo3(signature = (points, material, modes = 16, kernels = 1000, threads = None, progress = None))]
pub(crate) fn build_basis(
    py: Python<'_>,
    points: &PyIntegrationPoints,
    material: &PyMaterial,
    modes: usize,
    kernels: usize,
    threads: Option<usize>,
    progress: Option<Py<PyAny>>,
) -> PyResult<PyBasis> {
    let lame = material.lame_at(points.inner.positions())?;
    let params = BasisParams::default()
        .with_modes(modes)
        .with_kernels(kernels);
    let points = &points.inner;
    let progress = progress.map(PythonProgress::new);
    let total = BasisStage::ALL.len();
    let on_stage = |stage: BasisStage| {
        if let Some(progress) = &progress {
            let done = BasisStage::ALL
                .iter()
                .position(|&s| s == stage)
                .unwrap_or(0);
            progress.call(&format!("basis: {}", stage.name()), Some(done), Some(total));
        }
    };
    let built = py
        .detach(|| {
            with_threads(threads, || {
                build_basis_observed(points, &lame, &params, &on_stage)
            })
        })?
        .map(|(inner, _, _)| PyBasis { inner })
        .map_err(|e| errors::raise::<errors::BasisError>(&e))?;
    if let Some(progress) = &progress {
        progress.call("basis", Some(total), Some(total));
    }
    Ok(built)
}
