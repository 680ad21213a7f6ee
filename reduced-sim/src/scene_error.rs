//! Why a scene does not fit a model.

use thiserror::Error;

/// The scene does not fit the model.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum SceneError {
    /// A pinned point index is not an integration point of the model.
    #[error("pinned region {region} names point {point}, but the model has {points} points")]
    PinOutOfRange {
        /// Region index in [`crate::Scene::pins`], then [`crate::Scene::held`] (counting on from the pins).
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
    /// More held regions ([`crate::Scene::held`]) than the basis has handles.
    #[error(
        "{regions} regions are held exactly, but the basis has only {handles} handles; build it with skin_eigen::build_basis_with_regions for these regions"
    )]
    TooFewHandles {
        /// Pinned regions.
        regions: usize,
        /// Handles of the basis.
        handles: usize,
    },
    /// A held region ([`crate::Scene::held`]) with a basis that was not built for it.
    #[error(
        "held region {region} is not held by the basis: at point {point}, handle {handle} has weight {weight} instead of {expected}; build the basis with skin_eigen::build_basis_with_regions for the scene's held regions, in the same order"
    )]
    RegionNotHeld {
        /// Region index in [`crate::Scene::held`].
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
        /// Index in [`crate::Scene::colliders`].
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
