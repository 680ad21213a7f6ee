//! The external terms of a scene, each present only when the scene has it (design §3.7):
//! gravity, pinned or moving points, a floor half-space.

use std::fmt;
use std::sync::Arc;

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::contact::collider::Collider;

/// A target position (m) as a function of rest position X (m) and time t (s).
pub type TargetFunction = Arc<dyn Fn(&Vector3<f64>, f64) -> Vector3<f64> + Send + Sync>;

/// Where pinned points must be.
#[derive(Clone)]
pub enum PinTarget {
    /// At their rest positions (a fixed region).
    Rest,
    /// At `f(X, t)`: a moving handle such as the beam Twist's rotating end.
    Moving(TargetFunction),
}

impl PinTarget {
    /// The target of rest point `rest` at time `t` (m).
    pub fn at(&self, rest: &Vector3<f64>, t: f64) -> Vector3<f64> {
        match self {
            PinTarget::Rest => *rest,
            PinTarget::Moving(f) => f(rest, t),
        }
    }
}

impl fmt::Debug for PinTarget {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PinTarget::Rest => write!(f, "Rest"),
            PinTarget::Moving(_) => write!(f, "Moving(<function>)"),
        }
    }
}

/// A set of integration points held at targets by a penalty.
#[derive(Clone, Debug)]
pub struct PinnedRegion {
    /// Indices of the pinned integration points (see
    /// [`crate::ReducedModel::points_where`]).
    pub points: Vec<usize>,
    /// Where they must be.
    pub target: PinTarget,
}

/// The half-space `{x : n·x ≥ offset}` the object must stay in (a floor when n = +y).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Floor {
    /// Unit normal n, pointing into the allowed side.
    pub normal: Vector3<f64>,
    /// Offset (m): the plane is `n·x = offset`.
    pub offset: f64,
    /// Coulomb friction coefficient μ (dimensionless, default 0: frictionless), smoothed and
    /// lagged as in IPC (see [`PenaltyParams::friction_slip_speed`]).
    #[serde(default)]
    pub friction: f64,
}

impl Floor {
    /// A point's gap to the plane, `n·x − offset` (m): its height above a floor with a unit
    /// normal, negative below it.
    pub fn gap(&self, x: &Vector3<f64>) -> f64 {
        self.normal.dot(x) - self.offset
    }
}

/// Everything outside the object that acts on it.
#[derive(Clone, Debug, Default)]
pub struct Scene {
    /// Gravitational acceleration g (m/s²), e.g. `(0, -9.8, 0)`; `None` for no gravity term.
    pub gravity: Option<Vector3<f64>>,
    /// Pinned and moving regions.
    pub pins: Vec<PinnedRegion>,
    /// An optional floor.
    pub floor: Option<Floor>,
    /// Regions held exactly: each moves by the affine transform that best fits its
    /// targets, carried by handles the basis holds for it and eliminated from Newton, so the
    /// region sits on its targets whenever they are an affine motion of it (rest, rigid
    /// motions, the Twist's rotating end). Needs a basis built for these regions, in this order
    /// ([`skin_eigen::build_basis_with_regions`]); empty by default. [`Scene::pins`] keep their
    /// penalty beside them (e.g. on the band between a held region and the region's boundary).
    pub held: Vec<PinnedRegion>,
    /// Kinematic colliders: rigid shapes on prescribed paths that push the object
    /// (penalty on their signed distance, with the floor's stiffness) and rub it (their
    /// friction coefficient, the floor's friction model); empty by default.
    pub colliders: Vec<Collider>,
}

