//! Linear tetrahedral meshes: validation, volume, quality, and structured meshes of boxes
//! (design §3.8).

use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// The six edges of a tetrahedron as pairs of its corners, in VTK quadratic-tetra order (the
/// order of a P2 element's edge nodes).
pub const TET_EDGES: [[usize; 2]; 6] = [[0, 1], [1, 2], [0, 2], [0, 3], [1, 3], [2, 3]];

/// A tetrahedral mesh is unusable.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum TetMeshError {
    /// No vertices or no tetrahedra.
    #[error("the tetrahedral mesh is empty ({vertices} vertices, {tets} tetrahedra)")]
    Empty {
        /// Vertex count.
        vertices: usize,
        /// Tetrahedron count.
        tets: usize,
    },
    /// A vertex has a NaN or infinite coordinate.
    #[error("vertex {vertex} is not finite: {position:?}")]
    NonFiniteVertex {
        /// Index.
        vertex: usize,
        /// Coordinates.
        position: [f64; 3],
    },
    /// A tetrahedron names a vertex that does not exist.
    #[error("tetrahedron {tet} names vertex {vertex}, but there are {vertices} vertices")]
    IndexOutOfRange {
        /// Tetrahedron.
        tet: usize,
        /// The bad index.
        vertex: usize,
        /// Vertex count.
        vertices: usize,
    },
    /// A tetrahedron is inverted or flat (signed volume ≤ 0).
    #[error("tetrahedron {tet} has signed volume {volume:e} m³ (inverted or flat)")]
    NonPositiveVolume {
        /// Tetrahedron.
        tet: usize,
        /// Its signed volume.
        volume: f64,
    },
    /// A box mesh was asked for with a zero resolution or an empty box.
    #[error("invalid box mesh: {0}")]
    InvalidBox(String),
}

/// A linear tetrahedral mesh: vertices (m) and positively oriented tetrahedra
/// (`det[x1-x0, x2-x0, x3-x0] > 0`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TetMesh {
    vertices: Vec<Vector3<f64>>,
    tets: Vec<[usize; 4]>,
}

/// Shape statistics of a mesh.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TetQuality {
    /// Smallest dihedral angle over all tetrahedra (degrees; 70.5° for a regular one).
    pub min_dihedral_degrees: f64,
    /// Largest dihedral angle (degrees).
    pub max_dihedral_degrees: f64,
    /// Smallest and largest tetrahedron volume (m³).
    pub volume_range: [f64; 2],
}

impl TetMesh {
    /// A validated mesh.
    ///
    /// # Errors
    /// [`TetMeshError`]: empty, non-finite vertices, indices out of range, non-positive volumes.
    pub fn new(vertices: Vec<Vector3<f64>>, tets: Vec<[usize; 4]>) -> Result<Self, TetMeshError> {
        if vertices.is_empty() || tets.is_empty() {
            return Err(TetMeshError::Empty {
                vertices: vertices.len(),
                tets: tets.len(),
            });
        }
        if let Some(vertex) = vertices
            .iter()
            .position(|v| !v.iter().all(|c| c.is_finite()))
        {
            return Err(TetMeshError::NonFiniteVertex {
                vertex,
                position: vertices[vertex].into(),
            });
        }
        for (tet, t) in tets.iter().enumerate() {
            if let Some(&vertex) = t.iter().find(|&&v| v >= vertices.len()) {
                return Err(TetMeshError::IndexOutOfRange {
                    tet,
                    vertex,
                    vertices: vertices.len(),
                });
            }
        }
        let mesh = TetMesh { vertices, tets };
        for tet in 0..mesh.tets.len() {
            let volume = mesh.tet_volume(tet);
            if !(volume > 0.0) {
                return Err(TetMeshError::NonPositiveVolume { tet, volume });
            }
        }
        Ok(mesh)
    }

    /// Vertices (m).
    pub fn vertices(&self) -> &[Vector3<f64>] {
        &self.vertices
    }

    /// Tetrahedra (vertex indices).
    pub fn tets(&self) -> &[[usize; 4]] {
        &self.tets
    }

    /// The mesh's edges, each once as `[a, b]` with vertex indices `a < b`, sorted: `E` pairs
    /// (a P2 mesh has `V + E` nodes).
    pub fn edges(&self) -> Vec<[usize; 2]> {
        let mut edges: Vec<[usize; 2]> = self
            .tets
            .iter()
            .flat_map(|t| TET_EDGES.map(|[i, j]| [t[i].min(t[j]), t[i].max(t[j])]))
            .collect();
        edges.sort_unstable();
        edges.dedup();
        edges
    }

