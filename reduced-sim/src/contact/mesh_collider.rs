//! A closed triangle mesh as a collider shape: a container, a ramp, pegs of any form.
//!
//! φ(p) = ±|p − c(p)|, c the closest surface point, negative
//! inside; ∇φ = ±(p − c)/|p − c|. The sign is that of `(p − c)·N`, N the angle-weighted
//! pseudonormal of the closest feature (the face's normal, the sum of an edge's two face
//! normals, the angle-weighted sum of a vertex's face normals): exact for a closed mesh
//! (Bærentzen and Aanæs 2005), convex and concave features alike, and far cheaper than a
//! ray cast per point. The closest point lies on a face,
//! an edge or a vertex; the unsigned distance's Hessian there is 0, `(I − t tᵀ − n nᵀ)/d`
//! (t the edge direction, n = ∇φ up to sign) or `(I − n nᵀ)/d`, and ∇²φ carries φ's sign.
//!
//! Only points within [`MeshShape::band`] of the surface are looked up: farther points are
//! reported outside at distance `band` (so a point that got deeper than `band` into the solid
//! is lost; choose it above the deepest penetration and below half the thinnest wall). A grid
//! of cells about `band` wide over the mesh's box lists the triangles within `band` of each
//! cell, so a point far from the surface costs one lookup and a point near it a few triangles.

use std::collections::HashMap;
use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use nalgebra::{Matrix3, Vector3};
use rkpm_core::surface_distance::closest_point_on_triangle;
use rkpm_core::{GeometryReadError, TriangleMesh, read_triangle_mesh};
use serde::{Deserialize, Serialize};

use crate::contact::signed_distance::SignedDistance;

/// The queries of one loaded mesh.
struct MeshSurface {
    mesh: TriangleMesh,
    near: TriangleGrid,
    normals: Pseudonormals,
}

/// Outward angle-weighted pseudonormals of a closed mesh (unnormalized: only their direction
/// is used).
struct Pseudonormals {
    /// Per triangle, its unit normal.
    faces: Vec<Vector3<f64>>,
    /// Per triangle, its edges' normals, the edge opposite corner k at k: the sum of the unit
    /// normals of the two triangles sharing the edge.
    edges: Vec<[Vector3<f64>; 3]>,
    /// Per vertex, Σ over its triangles of the corner angle times the unit normal.
    vertices: Vec<Vector3<f64>>,
}

impl Pseudonormals {
    /// The pseudonormals of `mesh`, pointing out of the solid (a validated mesh winds its
    /// triangles outward: it encloses a positive volume).
    fn new(mesh: &TriangleMesh) -> Self {
        let triangles = mesh.triangles();
        let faces: Vec<Vector3<f64>> = (0..triangles.len())
            .map(|t| {
                let [a, b, c] = mesh.triangle_corners(t);
                (b - a)
                    .cross(&(c - a))
                    .try_normalize(0.0)
                    .unwrap_or_default()
            })
            .collect();
        let mut shared: HashMap<(usize, usize), Vector3<f64>> = HashMap::new();
        let mut vertices = vec![Vector3::zeros(); mesh.vertices().len()];
        for (t, tri) in triangles.iter().enumerate() {
            let corners = mesh.triangle_corners(t);
            for k in 0..3 {
                let (i, j) = (tri[(k + 1) % 3], tri[(k + 2) % 3]);
                *shared.entry((i.min(j), i.max(j))).or_default() += faces[t];
                let (u, v) = (
                    corners[(k + 1) % 3] - corners[k],
                    corners[(k + 2) % 3] - corners[k],
                );
                vertices[tri[k]] += faces[t] * u.angle(&v);
            }
        }
        let edges = triangles
            .iter()
            .map(|tri| {
                [0, 1, 2].map(|k| {
                    let (i, j) = (tri[(k + 1) % 3], tri[(k + 2) % 3]);
                    shared[&(i.min(j), i.max(j))]
                })
            })
            .collect();
        Pseudonormals {
            faces,
            edges,
            vertices,
        }
    }
}

/// Cells over a mesh's bounding box grown by a band, each listing the triangles whose boxes,
/// grown by the band, overlap it: every triangle within the band of a point in the cell.
struct TriangleGrid {
    origin: Vector3<f64>,
    cell: f64,
    dims: [usize; 3],
    /// CSR: the triangles of cell c are `triangles[offsets[c]..offsets[c + 1]]`.
    offsets: Vec<usize>,
    triangles: Vec<u32>,
}

/// Most cells along one axis of a [`TriangleGrid`].
const MAX_CELLS_PER_AXIS: usize = 64;