/// Penalty stiffnesses, scale-aware: with `L` the largest side of the object's rest bounding
/// box (m), `E_pin` the largest modulus of [`PenaltyParams::pin_modulus`] over the object and
/// `E_floor` its largest p-wave modulus λ + 2μ (Pa),
///
/// ```text
/// κ_pin   = pin_factor   · E_pin / L²     E_pin   = κ_pin/2   Σ_{i pinned} v_i |x_i - target_i|²
/// κ_floor = floor_factor · E_floor / L²   E_floor = κ_floor/2 Σ_i v_i max(0, offset - n·x_i)²
/// ```
///
/// (κ in Pa/m², energies in J). With these rules, a pinned region deviates from its target by
/// roughly `strain · L / factor` under the elastic forces acting on it, whatever the units or
/// size of the object.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PenaltyParams {
    /// Pin stiffness factor (dimensionless, default 3e3 with [`PinModulus::Young`]).
    ///
    /// Chosen against the converged FEM (`freeform-paper pins`: beam Bend and Twist, m = 16 and 32,
    /// ν = 0.3 / 0.45 / 0.49, factors 1e2 … 3e4 under both moduli): E · 3e3 has the lowest
    /// geometric-mean MSE over the sweep's ten scored runs together with E · 1e3 (both 1.8×
    /// below the former tables' rule, (λ + 2μ) · 1e3), beats that rule in 9 of the 10 runs, and
    /// puts the beam Bend tip at t = 0.5 / 1.0 s within 2.0 / 9.0% of the FEM at m = 16 and
    /// 0.6 / 2.1% at m = 32 (`reduced_beam_bend` example). The former library default,
    /// (λ + 2μ) · 1e4, was 6.6 / 27.6% too stiff at m = 16. The penalty's best factor still
    /// moves with ν and m: its softness cancels part of the subspace's stiffness.
    pub pin_factor: f64,
    /// Floor stiffness factor (dimensionless, default 1e4).
    pub floor_factor: f64,
    /// The modulus the pin stiffness scales with (default [`PinModulus::Young`]: the same
    /// factor gives the same pin drift at every ν).
    #[serde(default)]
    pub pin_modulus: PinModulus,
    /// Slip speed ε_v (m/s, default 1e-3, IPC's) at which floor friction reaches its Coulomb
    /// limit μλ. Below it friction is smoothed: a contact loaded tangentially by a fraction
    /// s < 1 of μλ creeps at `(1 − sqrt(1 − s)) ε_v` instead of sticking (a block on a 30°
    /// incline with μ = 0.7, s = 0.82, creeps about 0.6 mm/s). Normal forces are lagged: each
    /// step uses the floor's forces at its start.
    #[serde(default = "default_friction_slip_speed")]
    pub friction_slip_speed: f64,
    /// How many times a step with floor friction is solved again with the contacts and normal
    /// forces of its last solution (default 2; 0: the forces at the start of the step only, so
    /// a body landing in a step slides freely through it).
    #[serde(default = "default_friction_lag_iterations")]
    pub friction_lag_iterations: usize,
    /// How the floor and the colliders push back (default [`FloorContact::Penalty`]).
    #[serde(default)]
    pub floor_contact: FloorContact,
}

/// How the floor and the kinematic colliders push an integration point back, as a function of
/// its gap g (m: `n·x − offset` above the floor, the signed distance φ outside a collider),
/// with κ = [`PenaltyParams::floor_factor`] · (λ + 2μ) / L² (Pa/m²) and v the point's volume:
///
/// ```text
/// penalty:  e(g) = κ v ½ g²                         (g < 0; nothing at g ≥ 0)
/// barrier:  e(g) = κ v b(g),  b = −(g − d̂)² ln(g/d̂)  (0 < g < d̂; +∞ at g ≤ 0)
/// ```
///
/// The penalty lets points in by a depth that falls as 1/κ; the barrier (IPC's, as between
/// objects, [`crate::BodyContactModel::Barrier`]) never does: Newton's line search stops each
/// iteration short of the floor and the colliders ([`crate::Simulator::step`]), and a point
/// rests a little inside the distance d̂ instead.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FloorContact {
    /// The quadratic penalty on the depth (default, the paper's).
    #[default]
    Penalty,
    /// IPC's log barrier, active within `distance` of the floor or a collider.
    Barrier {
        /// d̂ (m): points closer than this are pushed back.
        distance: f64,
    },
}

impl FloorContact {
    /// The gap (m) below which a point is in contact: 0 for the penalty, d̂ for the barrier.
    pub fn reach(&self) -> f64 {
        match *self {
            FloorContact::Penalty => 0.0,
            FloorContact::Barrier { distance } => distance,
        }
    }

    /// `(ψ, ψ', ψ'')` (m², m, 1) at gap g (m), with e = κ v ψ(g): zero from the reach on; for
    /// the barrier at g ≤ 0, `(+∞, NaN, NaN)` (a state Newton's line search never accepts).
    pub fn profile(&self, gap: f64) -> (f64, f64, f64) {
        if gap >= self.reach() {
            return (0.0, 0.0, 0.0);
        }
        match *self {
            FloorContact::Penalty => (0.5 * gap * gap, gap, 1.0),
            FloorContact::Barrier { .. } if gap <= 0.0 => (f64::INFINITY, f64::NAN, f64::NAN),
            FloorContact::Barrier { distance } => {
                crate::contact::log_barrier::log_barrier(gap, distance)
            }
        }
    }
}

fn default_friction_slip_speed() -> f64 {
    1e-3
}

fn default_friction_lag_iterations() -> usize {
    2
}

/// Which material modulus scales the pin penalty.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PinModulus {
    /// λ + 2μ: grows without bound as ν → 1/2, so the same factor pins a nearly
    /// incompressible object far more stiffly (relative to its bending) than a compressible one
    /// (the rule of the first tables, with factor 1e3).
    PWave,
    /// Young's modulus E (default; at most 3μ as ν → 1/2): the same factor gives about the same
    /// pin drift relative to the deformation at any ν.
    #[default]
    Young,
}

impl Default for PenaltyParams {
    fn default() -> Self {
        PenaltyParams {
            pin_factor: 3e3,
            floor_factor: 1e4,
            pin_modulus: PinModulus::Young,
            friction_slip_speed: default_friction_slip_speed(),
            friction_lag_iterations: default_friction_lag_iterations(),
            floor_contact: FloorContact::Penalty,
        }
    }
}
