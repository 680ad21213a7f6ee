//! Closed, consistently oriented triangle meshes: the boundary of a solid.

use std::collections::HashMap;

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::aabb::Aabb;

/// Why a triangle soup is not the boundary of a solid.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeshValidationError {
    /// No vertices or no triangles.
    #[error("the mesh is empty ({vertices} vertices, {triangles} triangles)")]
    Empty {
        /// Number of vertices.
        vertices: usize,
        /// Number of triangles.
        triangles: usize,
    },
    /// A vertex coordinate is NaN or infinite.
    #[error("vertex {vertex} has a non-finite coordinate {position:?}")]
    NonFiniteVertex {
        /// Index of the vertex.
        vertex: usize,
        /// Its coordinates.
        position: [f64; 3],
    },
    /// A triangle refers to a vertex that does not exist.
    #[error("triangle {triangle} refers to vertex {index}, but there are only {vertices} vertices")]
    IndexOutOfRange {
        /// Index of the triangle.
        triangle: usize,
        /// The offending vertex index.
        index: usize,
        /// Number of vertices.
        vertices: usize,
    },
    /// A triangle uses the same vertex twice.
    #[error("triangle {triangle} repeats a vertex: {indices:?}")]
    DegenerateTriangle {
        /// Index of the triangle.
        triangle: usize,
        /// Its vertex indices.
        indices: [usize; 3],
    },
    /// An edge has no opposite half-edge: the surface has a hole (boundary edge) or two
    /// neighbouring triangles are oriented inconsistently.
    #[error(
        "edge ({from}, {to}) of triangle {triangle} has no matching opposite edge: the mesh is \
         open or inconsistently oriented ({count} such edges)"
    )]
    OpenOrInconsistent {
        /// First vertex of the edge.
        from: usize,
        /// Second vertex of the edge.
        to: usize,
        /// A triangle holding it.
        triangle: usize,
        /// How many directed edges have this problem.
        count: usize,
    },
    /// The same directed edge appears in more than one triangle (non-manifold or flipped).
    #[error(
        "directed edge ({from}, {to}) appears {times} times: the mesh is non-manifold or has \
         flipped triangles"
    )]
    NonManifoldEdge {
        /// First vertex of the edge.
        from: usize,
        /// Second vertex of the edge.
        to: usize,
        /// Multiplicity.
        times: usize,
    },
    /// The enclosed signed volume is not positive: normals point inward (or the solid is flat).
    #[error(
        "the signed volume is {volume:e} (not positive): the triangles are oriented inward or \
         the solid has no volume"
    )]
    NonPositiveVolume {
        /// The signed volume by the divergence theorem.
        volume: f64,
    },
}

/// A triangle mesh: vertex positions and counter-clockwise (outward) triangles.
///
/// Construct with [`TriangleMesh::new`] (validated: closed, consistently and outwardly oriented,
/// finite, non-empty). Positions are in the file's units until [`TriangleMesh::normalized`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TriangleMesh {
    vertices: Vec<Vector3<f64>>,
    triangles: Vec<[usize; 3]>,
}

/// The similarity transform applied by [`TriangleMesh::normalized`]:
/// `X_normalized = (X_original - origin) * scale`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Normalization {
    /// The original bounding box's minimum corner (maps to the origin).
    pub origin: Vector3<f64>,
    /// `1 / L`, L the original largest bounding-box side.
    pub scale: f64,
}

impl Normalization {
    /// Maps an original-units point into the normalized frame.
    pub fn apply(&self, p: &Vector3<f64>) -> Vector3<f64> {
        (p - self.origin) * self.scale
    }

    /// Maps a normalized point back to original units.
    pub fn invert(&self, p: &Vector3<f64>) -> Vector3<f64> {
        p / self.scale + self.origin
    }
}

impl TriangleMesh {
    /// Builds and validates a solid's boundary.
    ///
    /// # Errors
    /// [`MeshValidationError`] naming the first problem found: empty, non-finite vertex, index
    /// out of range, repeated vertex in a triangle, open or inconsistently oriented edge,
    /// non-manifold edge, or non-positive enclosed volume.
    pub fn new(
        vertices: Vec<Vector3<f64>>,
        triangles: Vec<[usize; 3]>,
    ) -> Result<Self, MeshValidationError> {
        let mesh = TriangleMesh {
            vertices,
            triangles,
        };
        mesh.validate()?;
        Ok(mesh)
    }

