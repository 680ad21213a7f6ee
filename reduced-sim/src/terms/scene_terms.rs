//! A [`Scene`] turned into the terms of the incremental potential on one model (design §3.7):
//! gravity, the pin penalty, the floor and the colliders, each a [`StepTerm`], the held
//! regions (coordinates prescribed, not penalized), and terms a user adds.

use faer::Mat;
use hyperelastic::{HyperelasticMaterial, Tangent};
use nalgebra::Vector3;

use crate::contact::collider::ColliderShape;
use crate::model::reduced_model::ReducedModel;
use crate::scene::{Floor, FloorContact, PenaltyParams, PinModulus, Scene};
use crate::scene_error::SceneError;
use crate::terms::collider_term::ColliderTerm;
use crate::terms::floor_term::{ContactLaw, FloorTerm};
use crate::terms::friction_term::ContactFriction;
use crate::terms::gravity_term::GravityTerm;
use crate::terms::held_regions::HeldRegions;
use crate::terms::pin_penalty::PinPenalty;
use crate::terms::pinned_points::PinnedPoints;
use crate::terms::step_term::{StepTerm, TermPoint};

/// The scene's terms prepared on one model. Terms the scene does not have cost nothing.
pub(crate) struct SceneTerms {
    colliders: Option<ColliderTerm>,
    gravity: Option<GravityTerm>,
    pins: Option<PinPenalty>,
    floor: Option<FloorTerm>,
    /// The held regions ([`Scene::held`]) and their points.
    held: Option<(HeldRegions, Vec<PinnedPoints>)>,
    /// Terms added by the caller ([`crate::Simulator::add_term`]), summed after the scene's.
    added: Vec<Box<dyn StepTerm>>,
    /// κ_pin (Pa/m²).
    pin_stiffness: f64,
    /// ε_v (m/s) of the floor's and colliders' friction.
    friction_slip_speed: f64,
}

/// The term point of `model`'s integration points at z and `time` (s).
pub(crate) fn term_point<'a, M: HyperelasticMaterial>(
    model: &'a ReducedModel<M>,
    z: &'a [f64],
    time: f64,
) -> TermPoint<'a> {
    TermPoint::new(model.deformation_map(), model.volumes(), z, time)
}

