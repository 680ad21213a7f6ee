//! Kinematic colliders: rigid shapes moving on prescribed paths that push the object
//! through a penalty on their signed distance (or the floor's barrier,
//! [`crate::FloorContact::Barrier`]), with the floor's friction model (a pusher, a peg, a
//! container wall, the jointed links of a robot arm).
//!
//! A collider's shape is given in its own frame; its pose `x = R(t) p + c(t)` follows a
//! keyframed path (translation linear, rotation slerped between keys, held before the first
//! and after the last). The signed distance φ(x, t) is negative inside; integration points with
//! φ < 0 get the energy `κ/2 v_i φ²` (κ the floor's stiffness, see
//! [`crate::PenaltyParams`]), whose gradient and Hessian in x are
//!
//! ```text
//! κ v φ ∇φ,      κ v (∇φ ∇φᵀ + φ ∇²φ).
//! ```
//!
//! For the convex shapes `∇²φ` is positive semidefinite, so inside (φ < 0) the second term is
//! negative semidefinite: the projected tangent keeps `κ v ∇φ∇φᵀ` alone (for a mesh too,
//! where the term has either sign).

use nalgebra::{Isometry3, Matrix3, Translation3, UnitQuaternion, Vector3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::contact::mesh_collider::MeshShape;
pub use crate::contact::signed_distance::SignedDistance;

/// A shape in the collider's frame (m): a half-space, three convex primitives and closed
/// triangle meshes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ColliderShape {
    /// The half-space `y ≤ 0` (solid below its plane y = 0): φ = y. Posed and moved like any
    /// collider (a tilting ramp, a wall closing in); in scene files `shape = "plane"`.
    Plane,
    /// A ball of `radius` about the origin.
    Sphere {
        /// Radius (m).
        radius: f64,
    },
    /// A box `|p_k| ≤ half_extents_k`.
    Box {
        /// Half side lengths (m).
        half_extents: Vector3<f64>,
    },
    /// The points within `radius` of the segment from `(−half_length, 0, 0)` to
    /// `(half_length, 0, 0)`.
    Capsule {
        /// Half the segment's length (m).
        half_length: f64,
        /// Radius (m).
        radius: f64,
    },
    /// A closed triangle mesh (a container, a ramp); see [`MeshShape`].
    Mesh(MeshShape),
}

impl ColliderShape {
    /// φ, ∇φ and ∇²φ at `p` (m, shape frame).
    pub fn signed_distance(&self, p: &Vector3<f64>) -> SignedDistance {
        match *self {
            ColliderShape::Mesh(ref mesh) => mesh.signed_distance(p),
            ColliderShape::Plane => SignedDistance {
                distance: p.y,
                gradient: Vector3::y(),
                hessian: Matrix3::zeros(),
            },
            ColliderShape::Sphere { radius } => ball(p, radius),
            ColliderShape::Capsule {
                half_length,
                radius,
            } => {
                let along = p.x.clamp(-half_length, half_length);
                let axis_point = Vector3::new(along, 0.0, 0.0);
                let mut d = ball(&(p - axis_point), radius);
                if along.abs() < half_length {
                    // Beside the segment φ does not change along the axis (∇φ has no x part,
                    // so only the ball's 1/|p⊥| on the diagonal goes).
                    d.hessian[(0, 0)] = 0.0;
                }
                d
            }
            ColliderShape::Box { half_extents } => {
                let q = p.abs() - half_extents;
                let outside = q.map(|v| v.max(0.0));
                let length = outside.norm();
                if length > 0.0 {
                    // Outside: the distance to the nearest face, edge or corner.
                    let n_local = outside / length;
                    let gradient = n_local.component_mul(&p.map(f64::signum));
                    // Curvature across the active axes only (a face is flat).
                    let active =
                        Matrix3::from_diagonal(&outside.map(|v| f64::from(u8::from(v > 0.0))));
                    let hessian = (active - gradient * gradient.transpose()) / length;
                    SignedDistance {
                        distance: length,
                        gradient,
                        hessian: 0.5 * (hessian + hessian.transpose()),
                    }
                } else {
                    // Inside: the nearest face.
                    let k = q.imax();
                    let mut gradient = Vector3::zeros();
                    gradient[k] = p[k].signum();
                    SignedDistance {
                        distance: q[k],
                        gradient,
                        hessian: Matrix3::zeros(),
                    }
                }
            }
        }
    }

