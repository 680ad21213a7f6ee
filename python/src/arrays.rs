//! numpy arrays across the boundary: inputs of any float dtype, layout or a nested list,
//! converted once to the library's types; outputs built in Rust buffers that numpy takes over
//! without a copy (an output's `.base` is the Rust buffer), or written into a caller's array.

use nalgebra::{DMatrix, Vector3};
use numpy::ndarray::Array2;
use numpy::{
    AllowTypeChange, IntoPyArray, PyArray2, PyArrayLike2, PyArrayMethods, PyUntypedArrayMethods,
};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

/// An `(n, 3)` array of points as Python gives it: float64 C-contiguous arrays are read in
/// place; other dtypes, strides and nested lists are converted once by numpy.
pub(crate) type Points<'py> = PyArrayLike2<'py, f64, AllowTypeChange>;

/// Points of an `(n, 3)` float64 array, refused unless every coordinate is finite.
pub(crate) fn points_of(array: &Points<'_>, what: &str) -> PyResult<Vec<Vector3<f64>>> {
    let view = array.as_array();
    if view.ncols() != 3 {
        return Err(PyValueError::new_err(format!(
            "{what} must have shape (n, 3), got {:?}",
            view.shape()
        )));
    }
    let points: Vec<Vector3<f64>> = view
        .rows()
        .into_iter()
        .map(|r| Vector3::new(r[0], r[1], r[2]))
        .collect();
    if let Some(i) = points.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        return Err(PyValueError::new_err(format!(
            "{what}: point {i} has a coordinate that is not finite"
        )));
    }
    Ok(points)
}

/// An `(n, 3)` array of points.
pub(crate) fn points_array<'py>(
    py: Python<'py>,
    points: &[Vector3<f64>],
) -> Bound<'py, PyArray2<f64>> {
    Array2::from_shape_fn((points.len(), 3), |(i, k)| points[i][k]).into_pyarray(py)
}

/// An `n × c` matrix as an `(n, c)` array.
pub(crate) fn matrix_array<'py>(py: Python<'py>, m: &DMatrix<f64>) -> Bound<'py, PyArray2<f64>> {
    Array2::from_shape_fn((m.nrows(), m.ncols()), |(i, j)| m[(i, j)]).into_pyarray(py)
}

/// Writes `points` into `out`, an `(n, 3)` float64 array of the caller's, and returns it.
///
/// # Errors
/// `ValueError` when `out` has another shape, or is not writeable and C-contiguous.
pub(crate) fn write_points_into<'py>(
    out: Bound<'py, PyArray2<f64>>,
    points: &[Vector3<f64>],
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let shape = out.shape().to_vec();
    if shape != [points.len(), 3] {
        return Err(PyValueError::new_err(format!(
            "out must have shape ({}, 3), got {shape:?}",
            points.len()
        )));
    }
    {
        let mut view = out.try_readwrite().map_err(|e| {
            PyValueError::new_err(format!("out: cannot write into the array ({e})"))
        })?;
        let slice = view
            .as_slice_mut()
            .map_err(|_| PyValueError::new_err("out must be a C-contiguous float64 array"))?;
        for (chunk, p) in slice.chunks_exact_mut(3).zip(points) {
            chunk.copy_from_slice(p.as_slice());
        }
    }
    Ok(out)
}
