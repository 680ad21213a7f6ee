//! A [`Scene`] turned into reduced energy terms on one model: gravity, pin and floor penalties
//! with their gradients and Hessians in z (design §3.7).

use faer::{Accum, Mat, MatRef, Par};
use hyperelastic::HyperelasticMaterial;
use hyperelastic::Tangent;
use nalgebra::{Isometry3, Matrix3, Vector3};
use thiserror::Error;

use std::sync::{Arc, Mutex};

use crate::collider::{Collider, SignedDistance};
use crate::contact_friction::{ContactFriction, FrictionContact};
use crate::held_regions::HeldRegions;
use crate::reduced_model::ReducedModel;
use crate::scene::{Floor, FloorContact, PenaltyParams, PinModulus, PinTarget, Scene};

/// The scene does not fit the model.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum SceneError {
    /// A pinned point index is not an integration point of the model.
    #[error("pinned region {region} names point {point}, but the model has {points} points")]
    PinOutOfRange {
        /// Region index in [`Scene::pins`], then [`Scene::held`] (counting on from the pins).
        region: usize,
        /// The bad index.
        point: usize,
        /// Number of integration points.
        points: usize,
    },
    /// A pinned region selects no point.
    #[error("pinned region {region} contains no integration point")]
    EmptyPin {
        /// Region index.
        region: usize,
    },
    /// Gravity is not finite.
    #[error("gravity must be finite, got {0:?}")]
    Gravity([f64; 3]),
    /// The floor's normal is zero or not finite, or its offset is not finite.
    #[error(
        "the floor needs a finite non-zero normal and a finite offset, got {normal:?}, {offset}"
    )]
    Floor {
        /// The normal given.
        normal: [f64; 3],
        /// The offset given.
        offset: f64,
    },
    /// More held regions ([`Scene::held`]) than the basis has handles.
    #[error(
        "{regions} regions are held exactly, but the basis has only {handles} handles; build it with skin_eigen::build_basis_with_regions for these regions"
    )]
    TooFewHandles {
        /// Pinned regions.
        regions: usize,
        /// Handles of the basis.
        handles: usize,
    },
    /// A held region ([`Scene::held`]) with a basis that was not built for it.
    #[error(
        "held region {region} is not held by the basis: at point {point}, handle {handle} has weight {weight} instead of {expected}; build the basis with skin_eigen::build_basis_with_regions for the scene's held regions, in the same order"
    )]
    RegionNotHeld {
        /// Region index in [`Scene::held`].
        region: usize,
        /// The point.
        point: usize,
        /// The handle.
        handle: usize,
        /// Its weight there.
        weight: f64,
        /// The weight of a held region (1 or 0).
        expected: f64,
    },
    /// The floor's friction coefficient is negative or not finite, or the slip speed is not
    /// finite and positive.
    #[error(
        "floor friction needs a finite coefficient μ ≥ 0 and a finite slip speed ε_v > 0, got μ = {friction}, ε_v = {slip_speed} m/s"
    )]
    Friction {
        /// μ given.
        friction: f64,
        /// ε_v given (m/s).
        slip_speed: f64,
    },
    /// A collider is malformed.
    #[error("collider {index}: {why}")]
    Collider {
        /// Index in [`Scene::colliders`].
        index: usize,
        /// What is wrong.
        why: String,
    },
    /// A penalty factor is not finite and positive.
    #[error("penalty factors must be finite and positive, got pin {pin}, floor {floor}")]
    Penalty {
        /// Pin factor.
        pin: f64,
        /// Floor factor.
        floor: f64,
    },
    /// The floor's barrier distance d̂ is not finite and positive.
    #[error("the floor's barrier distance must be finite and positive, got {0} m")]
    BarrierDistance(f64),
}

struct PinTerm {
    rest: Vec<Vector3<f64>>,
    volumes: Vec<f64>,
    /// B restricted to the pinned points, column-major `4(m+1) × P`.
    b: Vec<f64>,
    target: PinTarget,
}