    fn validate(&self) -> Result<(), MeshValidationError> {
        let (nv, nt) = (self.vertices.len(), self.triangles.len());
        if nv == 0 || nt == 0 {
            return Err(MeshValidationError::Empty {
                vertices: nv,
                triangles: nt,
            });
        }
        if let Some((vertex, p)) = self
            .vertices
            .iter()
            .enumerate()
            .find(|(_, p)| !p.iter().all(|c| c.is_finite()))
        {
            return Err(MeshValidationError::NonFiniteVertex {
                vertex,
                position: [p.x, p.y, p.z],
            });
        }
        let mut directed: HashMap<(usize, usize), (usize, usize)> = HashMap::with_capacity(3 * nt);
        for (t, tri) in self.triangles.iter().enumerate() {
            if let Some(&index) = tri.iter().find(|&&i| i >= nv) {
                return Err(MeshValidationError::IndexOutOfRange {
                    triangle: t,
                    index,
                    vertices: nv,
                });
            }
            if tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2] {
                return Err(MeshValidationError::DegenerateTriangle {
                    triangle: t,
                    indices: *tri,
                });
            }
            for e in 0..3 {
                let entry = directed.entry((tri[e], tri[(e + 1) % 3])).or_insert((t, 0));
                entry.1 += 1;
            }
        }
        if let Some((&(from, to), &(_, times))) = directed.iter().find(|(_, (_, n))| *n > 1) {
            return Err(MeshValidationError::NonManifoldEdge { from, to, times });
        }
        let unmatched: Vec<_> = directed
            .iter()
            .filter(|((a, b), _)| !directed.contains_key(&(*b, *a)))
            .collect();
        if let Some(&(&(from, to), &(triangle, _))) = unmatched.iter().min_by_key(|(e, _)| **e) {
            return Err(MeshValidationError::OpenOrInconsistent {
                from,
                to,
                triangle,
                count: unmatched.len(),
            });
        }
        let volume = self.volume();
        if !(volume > 0.0) {
            return Err(MeshValidationError::NonPositiveVolume { volume });
        }
        Ok(())
    }

    /// Vertex positions.
    pub fn vertices(&self) -> &[Vector3<f64>] {
        &self.vertices
    }

    /// Triangles as vertex-index triples, counter-clockwise seen from outside.
    pub fn triangles(&self) -> &[[usize; 3]] {
        &self.triangles
    }

    /// The three corners of triangle `t`.
    pub fn triangle_corners(&self, t: usize) -> [Vector3<f64>; 3] {
        let [a, b, c] = self.triangles[t];
        [self.vertices[a], self.vertices[b], self.vertices[c]]
    }

    /// Bounding box of the vertices.
    pub fn bounding_box(&self) -> Aabb {
        Aabb::from_points(&self.vertices).expect("a validated mesh has vertices")
    }

    /// Enclosed volume by the divergence theorem, `V = Σ_t a·(b×c) / 6` over the triangles
    /// (a, b, c) (exact for a closed, outward-oriented surface; units³). Positions are taken
    /// relative to the bounding-box centre to limit cancellation.
    pub fn volume(&self) -> f64 {
        let c = Aabb::from_points(&self.vertices).map_or(Vector3::zeros(), |b| b.center());
        self.triangles
            .iter()
            .map(|&[a, b, d]| {
                let (a, b, d) = (
                    self.vertices[a] - c,
                    self.vertices[b] - c,
                    self.vertices[d] - c,
                );
                a.dot(&b.cross(&d))
            })
            .sum::<f64>()
            / 6.0
    }

    /// Total surface area `Σ_t |(b-a)×(c-a)| / 2` (units²).
    pub fn surface_area(&self) -> f64 {
        (0..self.triangles.len())
            .map(|t| {
                let [a, b, c] = self.triangle_corners(t);
                (b - a).cross(&(c - a)).norm() * 0.5
            })
            .sum()
    }

    /// A copy translated and scaled so its bounding box starts at the origin and its largest
    /// side is 1, with the transform applied (design §4.2).
    pub fn normalized(&self) -> (TriangleMesh, Normalization) {
        let bbox = self.bounding_box();
        let normalization = Normalization {
            origin: bbox.min,
            scale: 1.0 / bbox.largest_side(),
        };
        let mesh = TriangleMesh {
            vertices: self
                .vertices
                .iter()
                .map(|p| normalization.apply(p))
                .collect(),
            triangles: self.triangles.clone(),
        };
        (mesh, normalization)
    }

    /// A copy with every vertex scaled by `factor` about the origin (e.g. to metres).
    pub fn scaled(&self, factor: f64) -> TriangleMesh {
        TriangleMesh {
            vertices: self.vertices.iter().map(|p| p * factor).collect(),
            triangles: self.triangles.clone(),
        }
    }

    /// The closed, outward-oriented surface of the box `[min, max]` (12 triangles).
    pub fn cuboid(min: Vector3<f64>, max: Vector3<f64>) -> TriangleMesh {
        let corner = |i: usize| {
            Vector3::new(
                if i & 1 == 0 { min.x } else { max.x },
                if i & 2 == 0 { min.y } else { max.y },
                if i & 4 == 0 { min.z } else { max.z },
            )
        };
        let vertices = (0..8).map(corner).collect();
        let triangles = vec![
            [0, 2, 1],
            [1, 2, 3], // z = min
            [4, 5, 6],
            [5, 7, 6], // z = max
            [0, 1, 4],
            [1, 5, 4], // y = min
            [2, 6, 3],
            [3, 6, 7], // y = max
            [0, 4, 2],
            [2, 4, 6], // x = min
            [1, 3, 5],
            [3, 7, 5], // x = max
        ];
        TriangleMesh {
            vertices,
            triangles,
        }
    }
}

