//! Kinematic colliders: shapes moving on prescribed paths that push the body out by the
//! floor's penalty or barrier.

use std::sync::{Arc, Mutex};

use faer::Mat;
use hyperelastic::Tangent;
use nalgebra::{Isometry3, Matrix3, Vector3};

use crate::contact::collider::{Collider, ColliderShape, SignedDistance};
use crate::terms::floor_term::ContactLaw;
use crate::terms::friction_term::FrictionContact;
use crate::terms::step_term::{StepTerm, TermPoint};

/// `E_col(z, t) = Σ_k Σ_i κ v_i ψ(φ_k(x_i(z), t))` (J) over the colliders k, with φ_k the
/// signed distance to collider k at its pose at time t ([`ContactLaw`]): gradient
/// `κ v ψ' ∇φ` and Hessian `κ v (ψ'' ∇φ∇φᵀ + ψ' ∇²φ)` per point through the rows B_i, the
/// second part left out for the tangents other than [`Tangent::Exact`] (ψ' ≤ 0, and ∇²φ is
/// positive semidefinite outside a convex shape and negative semidefinite inside it: the part
/// can be indefinite). The colliders are one term because their poses form one kinematic chain
/// ([`Collider::parent`]).
pub(crate) struct ColliderTerm {
    pub(crate) colliders: Vec<Collider>,
    pub(crate) law: ContactLaw,
    /// The last signed distances: Newton asks again at the z whose energy the line search
    /// accepted, and for the projected Hessian after an indefinite exact one.
    last_query: Mutex<Option<ColliderQuery>>,
}

/// Every collider's signed distances at the points of one z, with the colliders at `poses`.
struct ColliderQuery {
    z: Vec<f64>,
    poses: Vec<Isometry3<f64>>,
    distances: Arc<Vec<Vec<SignedDistance>>>,
}

impl ColliderTerm {
    /// `colliders` (checked) pushing with `law`.
    pub(crate) fn new(colliders: Vec<Collider>, law: ContactLaw) -> Self {
        ColliderTerm {
            colliders,
            law,
            last_query: Mutex::new(None),
        }
    }

    /// The colliders' poses in the world at `time` (s).
    pub(crate) fn poses(&self, time: f64) -> Vec<Isometry3<f64>> {
        crate::contact::collider::collider_poses(&self.colliders, time)
    }

    /// The narrowest band (m) of the mesh colliders ([`crate::MeshShape::band`]).
    pub(crate) fn mesh_band(&self) -> Option<f64> {
        self.colliders
            .iter()
            .filter_map(|c| match &c.shape {
                ColliderShape::Mesh(mesh) => Some(mesh.band),
                _ => None,
            })
            .reduce(f64::min)
    }

    /// Every collider's signed distances at `positions`, the points at z (m), with the
    /// colliders at `poses`; the last answer again when z and the poses are the last call's.
    pub(crate) fn distances(
        &self,
        z: &[f64],
        poses: &[Isometry3<f64>],
        positions: &[Vector3<f64>],
    ) -> Arc<Vec<Vec<SignedDistance>>> {
        let mut last = self.last_query.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(query) = last.as_ref()
            && query.z == z
            && query.poses == poses
        {
            return Arc::clone(&query.distances);
        }
        let distances: Arc<Vec<Vec<SignedDistance>>> = Arc::new(
            self.colliders
                .iter()
                .zip(poses)
                .map(|(collider, pose)| collider.signed_distances(pose, positions))
                .collect(),
        );
        *last = Some(ColliderQuery {
            z: z.to_vec(),
            poses: poses.to_vec(),
            distances: Arc::clone(&distances),
        });
        distances
    }

    /// The signed distances at `at`, the colliders at `at.time`.
    fn distances_at(&self, at: &TermPoint<'_>) -> Arc<Vec<Vec<SignedDistance>>> {
        self.distances(at.z, &self.poses(at.time), at.positions())
    }

    /// The points within reach of collider k at `at`, numbered `(k + 1) n + i` (n points).
    pub(crate) fn contacts(&self, at: &TermPoint<'_>) -> Vec<usize> {
        let n = at.positions().len();
        let reach = self.law.reach();
        let mut contacts = Vec::new();
        for (k, distances) in self.distances_at(at).iter().enumerate() {
            contacts.extend(
                (0..n)
                    .filter(|&i| distances[i].distance < reach)
                    .map(|i| (k + 1) * n + i),
            );
        }
        contacts
    }

    /// The largest depth (m) of a point inside a collider at `at` (negative when all are
    /// clear, −∞ without colliders).
    pub(crate) fn deepest(&self, at: &TermPoint<'_>) -> f64 {
        self.distances_at(at)
            .iter()
            .flatten()
            .map(|d| -d.distance)
            .fold(f64::NEG_INFINITY, f64::max)
    }