/// The scene's terms prepared on one model. Terms the scene does not have cost nothing.
pub(crate) struct SceneTerms {
    /// `∂E_grav/∂z` (constant), or `None` without gravity.
    gravity_gradient: Option<Vec<f64>>,
    pins: Vec<PinTerm>,
    /// κ_pin Σ_pinned v_i b_i b_iᵀ: the pin Hessian's diagonal block, constant.
    pin_hessian_block: Option<Mat<f64>>,
    pin_stiffness: f64,
    floor: Option<Floor>,
    floor_stiffness: f64,
    /// Penalty or barrier, for the floor and the colliders.
    floor_contact: FloorContact,
    /// ε_v (m/s) of the floor's and colliders' friction.
    friction_slip_speed: f64,
    /// Kinematic colliders, with the floor's stiffness.
    colliders: Vec<Collider>,
    /// The held regions ([`Scene::held`]), whose terms follow the penalized ones in `pins`.
    held: Option<HeldRegions>,
    /// How many of `pins` carry the penalty (the first ones).
    penalized: usize,
    /// The colliders' last signed distances: Newton asks again at the z whose energy the line
    /// search accepted, and for the projected Hessian after an indefinite exact one.
    last_query: Mutex<Option<ColliderQuery>>,
}

/// Every collider's signed distances at the points of one z, with the colliders at `poses`.
struct ColliderQuery {
    z: Vec<f64>,
    poses: Vec<Isometry3<f64>>,
    distances: Arc<Vec<Vec<SignedDistance>>>,
}

/// What the scene prescribes at one time, evaluated once per step: every pinned region's
/// targets and every collider's pose.
pub(crate) struct StepTargets {
    pins: Vec<Vec<Vector3<f64>>>,
    colliders: Vec<Isometry3<f64>>,
    /// The penalized pins' gradient at z = 0, `c_r = κ Σ_i v_i b_i (X_i − t_i)_r` (`3 · 4(m+1)`;
    /// empty without penalized pins): with the constant block `H = κ Σ v_i b_i b_iᵀ` their
    /// gradient is `H z_r + c_r`, one small matrix-vector product instead of a pass over every
    /// pinned point.
    pin_gradient_at_zero: Vec<f64>,
}