    /// Checks sizes: finite and positive.
    fn defect(&self) -> Option<String> {
        let ok = |v: f64| v.is_finite() && v > 0.0;
        match *self {
            ColliderShape::Mesh(ref mesh) => mesh.defect(),
            ColliderShape::Sphere { radius } if !ok(radius) => Some(format!("radius {radius}")),
            ColliderShape::Capsule {
                half_length,
                radius,
            } if !(ok(radius) && half_length.is_finite() && half_length >= 0.0) => {
                Some(format!("half length {half_length} / radius {radius}"))
            }
            ColliderShape::Box { half_extents } if !half_extents.iter().all(|&v| ok(v)) => {
                Some(format!("half extents {half_extents:?}"))
            }
            _ => None,
        }
    }
}

/// φ of a ball of `radius` about the origin: `|p| − r`, ∇φ = p/|p|, ∇²φ = (I − ∇φ∇φᵀ)/|p|.
fn ball(p: &Vector3<f64>, radius: f64) -> SignedDistance {
    let length = p.norm();
    if length == 0.0 {
        // The centre: every direction is nearest; pick +x (φ is not differentiable here).
        return SignedDistance {
            distance: -radius,
            gradient: Vector3::x(),
            hessian: Matrix3::zeros(),
        };
    }
    let n = p / length;
    SignedDistance {
        distance: length - radius,
        gradient: n,
        hessian: (Matrix3::identity() - n * n.transpose()) / length,
    }
}

/// A pose of a collider at a time.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Keyframe {
    /// t (s).
    pub time: f64,
    /// Rotation of the shape frame (default identity; in files `[i, j, k, w]`).
    #[serde(default = "UnitQuaternion::identity")]
    pub rotation: UnitQuaternion<f64>,
    /// Position of the shape frame's origin (m).
    pub translation: Vector3<f64>,
}

/// A rigid shape on a keyframed path, with the Coulomb friction of its surface.
///
/// Colliders can form kinematic chains (the links of a robot arm): a collider with a
/// [`Collider::parent`] moves with it, its path then the motion of its joint in the parent's
/// frame, `pose_world(t) = pose_world(parent, t) · path(t)` ([`collider_poses`]). A revolute
/// joint is a path whose rotations turn about the joint's axis through the link frame's origin.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Collider {
    /// The shape in its own frame.
    pub shape: ColliderShape,
    /// Poses at increasing times (at least one): translation linear and rotation slerped
    /// between them, the first before and the last after; in the parent's frame when there is
    /// one, else in the world.
    pub path: Vec<Keyframe>,
    /// Coulomb friction coefficient μ against the object (dimensionless, default 0).
    #[serde(default)]
    pub friction: f64,
    /// The index of an earlier collider of the scene this one is attached to (default none:
    /// its path is in the world).
    #[serde(default)]
    pub parent: Option<usize>,
}

/// The first collider of a scene whose [`Collider::parent`] is not an earlier collider, with
/// what is wrong; `None` when every chain is in order.
pub fn chain_defect(colliders: &[Collider]) -> Option<(usize, String)> {
    colliders.iter().enumerate().find_map(|(i, c)| {
        c.parent
            .filter(|&p| p >= i)
            .map(|p| (i, format!("its parent {p} must be an earlier collider")))
    })
}

/// Every collider's pose in the world at time `t` (s), a chain's links composed from its root:
/// `pose_i = pose_parent(i) · path_i(t)`. A parent must come before its children (what
/// [`crate::Scene::validate`] checks); a parent index out of order is taken as no parent.
pub fn collider_poses(colliders: &[Collider], t: f64) -> Vec<Isometry3<f64>> {
    let mut poses: Vec<Isometry3<f64>> = Vec::with_capacity(colliders.len());
    for (i, collider) in colliders.iter().enumerate() {
        let own = collider.pose(t);
        let pose = match collider.parent {
            Some(p) if p < i => poses[p] * own,
            _ => own,
        };
        poses.push(pose);
    }
    poses
}