    /// `[x1 - x0, x2 - x0, x3 - x0]` of tetrahedron `tet`.
    pub fn edge_matrix(&self, tet: usize) -> Matrix3<f64> {
        let [a, b, c, d] = self.tets[tet].map(|v| self.vertices[v]);
        Matrix3::from_columns(&[b - a, c - a, d - a])
    }

    /// Signed volume of tetrahedron `tet` (m³).
    pub fn tet_volume(&self, tet: usize) -> f64 {
        signed_volume(&self.tets[tet].map(|v| self.vertices[v]))
    }

    /// Total volume (m³).
    pub fn volume(&self) -> f64 {
        (0..self.tets.len()).map(|t| self.tet_volume(t)).sum()
    }

    /// The face-connected pieces of the mesh (tetrahedra sharing a triangle are in one piece),
    /// as lists of tetrahedron indices, largest volume first.
    pub fn face_connected_components(&self) -> Vec<Vec<usize>> {
        let mut parent: Vec<usize> = (0..self.tets.len()).collect();
        fn root(parent: &mut [usize], mut i: usize) -> usize {
            while parent[i] != i {
                parent[i] = parent[parent[i]];
                i = parent[i];
            }
            i
        }
        let mut faces: std::collections::HashMap<[usize; 3], usize> =
            std::collections::HashMap::with_capacity(2 * self.tets.len());
        for (t, tet) in self.tets.iter().enumerate() {
            for face in sorted_faces(tet) {
                if let Some(&other) = faces.get(&face) {
                    let (a, b) = (root(&mut parent, t), root(&mut parent, other));
                    parent[a.max(b)] = a.min(b);
                } else {
                    faces.insert(face, t);
                }
            }
        }
        let mut pieces: std::collections::BTreeMap<usize, Vec<usize>> = Default::default();
        for t in 0..self.tets.len() {
            let r = root(&mut parent, t);
            pieces.entry(r).or_default().push(t);
        }
        let mut pieces: Vec<(f64, Vec<usize>)> = pieces
            .into_values()
            .map(|tets| (tets.iter().map(|&t| self.tet_volume(t)).sum(), tets))
            .collect();
        pieces.sort_by(|a, b| b.0.total_cmp(&a.0));
        pieces.into_iter().map(|(_, tets)| tets).collect()
    }

    /// The mesh of the face-connected piece of largest volume, its vertices renumbered in their
    /// original order, and the volume of everything dropped (m³). A lattice mesh of a surface
    /// with parts thinner than its cells can hold islands the cutting separated from the body;
    /// in a simulation they fall freely.
    pub fn largest_component(&self) -> (TetMesh, f64) {
        let pieces = self.face_connected_components();
        let dropped: f64 = pieces[1..]
            .iter()
            .flatten()
            .map(|&t| self.tet_volume(t))
            .sum();
        let mut keep = vec![false; self.tets.len()];
        for &t in &pieces[0] {
            keep[t] = true;
        }
        let mut used = vec![false; self.vertices.len()];
        for (tet, _) in self.tets.iter().zip(&keep).filter(|(_, k)| **k) {
            for &v in tet {
                used[v] = true;
            }
        }
        let mut new_index = vec![usize::MAX; self.vertices.len()];
        let mut vertices = Vec::new();
        for (v, _) in used.iter().enumerate().filter(|(_, u)| **u) {
            new_index[v] = vertices.len();
            vertices.push(self.vertices[v]);
        }
        let tets = self
            .tets
            .iter()
            .zip(&keep)
            .filter(|(_, k)| **k)
            .map(|(tet, _)| tet.map(|v| new_index[v]))
            .collect();
        (TetMesh { vertices, tets }, dropped)
    }

    /// Dihedral angles and volumes.
    pub fn quality(&self) -> TetQuality {
        let mut q = TetQuality {
            min_dihedral_degrees: 180.0,
            max_dihedral_degrees: 0.0,
            volume_range: [f64::INFINITY, 0.0],
        };
        for (t, tet) in self.tets.iter().enumerate() {
            let [lo, hi] = dihedral_angle_range(&tet.map(|v| self.vertices[v]));
            q.min_dihedral_degrees = q.min_dihedral_degrees.min(lo);
            q.max_dihedral_degrees = q.max_dihedral_degrees.max(hi);
            let v = self.tet_volume(t);
            q.volume_range[0] = q.volume_range[0].min(v);
            q.volume_range[1] = q.volume_range[1].max(v);
        }
        q
    }