impl SceneTerms {
    pub(crate) fn new<M: HyperelasticMaterial>(
        model: &ReducedModel<M>,
        scene: &Scene,
        penalty: &PenaltyParams,
    ) -> Result<Self, SceneError> {
        let valid = |x: f64| x.is_finite() && x > 0.0;
        if !valid(penalty.pin_factor) || !valid(penalty.floor_factor) {
            return Err(SceneError::Penalty {
                pin: penalty.pin_factor,
                floor: penalty.floor_factor,
            });
        }
        if let FloorContact::Barrier { distance } = penalty.floor_contact
            && !valid(distance)
        {
            return Err(SceneError::BarrierDistance(distance));
        }
        let map = model.deformation_map();
        let n4 = map.layout().block_len();
        let n = map.len();
        let area = model.bounds().largest_side().powi(2);
        let scale = model.max_p_wave_modulus() / area;
        let pin_scale = match penalty.pin_modulus {
            PinModulus::PWave => scale,
            PinModulus::Young => model.max_youngs_modulus() / area,
        };

        let gravity_gradient = match scene.gravity {
            None => None,
            Some(g) if !g.iter().all(|v| v.is_finite()) => {
                return Err(SceneError::Gravity(g.into()));
            }
            Some(g) => {
                // E_grav = -Σ ρ v gᵀ x_i  ⇒  ∂E/∂z_r = -g_r Σ ρ_i v_i b_i.
                let mut weighted_sum = vec![0.0; n4];
                for i in 0..n {
                    let w = model.densities()[i] * model.volumes()[i];
                    for (s, b) in weighted_sum.iter_mut().zip(map.position_row(i)) {
                        *s += w * b;
                    }
                }
                Some(
                    (0..3)
                        .flat_map(|r| weighted_sum.iter().map(move |s| -g[r] * s))
                        .collect(),
                )
            }
        };

        let pin_stiffness = penalty.pin_factor * pin_scale;
        let mut pins = Vec::with_capacity(scene.pins.len());
        let mut pin_hessian_block: Option<Mat<f64>> = None;
        let penalized = scene.pins.len();
        for (region, pin) in scene.pins.iter().chain(&scene.held).enumerate() {
            if pin.points.is_empty() {
                return Err(SceneError::EmptyPin { region });
            }
            if let Some(&point) = pin.points.iter().find(|&&p| p >= n) {
                return Err(SceneError::PinOutOfRange {
                    region,
                    point,
                    points: n,
                });
            }
            let b: Vec<f64> = pin
                .points
                .iter()
                .flat_map(|&i| map.position_row(i).iter().copied())
                .collect();
            let volumes: Vec<f64> = pin.points.iter().map(|&i| model.volumes()[i]).collect();
            if region < penalized {
                let scaled: Vec<f64> = b
                    .chunks_exact(n4)
                    .zip(&volumes)
                    .flat_map(|(bi, v)| bi.iter().map(move |x| x * v * pin_stiffness))
                    .collect();
                let block = pin_hessian_block.get_or_insert_with(|| Mat::zeros(n4, n4));
                let p = pin.points.len();
                faer::linalg::matmul::matmul(
                    block.as_mut(),
                    Accum::Add,
                    MatRef::from_column_major_slice(&scaled, n4, p),
                    MatRef::from_column_major_slice(&b, n4, p).transpose(),
                    1.0,
                    Par::rayon(0),
                );
            }
            pins.push(PinTerm {
                rest: pin
                    .points
                    .iter()
                    .map(|&i| map.rest_positions()[i])
                    .collect(),
                volumes,
                b,
                target: pin.target.clone(),
            });
        }
        if let Some(block) = pin_hessian_block.as_mut() {
            crate::reduced_model::symmetrize(block);
        }

        let floor = match scene.floor {
            None => None,
            Some(floor) => {
                let norm = floor.normal.norm();
                if !(norm > 0.0 && norm.is_finite() && floor.offset.is_finite()) {
                    return Err(SceneError::Floor {
                        normal: floor.normal.into(),
                        offset: floor.offset,
                    });
                }
                let slip_speed = penalty.friction_slip_speed;
                let friction_valid = floor.friction >= 0.0 && floor.friction.is_finite();
                let slip_valid = slip_speed > 0.0 && slip_speed.is_finite();
                if !(friction_valid && slip_valid) {
                    return Err(SceneError::Friction {
                        friction: floor.friction,
                        slip_speed,
                    });
                }
                Some(Floor {
                    normal: floor.normal / norm,
                    offset: floor.offset / norm,
                    friction: floor.friction,
                })
            }
        };
        if let Some((index, why)) = scene
            .colliders
            .iter()
            .enumerate()
            .find_map(|(i, c)| c.defect().map(|why| (i, why)))
        {
            return Err(SceneError::Collider { index, why });
        }
        if let Some((index, why)) = crate::collider::chain_defect(&scene.colliders) {
            return Err(SceneError::Collider { index, why });
        }
        let reach = penalty.floor_contact.reach();
        if let Some((index, band)) = scene
            .colliders
            .iter()
            .enumerate()
            .find_map(|(i, c)| match &c.shape {
                crate::ColliderShape::Mesh(mesh) if mesh.band <= reach => Some((i, mesh.band)),
                _ => None,
            })
        {
            return Err(SceneError::Collider {
                index,
                why: format!(
                    "its band {band} m must exceed the barrier distance {reach} m (the mesh is not looked up beyond the band)"
                ),
            });
        }
        let held = if scene.held.is_empty() {
            None
        } else {
            let regions: Vec<Vec<usize>> = scene.held.iter().map(|p| p.points.clone()).collect();
            Some(HeldRegions::new(
                map.layout(),
                &regions,
                map.rest_positions(),
                model.volumes(),
                |point, handle| map.position_row(point)[4 * handle + 3],
            )?)
        };
        Ok(SceneTerms {
            gravity_gradient,
            pins,
            pin_hessian_block,
            pin_stiffness,
            floor,
            floor_stiffness: penalty.floor_factor * scale,
            floor_contact: penalty.floor_contact,
            friction_slip_speed: penalty.friction_slip_speed,
            colliders: scene.colliders.clone(),
            held,
            penalized,
            last_query: Mutex::new(None),
        })
    }

    /// With held regions: the indices of z that Newton solves for; `None` when every entry is
    /// free (pins by penalty).
    pub(crate) fn free_coordinates(&self) -> Option<&[usize]> {
        self.held.as_ref().map(HeldRegions::free_coordinates)
    }

    /// With held regions: writes the held handles' entries of z for `targets` (nothing
    /// otherwise).
    pub(crate) fn prescribe(&self, z: &mut [f64], targets: &StepTargets) {
        if let Some(held) = &self.held {
            held.prescribe(z, &targets.pins[self.penalized..]);
        }
    }

