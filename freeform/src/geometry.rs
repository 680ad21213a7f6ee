//! An object's shape, read from a file or given as a box, turned into the integration points
//! every other step works on (design §3.1): grid points inside a closed surface, or the points
//! of a cloud (a plain PLY cloud or a 3D Gaussian Splatting file) with estimated volumes.

use std::path::{Path, PathBuf};

use nalgebra::Vector3;
use rkpm_core::{
    GeometryReadError, GridSamplingParams, IntegrationPoints, PointCloud, PointCloudSamplingParams,
    SamplingError, TriangleMesh, read_point_cloud, read_triangle_mesh, sample_grid,
    sample_point_cloud,
};
use thiserror::Error;

/// A shape: a closed triangle surface or a point cloud.
#[derive(Clone, Debug)]
pub enum Geometry {
    /// A closed, consistently oriented triangle mesh (m).
    Surface(TriangleMesh),
    /// Points sampled on or in the object (m), with 3DGS attributes when the file had them.
    Cloud(PointCloud),
}

/// A geometry could not be read or sampled.
#[derive(Debug, Error)]
pub enum GeometryError {
    /// The path names no file.
    #[error("{path}: no such file")]
    Missing {
        /// The path given.
        path: PathBuf,
    },
    /// The file is neither a closed triangle mesh nor a point cloud.
    #[error("not a closed triangle mesh ({mesh}) and not a point cloud")]
    Unreadable {
        /// Why the mesh reader refused it.
        mesh: Box<GeometryReadError>,
        /// Why the point-cloud reader refused it.
        #[source]
        cloud: Box<GeometryReadError>,
    },
    /// The file is a malformed or open mesh (an open mesh is never read as a cloud of its
    /// vertices).
    #[error(transparent)]
    Read(#[from] GeometryReadError),
    /// No integration point could be placed.
    #[error("sampling integration points failed")]
    Sampling(#[source] SamplingError),
}

impl Geometry {
    /// Reads a closed mesh (OBJ, STL, PLY with faces) or, from a PLY without faces, a point
    /// cloud (plain or 3DGS).
    ///
    /// # Errors
    /// [`GeometryError::Missing`] for a path that is not a file; [`GeometryError::Read`] for a
    /// malformed, open or non-manifold mesh; [`GeometryError::Unreadable`] when neither reader
    /// accepts a file without faces.
    pub fn read(path: &Path) -> Result<Self, GeometryError> {
        if !path.is_file() {
            return Err(GeometryError::Missing {
                path: path.to_owned(),
            });
        }
        match read_triangle_mesh(path) {
            Ok(mesh) => Ok(Geometry::Surface(mesh)),
            // Only a file without faces is a point cloud: an open or broken mesh is an error,
            // not a cloud of its vertices.
            Err(mesh @ GeometryReadError::NoData { .. }) => read_point_cloud(path)
                .map(Geometry::Cloud)
                .map_err(|cloud| GeometryError::Unreadable {
                    mesh: Box::new(mesh),
                    cloud: Box::new(cloud),
                }),
            Err(e) => Err(e.into()),
        }
    }

    /// An axis-aligned box `[min, max]` (m) as a closed surface.
    pub fn cuboid(min: Vector3<f64>, max: Vector3<f64>) -> Self {
        Geometry::Surface(TriangleMesh::cuboid(min, max))
    }

    /// The same shape scaled so that the largest side of a surface's bounding box is 1 m, its
    /// minimum corner at the origin ([`TriangleMesh::normalized`]). A cloud keeps its units.
    pub fn normalized(self) -> Self {
        match self {
            Geometry::Surface(mesh) => Geometry::Surface(mesh.normalized().0),
            cloud => cloud,
        }
    }

    /// The same shape scaled by `factor` about the origin (a cloud's splat attributes dropped:
    /// only positions are scaled).
    pub fn scaled(self, factor: f64) -> Self {
        match self {
            Geometry::Surface(mesh) => Geometry::Surface(mesh.scaled(factor)),
            Geometry::Cloud(cloud) => Geometry::Cloud(PointCloud::new(
                cloud.positions().iter().map(|p| p * factor).collect(),
                None,
            )),
        }
    }

    /// Points on the shape's surface at most about `spacing` (m) apart, where other objects
    /// touch it ([`reduced_sim::BodyContactParams::radius`]): a surface's triangles sampled
    /// finely, or a cloud's points, thinned to one per cell of side `spacing / 2` (every part
    /// of the surface within `0.87 spacing` of a sample), in a fixed order.
    pub fn contact_samples(&self, spacing: f64) -> Vec<Vector3<f64>> {
        let cell = 0.5 * spacing;
        let mut kept = std::collections::HashSet::new();
        let mut samples = Vec::new();
        let mut keep = |p: Vector3<f64>| {
            if kept.insert([0, 1, 2].map(|k| (p[k] / cell).floor() as i64)) {
                samples.push(p);
            }
        };
        match self {
            Geometry::Surface(mesh) => {
                for t in 0..mesh.triangles().len() {
                    let [a, b, c] = mesh.triangle_corners(t);
                    let longest = (b - a).norm().max((c - b).norm()).max((a - c).norm());
                    // Four times finer than the cells, so every cell the triangle crosses gets one.
                    let n = ((longest / (0.25 * cell)).ceil() as usize).max(1);
                    for i in 0..=n {
                        for j in 0..=n - i {
                            let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                            keep(a + (b - a) * u + (c - a) * v);
                        }
                    }
                }
            }
            Geometry::Cloud(cloud) => cloud.positions().iter().for_each(|&p| keep(p)),
        }
        samples
    }

    /// The closed surface, if this is one.
    pub fn surface(&self) -> Option<&TriangleMesh> {
        match self {
            Geometry::Surface(mesh) => Some(mesh),
            Geometry::Cloud(_) => None,
        }
    }

    /// Integration points: about `points` grid points inside a surface
    /// ([`rkpm_core::sample_grid`], volumes summing to the grid's share of the enclosed
    /// volume), or at most `points` points of a cloud ([`rkpm_core::sample_point_cloud`] with
    /// its default volume estimate, the volume the cloud encloses).
    ///
    /// # Errors
    /// [`GeometryError::Sampling`]: `points` is zero, the shape is thinner than a grid cell,
    /// or the cloud is empty.
    pub fn integration_points(&self, points: usize) -> Result<IntegrationPoints, GeometryError> {
        self.integration_points_filling(points, false)
    }

    /// [`Geometry::integration_points`]; for a cloud with `fill_interior`, about `points` more
    /// inside it ([`rkpm_core::PointCloudSamplingParams::fill_interior`]), so that a cloud on a
    /// surface (a 3DGS file) carries mass and elastic energy inside too. A surface ignores it.
    ///
    /// # Errors
    /// As [`Geometry::integration_points`].
    pub fn integration_points_filling(
        &self,
        points: usize,
        fill_interior: bool,
    ) -> Result<IntegrationPoints, GeometryError> {
        match self {
            Geometry::Surface(mesh) => sample_grid(
                mesh,
                &GridSamplingParams {
                    target_points: points,
                },
            ),
            Geometry::Cloud(cloud) => sample_point_cloud(
                cloud,
                &PointCloudSamplingParams {
                    max_points: points,
                    fill_interior,
                    ..Default::default()
                },
            ),
        }
        .map_err(GeometryError::Sampling)
    }

    /// Points that carry the object's appearance and are written per frame (m): a surface's
    /// vertices or a cloud's points.
    pub fn display_points(&self) -> &[Vector3<f64>] {
        match self {
            Geometry::Surface(mesh) => mesh.vertices(),
            Geometry::Cloud(cloud) => cloud.positions(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_unit_box_gives_grid_points_whose_volumes_sum_to_one() {
        let geometry = Geometry::cuboid(Vector3::zeros(), Vector3::new(1.0, 1.0, 1.0));
        let points = geometry.integration_points(1000).unwrap();
        assert!((points.total_volume() - 1.0).abs() < 1e-12);
        assert_eq!(points.len(), 1000);
    }

    #[test]
    fn contact_samples_cover_a_box_surface_within_the_spacing() {
        let geometry = Geometry::cuboid(Vector3::zeros(), Vector3::new(0.4, 0.2, 0.3));
        let spacing = 0.05;
        let samples = geometry.contact_samples(spacing);
        // All on the surface.
        let on_surface = |p: &Vector3<f64>| {
            let max = Vector3::new(0.4, 0.2, 0.3);
            (0..3).any(|k| p[k].abs() < 1e-12 || (p[k] - max[k]).abs() < 1e-12)
        };
        assert!(samples.iter().all(on_surface));
        // Every point of a fine probe grid on the faces has a sample within 0.87 spacing.
        let index = rkpm_core::SpatialIndex::new(&samples);
        for i in 0..=40 {
            for j in 0..=20 {
                for probe in [
                    Vector3::new(0.01 * i as f64, 0.01 * j as f64, 0.0),
                    Vector3::new(0.01 * i as f64, 0.2, 0.015 * j as f64),
                ] {
                    let (_, d) = index.nearest(&probe, 1)[0];
                    assert!(d <= 0.87 * spacing, "{probe:?}: nearest sample {d} m away");
                }
            }
        }
        // Not much denser than needed: the area over a cell's face, give or take.
        let area = 2.0 * (0.4 * 0.2 + 0.2 * 0.3 + 0.3 * 0.4);
        let cells = area / (0.5 * spacing).powi(2);
        assert!(
            (samples.len() as f64) < 2.0 * cells,
            "{} samples",
            samples.len()
        );
    }

    #[test]
    fn a_missing_file_is_named_in_the_error() {
        let err = Geometry::read(Path::new("no/such/shape.obj")).unwrap_err();
        assert!(matches!(err, GeometryError::Missing { .. }));
        assert!(err.to_string().contains("no/such/shape.obj"));
    }
}
