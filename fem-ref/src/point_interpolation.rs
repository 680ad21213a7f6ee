//! Interpolating the FEM displacement at arbitrary points inside the mesh.

use nalgebra::{Vector3, Vector4};
use thiserror::Error;

use crate::element::{FemMesh, shape_values};

/// A query point is not inside any element.
#[derive(Clone, Debug, Error, PartialEq)]
#[error("point {point} at {position:?} is not inside the mesh (tolerance {tolerance:e})")]
pub struct PointLocationError {
    /// Index of the query.
    pub point: usize,
    /// Its coordinates.
    pub position: [f64; 3],
    /// Barycentric tolerance used.
    pub tolerance: f64,
}

/// Barycentric tolerance within which a point on an element's face counts as inside.
const LOCATION_TOLERANCE: f64 = 1e-9;

/// For each query point: its element and shape-function values, so that
/// `x(p) = Σ_a N_a(p) x_a` is a cheap sum per frame.
#[derive(Clone, Debug)]
pub struct PointInterpolation {
    entries: Vec<(Vec<usize>, Vec<f64>)>,
}

impl PointInterpolation {
    /// Locates every point (rest coordinates, m) in `mesh`; points on faces or edges (within a
    /// barycentric tolerance of 1e-9) belong to one of the touching elements.
    ///
    /// # Errors
    /// [`PointLocationError`] for the first point outside the mesh.
    pub fn new(mesh: &FemMesh, points: &[Vector3<f64>]) -> Result<Self, PointLocationError> {
        let (interpolation, inside) = PointInterpolation::inside(mesh, points);
        match (0..points.len()).zip(&inside).find(|(i, j)| i != *j) {
            None if inside.len() == points.len() => Ok(interpolation),
            found => {
                let point = found.map_or(inside.len(), |(i, _)| i);
                Err(PointLocationError {
                    point,
                    position: points[point].into(),
                    tolerance: LOCATION_TOLERANCE,
                })
            }
        }
    }

    /// The points of `points` inside `mesh` (as [`PointInterpolation::new`] locates them) and
    /// their indices, ascending; points outside are skipped (e.g. to compare two meshes of one
    /// shape whose boundaries differ).
    pub fn inside(mesh: &FemMesh, points: &[Vector3<f64>]) -> (Self, Vec<usize>) {
        let tets = mesh.tet_mesh();
        let inverses: Vec<_> = (0..mesh.element_count())
            .map(|e| tets.edge_matrix(e).try_inverse().expect("positive volume"))
            .collect();
        let mut entries = Vec::with_capacity(points.len());
        let mut inside = Vec::with_capacity(points.len());
        for (i, p) in points.iter().enumerate() {
            let mut best: Option<(usize, Vector4<f64>, f64)> = None;
            for (e, inv) in inverses.iter().enumerate() {
                let x0 = tets.vertices()[tets.tets()[e][0]];
                let l = inv * (p - x0);
                let lambda = Vector4::new(1.0 - l.sum(), l.x, l.y, l.z);
                let worst = lambda.min();
                if best.as_ref().is_none_or(|b| worst > b.2) {
                    best = Some((e, lambda, worst));
                }
            }
            if let Some((e, lambda, worst)) = best
                && worst >= -LOCATION_TOLERANCE
            {
                entries.push((
                    mesh.element(e).to_vec(),
                    shape_values(mesh.order(), &lambda),
                ));
                inside.push(i);
            }
        }
        (PointInterpolation { entries }, inside)
    }

    /// Interpolated positions from node positions (m).
    pub fn interpolate(&self, node_positions: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
        self.entries
            .iter()
            .map(|(nodes, values)| {
                nodes
                    .iter()
                    .zip(values)
                    .map(|(&n, v)| node_positions[n] * *v)
                    .sum()
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::element::ElementOrder;
    use crate::tet_mesh::TetMesh;

    #[test]
    fn inside_skips_points_outside_and_interpolates_the_others_exactly() {
        let tets = TetMesh::cuboid(Vector3::zeros(), Vector3::new(2.0, 1.0, 1.0), [4, 2, 2])
            .expect("a valid box");
        let mesh = FemMesh::new(tets, ElementOrder::Quadratic);
        let points = [
            Vector3::new(0.3, 0.2, 0.7),
            Vector3::new(2.5, 0.5, 0.5),
            Vector3::new(1.9, 1.0, 0.0),
            Vector3::new(-0.1, 0.5, 0.5),
        ];
        let (interpolation, inside) = PointInterpolation::inside(&mesh, &points);
        assert_eq!(inside, vec![0, 2]);
        // P2 reproduces any quadratic field exactly: here x ↦ (x², yz, x + z).
        let field = |p: &Vector3<f64>| Vector3::new(p.x * p.x, p.y * p.z, p.x + p.z);
        let nodes: Vec<Vector3<f64>> = mesh.nodes().iter().map(field).collect();
        for (value, &i) in interpolation.interpolate(&nodes).iter().zip(&inside) {
            assert!((value - field(&points[i])).norm() < 1e-12, "{value:?}");
        }
        let error = PointInterpolation::new(&mesh, &points).err().unwrap();
        assert_eq!(error.point, 1);
    }
}