    /// A structured mesh of the box `[min, max]` with `cells[d]` cubes per axis, each split into
    /// six tetrahedra around its diagonal from corner (0,0,0) to (1,1,1) (the Kuhn/Freudenthal
    /// split: one tetrahedron per permutation of the axes). All cubes use the same split, so
    /// faces match across cubes and the mesh is conforming.
    ///
    /// # Errors
    /// [`TetMeshError::InvalidBox`] for a zero resolution or a box with a non-positive side.
    pub fn cuboid(
        min: Vector3<f64>,
        max: Vector3<f64>,
        cells: [usize; 3],
    ) -> Result<Self, TetMeshError> {
        if cells.contains(&0) {
            return Err(TetMeshError::InvalidBox(format!(
                "{cells:?} cells: every axis needs at least one"
            )));
        }
        let extent = max - min;
        if !(extent.min() > 0.0) || !extent.iter().all(|e| e.is_finite()) {
            return Err(TetMeshError::InvalidBox(format!(
                "box from {min:?} to {max:?} has a non-positive or infinite side"
            )));
        }
        let [nx, ny, nz] = cells;
        let index = |i: usize, j: usize, k: usize| (i * (ny + 1) + j) * (nz + 1) + k;
        let mut vertices = Vec::with_capacity((nx + 1) * (ny + 1) * (nz + 1));
        for i in 0..=nx {
            for j in 0..=ny {
                for k in 0..=nz {
                    vertices.push(
                        min + Vector3::new(
                            extent.x * i as f64 / nx as f64,
                            extent.y * j as f64 / ny as f64,
                            extent.z * k as f64 / nz as f64,
                        ),
                    );
                }
            }
        }
        let mut tets = Vec::with_capacity(6 * nx * ny * nz);
        for i in 0..nx {
            for j in 0..ny {
                for k in 0..nz {
                    for corners in KUHN_CUBE_TETS {
                        let mut tet = corners.map(|[a, b, c]| index(i + a, j + b, k + c));
                        let [p0, p1, p2, p3] = tet.map(|v| vertices[v]);
                        if signed_volume(&[p0, p1, p2, p3]) < 0.0 {
                            tet.swap(2, 3);
                        }
                        tets.push(tet);
                    }
                }
            }
        }
        TetMesh::new(vertices, tets)
    }
}

/// The six tetrahedra of the Kuhn (Freudenthal) split of the unit cube, as corner offsets: each
/// walks from corner (0,0,0) to (1,1,1) adding one axis at a time, one tetrahedron per
/// permutation of the axes. Odd permutations come out negatively oriented.
pub(crate) const KUHN_CUBE_TETS: [[[usize; 3]; 4]; 6] = {
    const PERMUTATIONS: [[usize; 3]; 6] = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    let mut tets = [[[0; 3]; 4]; 6];
    let mut t = 0;
    while t < 6 {
        let mut n = 0;
        while n < 3 {
            tets[t][n + 1] = tets[t][n];
            tets[t][n + 1][PERMUTATIONS[t][n]] = 1;
            n += 1;
        }
        t += 1;
    }
    tets
};

/// The four triangles of a tetrahedron, each with its vertex indices sorted (a key shared by
/// the two tetrahedra on either side of an interior face).
pub fn sorted_faces(tet: &[usize; 4]) -> [[usize; 3]; 4] {
    std::array::from_fn(|skip| {
        let mut face = [0; 3];
        let mut k = 0;
        for (j, &v) in tet.iter().enumerate() {
            if j != skip {
                face[k] = v;
                k += 1;
            }
        }
        face.sort_unstable();
        face
    })
}

/// Signed volume `det[x1-x0, x2-x0, x3-x0] / 6` of a tetrahedron (m³).
pub fn signed_volume([a, b, c, d]: &[Vector3<f64>; 4]) -> f64 {
    Matrix3::from_columns(&[b - a, c - a, d - a]).determinant() / 6.0
}

/// Smallest and largest of a tetrahedron's six dihedral angles (degrees; 70.53° each for a
/// regular one, 0° or 180° for a flat one).
pub fn dihedral_angle_range(p: &[Vector3<f64>; 4]) -> [f64; 2] {
    // Outward face normals; the dihedral angle at the edge shared by faces i and j is π minus
    // the angle between their outward normals. Face i is the one opposite vertex i.
    let normals: [Vector3<f64>; 4] = std::array::from_fn(|i| {
        let [a, b, c] = [(i + 1) % 4, (i + 2) % 4, (i + 3) % 4].map(|k| p[k]);
        let n = (b - a).cross(&(c - a)).normalize();
        if n.dot(&(p[i] - a)) > 0.0 { -n } else { n }
    });
    let mut range = [180.0_f64, 0.0_f64];
    for i in 0..4 {
        for j in i + 1..4 {
            let angle = 180.0
                - normals[i]
                    .dot(&normals[j])
                    .clamp(-1.0, 1.0)
                    .acos()
                    .to_degrees();
            range[0] = range[0].min(angle);
            range[1] = range[1].max(angle);
        }
    }
    range
}