impl TriangleGrid {
    fn new(mesh: &TriangleMesh, band: f64) -> Self {
        let bounds = mesh.bounding_box();
        let origin = bounds.min - Vector3::repeat(band);
        let extent = bounds.extent() + Vector3::repeat(2.0 * band);
        let cell = band.max(extent.max() / MAX_CELLS_PER_AXIS as f64);
        let dims = [0, 1, 2].map(|k| ((extent[k] / cell).ceil() as usize).max(1));
        let cell_of = |x: f64, k: usize| {
            (((x - origin[k]) / cell).floor().max(0.0) as usize).min(dims[k] - 1)
        };
        let mut lists: Vec<Vec<u32>> = vec![Vec::new(); dims[0] * dims[1] * dims[2]];
        for t in 0..mesh.triangles().len() {
            let corners = mesh.triangle_corners(t);
            let lo = corners[0].inf(&corners[1]).inf(&corners[2]) - Vector3::repeat(band);
            let hi = corners[0].sup(&corners[1]).sup(&corners[2]) + Vector3::repeat(band);
            for i in cell_of(lo.x, 0)..=cell_of(hi.x, 0) {
                for j in cell_of(lo.y, 1)..=cell_of(hi.y, 1) {
                    for k in cell_of(lo.z, 2)..=cell_of(hi.z, 2) {
                        lists[(i * dims[1] + j) * dims[2] + k].push(t as u32);
                    }
                }
            }
        }
        let mut offsets = Vec::with_capacity(lists.len() + 1);
        offsets.push(0);
        for list in &lists {
            offsets.push(offsets.last().unwrap() + list.len());
        }
        TriangleGrid {
            origin,
            cell,
            dims,
            offsets,
            triangles: lists.concat(),
        }
    }

    /// The triangles that may lie within the band of `p` (none outside the grid).
    fn near(&self, p: &Vector3<f64>) -> &[u32] {
        let mut index = 0;
        for k in 0..3 {
            let c = ((p[k] - self.origin[k]) / self.cell).floor();
            if !(c >= 0.0 && c < self.dims[k] as f64) {
                return &[];
            }
            index = index * self.dims[k] + c as usize;
        }
        &self.triangles[self.offsets[index]..self.offsets[index + 1]]
    }
}

/// A closed, consistently oriented triangle mesh in the collider's frame (m).
///
/// In scene files `{ mesh = { path = "container.obj", band = 0.05 } }`; the file is read by
/// [`MeshShape::load`] (relative paths against the scene file's folder), or the shape is made
/// from a mesh in memory with [`MeshShape::from_mesh`].
#[derive(Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshShape {
    /// The mesh file (OBJ, STL or PLY; coordinates used as they are, in m). Empty for a mesh
    /// given in memory.
    #[serde(default)]
    pub path: PathBuf,
    /// How far from the surface (m) points are looked up (default 0.05); read when the mesh
    /// is loaded.
    #[serde(default = "default_band")]
    pub band: f64,
    #[serde(skip)]
    surface: Option<Arc<MeshSurface>>,
}

fn default_band() -> f64 {
    0.05
}

impl MeshShape {
    /// The shape of `mesh` (already validated as a closed surface), looked up within `band` (m).
    pub fn from_mesh(mesh: TriangleMesh, band: f64) -> Self {
        MeshShape {
            path: PathBuf::new(),
            band,
            surface: Some(Arc::new(MeshSurface {
                near: TriangleGrid::new(&mesh, band.abs().max(f64::MIN_POSITIVE)),
                normals: Pseudonormals::new(&mesh),
                mesh,
            })),
        }
    }

    /// Reads [`MeshShape::path`] (relative to `folder` unless absolute) and builds its queries.
    ///
    /// # Errors
    /// [`GeometryReadError`]: unreadable, malformed, or not a closed surface.
    pub fn load(&mut self, folder: &Path) -> Result<(), GeometryReadError> {
        let path = folder.join(&self.path);
        let loaded = MeshShape::from_mesh(read_triangle_mesh(&path)?, self.band);
        self.surface = loaded.surface;
        Ok(())
    }

    /// The mesh, once loaded.
    pub fn mesh(&self) -> Option<&TriangleMesh> {
        self.surface.as_ref().map(|s| &s.mesh)
    }

    /// What is wrong with the shape, if anything: not loaded, or a band that is not finite and
    /// positive.
    pub(crate) fn defect(&self) -> Option<String> {
        if self.surface.is_none() {
            return Some(format!("mesh {} is not loaded", self.path.display()));
        }
        if !(self.band.is_finite() && self.band > 0.0) {
            return Some(format!("band {}", self.band));
        }
        None
    }

