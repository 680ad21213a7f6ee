//! Interpolating the FEM displacement at arbitrary points inside the mesh.

use nalgebra::{Vector3, Vector4};
use rkpm_core::{Aabb, GridBins};
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
        let grid = element_grid(mesh);
        let mut entries = Vec::with_capacity(points.len());
        let mut inside = Vec::with_capacity(points.len());
        for (i, p) in points.iter().enumerate() {
            // The element whose smallest barycentric coordinate at p is largest (the first of
            // equals): only elements whose box holds p can have it non-negative.
            let mut best: Option<(usize, Vector4<f64>, f64)> = None;
            for e in grid.items_at((*p).into()).iter().map(|&e| e as usize) {
                let x0 = tets.vertices()[tets.tets()[e][0]];
                let l = inverses[e] * (p - x0);
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

/// The mesh's elements binned on a uniform grid over its bounding box by their bounding boxes
/// (widened by a millionth of their diagonal, far more than the location tolerance): a point's
/// candidates are its cell's list, ascending. About one cell per element, at most eight.
/// Points outside the grid are clamped into it (their candidates then all leave them outside,
/// as every element would).
fn element_grid(mesh: &FemMesh) -> GridBins<3> {
    let tets = mesh.tet_mesh();
    let vertices = tets.vertices();
    let boxes: Vec<Aabb> = tets
        .tets()
        .iter()
        .map(|t| {
            let b = Aabb::from_points(t.iter().map(|&v| &vertices[v])).expect("four corners");
            let widen = Vector3::repeat(1e-6 * b.extent().norm());
            Aabb {
                min: b.min - widen,
                max: b.max + widen,
            }
        })
        .collect();
    let all = Aabb::from_points(boxes.iter().flat_map(|b| [&b.min, &b.max])).unwrap_or(Aabb {
        min: Vector3::zeros(),
        max: Vector3::zeros(),
    });
    let extent = all.extent();
    let volume = extent.x.max(f64::MIN_POSITIVE)
        * extent.y.max(f64::MIN_POSITIVE)
        * extent.z.max(f64::MIN_POSITIVE);
    let mut cell = (volume / boxes.len().max(1) as f64)
        .cbrt()
        .max(f64::MIN_POSITIVE);
    let dims_of =
        |cell: f64| [0, 1, 2].map(|k| ((extent[k] / cell).ceil() as usize).clamp(1, 1 << 10));
    // At most eight cells an element, however flat the box.
    while dims_of(cell).iter().product::<usize>() > 8 * (boxes.len() + 1) {
        cell *= 1.5;
    }
    let corners: Vec<_> = boxes.iter().map(|b| (b.min.into(), b.max.into())).collect();
    GridBins::new(all.min.into(), [cell; 3], dims_of(cell), &corners)
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

    /// Every element tried for every point: what the grid must reproduce.
    fn located_by_every_element(mesh: &FemMesh, points: &[Vector3<f64>]) -> Vec<Option<usize>> {
        let tets = mesh.tet_mesh();
        points
            .iter()
            .map(|p| {
                let mut best: Option<(usize, f64)> = None;
                for e in 0..mesh.element_count() {
                    let inv = tets.edge_matrix(e).try_inverse().unwrap();
                    let l = inv * (p - tets.vertices()[tets.tets()[e][0]]);
                    let worst = Vector4::new(1.0 - l.sum(), l.x, l.y, l.z).min();
                    if best.is_none_or(|b| worst > b.1) {
                        best = Some((e, worst));
                    }
                }
                best.filter(|b| b.1 >= -LOCATION_TOLERANCE).map(|b| b.0)
            })
            .collect()
    }

    #[test]
    fn the_grid_locates_every_point_in_the_element_a_search_of_all_elements_picks() {
        let tets = TetMesh::cuboid(
            Vector3::new(-0.3, 0.1, 0.0),
            Vector3::new(2.0, 1.0, 0.5),
            [9, 4, 3],
        )
        .expect("a valid box");
        // Sheared, so that element boxes overlap unevenly.
        let sheared: Vec<Vector3<f64>> = tets
            .vertices()
            .iter()
            .map(|v| Vector3::new(v.x + 0.3 * v.y, v.y, v.z + 0.2 * v.x))
            .collect();
        let tets = TetMesh::new(sheared, tets.tets().to_vec()).expect("still valid");
        let mesh = FemMesh::new(tets, ElementOrder::Quadratic);
        // Interior points, the vertices and edge midpoints themselves (on faces and edges),
        // and points outside on every side.
        let mut state = 12345u64;
        let mut uniform = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut points: Vec<Vector3<f64>> = (0..400)
            .map(|_| {
                Vector3::new(
                    -0.6 + 3.4 * uniform(),
                    -0.1 + 1.3 * uniform(),
                    -0.2 + 1.2 * uniform(),
                )
            })
            .collect();
        points.extend(mesh.nodes().iter().copied());
        let expected = located_by_every_element(&mesh, &points);
        let (interpolation, inside) = PointInterpolation::inside(&mesh, &points);
        let located: Vec<usize> = expected.iter().flatten().copied().collect();
        assert_eq!(
            inside,
            (0..points.len())
                .filter(|&i| expected[i].is_some())
                .collect::<Vec<_>>()
        );
        assert!(inside.len() > mesh.nodes().len() && inside.len() < points.len());
        for ((nodes, _), e) in interpolation.entries.iter().zip(located) {
            assert_eq!(nodes.as_slice(), mesh.element(e));
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig { cases: 32, rng_seed: proptest::test_runner::RngSeed::Fixed(3), ..Default::default() })]

        /// On any sheared box mesh, for points inside, outside and on its nodes, the grid's
        /// pick is the full search's.
        #[test]
        fn the_grid_agrees_with_the_full_search_on_any_sheared_box(
            cells in proptest::array::uniform3(1usize..5),
            shear in proptest::array::uniform3(-0.8f64..0.8),
            points in proptest::collection::vec(proptest::array::uniform3(-0.3f64..1.3), 1..60),
        ) {
            let tets = TetMesh::cuboid(Vector3::zeros(), Vector3::new(1.0, 1.0, 1.0), cells)
                .expect("a valid box");
            let sheared: Vec<Vector3<f64>> = tets
                .vertices()
                .iter()
                .map(|v| Vector3::new(v.x + shear[0] * v.y, v.y + shear[1] * v.z, v.z + shear[2] * v.x))
                .collect();
            let tets = TetMesh::new(sheared.clone(), tets.tets().to_vec()).expect("still valid");
            let mesh = FemMesh::new(tets, ElementOrder::Linear);
            let mut queries: Vec<Vector3<f64>> = points
                .iter()
                .map(|p| Vector3::new(p[0] + shear[0] * p[1], p[1] + shear[1] * p[2], p[2] + shear[2] * p[0]))
                .collect();
            queries.extend(sheared);
            let expected = located_by_every_element(&mesh, &queries);
            let (interpolation, inside) = PointInterpolation::inside(&mesh, &queries);
            let expected_inside: Vec<usize> =
                (0..queries.len()).filter(|&i| expected[i].is_some()).collect();
            proptest::prop_assert_eq!(&inside, &expected_inside);
            for ((nodes, _), e) in interpolation.entries.iter().zip(expected.iter().flatten()) {
                proptest::prop_assert_eq!(nodes.as_slice(), mesh.element(*e));
            }
        }
    }
}
