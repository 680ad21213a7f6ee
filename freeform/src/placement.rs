//! Where an object starts in the world and how fast it moves.

use std::sync::Arc;

use nalgebra::{UnitQuaternion, Vector3};
use reduced_sim::{PinTarget, ReducedLayout, ReducedState, Scene};

/// An object's rest frame placed in the world, `x = R X + p`, moving at a uniform velocity:
/// the state a run of it starts from. Its constraints' targets (given in its rest frame) move
/// with it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    /// R.
    pub rotation: UnitQuaternion<f64>,
    /// p (m).
    pub position: Vector3<f64>,
    /// Initial velocity of every point (m/s).
    pub velocity: Vector3<f64>,
}

impl Default for Placement {
    /// At rest where it was made: R = I, p = 0, no velocity.
    fn default() -> Self {
        Placement {
            rotation: UnitQuaternion::identity(),
            position: Vector3::zeros(),
            velocity: Vector3::zeros(),
        }
    }
}

impl Placement {
    /// Whether every entry is finite.
    pub fn is_finite(&self) -> bool {
        self.position
            .iter()
            .chain(&self.velocity)
            .chain(self.rotation.coords.iter())
            .all(|v| v.is_finite())
    }

    /// The reduced state of this placement on `layout` at t = 0.
    pub fn state(&self, layout: &ReducedLayout) -> ReducedState {
        let rotation = self.rotation.to_rotation_matrix().into_inner();
        ReducedState {
            z: layout.rigid_motion(&rotation, &self.position),
            velocity: layout.uniform_velocity(&self.velocity),
            time: 0.0,
        }
    }

    /// `scene` with every pinned and held region's targets carried into the world,
    /// `t ↦ R t + p` (nothing to do at the identity).
    pub fn place(&self, mut scene: Scene) -> Scene {
        if self.rotation == UnitQuaternion::identity() && self.position == Vector3::zeros() {
            return scene;
        }
        let (rotation, position) = (self.rotation, self.position);
        for region in scene.pins.iter_mut().chain(scene.held.iter_mut()) {
            let target = region.target.clone();
            region.target =
                PinTarget::Moving(Arc::new(move |x, t| rotation * target.at(x, t) + position));
        }
        scene
    }
}