impl Collider {
    /// A collider that stays at one pose.
    pub fn fixed(
        shape: ColliderShape,
        rotation: UnitQuaternion<f64>,
        translation: Vector3<f64>,
    ) -> Self {
        Collider {
            shape,
            path: vec![Keyframe {
                time: 0.0,
                rotation,
                translation,
            }],
            friction: 0.0,
            parent: None,
        }
    }

    /// The pose of its path at time `t` (s): in the world without a parent, else relative to
    /// the parent ([`collider_poses`] composes a chain).
    pub fn pose(&self, t: f64) -> Isometry3<f64> {
        let at =
            |k: &Keyframe| Isometry3::from_parts(Translation3::from(k.translation), k.rotation);
        let (Some(first), Some(last)) = (self.path.first(), self.path.last()) else {
            return Isometry3::identity();
        };
        if t <= first.time {
            return at(first);
        }
        if t >= last.time {
            return at(last);
        }
        let k = self.path.partition_point(|k| k.time <= t);
        let (a, b) = (&self.path[k - 1], &self.path[k]);
        let s = (t - a.time) / (b.time - a.time);
        Isometry3::from_parts(
            Translation3::from(a.translation.lerp(&b.translation, s)),
            a.rotation.slerp(&b.rotation, s),
        )
    }

    /// φ, ∇φ, ∇²φ at world point `x` (m) with the collider at `pose`.
    pub fn signed_distance(&self, pose: &Isometry3<f64>, x: &Vector3<f64>) -> SignedDistance {
        let local = pose
            .inverse_transform_point(&nalgebra::Point3::from(*x))
            .coords;
        let d = self.shape.signed_distance(&local);
        let r = pose.rotation.to_rotation_matrix().into_inner();
        SignedDistance {
            distance: d.distance,
            gradient: r * d.gradient,
            hessian: r * d.hessian * r.transpose(),
        }
    }

    /// [`Collider::signed_distance`] at every point of `points` (m), in order, computed in
    /// parallel.
    pub fn signed_distances(
        &self,
        pose: &Isometry3<f64>,
        points: &[Vector3<f64>],
    ) -> Vec<SignedDistance> {
        points
            .par_iter()
            .with_min_len(256)
            .map(|x| self.signed_distance(pose, x))
            .collect()
    }