    /// The pins held by the penalty ([`Scene::pins`]; the held regions follow them).
    fn penalized_pins(&self) -> impl Iterator<Item = &PinTerm> {
        self.pins.iter().take(self.penalized)
    }

    /// The narrowest band (m) of the mesh colliders ([`crate::MeshShape::band`]), `None`
    /// without them.
    pub(crate) fn mesh_band(&self) -> Option<f64> {
        self.colliders
            .iter()
            .filter_map(|c| match &c.shape {
                crate::ColliderShape::Mesh(mesh) => Some(mesh.band),
                _ => None,
            })
            .reduce(f64::min)
    }

    /// Every collider's signed distances at `positions`, the points at z (m), with the
    /// colliders at `poses`; the last answer again when z and the poses are the last call's.
    fn collider_distances(
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

    /// The colliders' poses in the world at `time` (s).
    fn collider_poses(&self, time: f64) -> Vec<Isometry3<f64>> {
        crate::collider::collider_poses(&self.colliders, time)
    }

    /// The pin stiffness κ_pin (Pa/m²).
    pub(crate) fn pin_stiffness(&self) -> f64 {
        self.pin_stiffness
    }

    /// Every region's targets and every collider's pose at time `t` (s).
    pub(crate) fn step_targets(&self, t: f64) -> StepTargets {
        let pins: Vec<Vec<Vector3<f64>>> = self
            .pins
            .iter()
            .map(|p| p.rest.iter().map(|x| p.target.at(x, t)).collect())
            .collect();
        let mut pin_gradient_at_zero = Vec::new();
        for (pin, targets) in self.penalized_pins().zip(&pins) {
            let p = pin.rest.len();
            let n4 = pin.b.len() / p;
            pin_gradient_at_zero.resize(3 * n4, 0.0);
            // c = B_pin · D, D[i, r] = κ v_i (X_i − t_i)_r (`P × 3`), c column-major `n4 × 3`.
            let mut d = vec![0.0; 3 * p];
            for (i, (x, t)) in pin.rest.iter().zip(targets).enumerate() {
                let w = self.pin_stiffness * pin.volumes[i];
                for r in 0..3 {
                    d[r * p + i] = w * (x[r] - t[r]);
                }
            }
            faer::linalg::matmul::matmul(
                faer::MatMut::from_column_major_slice_mut(&mut pin_gradient_at_zero, n4, 3),
                Accum::Add,
                MatRef::from_column_major_slice(&pin.b, n4, p),
                MatRef::from_column_major_slice(&d, p, 3),
                1.0,
                Par::Seq,
            );
        }
        StepTargets {
            pins,
            colliders: self.collider_poses(t),
            pin_gradient_at_zero,
        }
    }

    /// The largest distance (m) of a pinned point from its target at z, or `None` without pins:
    /// of every pinned and held point, or (`held_only`) of the held ones.
    pub(crate) fn max_pin_deviation<M: HyperelasticMaterial>(
        &self,
        model: &ReducedModel<M>,
        z: &[f64],
        targets: &StepTargets,
        held_only: bool,
    ) -> Option<f64> {
        let skip = if held_only { self.penalized } else { 0 };
        let mut max: Option<f64> = None;
        for (pin, targets) in self.pins.iter().zip(&targets.pins).skip(skip) {
            for (x, t) in pinned_positions(model, pin, z).iter().zip(targets) {
                let d = (x - t).norm();
                max = Some(max.map_or(d, |m| m.max(d)));
            }
        }
        max
    }

    /// Energy of every external term at z (J; gravity up to a constant).
    pub(crate) fn energy<M: HyperelasticMaterial>(
        &self,
        model: &ReducedModel<M>,
        z: &[f64],
        targets: &StepTargets,
    ) -> f64 {
        let mut e = 0.0;
        if let Some(g) = &self.gravity_gradient {
            e += g.iter().zip(z).map(|(a, b)| a * b).sum::<f64>();
        }
        for (pin, targets) in self.penalized_pins().zip(&targets.pins) {
            let x = pinned_positions(model, pin, z);
            for ((x, t), v) in x.iter().zip(targets).zip(&pin.volumes) {
                e += 0.5 * self.pin_stiffness * v * (x - t).norm_squared();
            }
        }
        if self.floor.is_none() && self.colliders.is_empty() {
            return e;
        }
        let x = model.deformation_map().positions(z);
        let contact =
            |gap: f64, v: f64| self.floor_stiffness * v * self.floor_contact.profile(gap).0;
        if let Some(floor) = &self.floor {
            for (x, &v) in x.iter().zip(model.volumes()) {
                e += contact(floor.gap(x), v);
            }
        }
        for distances in self.collider_distances(z, &targets.colliders, &x).iter() {
            for (d, &v) in distances.iter().zip(model.volumes()) {
                e += contact(d.distance, v);
            }
        }
        e
    }

    /// The friction of the floor and the colliders over the step from `time` to `time +
    /// time_step` (s) that starts at z = `start` (slips are measured from there, moved with
    /// the surface touched), with contacts, normals and normal forces lagged at z = `contact`:
    /// the start itself (`contact == start`, the colliders then where they are at `time`, their
    /// normals turned with them to the step's end) or a solution of the step (the colliders at
    /// `time + time_step`); `None` without friction or contact.
    pub(crate) fn contact_friction<M: HyperelasticMaterial>(
        &self,
        model: &ReducedModel<M>,
        start: &[f64],
        contact: &[f64],
        time: f64,
        time_step: f64,
    ) -> Option<ContactFriction> {
        let floor = self.floor.as_ref().filter(|f| f.friction > 0.0);
        let rubbing = self.colliders.iter().any(|c| c.friction > 0.0);
        if floor.is_none() && !rubbing {
            return None;
        }
        let map = model.deformation_map();
        let (start_z, contact_z) = (start, contact);
        let (start, contact) = (map.positions(start), map.positions(contact));
        let volumes = model.volumes();
        let reach = self.floor_contact.reach();
        // The normal force κ v (−ψ'(g)) (N) at gap g.
        let normal_force = |gap: f64, i: usize| {
            -self.floor_stiffness * volumes[i] * self.floor_contact.profile(gap).1
        };
        let mut contacts = Vec::new();
        if let Some(floor) = floor {
            for (i, x) in contact.iter().enumerate() {
                let gap = floor.gap(x);
                if gap < reach {
                    contacts.push(FrictionContact {
                        point: i,
                        previous: start[i],
                        limit: floor.friction * normal_force(gap, i),
                        normal: floor.normal,
                    });
                }
            }
        }
        let poses = self.collider_poses(time + time_step);
        let before = self.collider_poses(time);
        // Lagged at the start of the step: the colliders where they were then.
        let at_start = contact_z == start_z;
        let distances = if !rubbing {
            Arc::default()
        } else if at_start {
            self.collider_distances(contact_z, &before, &contact)
        } else {
            self.collider_distances(contact_z, &poses, &contact)
        };
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
                        limit: collider.friction * normal_force(d.distance, i),
                        normal: if at_start {
                            carry.rotation * d.gradient
                        } else {
                            d.gradient
                        },
                    });
                }
            }
        }
        ContactFriction::new(&contacts, self.friction_slip_speed * time_step)
    }

    /// The deepest penetration (m) of an integration point into the floor or a collider at z
    /// and time `time` (s); 0 without contact.
    pub(crate) fn max_penetration<M: HyperelasticMaterial>(
        &self,
        model: &ReducedModel<M>,
        z: &[f64],
        time: f64,
    ) -> f64 {
        self.deepest(model, z, time).max(0.0)
    }

    /// The largest depth (m, negative when every point is clear) of a point below the floor or
    /// inside a collider; −∞ without them.
    fn deepest<M: HyperelasticMaterial>(
        &self,
        model: &ReducedModel<M>,
        z: &[f64],
        time: f64,
    ) -> f64 {
        if self.floor.is_none() && self.colliders.is_empty() {
            return f64::NEG_INFINITY;
        }
        let positions = model.deformation_map().positions(z);
        let mut deepest = f64::NEG_INFINITY;
        if let Some(floor) = &self.floor {
            for x in &positions {
                deepest = deepest.max(-floor.gap(x));
            }
        }
        let poses = self.collider_poses(time);
        for distances in self.collider_distances(z, &poses, &positions).iter() {
            for d in distances {
                deepest = deepest.max(-d.distance);
            }
        }
        deepest
    }

    /// The smallest gap (m) of an integration point to the floor or a collider at z and time
    /// `time` (s): its height above the floor, its signed distance to a collider (negative
    /// inside); +∞ without them.
    pub(crate) fn closest_gap<M: HyperelasticMaterial>(
        &self,
        model: &ReducedModel<M>,
        z: &[f64],
        time: f64,
    ) -> f64 {
        -self.deepest(model, z, time)
    }

    /// Whether the floor and the colliders repel by the barrier ([`FloorContact::Barrier`]).
    pub(crate) fn has_barrier(&self) -> bool {
        matches!(self.floor_contact, FloorContact::Barrier { .. })
            && (self.floor.is_some() || !self.colliders.is_empty())
    }

    /// With the barrier ([`FloorContact::Barrier`]): the largest α ≤ 1 such that no point
    /// closes more than 90% of its gap to the floor or a collider along α·`step` from z, so no
    /// iterate reaches one (nor passes through a thin collider). Exact for the floor, whose gap
    /// is linear in z; for a collider a bound, since φ changes by at most |Δx| when a point
    /// moves by Δx. 1 with the penalty.
    pub(crate) fn barrier_step<M: HyperelasticMaterial>(
        &self,
        model: &ReducedModel<M>,
        z: &[f64],
        step: &[f64],
        targets: &StepTargets,
    ) -> f64 {
        if !self.has_barrier() {
            return 1.0;
        }
        let map = model.deformation_map();
        let (positions, moves) = (map.positions(z), map.displacements(step));
        let mut alpha: f64 = 1.0;
        if let Some(floor) = &self.floor {
            for (x, dx) in positions.iter().zip(&moves) {
                let closing = -floor.normal.dot(dx);
                if closing > 0.0 {
                    alpha = alpha.min(0.9 * floor.gap(x) / closing);
                }
            }
        }
        for distances in self
            .collider_distances(z, &targets.colliders, &positions)
            .iter()
        {
            for (d, dx) in distances.iter().zip(&moves) {
                let length = dx.norm();
                if length > 0.0 {
                    alpha = alpha.min(0.9 * d.distance / length);
                }
            }
        }
        alpha.max(0.0)
    }

    /// The points in contact at z and time `time` (s), in index order: within the contact's
    /// reach of the floor ([`FloorContact::reach`]: below it for the penalty), then of
    /// collider k, numbered `(k + 1) n + i` (n points). The contact terms' Hessians change when
    /// this set does.
    pub(crate) fn contacts<M: HyperelasticMaterial>(
        &self,
        model: &ReducedModel<M>,
        z: &[f64],
        time: f64,
    ) -> Vec<usize> {
        if self.floor.is_none() && self.colliders.is_empty() {
            return Vec::new();
        }
        let positions = model.deformation_map().positions(z);
        let n = positions.len();
        let reach = self.floor_contact.reach();
        let mut contacts = Vec::new();
        if let Some(floor) = &self.floor {
            contacts.extend((0..n).filter(|&i| floor.gap(&positions[i]) < reach));
        }
        let poses = self.collider_poses(time);
        for (k, distances) in self
            .collider_distances(z, &poses, &positions)
            .iter()
            .enumerate()
        {
            contacts.extend(
                (0..n)
                    .filter(|&i| distances[i].distance < reach)
                    .map(|i| (k + 1) * n + i),
            );
        }
        contacts
    }

    /// Adds every external term's gradient at z to `gradient`, and its Hessian to `hessian`
    /// when given (the colliders' curvature term dropped for the tangents other than
    /// [`Tangent::Exact`], which keeps it positive semidefinite).
    pub(crate) fn add_derivatives<M: HyperelasticMaterial>(
        &self,
        model: &ReducedModel<M>,
        z: &[f64],
        targets: &StepTargets,
        tangent: Tangent,
        gradient: &mut [f64],
        mut hessian: Option<&mut Mat<f64>>,
    ) {
        self.add_collider_derivatives(model, z, targets, tangent, gradient, hessian.as_deref_mut());
        let map = model.deformation_map();
        let n4 = map.layout().block_len();
        if let Some(g) = &self.gravity_gradient {
            for (a, b) in gradient.iter_mut().zip(g) {
                *a += b;
            }
        }
        if let Some(block) = &self.pin_hessian_block {
            // ∂E/∂z_r = κ Σ v_i b_i (x_i − t_i)_r = H z_r + c_r, x_i = X_i + b_iᵀ z_r.
            for (gk, ck) in gradient.iter_mut().zip(&targets.pin_gradient_at_zero) {
                *gk += ck;
            }
            crate::reduced_model::add_block_diagonal_product(gradient, block, z, 1.0);
        }
        if let (Some(block), Some(hessian)) = (&self.pin_hessian_block, hessian.as_deref_mut()) {
            for r in 0..3 {
                for b in 0..n4 {
                    for a in 0..n4 {
                        hessian[(r * n4 + a, r * n4 + b)] += block[(a, b)];
                    }
                }
            }
        }
        if let Some(floor) = &self.floor {
            // Active points: E = κ v ψ(g), g = n·x − offset, ∂g/∂z_r = n_r b_i.
            let mut active_b = Vec::new();
            let mut active_bw = Vec::new();
            let reach = self.floor_contact.reach();
            for (i, x) in map.positions(z).iter().enumerate() {
                let gap = floor.gap(x);
                if gap < reach {
                    let w = self.floor_stiffness * model.volumes()[i];
                    let (_, slope, curvature) = self.floor_contact.profile(gap);
                    let bi = map.position_row(i);
                    for r in 0..3 {
                        let c = w * slope * floor.normal[r];
                        for (gk, bk) in gradient[r * n4..(r + 1) * n4].iter_mut().zip(bi) {
                            *gk += c * bk;
                        }
                    }
                    active_b.extend_from_slice(bi);
                    active_bw.extend(bi.iter().map(|b| b * w * curvature));
                }
            }
            let active = active_b.len() / n4;
            if let (true, Some(hessian)) = (active > 0, hessian) {
                let mut block = Mat::<f64>::zeros(n4, n4);
                faer::linalg::matmul::matmul(
                    block.as_mut(),
                    Accum::Replace,
                    MatRef::from_column_major_slice(&active_bw, n4, active),
                    MatRef::from_column_major_slice(&active_b, n4, active).transpose(),
                    1.0,
                    Par::rayon(0),
                );
                let nrm = floor.normal;
                for r in 0..3 {
                    for q in 0..3 {
                        let c = nrm[r] * nrm[q];
                        if c == 0.0 {
                            continue;
                        }
                        for b in 0..n4 {
                            for a in 0..n4 {
                                hessian[(r * n4 + a, q * n4 + b)] += c * block[(a, b)];
                            }
                        }
                    }
                }
            }
        }
    }
}