/// Merges vertices with bit-identical coordinates and reindexes the triangles (the weld every
/// STL file needs, applied to every format so that split OBJ groups join up).
pub fn weld_exact_duplicates(
    vertices: &[Vector3<f64>],
    triangles: &[[usize; 3]],
) -> (Vec<Vector3<f64>>, Vec<[usize; 3]>) {
    let mut index_of: HashMap<[u64; 3], usize> = HashMap::with_capacity(vertices.len());
    let mut welded = Vec::with_capacity(vertices.len());
    let remap: Vec<usize> = vertices
        .iter()
        .map(|p| {
            // +0.0 and -0.0 are the same point.
            let key = [p.x, p.y, p.z].map(|c| if c == 0.0 { 0u64 } else { c.to_bits() });
            *index_of.entry(key).or_insert_with(|| {
                welded.push(*p);
                welded.len() - 1
            })
        })
        .collect();
    let triangles = triangles
        .iter()
        .map(|t| t.map(|i| remap.get(i).copied().unwrap_or(usize::MAX)))
        .collect();
    (welded, triangles)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_box() -> TriangleMesh {
        TriangleMesh::cuboid(Vector3::zeros(), Vector3::new(2.0, 3.0, 4.0))
    }

    #[test]
    fn cuboid_is_valid_with_exact_volume_and_area() {
        let b = unit_box();
        b.validate().unwrap();
        assert!((b.volume() - 24.0).abs() < 1e-12);
        assert!((b.surface_area() - 2.0 * (6.0 + 8.0 + 12.0)).abs() < 1e-12);
    }

    #[test]
    fn removing_a_triangle_is_reported_as_open() {
        let b = unit_box();
        let mut tris = b.triangles().to_vec();
        tris.pop();
        let err = TriangleMesh::new(b.vertices().to_vec(), tris).unwrap_err();
        assert!(
            matches!(
                err,
                MeshValidationError::OpenOrInconsistent { count: 3, .. }
            ),
            "{err}"
        );
    }

    #[test]
    fn flipping_one_triangle_is_reported() {
        let b = unit_box();
        let mut tris = b.triangles().to_vec();
        tris[0].swap(0, 1);
        assert!(TriangleMesh::new(b.vertices().to_vec(), tris).is_err());
    }

    #[test]
    fn inside_out_mesh_has_non_positive_volume_error() {
        let b = unit_box();
        let tris = b.triangles().iter().map(|&[a, b, c]| [a, c, b]).collect();
        let err = TriangleMesh::new(b.vertices().to_vec(), tris).unwrap_err();
        assert!(matches!(err, MeshValidationError::NonPositiveVolume { .. }));
    }

    #[test]
    fn nan_vertex_is_reported_with_its_index() {
        let b = unit_box();
        let mut v = b.vertices().to_vec();
        v[5].y = f64::NAN;
        let err = TriangleMesh::new(v, b.triangles().to_vec()).unwrap_err();
        assert!(matches!(
            err,
            MeshValidationError::NonFiniteVertex { vertex: 5, .. }
        ));
    }

    #[test]
    fn empty_mesh_is_reported() {
        let err = TriangleMesh::new(vec![], vec![]).unwrap_err();
        assert!(matches!(err, MeshValidationError::Empty { .. }));
    }

    #[test]
    fn normalization_gives_unit_largest_side_and_inverts() {
        let (n, t) = unit_box().normalized();
        let bb = n.bounding_box();
        assert!((bb.largest_side() - 1.0).abs() < 1e-15);
        assert!(bb.min.norm() < 1e-15);
        let p = Vector3::new(1.0, 2.0, 3.0);
        assert!((t.invert(&t.apply(&p)) - p).norm() < 1e-14);
        assert!((n.volume() - 24.0 / 64.0).abs() < 1e-12);
    }

    #[test]
    fn weld_merges_identical_points_only() {
        let v = vec![
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(1.0, 0.0, 0.0),
            Vector3::new(-0.0, 0.0, 0.0),
            Vector3::new(1.0, 0.0, 1e-300),
        ];
        let (w, t) = weld_exact_duplicates(&v, &[[0, 1, 2], [2, 3, 1]]);
        assert_eq!(w.len(), 3);
        assert_eq!(t, vec![[0, 1, 0], [0, 2, 1]]);
    }
}