    /// The friction contacts of the rubbing colliders (μ > 0) over the step from `time` to
    /// `time + time_step` (s): lagged at `contact_z` (points `contact`), slips measured from the
    /// start `start` moved with the surface touched. Lagged at the start itself (`at_start`),
    /// the colliders are where they were at `time`, their normals turned with them to the
    /// step's end; otherwise where they are at its end.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn friction_contacts(
        &self,
        contact_z: &[f64],
        start: &[Vector3<f64>],
        contact: &[Vector3<f64>],
        volumes: &[f64],
        time: f64,
        time_step: f64,
        at_start: bool,
    ) -> Vec<FrictionContact> {
        if !self.colliders.iter().any(|c| c.friction > 0.0) {
            return Vec::new();
        }
        let reach = self.law.reach();
        let poses = self.poses(time + time_step);
        let before = self.poses(time);
        let distances = if at_start {
            self.distances(contact_z, &before, contact)
        } else {
            self.distances(contact_z, &poses, contact)
        };
        let mut contacts = Vec::new();
        for (((collider, after), before), distances) in self
            .colliders
            .iter()
            .zip(&poses)
            .zip(&before)
            .zip(distances.iter())
        {
            if collider.friction <= 0.0 {
                continue;
            }
            let carry = after * before.inverse();
            for (i, d) in distances.iter().enumerate() {
                if d.distance < reach {
                    contacts.push(FrictionContact {
                        point: i,
                        previous: carry.transform_point(&start[i].into()).coords,
                        limit: collider.friction * self.law.normal_force(d.distance, volumes[i]),
                        normal: if at_start {
                            carry.rotation * d.gradient
                        } else {
                            d.gradient
                        },
                    });
                }
            }
        }
        contacts
    }
}

impl StepTerm for ColliderTerm {
    fn name(&self) -> &str {
        "colliders"
    }

    fn add_energy(&self, at: &TermPoint<'_>, energy: &mut f64) {
        for distances in self.distances_at(at).iter() {
            for (d, &v) in distances.iter().zip(at.volumes) {
                *energy += self.law.weighted_profile(d.distance, v).0;
            }
        }
    }

    fn add_derivatives(
        &self,
        at: &TermPoint<'_>,
        tangent: Tangent,
        gradient: &mut [f64],
        hessian: Option<&mut Mat<f64>>,
    ) {
        let reach = self.law.reach();
        let mut points = Vec::new();
        let mut forces = Vec::new();
        let mut stiffnesses = Vec::new();
        for distances in self.distances_at(at).iter() {
            for (i, d) in distances.iter().enumerate() {
                if d.distance < reach {
                    let w = self.law.stiffness * at.volumes[i];
                    let (_, slope, curvature) = self.law.contact.profile(d.distance);
                    points.push(i);
                    forces.push(d.gradient * (w * slope));
                    let mut h: Matrix3<f64> = d.gradient * d.gradient.transpose() * (w * curvature);
                    if tangent == Tangent::Exact {
                        h += d.hessian * (w * slope);
                    }
                    stiffnesses.push(h);
                }
            }
        }
        at.map.add_point_gradients(&points, &forces, gradient);
        if let Some(hessian) = hessian {
            at.map.add_point_hessians(&points, &stiffnesses, hessian);
        }
    }

    /// The largest α ≤ 1 that moves no point by more than half the narrowest mesh band (so no
    /// point crosses the band, beyond which the mesh is not looked up, into a wall in one
    /// iteration) and, with the barrier, closes no more than 90% of any point's distance (a
    /// bound: φ changes by at most |Δx| when a point moves by Δx).
    fn max_step(&self, at: &TermPoint<'_>, step: &[f64]) -> f64 {
        let band = self.mesh_band();
        if !self.law.is_barrier() && band.is_none() {
            return 1.0;
        }
        let moves = at.map.displacements(step);
        let mut alpha: f64 = 1.0;
        if self.law.is_barrier() {
            for distances in self.distances_at(at).iter() {
                for (d, dx) in distances.iter().zip(&moves) {
                    let length = dx.norm();
                    if length > 0.0 {
                        alpha = alpha.min(0.9 * d.distance / length);
                    }
                }
            }
            alpha = alpha.max(0.0);
        }
        if let Some(band) = band {
            let largest = moves.iter().map(|d| d.norm()).fold(0.0, f64::max);
            if largest > 0.0 {
                alpha = alpha.min(0.5 * band / largest);
            }
        }
        alpha
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::UnitQuaternion;

    use super::*;
    use crate::contact::collider::Keyframe;
    use crate::model::analytic_field::{analytic_model, probe_z};
    use crate::scene::FloorContact;
    use crate::terms::scene_terms::term_point;
    use crate::terms::term_check::{TermCheckParams, check_term};

    #[test]
    fn a_moving_sphere_and_a_turned_box_pass_the_term_check_with_the_exact_hessian() {
        let (model, _) = analytic_model();
        let key = |time: f64, translation: Vector3<f64>| Keyframe {
            time,
            rotation: UnitQuaternion::identity(),
            translation,
        };
        let sphere = Collider {
            path: vec![
                key(0.0, Vector3::new(0.9, 0.5, 1.2)),
                key(1.0, Vector3::new(1.1, 0.5, 1.2)),
            ],
            ..Collider::fixed(
                ColliderShape::Sphere { radius: 0.4 },
                UnitQuaternion::identity(),
                Vector3::zeros(),
            )
        };
        let turned_box = Collider::fixed(
            ColliderShape::Box {
                half_extents: Vector3::new(0.3, 0.4, 0.4),
            },
            UnitQuaternion::from_euler_angles(0.3, 0.2, 0.1),
            Vector3::new(2.1, 0.5, 0.5),
        );
        let term = ColliderTerm::new(
            vec![sphere, turned_box],
            ContactLaw {
                stiffness: 1e8,
                contact: FloorContact::Penalty,
            },
        );
        let z = probe_z(model.deformation_map().layout().len(), 0.02);
        let at = term_point(&model, &z, 0.5);
        let contacts = term.contacts(&at);
        let n = model.volumes().len();
        assert!(contacts.iter().any(|&c| c < 2 * n) && contacts.iter().any(|&c| c >= 2 * n));
        check_term(&term, &at, &TermCheckParams::default()).unwrap();
    }
}
