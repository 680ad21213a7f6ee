//! A closed triangle mesh as a collider shape (issue 21): a container, a ramp, pegs of any form.
//!
//! φ(p) = ±|p − c(p)|, c the closest surface point ([`rkpm_core::SurfaceDistance`]), negative
//! inside ([`rkpm_core::InsideTest`]); ∇φ = ±(p − c)/|p − c|. The closest point lies on a face,
//! an edge or a vertex; the unsigned distance's Hessian there is 0, `(I − t tᵀ − n nᵀ)/d`
//! (t the edge direction, n = ∇φ up to sign) or `(I − n nᵀ)/d`, and ∇²φ carries φ's sign.
//!
//! Only points within [`MeshShape::band`] of the surface are looked up: farther points are
//! reported outside at distance `band` (so a point that got deeper than `band` into the solid
//! is lost; choose it above the deepest penetration and below half the thinnest wall).

use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use nalgebra::{Matrix3, Vector3};
use rkpm_core::{GeometryReadError, InsideTest, SurfaceDistance, TriangleMesh, read_triangle_mesh};
use serde::{Deserialize, Serialize};

use crate::collider::SignedDistance;

/// The queries of one loaded mesh.
struct MeshSurface {
    mesh: TriangleMesh,
    distance: SurfaceDistance,
    inside: InsideTest,
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
    /// How far from the surface (m) points are looked up (default 0.05).
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
                distance: SurfaceDistance::new(&mesh),
                inside: InsideTest::new(&mesh),
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
        let Some(closest) = surface.distance.closest_point(p, self.band) else {
            return far;
        };
        let d = closest.distance;
        if d == 0.0 {
            // On the surface: φ = 0, no direction; the penalty's force is zero there anyway.
            return SignedDistance {
                distance: 0.0,
                ..far
            };
        }
        let sign = if surface.inside.contains(p) {
            -1.0
        } else {
            1.0
        };
        let away = (p - closest.point) / d;
        let [a, b, c] = surface.mesh.triangle_corners(closest.triangle);
        let curvature = match feature(&closest.point, &a, &b, &c) {
            Feature::Face => Matrix3::zeros(),
            Feature::Edge(t) => {
                (Matrix3::identity() - t * t.transpose() - away * away.transpose()) / d
            }
            Feature::Vertex => (Matrix3::identity() - away * away.transpose()) / d,
        };
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
    /// On an edge, with the edge's unit direction.
    Edge(Vector3<f64>),
    Vertex,
}

/// The feature of triangle abc that `q` (a point of it) lies on, by its barycentric
/// coordinates (a coordinate below 1e-9 counts as zero).
fn feature(q: &Vector3<f64>, a: &Vector3<f64>, b: &Vector3<f64>, c: &Vector3<f64>) -> Feature {
    let n = (b - a).cross(&(c - a));
    let area = n.norm_squared();
    let weight = |u: &Vector3<f64>, v: &Vector3<f64>| (u - q).cross(&(v - q)).dot(&n) / area;
    let (wa, wb, wc) = (weight(b, c), weight(c, a), weight(a, b));
    let zero = |w: f64| w.abs() < 1e-9;
    match (zero(wa), zero(wb), zero(wc)) {
        (false, false, false) => Feature::Face,
        (true, false, false) => Feature::Edge((c - b).normalize()),
        (false, true, false) => Feature::Edge((a - c).normalize()),
        (false, false, true) => Feature::Edge((b - a).normalize()),
        _ => Feature::Vertex,
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
        let analytic = crate::collider::ColliderShape::Box {
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
