//! The kinematic colliders as files a user opens beside the object's frames:
//! `colliders_NNNNN.ply`, every collider's surface at the frame's time, as one triangle mesh
//! (spheres and capsules tessellated, boxes and meshes as they are), posed by
//! [`reduced_sim::collider_poses`] (chains composed).

use std::f64::consts::PI;
use std::path::{Path, PathBuf};

use artifact::{ArtifactError, write_atomically};
use nalgebra::{Point3, Vector3};
use reduced_sim::{Collider, ColliderShape, collider_poses};

use crate::frames::triangle_mesh_ply;

/// Segments around a sphere's or capsule's axis (and half as many rings per hemisphere).
const SEGMENTS: usize = 24;

/// A triangle surface: vertices (m) and triangles (indices into them, outward).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Surface {
    /// Vertex positions (m).
    pub vertices: Vec<Vector3<f64>>,
    /// Triangles, counter-clockwise seen from outside.
    pub triangles: Vec<[usize; 3]>,
}

/// Writes `colliders_NNNNN.ply` for a scene's colliders; nothing without colliders.
#[derive(Clone, Debug)]
pub struct ColliderFrames {
    dir: PathBuf,
    colliders: Vec<Collider>,
    /// Each collider's surface in its own frame.
    surfaces: Vec<Surface>,
}

impl ColliderFrames {
    /// A writer into `dir` for `colliders`.
    pub fn new(dir: impl Into<PathBuf>, colliders: &[Collider]) -> Self {
        ColliderFrames {
            dir: dir.into(),
            colliders: colliders.to_vec(),
            surfaces: colliders.iter().map(|c| local_surface(&c.shape)).collect(),
        }
    }

    /// Writes frame `index` with the colliders at time `time` (s); `None` without colliders.
    ///
    /// # Errors
    /// [`ArtifactError`] naming the file that could not be written.
    pub fn write(&self, index: usize, time: f64) -> Result<Option<PathBuf>, ArtifactError> {
        if self.colliders.is_empty() {
            return Ok(None);
        }
        let mut vertices = Vec::new();
        let mut triangles = Vec::new();
        for surface in self.surfaces_at(time) {
            let offset = vertices.len();
            vertices.extend(surface.vertices);
            triangles.extend(surface.triangles.iter().map(|t| t.map(|v| v + offset)));
        }
        let path = self.dir.join(format!("colliders_{index:05}.ply"));
        write_atomically(&path, triangle_mesh_ply(&vertices, &triangles).as_bytes())?;
        Ok(Some(path))
    }

    /// Each collider's surface in the world at time `time` (s), in the colliders' order.
    pub fn surfaces_at(&self, time: f64) -> Vec<Surface> {
        self.surfaces
            .iter()
            .zip(collider_poses(&self.colliders, time))
            .map(|(local, pose)| Surface {
                vertices: local
                    .vertices
                    .iter()
                    .map(|p| pose.transform_point(&Point3::from(*p)).coords)
                    .collect(),
                triangles: local.triangles.clone(),
            })
            .collect()
    }

    /// The folder written into.
    pub fn dir(&self) -> &Path {
        &self.dir
    }
}

/// A shape's surface in its own frame: a mesh as loaded (nothing when not loaded), a box's
/// 12 triangles, a sphere or capsule tessellated into rings about its x axis, a half-space as
/// a 2 m square slab 1 cm thick under its plane.
fn local_surface(shape: &ColliderShape) -> Surface {
    match shape {
        ColliderShape::Plane => {
            let mut slab = local_surface(&ColliderShape::Box {
                half_extents: Vector3::new(1.0, 0.005, 1.0),
            });
            for v in &mut slab.vertices {
                v.y -= 0.005;
            }
            slab
        }
        ColliderShape::Mesh(mesh) => mesh
            .mesh()
            .map(|m| Surface {
                vertices: m.vertices().to_vec(),
                triangles: m.triangles().to_vec(),
            })
            .unwrap_or_default(),
        ColliderShape::Box { half_extents } => {
            let h = half_extents;
            let vertices = (0..8)
                .map(|k| {
                    let s = |bit: usize| if k & bit == 0 { -1.0 } else { 1.0 };
                    Vector3::new(s(1) * h.x, s(2) * h.y, s(4) * h.z)
                })
                .collect();
            // Two outward triangles per face (corner k has bit 1 for +x, 2 for +y, 4 for +z).
            let faces = [
                [0, 4, 6, 2],
                [1, 3, 7, 5],
                [0, 1, 5, 4],
                [2, 6, 7, 3],
                [0, 2, 3, 1],
                [4, 5, 7, 6],
            ];
            let triangles = faces
                .iter()
                .flat_map(|[a, b, c, d]| [[*a, *b, *c], [*a, *c, *d]])
                .collect();
            Surface {
                vertices,
                triangles,
            }
        }
        ColliderShape::Sphere { radius } => capsule(0.0, *radius),
        ColliderShape::Capsule {
            half_length,
            radius,
        } => capsule(*half_length, *radius),
    }
}