    /// φ, ∇φ and ∇²φ at `p` (m, shape frame); `band` with zero derivatives beyond the band or
    /// before the mesh is loaded.
    pub(crate) fn signed_distance(&self, p: &Vector3<f64>) -> SignedDistance {
        let far = SignedDistance {
            distance: self.band,
            gradient: Vector3::zeros(),
            hessian: Matrix3::zeros(),
        };
        let Some(surface) = &self.surface else {
            return far;
        };
        let mut closest: Option<(Vector3<f64>, f64, usize)> = None;
        for &t in surface.near.near(p) {
            let [a, b, c] = surface.mesh.triangle_corners(t as usize);
            let q = closest_point_on_triangle(p, &a, &b, &c);
            let d = (q - p).norm();
            if d <= self.band && closest.is_none_or(|(_, best, _)| d < best) {
                closest = Some((q, d, t as usize));
            }
        }
        let Some((point, d, triangle)) = closest else {
            return far;
        };
        if d == 0.0 {
            // On the surface: φ = 0, no direction; the penalty's force is zero there anyway.
            return SignedDistance {
                distance: 0.0,
                ..far
            };
        }
        let away = (p - point) / d;
        let [a, b, c] = surface.mesh.triangle_corners(triangle);
        let normals = &surface.normals;
        let (normal, curvature) = match feature(&point, &a, &b, &c) {
            Feature::Face => (normals.faces[triangle], Matrix3::zeros()),
            Feature::Edge {
                opposite,
                direction: t,
            } => (
                normals.edges[triangle][opposite],
                (Matrix3::identity() - t * t.transpose() - away * away.transpose()) / d,
            ),
            Feature::Vertex(k) => (
                normals.vertices[surface.mesh.triangles()[triangle][k]],
                (Matrix3::identity() - away * away.transpose()) / d,
            ),
        };
        let sign = if away.dot(&normal) < 0.0 { -1.0 } else { 1.0 };
        SignedDistance {
            distance: sign * d,
            gradient: away * sign,
            hessian: curvature * sign,
        }
    }
}

/// Where on a triangle its closest point lies.
enum Feature {
    Face,
    /// On the edge opposite corner `opposite` (0, 1, 2 for a, b, c), with its unit direction.
    Edge {
        opposite: usize,
        direction: Vector3<f64>,
    },
    /// At corner k (0, 1, 2 for a, b, c).
    Vertex(usize),
}

/// The feature of triangle abc that `q` (a point of it) lies on, by its barycentric
/// coordinates (a coordinate below 1e-9 counts as zero).
fn feature(q: &Vector3<f64>, a: &Vector3<f64>, b: &Vector3<f64>, c: &Vector3<f64>) -> Feature {
    let n = (b - a).cross(&(c - a));
    let area = n.norm_squared();
    let weight = |u: &Vector3<f64>, v: &Vector3<f64>| (u - q).cross(&(v - q)).dot(&n) / area;
    let (wa, wb, wc) = (weight(b, c), weight(c, a), weight(a, b));
    let zero = |w: f64| w.abs() < 1e-9;
    let edge = |opposite: usize, from: &Vector3<f64>, to: &Vector3<f64>| Feature::Edge {
        opposite,
        direction: (to - from).normalize(),
    };
    match (zero(wa), zero(wb), zero(wc)) {
        (false, false, false) => Feature::Face,
        (true, false, false) => edge(0, b, c),
        (false, true, false) => edge(1, c, a),
        (false, false, true) => edge(2, a, b),
        // Two coordinates zero: at the third corner.
        (false, true, true) => Feature::Vertex(0),
        (true, false, true) => Feature::Vertex(1),
        _ => Feature::Vertex(2),
    }
}

impl PartialEq for MeshShape {
    /// The same file and band, and the same mesh in memory (or both not loaded).
    fn eq(&self, other: &Self) -> bool {
        let same_surface = match (&self.surface, &other.surface) {
            (Some(a), Some(b)) => Arc::ptr_eq(a, b) || a.mesh == b.mesh,
            (None, None) => true,
            _ => false,
        };
        self.path == other.path && self.band == other.band && same_surface
    }
}

impl fmt::Debug for MeshShape {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("MeshShape")
            .field("path", &self.path)
            .field("band", &self.band)
            .field(
                "triangles",
                &self.surface.as_ref().map(|s| s.mesh.triangles().len()),
            )
            .finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A closed box mesh, 1 × 0.6 × 0.8 m about the origin.
    fn cube() -> MeshShape {
        MeshShape::from_mesh(
            TriangleMesh::cuboid(Vector3::new(-0.5, -0.3, -0.4), Vector3::new(0.5, 0.3, 0.4)),
            0.2,
        )
    }