    /// What is wrong with this collider, if anything: a shape size that is not finite and
    /// positive, an empty path, times that do not increase, a non-finite pose, or a friction
    /// coefficient that is negative or not finite.
    pub fn defect(&self) -> Option<String> {
        if let Some(why) = self.shape.defect() {
            return Some(format!("shape: {why}"));
        }
        if self.path.is_empty() {
            return Some("the path has no keyframe".into());
        }
        if self.path.windows(2).any(|w| !(w[1].time > w[0].time)) {
            return Some("keyframe times must increase".into());
        }
        let finite = |k: &Keyframe| {
            k.time.is_finite()
                && k.translation.iter().all(|v| v.is_finite())
                && k.rotation.coords.iter().all(|v| v.is_finite())
        };
        if !self.path.iter().all(finite) {
            return Some("a keyframe is not finite".into());
        }
        if !(self.friction >= 0.0 && self.friction.is_finite()) {
            return Some(format!("friction {}", self.friction));
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ∇φ and ∇²φ against central differences at points inside and outside each shape.
    #[test]
    fn signed_distance_derivatives_match_central_differences() {
        let shapes = [
            ColliderShape::Plane,
            ColliderShape::Sphere { radius: 0.3 },
            ColliderShape::Capsule {
                half_length: 0.4,
                radius: 0.2,
            },
            ColliderShape::Box {
                half_extents: Vector3::new(0.3, 0.2, 0.4),
            },
        ];
        let points = [
            Vector3::new(0.1, 0.05, -0.02),
            Vector3::new(0.5, 0.3, 0.1),
            Vector3::new(-0.2, 0.45, 0.6),
            Vector3::new(0.7, -0.1, 0.05),
            Vector3::new(0.25, 0.12, -0.3),
        ];
        let h = 1e-6;
        for shape in shapes {
            for p in points {
                let d = shape.signed_distance(&p);
                for k in 0..3 {
                    let e = Vector3::ith(k, h);
                    let plus = shape.signed_distance(&(p + e));
                    let minus = shape.signed_distance(&(p - e));
                    let slope = (plus.distance - minus.distance) / (2.0 * h);
                    assert!(
                        (slope - d.gradient[k]).abs() < 1e-6,
                        "{shape:?} at {p:?}: ∂φ/∂x{k} {slope} vs {}",
                        d.gradient[k]
                    );
                    let column = (plus.gradient - minus.gradient) / (2.0 * h);
                    assert!(
                        (column - d.hessian.column(k)).norm() < 1e-5,
                        "{shape:?} at {p:?}: ∇²φ column {k} {column:?} vs {:?}",
                        d.hessian.column(k)
                    );
                }
            }
        }
    }

    /// A two-link arm: link 0 turns 90° about z at the origin over 1 s, link 1 is jointed at
    /// (1, 0, 0) of link 0 and turns another 90° there.
    #[test]
    fn a_chained_collider_moves_with_its_parent_and_a_chain_out_of_order_is_named() {
        let turn = |time: f64, angle: f64, at: Vector3<f64>| Keyframe {
            time,
            rotation: UnitQuaternion::from_axis_angle(&Vector3::z_axis(), angle),
            translation: at,
        };
        let quarter = std::f64::consts::FRAC_PI_2;
        let sphere = ColliderShape::Sphere { radius: 0.1 };
        let base = Collider {
            path: vec![
                turn(0.0, 0.0, Vector3::zeros()),
                turn(1.0, quarter, Vector3::zeros()),
            ],
            ..Collider::fixed(sphere.clone(), UnitQuaternion::identity(), Vector3::zeros())
        };
        let elbow = Vector3::x();
        let forearm = Collider {
            path: vec![turn(0.0, 0.0, elbow), turn(1.0, quarter, elbow)],
            parent: Some(0),
            ..base.clone()
        };
        let arm = [base, forearm];
        let tip = nalgebra::Point3::new(0.5, 0.0, 0.0);
        // At rest the tip is at (1.5, 0, 0); at the end (−0.5, 1, 0); half way both joints
        // are at 45°.
        let at = |t: f64| collider_poses(&arm, t)[1].transform_point(&tip).coords;
        assert!((at(0.0) - Vector3::new(1.5, 0.0, 0.0)).norm() < 1e-14);
        assert!((at(1.0) - Vector3::new(-0.5, 1.0, 0.0)).norm() < 1e-14);
        let s = std::f64::consts::FRAC_1_SQRT_2;
        let half = Vector3::new(s, s, 0.0) + Vector3::new(0.0, 0.5, 0.0);
        assert!((at(0.5) - half).norm() < 1e-14, "{:?}", at(0.5));
        // The forearm's sphere (about its joint) is where its pose says: centred at (0, 1, 0).
        let pose = collider_poses(&arm, 1.0)[1];
        let phi = |x: Vector3<f64>| arm[1].signed_distance(&pose, &x).distance;
        assert!((phi(Vector3::y()) + 0.1).abs() < 1e-14);
        assert!((phi(Vector3::new(-0.5, 1.0, 0.0)) - 0.4).abs() < 1e-14);
        assert_eq!(chain_defect(&arm), None);
        let mut loop_back = arm.clone();
        loop_back[0].parent = Some(1);
        assert_eq!(chain_defect(&loop_back).map(|(i, _)| i), Some(0));
    }

    #[test]
    fn the_path_interpolates_between_keys_and_holds_outside_them() {
        let mut collider = Collider::fixed(
            ColliderShape::Sphere { radius: 0.1 },
            UnitQuaternion::identity(),
            Vector3::zeros(),
        );
        collider.path.push(Keyframe {
            time: 2.0,
            rotation: UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 1.0),
            translation: Vector3::new(1.0, 0.0, 0.0),
        });
        let mid = collider.pose(1.0);
        assert!((mid.translation.vector - Vector3::new(0.5, 0.0, 0.0)).norm() < 1e-15);
        assert!((mid.rotation.angle() - 0.5).abs() < 1e-12);
        assert_eq!(collider.pose(-1.0), collider.pose(0.0));
        assert_eq!(collider.pose(5.0), collider.pose(2.0));
        assert!(collider.defect().is_none());
        collider.path[1].time = 0.0;
        assert!(collider.defect().is_some());
    }
}
