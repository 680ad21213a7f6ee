//! `freeform.render_preview`: a quick look at points.

use freeform::points_preview;
use nalgebra::Vector3;
use numpy::ndarray::Array3;
use numpy::{IntoPyArray, PyArray3};
use pyo3::prelude::*;

use crate::arrays::{Points, points_of};
use crate::errors::value_error;

/// A `(height, width, 3)` uint8 RGB preview of `points` (`(n, 3)`, m) seen from 30° about and
/// 20° above `up`, each point a round splat, coloured by `values` (`(n,)`, e.g. von Mises
/// stress; grey without) with `opacity` (`(n,)` in [0, 1]; opaque without), on white.
#[pyfunction]
#[pyo3(signature = (points, values = None, opacity = None, up = [0.0, 1.0, 0.0], width = 512, height = 512))]
pub(crate) fn render_preview<'py>(
    py: Python<'py>,
    points: Points<'py>,
    values: Option<Vec<f64>>,
    opacity: Option<Vec<f64>>,
    up: [f64; 3],
    width: usize,
    height: usize,
) -> PyResult<Bound<'py, PyArray3<u8>>> {
    let points = points_of(&points, "points")?;
    let image = py
        .detach(|| {
            points_preview(
                &points,
                values.as_deref(),
                opacity.as_deref(),
                Vector3::from(up),
                width,
                height,
            )
        })
        .map_err(|e| value_error(&e))?;
    let shape = (image.height, image.width, 3);
    Ok(Array3::from_shape_fn(shape, |(y, x, c)| image.pixel(x, y)[c]).into_pyarray(py))
}