impl SceneTerms {
    /// The terms of `scene` on `model` with the penalties of `penalty`.
    ///
    /// # Errors
    /// [`SceneError`] when the scene does not fit the model or a value is invalid.
    pub(crate) fn new<M: HyperelasticMaterial>(
        model: &ReducedModel<M>,
        scene: &Scene,
        penalty: &PenaltyParams,
    ) -> Result<Self, SceneError> {
        check_penalty(penalty)?;
        let map = model.deformation_map();
        let area = model.bounds().largest_side().powi(2);
        let scale = model.max_p_wave_modulus() / area;
        let pin_stiffness = penalty.pin_factor
            * match penalty.pin_modulus {
                PinModulus::PWave => scale,
                PinModulus::Young => model.max_youngs_modulus() / area,
            };
        let gravity = match scene.gravity {
            None => None,
            Some(g) if !g.iter().all(|v| v.is_finite()) => {
                return Err(SceneError::Gravity(g.into()));
            }
            Some(g) => Some(GravityTerm::new(model, g)),
        };
        let n = map.len();
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
        }
        let points = |regions: &[crate::PinnedRegion]| -> Vec<PinnedPoints> {
            regions
                .iter()
                .map(|r| PinnedPoints::new(map, model.volumes(), r))
                .collect()
        };
        let pins = (!scene.pins.is_empty())
            .then(|| PinPenalty::new(points(&scene.pins), pin_stiffness, map.layout().block_len()));
        let law = ContactLaw {
            stiffness: penalty.floor_factor * scale,
            contact: penalty.floor_contact,
        };
        let floor = match scene.floor {
            None => None,
            Some(floor) => Some(FloorTerm {
                floor: unit_floor(floor, penalty.friction_slip_speed)?,
                law,
            }),
        };
        check_colliders(scene, penalty.floor_contact)?;
        let colliders =
            (!scene.colliders.is_empty()).then(|| ColliderTerm::new(scene.colliders.clone(), law));
        let held = if scene.held.is_empty() {
            None
        } else {
            let regions: Vec<Vec<usize>> = scene.held.iter().map(|p| p.points.clone()).collect();
            let held = HeldRegions::new(
                map.layout(),
                &regions,
                map.rest_positions(),
                model.volumes(),
                |point, handle| map.position_row(point)[4 * handle + 3],
            )?;
            Some((held, points(&scene.held)))
        };
        Ok(SceneTerms {
            colliders,
            gravity,
            pins,
            floor,
            held,
            added: Vec::new(),
            pin_stiffness,
            friction_slip_speed: penalty.friction_slip_speed,
        })
    }

    /// Adds `term` to the potential, after the scene's own terms.
    pub(crate) fn add_term(&mut self, term: Box<dyn StepTerm>) {
        self.added.push(term);
    }

    /// Every energy term, in the order they are summed: the colliders, gravity, the pin
    /// penalty, the floor, then the added terms.
    pub(crate) fn terms(&self) -> impl Iterator<Item = &dyn StepTerm> {
        let colliders = self.colliders.iter().map(|t| t as &dyn StepTerm);
        let gravity = self.gravity.iter().map(|t| t as &dyn StepTerm);
        let pins = self.pins.iter().map(|t| t as &dyn StepTerm);
        let floor = self.floor.iter().map(|t| t as &dyn StepTerm);
        colliders
            .chain(gravity)
            .chain(pins)
            .chain(floor)
            .chain(self.added.iter().map(|t| t.as_ref()))
    }

    /// With held regions: the indices of z that Newton solves for; `None` when every entry is
    /// free (pins by penalty).
    pub(crate) fn free_coordinates(&self) -> Option<&[usize]> {
        self.held.as_ref().map(|(held, _)| held.free_coordinates())
    }

    /// With held regions: writes the held handles' entries of z for their targets at `time`
    /// (s; nothing otherwise).
    pub(crate) fn prescribe(&self, z: &mut [f64], time: f64) {
        if let Some((held, points)) = &self.held {
            let targets: Vec<Vec<Vector3<f64>>> = points.iter().map(|p| p.targets(time)).collect();
            held.prescribe(z, &targets);
        }
    }

    /// The pin stiffness κ_pin (Pa/m²).
    pub(crate) fn pin_stiffness(&self) -> f64 {
        self.pin_stiffness
    }

    /// The largest distance (m) of a pinned point from its target at `at`, or `None` without
    /// pins: of every pinned and held point, or (`held_only`) of the held ones.
    pub(crate) fn max_pin_deviation(&self, at: &TermPoint<'_>, held_only: bool) -> Option<f64> {
        let held = self.held.as_ref().map(|(_, points)| {
            points
                .iter()
                .map(|p| p.max_deviation(at.map, at.z, at.time))
                .fold(0.0, f64::max)
        });
        if held_only {
            return held;
        }
        let pinned = self.pins.as_ref().map(|p| p.max_deviation(at));
        match (pinned, held) {
            (Some(a), Some(b)) => Some(a.max(b)),
            (a, b) => a.or(b),
        }
    }

    /// Energy of every term at `at` (J; gravity up to a constant).
    pub(crate) fn energy(&self, at: &TermPoint<'_>) -> f64 {
        let mut energy = 0.0;
        for term in self.terms() {
            term.add_energy(at, &mut energy);
        }
        energy
    }

    /// Adds every term's gradient at `at` to `gradient`, and its Hessian to `hessian` when
    /// given ([`StepTerm::add_derivatives`]).
    pub(crate) fn add_derivatives(
        &self,
        at: &TermPoint<'_>,
        tangent: Tangent,
        gradient: &mut [f64],
        mut hessian: Option<&mut Mat<f64>>,
    ) {
        for term in self.terms() {
            term.add_derivatives(at, tangent, gradient, hessian.as_deref_mut());
        }
    }

    /// The largest fraction of `step` from `at` that every term allows
    /// ([`StepTerm::max_step`]).
    pub(crate) fn max_step(&self, at: &TermPoint<'_>, step: &[f64]) -> f64 {
        self.terms()
            .map(|t| t.max_step(at, step))
            .fold(1.0, f64::min)
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
        let floor = self.floor.as_ref().filter(|f| f.floor.friction > 0.0);
        let colliders = self
            .colliders
            .as_ref()
            .filter(|c| c.colliders.iter().any(|c| c.friction > 0.0));
        if floor.is_none() && colliders.is_none() {
            return None;
        }
        let map = model.deformation_map();
        let at_start = contact == start;
        let (contact_z, start, contact) = (contact, map.positions(start), map.positions(contact));
        let volumes = model.volumes();
        let mut contacts = Vec::new();
        if let Some(floor) = floor {
            contacts.extend(floor.friction_contacts(&start, &contact, volumes));
        }
        if let Some(colliders) = colliders {
            contacts.extend(colliders.friction_contacts(
                contact_z, &start, &contact, volumes, time, time_step, at_start,
            ));
        }
        ContactFriction::new(&contacts, self.friction_slip_speed * time_step)
    }

    /// The largest depth (m, negative when every point is clear) of a point below the floor or
    /// inside a collider at `at`; −∞ without them.
    pub(crate) fn deepest(&self, at: &TermPoint<'_>) -> f64 {
        let floor = self.floor.as_ref().map(|f| f.deepest(at));
        let colliders = self.colliders.as_ref().map(|c| c.deepest(at));
        floor
            .into_iter()
            .chain(colliders)
            .fold(f64::NEG_INFINITY, f64::max)
    }

    /// Whether the floor and the colliders repel by the barrier ([`FloorContact::Barrier`]).
    pub(crate) fn has_barrier(&self) -> bool {
        let floor = self.floor.as_ref().map(|f| f.law);
        let colliders = self.colliders.as_ref().map(|c| c.law);
        floor.or(colliders).is_some_and(|law| law.is_barrier())
    }

    /// The points in contact at `at`, in index order: within the contact's reach of the floor
    /// ([`FloorContact::reach`]: below it for the penalty), then of collider k, numbered
    /// `(k + 1) n + i` (n points). The contact terms' Hessians change when this set does.
    pub(crate) fn contacts(&self, at: &TermPoint<'_>) -> Vec<usize> {
        let mut contacts = Vec::new();
        if let Some(floor) = &self.floor {
            contacts.extend(floor.contacts(at));
        }
        if let Some(colliders) = &self.colliders {
            contacts.extend(colliders.contacts(at));
        }
        contacts
    }
}

