//! `freeform.FrameWriter`: PLY and VTK frames of a geometry's display points.

use std::path::PathBuf;

use freeform::FrameWriter;
use numpy::PyArray2;
use pyo3::exceptions::{PyOSError, PyValueError};
use pyo3::prelude::*;

use crate::arrays::{Points, points_array, points_of};
use crate::errors::{self};
use crate::geometry::PyGeometry;

/// Writes frames of a geometry's display points (its surface's vertices, or its cloud) as PLY
/// and VTK files (`frame_NNNNN.ply` / `.vtk`), for ParaView, Blender or MeshLab.
#[pyclass(module = "freeform._native", name = "FrameWriter", frozen)]
pub(crate) struct PyFrameWriter {
    inner: FrameWriter,
}

#[pymethods]
impl PyFrameWriter {
    /// A writer into folder `out_dir` for `geometry`.
    #[new]
    fn new(out_dir: PathBuf, geometry: &PyGeometry) -> Self {
        PyFrameWriter {
            inner: FrameWriter::new(out_dir, &geometry.inner),
        }
    }

    /// The rest positions `(n, 3)` (m) the frames deform: pass these to
    /// `Simulation.deformed_points` and write what it returns.
    #[getter]
    fn rest_positions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        points_array(py, self.inner.rest_positions())
    }

    /// Writes frame `index` at `time` (s) with the display points at `positions` (`(n, 3)`, m,
    /// in the order of `rest_positions`); returns the PLY and VTK paths.
    fn write(
        &self,
        index: usize,
        positions: Points<'_>,
        time: f64,
    ) -> PyResult<(PathBuf, PathBuf)> {
        let positions = points_of(&positions, "positions")?;
        let expected = self.inner.rest_positions().len();
        if positions.len() != expected {
            return Err(PyValueError::new_err(format!(
                "{} positions for {expected} display points",
                positions.len()
            )));
        }
        let [ply, vtk] = self
            .inner
            .write(index, &positions, time)
            .map_err(|e| errors::raise::<PyOSError>(&e))?;
        Ok((ply, vtk))
    }
}
