//! One scene description, translated into each solver's inputs: the reduced simulator's and
//! the FEM reference's, so that every method sees the same problem.
//!
//! A [`SceneSpec`] says what acts on the object: gravity, constrained regions with a motion, a
//! floor. [`SceneSpec::reduced_scene`] selects the reduced model's integration points in each
//! region and `SceneSpec::fem_scene` (feature `fem`) selects the FEM nodes; both receive the same target
//! function [`Motion::at`], so every method sees the same problem.

use std::sync::Arc;

#[cfg(feature = "fem")]
use fem_ref::{DirichletRegion, FemFloor, FemScene, NodeTarget};
use nalgebra::{Rotation3, Unit, Vector3};
use reduced_sim::{Collider, Floor, PinTarget, PinnedRegion, Scene, TargetFunction};
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Points closer than this to a region's boundary plane count as inside it (m). design §4.1:
/// FEM nodes on the plane x = 0.5 are pinned.
pub const REGION_TOLERANCE: f64 = 1e-9;

/// A closed region of rest space.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Region {
    /// `x[axis] ≤ value` (plus [`REGION_TOLERANCE`]).
    Below {
        /// 0, 1 or 2 for x, y, z.
        axis: usize,
        /// Plane position (m).
        value: f64,
    },
    /// `x[axis] ≥ value` (minus [`REGION_TOLERANCE`]).
    Above {
        /// 0, 1 or 2 for x, y, z.
        axis: usize,
        /// Plane position (m).
        value: f64,
    },
    /// `|x − center| ≤ radius` (plus [`REGION_TOLERANCE`]).
    Ball {
        /// Centre (m).
        center: Vector3<f64>,
        /// Radius (m), positive.
        radius: f64,
    },
}

impl Region {
    /// Whether rest position `x` lies in the region.
    pub fn contains(&self, x: &Vector3<f64>) -> bool {
        match *self {
            Region::Below { axis, value } => x[axis] <= value + REGION_TOLERANCE,
            Region::Above { axis, value } => x[axis] >= value - REGION_TOLERANCE,
            Region::Ball { center, radius } => (x - center).norm() <= radius + REGION_TOLERANCE,
        }
    }

    /// Why the region is malformed (an axis above 2, a non-finite plane, a ball that is not
    /// finite or not of positive radius), if it is.
    pub fn defect(&self) -> Option<String> {
        match *self {
            Region::Below { axis, value } | Region::Above { axis, value } => {
                if axis > 2 {
                    Some(format!("axis is {axis}, must be 0, 1 or 2"))
                } else if !value.is_finite() {
                    Some(format!("plane position {value} is not finite"))
                } else {
                    None
                }
            }
            Region::Ball { center, radius } => (!(radius > 0.0
                && radius.is_finite()
                && center.iter().all(|c| c.is_finite())))
            .then(|| {
                format!("ball about {center:?} of radius {radius} is not finite and positive")
            }),
        }
    }
}

/// How a constrained region moves: its target position as a function of rest position and time.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Motion {
    /// Held at rest.
    Rest,
    /// Rotated about the line through `center` along `axis` by
    /// `θ(t) = min(rate · t, max_angle)` (degrees/s, degrees; right-handed about `axis`).
    Rotate {
        /// A point on the rotation axis (m).
        center: Vector3<f64>,
        /// Axis direction (normalized on use).
        axis: Vector3<f64>,
        /// Angular speed (degrees/s).
        rate_degrees_per_second: f64,
        /// Angle at which the rotation stops (degrees).
        max_angle_degrees: f64,
    },
    /// Translated with constant velocity: `X + v t` (m/s).
    Translate {
        /// Velocity (m/s).
        velocity: Vector3<f64>,
    },
}

impl Motion {
    /// Target position of the rest point `x` at time `t` (m).
    pub fn at(&self, x: &Vector3<f64>, t: f64) -> Vector3<f64> {
        match self {
            Motion::Rest => *x,
            Motion::Rotate {
                center,
                axis,
                rate_degrees_per_second,
                max_angle_degrees,
            } => {
                let angle = (rate_degrees_per_second * t).min(*max_angle_degrees);
                let r = Rotation3::from_axis_angle(&Unit::new_normalize(*axis), angle.to_radians());
                center + r * (x - center)
            }
            Motion::Translate { velocity } => x + velocity * t,
        }
    }