/// The capsule of `radius` about the segment from `(−half_length, 0, 0)` to
/// `(half_length, 0, 0)` (a sphere when the length is 0): rings of [`SEGMENTS`] vertices
/// from pole to pole, joined by triangles.
fn capsule(half_length: f64, radius: f64) -> Surface {
    let rings_per_cap = SEGMENTS / 4;
    // (x, ring radius) from the −x pole to the +x pole, the poles excluded.
    let mut rings = Vec::new();
    for k in 1..=rings_per_cap {
        let angle = -0.5 * PI + 0.5 * PI * k as f64 / rings_per_cap as f64;
        rings.push((-half_length + radius * angle.sin(), radius * angle.cos()));
    }
    // A capsule's cylinder joins two rings at the equator; a sphere has one.
    let first = if half_length > 0.0 { 0 } else { 1 };
    for k in first..rings_per_cap {
        let angle = 0.5 * PI * k as f64 / rings_per_cap as f64;
        rings.push((half_length + radius * angle.sin(), radius * angle.cos()));
    }
    let mut vertices = vec![Vector3::new(-half_length - radius, 0.0, 0.0)];
    for &(x, r) in &rings {
        for s in 0..SEGMENTS {
            let phi = 2.0 * PI * s as f64 / SEGMENTS as f64;
            vertices.push(Vector3::new(x, r * phi.cos(), r * phi.sin()));
        }
    }
    vertices.push(Vector3::new(half_length + radius, 0.0, 0.0));
    let last = vertices.len() - 1;
    let at = |ring: usize, s: usize| 1 + ring * SEGMENTS + s % SEGMENTS;
    let mut triangles = Vec::new();
    for s in 0..SEGMENTS {
        triangles.push([0, at(0, s + 1), at(0, s)]);
        for ring in 0..rings.len() - 1 {
            triangles.push([at(ring, s), at(ring, s + 1), at(ring + 1, s + 1)]);
            triangles.push([at(ring, s), at(ring + 1, s + 1), at(ring + 1, s)]);
        }
        triangles.push([last, at(rings.len() - 1, s), at(rings.len() - 1, s + 1)]);
    }
    Surface {
        vertices,
        triangles,
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::UnitQuaternion;
    use reduced_sim::Keyframe;
    use rkpm_core::TriangleMesh;

    use super::*;

    /// The tessellated surfaces are closed, outward and lie on the shapes: volume within the
    /// tessellation's error of the exact one, every vertex at φ = 0.
    #[test]
    fn collider_surfaces_are_closed_outward_and_on_the_shape() {
        let shapes = [
            (
                ColliderShape::Sphere { radius: 0.3 },
                4.0 / 3.0 * PI * 0.027,
            ),
            (
                ColliderShape::Capsule {
                    half_length: 0.5,
                    radius: 0.2,
                },
                PI * 0.04 * 1.0 + 4.0 / 3.0 * PI * 0.008,
            ),
            (
                ColliderShape::Box {
                    half_extents: Vector3::new(0.1, 0.2, 0.3),
                },
                0.048,
            ),
        ];
        for (shape, exact) in shapes {
            let Surface {
                vertices,
                triangles,
            } = local_surface(&shape);
            let mesh = TriangleMesh::new(vertices.clone(), triangles).expect("closed surface");
            let volume = mesh.volume();
            assert!(
                volume > 0.0 && (volume - exact).abs() < 0.03 * exact,
                "{shape:?}: volume {volume} vs {exact}"
            );
            for v in &vertices {
                assert!(
                    shape.signed_distance(v).distance.abs() < 1e-12,
                    "{shape:?}: {v:?}"
                );
            }
        }
    }

    #[test]
    fn collider_frames_follow_the_chain_and_write_nothing_without_colliders() {
        let dir = std::env::temp_dir().join(format!("collider-frames-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        assert_eq!(ColliderFrames::new(&dir, &[]).write(0, 0.0).unwrap(), None);
        let sphere = ColliderShape::Sphere { radius: 0.1 };
        let base = Collider {
            path: vec![
                Keyframe {
                    time: 0.0,
                    rotation: UnitQuaternion::identity(),
                    translation: Vector3::zeros(),
                },
                Keyframe {
                    time: 1.0,
                    rotation: UnitQuaternion::identity(),
                    translation: Vector3::new(0.0, 1.0, 0.0),
                },
            ],
            ..Collider::fixed(sphere.clone(), UnitQuaternion::identity(), Vector3::zeros())
        };
        let child = Collider {
            parent: Some(0),
            ..Collider::fixed(sphere, UnitQuaternion::identity(), Vector3::x())
        };
        let frames = ColliderFrames::new(&dir, &[base, child]);
        let surfaces = frames.surfaces_at(1.0);
        let centre = |v: &[Vector3<f64>]| v.iter().sum::<Vector3<f64>>() / v.len() as f64;
        assert!((centre(&surfaces[0].vertices) - Vector3::y()).norm() < 1e-12);
        assert!((centre(&surfaces[1].vertices) - Vector3::new(1.0, 1.0, 0.0)).norm() < 1e-12);
        let vertices: Vec<Vector3<f64>> =
            surfaces.iter().flat_map(|s| s.vertices.clone()).collect();
        let path = frames.write(3, 1.0).unwrap().unwrap();
        assert!(path.ends_with("colliders_00003.ply"));
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains(&format!("element vertex {}", vertices.len())));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