#[cfg(test)]
mod tests {

    #[test]
    fn largest_component_drops_a_separate_island_and_renumbers_vertices() {
        let body =
            TetMesh::cuboid(Vector3::zeros(), Vector3::new(2.0, 1.0, 1.0), [2, 1, 1]).unwrap();
        let island = TetMesh::cuboid(
            Vector3::new(5.0, 0.0, 0.0),
            Vector3::new(5.5, 0.5, 0.5),
            [1, 1, 1],
        )
        .unwrap();
        // The island first, so renumbering is exercised.
        let offset = island.vertices().len();
        let vertices: Vec<_> = island
            .vertices()
            .iter()
            .chain(body.vertices())
            .copied()
            .collect();
        let tets: Vec<_> = island
            .tets()
            .iter()
            .copied()
            .chain(body.tets().iter().map(|t| t.map(|v| v + offset)))
            .collect();
        let both = TetMesh::new(vertices, tets).unwrap();
        let pieces = both.face_connected_components();
        assert_eq!(pieces.len(), 2);
        assert_eq!(pieces[0].len(), body.tets().len());
        let (kept, dropped) = both.largest_component();
        assert_eq!(kept.tets().len(), body.tets().len());
        assert_eq!(kept.vertices(), body.vertices());
        assert!((kept.volume() - 2.0).abs() < 1e-12);
        assert!((dropped - 0.125).abs() < 1e-12);
        // A connected mesh is one piece and comes back whole.
        let (same, none) = body.largest_component();
        assert_eq!(same, body);
        assert_eq!(none, 0.0);
    }
    use super::*;

    #[test]
    fn cuboid_mesh_tiles_the_box_exactly_with_six_tets_per_cell() {
        let mesh =
            TetMesh::cuboid(Vector3::zeros(), Vector3::new(5.0, 1.0, 1.0), [10, 2, 2]).unwrap();
        assert_eq!(mesh.tets().len(), 6 * 40);
        assert!((mesh.volume() - 5.0).abs() < 1e-12);
        let q = mesh.quality();
        // Kuhn tets of a cube: dihedral angles 45°, 60° and 90°; of these stretched cells less.
        assert!(
            q.min_dihedral_degrees > 30.0 && q.max_dihedral_degrees < 130.0,
            "{q:?}"
        );
    }

    #[test]
    fn a_cuboid_meshs_edges_satisfy_eulers_formula_for_a_ball() {
        // A tetrahedralized ball: V − E + F − T = 1, with F the distinct triangles.
        let mesh =
            TetMesh::cuboid(Vector3::zeros(), Vector3::new(3.0, 2.0, 1.0), [3, 2, 2]).unwrap();
        let edges = mesh.edges();
        assert!(edges.windows(2).all(|w| w[0] < w[1]) && edges.iter().all(|[a, b]| a < b));
        let mut faces: Vec<[usize; 3]> = mesh.tets().iter().flat_map(sorted_faces).collect();
        faces.sort_unstable();
        faces.dedup();
        let (v, e, f, t) = (
            mesh.vertices().len() as i64,
            edges.len() as i64,
            faces.len() as i64,
            mesh.tets().len() as i64,
        );
        assert_eq!(v - e + f - t, 1, "V {v}, E {e}, F {f}, T {t}");
        // Every tetrahedron's six edges are in the list.
        for tet in mesh.tets() {
            for [i, j] in TET_EDGES {
                let edge = [tet[i].min(tet[j]), tet[i].max(tet[j])];
                assert!(edges.binary_search(&edge).is_ok());
            }
        }
    }

    #[test]
    fn invalid_meshes_are_rejected_with_the_reason() {
        let v = vec![Vector3::zeros(), Vector3::x(), Vector3::y(), Vector3::z()];
        assert!(matches!(
            TetMesh::new(v.clone(), vec![[0, 2, 1, 3]]),
            Err(TetMeshError::NonPositiveVolume { tet: 0, .. })
        ));
        assert!(matches!(
            TetMesh::new(v.clone(), vec![[0, 1, 2, 4]]),
            Err(TetMeshError::IndexOutOfRange { vertex: 4, .. })
        ));
        assert!(matches!(
            TetMesh::new(v, vec![]),
            Err(TetMeshError::Empty { .. })
        ));
        assert!(TetMesh::cuboid(Vector3::zeros(), Vector3::x(), [1, 1, 1]).is_err());
    }
}