    /// [`Motion::at`] as the target closure both solvers take, or `None` for [`Motion::Rest`]
    /// (which the solvers treat without a function call).
    pub fn target_function(&self) -> Option<TargetFunction> {
        match self {
            Motion::Rest => None,
            motion => {
                let motion = motion.clone();
                Some(Arc::new(move |x, t| motion.at(x, t)))
            }
        }
    }
}

/// A region and how it moves.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Constraint {
    /// Where.
    pub region: Region,
    /// How.
    pub motion: Motion,
}

/// A floor half-space `n · x ≥ offset`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FloorSpec {
    /// Outward normal (normalized on use).
    pub normal: Vector3<f64>,
    /// Plane offset (m).
    pub offset: f64,
    /// Coulomb friction coefficient μ (default 0), for the reduced simulator
    /// ([`reduced_sim::Floor::friction`]); the FEM reference's floor is frictionless and
    /// refuses a floor with friction ([`SceneSpecError::FemFriction`]).
    #[serde(default)]
    pub friction: f64,
}

/// Everything that acts on the object, independent of the solver.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneSpec {
    /// Gravitational acceleration (m/s²), if any.
    #[serde(default)]
    pub gravity: Option<Vector3<f64>>,
    /// Constrained regions (pinned or moving).
    #[serde(default)]
    pub constraints: Vec<Constraint>,
    /// Floor, if any.
    #[serde(default)]
    pub floor: Option<FloorSpec>,
    /// Kinematic colliders (sphere, box, capsule on keyframed rigid paths) that push and rub
    /// the object; reduced simulator only (the FEM reference refuses them,
    /// [`SceneSpecError::FemColliders`]).
    #[serde(default)]
    pub colliders: Vec<Collider>,
}

/// A scene cannot be applied.
#[derive(Debug, Error, PartialEq)]
pub enum SceneSpecError {
    /// A region selects no point of the discretization.
    #[error("constraint {index} ({region:?}) selects none of the {available} {what}")]
    EmptyRegion {
        /// Constraint index.
        index: usize,
        /// The region.
        region: Region,
        /// "integration points" or "FEM nodes".
        what: &'static str,
        /// How many there were.
        available: usize,
    },
    /// An axis index above 2, a zero rotation axis or floor normal, or a non-finite value.
    #[error("invalid scene: {0}")]
    Invalid(String),
    /// The FEM reference has no friction model: a floor with friction cannot be compared.
    #[error(
        "the FEM reference's floor is frictionless; this scene's floor has friction μ = {friction}"
    )]
    FemFriction {
        /// μ of the floor.
        friction: f64,
    },
    /// The FEM reference has no kinematic colliders.
    #[error("the FEM reference has no colliders; this scene has {colliders}")]
    FemColliders {
        /// How many the scene has.
        colliders: usize,
    },
}

impl SceneSpec {
    /// Checks axes, directions and finiteness.
    ///
    /// # Errors
    /// [`SceneSpecError::Invalid`] naming the field.
    pub fn validate(&self) -> Result<(), SceneSpecError> {
        let finite = |v: &Vector3<f64>| v.iter().all(|c| c.is_finite());
        if let Some(g) = &self.gravity
            && !finite(g)
        {
            return Err(SceneSpecError::Invalid(format!(
                "gravity {g:?} is not finite"
            )));
        }
        for (i, c) in self.constraints.iter().enumerate() {
            if let Some(defect) = c.region.defect() {
                return Err(SceneSpecError::Invalid(format!(
                    "constraints[{i}].region: {defect}"
                )));
            }
            if let Motion::Rotate { axis, center, .. } = &c.motion
                && (!(axis.norm() > 0.0) || !finite(axis) || !finite(center))
            {
                return Err(SceneSpecError::Invalid(format!(
                    "constraints[{i}].motion: rotation axis {axis:?} about {center:?} is zero or not finite"
                )));
            }
        }
        if let Some(f) = &self.floor
            && (!(f.normal.norm() > 0.0) || !finite(&f.normal) || !f.offset.is_finite())
        {
            return Err(SceneSpecError::Invalid(format!(
                "floor normal {:?} / offset {} is zero or not finite",
                f.normal, f.offset
            )));
        }
        if let Some((i, why)) = self
            .colliders
            .iter()
            .enumerate()
            .find_map(|(i, c)| c.defect().map(|why| (i, why)))
            .or_else(|| reduced_sim::chain_defect(&self.colliders))
        {
            return Err(SceneSpecError::Invalid(format!("colliders[{i}]: {why}")));
        }
        if let Some(f) = &self.floor
            && !(f.friction >= 0.0 && f.friction.is_finite())
        {
            return Err(SceneSpecError::Invalid(format!(
                "floor friction {} is negative or not finite",
                f.friction
            )));
        }
        Ok(())
    }