impl SceneTerms {
    /// The colliders' contact `κ v_i ψ(φ_i)` ([`FloorContact::profile`]) at z: gradient
    /// `κ v ψ' ∇φ` and Hessian `κ v (ψ'' ∇φ∇φᵀ + ψ' ∇²φ)` per point through the LBS rows, the
    /// second term left out for the tangents other than [`Tangent::Exact`] (ψ' ≤ 0, and ∇²φ
    /// is positive semidefinite outside a convex shape and negative semidefinite inside it:
    /// the term can be indefinite).
    fn add_collider_derivatives<M: HyperelasticMaterial>(
        &self,
        model: &ReducedModel<M>,
        z: &[f64],
        targets: &StepTargets,
        tangent: Tangent,
        gradient: &mut [f64],
        hessian: Option<&mut Mat<f64>>,
    ) {
        if self.colliders.is_empty() {
            return;
        }
        let map = model.deformation_map();
        let positions = map.positions(z);
        let reach = self.floor_contact.reach();
        let mut points = Vec::new();
        let mut forces = Vec::new();
        let mut stiffnesses = Vec::new();
        for distances in self
            .collider_distances(z, &targets.colliders, &positions)
            .iter()
        {
            for (i, d) in distances.iter().enumerate() {
                if d.distance < reach {
                    let w = self.floor_stiffness * model.volumes()[i];
                    let (_, slope, curvature) = self.floor_contact.profile(d.distance);
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
        map.add_point_gradients(&points, &forces, gradient);
        if let Some(hessian) = hessian {
            map.add_point_hessians(&points, &stiffnesses, hessian);
        }
    }
}

/// Positions `x_i(z)` (m) of a region's pinned points.
fn pinned_positions<M: HyperelasticMaterial>(
    model: &ReducedModel<M>,
    pin: &PinTerm,
    z: &[f64],
) -> Vec<Vector3<f64>> {
    let map = model.deformation_map();
    let n4 = map.layout().block_len();
    let p = pin.rest.len();
    let mut u = vec![0.0; 3 * p];
    faer::linalg::matmul::matmul(
        faer::MatMut::from_column_major_slice_mut(&mut u, 3, p),
        Accum::Replace,
        map.z_matrix(z).transpose(),
        MatRef::from_column_major_slice(&pin.b, n4, p),
        1.0,
        Par::Seq,
    );
    pin.rest
        .iter()
        .zip(u.chunks_exact(3))
        .map(|(x, u)| x + Vector3::new(u[0], u[1], u[2]))
        .collect()
}

#[cfg(test)]
mod tests {
    use nalgebra::UnitQuaternion;

    use super::*;
    use crate::analytic_field::analytic_model;
    use crate::collider::{ColliderShape, Keyframe};

    /// `shape` sliding along x through the block's middle (y = z = 0.5 m), from `from` at t = 0
    /// to `to` at t = 1 s (m), rubbing with `friction`.
    fn sliding(shape: ColliderShape, from: f64, to: f64, friction: f64) -> Collider {
        let key = |time: f64, x: f64| Keyframe {
            time,
            rotation: UnitQuaternion::identity(),
            translation: Vector3::new(x, 0.5, 0.5),
        };
        Collider {
            path: vec![key(0.0, from), key(1.0, to)],
            friction,
            ..Collider::fixed(shape, UnitQuaternion::identity(), Vector3::zeros())
        }
    }

    /// The reused collider query answers only for the same z and the same collider poses: a
    /// moved collider or another z gives what a fresh evaluation gives.
    #[test]
    fn the_collider_query_is_reused_only_at_the_same_z_and_poses() {
        let (model, _) = analytic_model();
        let scene = Scene {
            colliders: vec![sliding(
                ColliderShape::Sphere { radius: 0.4 },
                0.0,
                2.0,
                0.0,
            )],
            ..Scene::default()
        };
        let penalty = PenaltyParams::default();
        let reused = SceneTerms::new(&model, &scene, &penalty).unwrap();
        let fresh = || SceneTerms::new(&model, &scene, &penalty).unwrap();
        let len = model.deformation_map().layout().len();
        let z0 = vec![0.0; len];
        let z1: Vec<f64> = (0..len).map(|i| 0.01 * (i as f64).sin()).collect();
        let mut energies = Vec::new();
        for (z, time) in [(&z0, 0.2), (&z0, 0.2), (&z0, 0.45), (&z1, 0.45), (&z0, 0.2)] {
            let targets = reused.step_targets(time);
            let e = reused.energy(&model, z, &targets);
            assert_eq!(e, fresh().energy(&model, z, &targets), "z, t = {time}");
            energies.push(e);
        }
        assert!(energies[0] > 0.0 && energies[2] > 0.0);
        assert_ne!(energies[0], energies[2]);
        assert_ne!(energies[2], energies[3]);
    }

    /// Friction lagged at the start of a step takes its contacts with the colliders where they
    /// were then: a collider moving 0.2 m into the block over the step does not make the points
    /// it reaches only at the end rub (nor press with the depth it will have then).
    #[test]
    fn friction_lagged_at_the_start_of_a_step_sees_the_colliders_where_they_were() {
        let (model, _) = analytic_model();
        let block = ColliderShape::Box {
            half_extents: Vector3::new(0.5, 0.7, 0.7),
        };
        let scene = Scene {
            colliders: vec![sliding(block, -0.35, 1.65, 0.5)],
            ..Scene::default()
        };
        let terms = SceneTerms::new(&model, &scene, &PenaltyParams::default()).unwrap();
        let z = vec![0.0; model.deformation_map().layout().len()];
        let n = model.volumes().len();
        let inside = |time: f64| {
            terms
                .contacts(&model, &z, time)
                .into_iter()
                .filter(|&c| c >= n)
                .map(|c| c - n)
                .collect::<Vec<usize>>()
        };
        let (at_start, at_end) = (inside(0.0), inside(0.1));
        assert!(!at_start.is_empty() && at_end.len() > at_start.len());
        let friction = terms.contact_friction(&model, &z, &z, 0.0, 0.1).unwrap();
        assert_eq!(friction.points(), &at_start[..]);
    }
}