impl Scene {
    /// Checks that the scene fits `model` (what [`crate::Simulator::new`] checks), without
    /// giving the model away: pin indices in range and non-empty, finite gravity, a valid floor,
    /// valid penalty factors.
    ///
    /// # Errors
    /// The first [`SceneError`] found.
    pub fn validate<M: HyperelasticMaterial>(
        &self,
        model: &ReducedModel<M>,
        penalty: &PenaltyParams,
    ) -> Result<(), SceneError> {
        SceneTerms::new(model, self, penalty).map(|_| ())
    }
}

/// The penalty factors finite and positive, and the barrier distance too.
fn check_penalty(penalty: &PenaltyParams) -> Result<(), SceneError> {
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
    Ok(())
}

/// `floor` with a unit normal, after checking it and its friction with slip speed
/// `slip_speed` (m/s).
fn unit_floor(floor: Floor, slip_speed: f64) -> Result<Floor, SceneError> {
    let norm = floor.normal.norm();
    if !(norm > 0.0 && norm.is_finite() && floor.offset.is_finite()) {
        return Err(SceneError::Floor {
            normal: floor.normal.into(),
            offset: floor.offset,
        });
    }
    let friction_valid = floor.friction >= 0.0 && floor.friction.is_finite();
    let slip_valid = slip_speed > 0.0 && slip_speed.is_finite();
    if !(friction_valid && slip_valid) {
        return Err(SceneError::Friction {
            friction: floor.friction,
            slip_speed,
        });
    }
    Ok(Floor {
        normal: floor.normal / norm,
        offset: floor.offset / norm,
        friction: floor.friction,
    })
}

/// Every collider well formed, their parents a chain, and every mesh band wider than the
/// contact's reach.
fn check_colliders(scene: &Scene, contact: FloorContact) -> Result<(), SceneError> {
    if let Some((index, why)) = scene
        .colliders
        .iter()
        .enumerate()
        .find_map(|(i, c)| c.defect().map(|why| (i, why)))
    {
        return Err(SceneError::Collider { index, why });
    }
    if let Some((index, why)) = crate::contact::collider::chain_defect(&scene.colliders) {
        return Err(SceneError::Collider { index, why });
    }
    let reach = contact.reach();
    if let Some((index, band)) =
        scene
            .colliders
            .iter()
            .enumerate()
            .find_map(|(i, c)| match &c.shape {
                ColliderShape::Mesh(mesh) if mesh.band <= reach => Some((i, mesh.band)),
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
    Ok(())
}

#[cfg(test)]
mod tests {
    use nalgebra::UnitQuaternion;

    use nalgebra::Vector3;

    use super::*;
    use crate::contact::collider::{Collider, ColliderShape, Keyframe};
    use crate::model::analytic_field::analytic_model;

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
            let at = term_point(&model, z, time);
            let e = reused.energy(&at);
            assert_eq!(e, fresh().energy(&at), "z, t = {time}");
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
                .contacts(&term_point(&model, &z, time))
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
