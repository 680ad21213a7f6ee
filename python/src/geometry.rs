//! `freeform.Geometry`: a closed surface or a point cloud.

use std::path::PathBuf;

use freeform::Geometry;
use nalgebra::Vector3;
use numpy::PyArray2;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rkpm_core::{PointCloud, TriangleMesh};

use crate::arrays::{Points, points_array, points_of};
use crate::errors::{self};
use crate::points::PyIntegrationPoints;

/// A shape: a closed triangle surface or a point cloud (m).
#[pyclass(module = "freeform._native", name = "Geometry", frozen)]
pub(crate) struct PyGeometry {
    pub(crate) inner: Geometry,
}

#[pymethods]
impl PyGeometry {
    /// Reads a closed mesh (OBJ, STL, PLY with faces) or, from a PLY without faces, a point
    /// cloud (plain or 3DGS).
    #[staticmethod]
    fn read(path: PathBuf) -> PyResult<Self> {
        Geometry::read(&path)
            .map(|inner| PyGeometry { inner })
            .map_err(|e| errors::geometry_error(&e))
    }

    /// The axis-aligned box from corner `lo` to corner `hi` (m).
    #[staticmethod]
    #[pyo3(name = "box")]
    fn cuboid(lo: [f64; 3], hi: [f64; 3]) -> PyResult<Self> {
        if !(0..3).all(|k| lo[k].is_finite() && hi[k].is_finite() && lo[k] < hi[k]) {
            return Err(PyValueError::new_err(format!(
                "a box needs finite corners with lo < hi on every axis, got lo {lo:?}, hi {hi:?}"
            )));
        }
        Ok(PyGeometry {
            inner: Geometry::cuboid(Vector3::from(lo), Vector3::from(hi)),
        })
    }

    /// A closed triangle surface from vertices `(n, 3)` (m) and triangles `(t, 3)` (vertex
    /// indices, counter-clockwise seen from outside).
    #[staticmethod]
    fn from_mesh(vertices: Points<'_>, triangles: Vec<[usize; 3]>) -> PyResult<Self> {
        let vertices = points_of(&vertices, "vertices")?;
        TriangleMesh::new(vertices, triangles)
            .map(|mesh| PyGeometry {
                inner: Geometry::Surface(mesh),
            })
            .map_err(|e| errors::raise::<errors::GeometryError>(&e))
    }

    /// A point cloud from an `(n, 3)` array of points (m).
    #[staticmethod]
    fn from_points(points: Points<'_>) -> PyResult<Self> {
        let points = points_of(&points, "points")?;
        if points.is_empty() {
            return Err(PyValueError::new_err(
                "a point cloud needs at least one point",
            ));
        }
        Ok(PyGeometry {
            inner: Geometry::Cloud(PointCloud::new(points, None)),
        })
    }

    /// About `n` integration points with their volumes: a grid inside a surface, or the
    /// cloud's points (down-sampled) with volumes from the voxels they fill.
    fn integration_points(&self, py: Python<'_>, n: usize) -> PyResult<PyIntegrationPoints> {
        let geometry = &self.inner;
        py.detach(|| geometry.integration_points(n))
            .map(|inner| PyIntegrationPoints { inner })
            .map_err(|e| errors::geometry_error(&e))
    }

    /// `(n, 3)` points that show the shape: the surface's vertices or the cloud's points (m).
    fn display_points<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        points_array(py, self.inner.display_points())
    }

    fn __repr__(&self) -> String {
        match &self.inner {
            Geometry::Surface(mesh) => format!(
                "Geometry(surface: {} vertices, {} triangles)",
                mesh.vertices().len(),
                mesh.triangles().len()
            ),
            Geometry::Cloud(cloud) => format!("Geometry(cloud: {} points)", cloud.len()),
        }
    }
}