    /// A stable text naming every part of the scene, for cache keys. Fields added after the
    /// first caches (floor friction, colliders) appear only when they differ from their
    /// defaults, so the keys of scenes without them did not change.
    pub fn label(&self) -> String {
        let floor = match &self.floor {
            None => "None".to_string(),
            Some(f) if f.friction == 0.0 => format!(
                "Some(FloorSpec {{ normal: {:?}, offset: {:?} }})",
                f.normal, f.offset
            ),
            Some(f) => format!("Some({f:?})"),
        };
        let mut label = format!(
            "SceneSpec {{ gravity: {:?}, constraints: {:?}, floor: {floor}",
            self.gravity, self.constraints
        );
        if !self.colliders.is_empty() {
            label += &format!(", colliders: {:?}", self.colliders);
        }
        label + " }"
    }

    /// Indices of `points` in each constraint's region.
    ///
    /// # Errors
    /// [`SceneSpecError::EmptyRegion`] if a region selects nothing.
    pub fn select(
        &self,
        points: &[Vector3<f64>],
        what: &'static str,
    ) -> Result<Vec<Vec<usize>>, SceneSpecError> {
        self.validate()?;
        self.constraints
            .iter()
            .enumerate()
            .map(|(index, c)| {
                let selected: Vec<usize> = (0..points.len())
                    .filter(|&i| c.region.contains(&points[i]))
                    .collect();
                if selected.is_empty() {
                    Err(SceneSpecError::EmptyRegion {
                        index,
                        region: c.region.clone(),
                        what,
                        available: points.len(),
                    })
                } else {
                    Ok(selected)
                }
            })
            .collect()
    }

    /// The reduced simulator's scene on integration points `points` (the model's rest positions).
    ///
    /// # Errors
    /// As [`SceneSpec::select`].
    pub fn reduced_scene(&self, points: &[Vector3<f64>]) -> Result<Scene, SceneSpecError> {
        let selections = self.select(points, "integration points")?;
        Ok(Scene {
            gravity: self.gravity,
            pins: self
                .constraints
                .iter()
                .zip(selections)
                .map(|(c, points)| PinnedRegion {
                    points,
                    target: c
                        .motion
                        .target_function()
                        .map_or(PinTarget::Rest, PinTarget::Moving),
                })
                .collect(),
            floor: self.floor.map(|f| Floor {
                normal: f.normal.normalize(),
                offset: f.offset,
                friction: f.friction,
            }),
            held: Vec::new(),
            colliders: self.colliders.clone(),
        })
    }

    /// The FEM reference's scene on nodes `nodes` (rest positions), with the floor penalty
    /// factor `floor_factor` (feature `fem`).
    ///
    /// # Errors
    /// As [`SceneSpec::select`]; [`SceneSpecError::FemFriction`] for a floor with friction,
    /// [`SceneSpecError::FemColliders`] for colliders.
    #[cfg(feature = "fem")]
    pub fn fem_scene(
        &self,
        nodes: &[Vector3<f64>],
        floor_factor: f64,
    ) -> Result<FemScene, SceneSpecError> {
        if let Some(f) = &self.floor
            && f.friction != 0.0
        {
            return Err(SceneSpecError::FemFriction {
                friction: f.friction,
            });
        }
        if !self.colliders.is_empty() {
            return Err(SceneSpecError::FemColliders {
                colliders: self.colliders.len(),
            });
        }
        let selections = self.select(nodes, "FEM nodes")?;
        Ok(FemScene {
            gravity: self.gravity,
            dirichlet: self
                .constraints
                .iter()
                .zip(selections)
                .map(|(c, nodes)| DirichletRegion {
                    nodes,
                    target: c
                        .motion
                        .target_function()
                        .map_or(NodeTarget::Rest, NodeTarget::Moving),
                })
                .collect(),
            floor: self.floor.map(|f| FemFloor {
                normal: f.normal.normalize(),
                offset: f.offset,
                floor_factor,
            }),
        })
    }
}