    #[test]
    fn mesh_signed_distance_matches_the_analytic_box_and_its_derivatives_match_differences() {
        let mesh = cube();
        let analytic = crate::contact::collider::ColliderShape::Box {
            half_extents: Vector3::new(0.5, 0.3, 0.4),
        };
        // Inside near a face, outside near a face, an edge and a corner.
        let points = [
            Vector3::new(0.1, 0.25, -0.02),
            Vector3::new(0.62, 0.1, 0.05),
            Vector3::new(0.6, 0.38, 0.1),
            Vector3::new(-0.58, 0.35, 0.47),
        ];
        let h = 1e-6;
        for p in points {
            let d = mesh.signed_distance(&p);
            let exact = analytic.signed_distance(&p);
            assert!(
                (d.distance - exact.distance).abs() < 1e-12,
                "{p:?}: φ {} vs box {}",
                d.distance,
                exact.distance
            );
            assert!((d.gradient - exact.gradient).norm() < 1e-9, "{p:?}: ∇φ");
            for k in 0..3 {
                let e = Vector3::ith(k, h);
                let (plus, minus) = (
                    mesh.signed_distance(&(p + e)),
                    mesh.signed_distance(&(p - e)),
                );
                let slope = (plus.distance - minus.distance) / (2.0 * h);
                assert!((slope - d.gradient[k]).abs() < 1e-6, "{p:?}: ∂φ/∂x{k}");
                let column = (plus.gradient - minus.gradient) / (2.0 * h);
                assert!(
                    (column - d.hessian.column(k)).norm() < 1e-5,
                    "{p:?}: ∇²φ column {k} {column:?} vs {:?}",
                    d.hessian.column(k)
                );
            }
        }
        // Beyond the band: reported outside at the band, no force.
        let far = mesh.signed_distance(&Vector3::new(2.0, 0.0, 0.0));
        assert_eq!(far.distance, 0.2);
        assert_eq!(far.gradient, Vector3::zeros());
    }

    /// An L-shaped prism (2 × 2 × 1 m with the 1 × 1 quarter x, y > 1 cut away): a concave
    /// edge along z at x = y = 1 and concave corners at its ends.
    fn l_prism() -> TriangleMesh {
        let outline = [
            (0.0, 0.0),
            (2.0, 0.0),
            (2.0, 1.0),
            (1.0, 1.0),
            (1.0, 2.0),
            (0.0, 2.0),
        ];
        let mut vertices = Vec::new();
        for z in [0.0, 1.0] {
            vertices.extend(outline.iter().map(|&(x, y)| Vector3::new(x, y, z)));
        }
        let mut triangles = Vec::new();
        // Caps: fans from the corner at the origin, which sees the whole outline.
        for i in 1..5 {
            triangles.push([0, i + 1, i]);
            triangles.push([6, 6 + i, 6 + i + 1]);
        }
        for i in 0..6 {
            let j = (i + 1) % 6;
            triangles.push([i, j, 6 + j]);
            triangles.push([i, 6 + j, 6 + i]);
        }
        TriangleMesh::new(vertices, triangles).expect("a closed L prism")
    }

    #[test]
    fn mesh_signed_distance_sign_matches_the_ray_cast_inside_test_near_concave_features() {
        use rand::{Rng, SeedableRng};
        let meshes = [
            l_prism(),
            rkpm_core::read_triangle_mesh(test_support::fixtures::shared_mesh("bunny.obj"))
                .expect("the bunny reads"),
        ];
        for mesh in meshes {
            let size = mesh.bounding_box().largest_side();
            let band = 0.1 * size;
            let inside = rkpm_core::InsideTest::new(&mesh);
            let shape = MeshShape::from_mesh(mesh.clone(), band);
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
            let (mut checked, mut negative) = (0, 0);
            for _ in 0..4000 {
                // Points near random vertices: near edges, corners and concave creases.
                let v = mesh.vertices()[rng.random_range(0..mesh.vertices().len())];
                let offset = Vector3::from_fn(|_, _| rng.random_range(-1.0..1.0)) * band * 0.5;
                let p = v + offset;
                let d = shape.signed_distance(&p);
                if d.distance.abs() < 1e-9 * size || d.distance >= band {
                    continue;
                }
                checked += 1;
                negative += usize::from(d.distance < 0.0);
                assert_eq!(
                    d.distance < 0.0,
                    inside.contains(&p),
                    "{p:?}: φ = {} disagrees with the inside test",
                    d.distance
                );
            }
            assert!(
                checked > 2000 && negative > 500,
                "{checked} checked, {negative} inside"
            );
        }
    }

    #[test]
    fn an_unloaded_mesh_shape_names_its_file() {
        let shape: MeshShape = toml_like();
        let why = shape.defect().unwrap();
        assert!(why.contains("bowl.obj"), "{why}");
        let mut shape = shape;
        let err = shape.load(Path::new("/nonexistent")).unwrap_err();
        assert!(err.to_string().contains("bowl.obj"), "{err}");
    }

    fn toml_like() -> MeshShape {
        MeshShape {
            path: PathBuf::from("bowl.obj"),
            band: 0.05,
            surface: None,
        }
    }
}
