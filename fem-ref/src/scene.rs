//! What acts on the FEM model: gravity, Dirichlet regions (fixed or moving), a floor.

use std::fmt;
use std::sync::Arc;

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::fem_setup_error::FemSetupError;

/// A target position (m) as a function of rest position X (m) and time t (s).
pub type NodeTargetFunction = Arc<dyn Fn(&Vector3<f64>, f64) -> Vector3<f64> + Send + Sync>;

/// Where the nodes of a Dirichlet region are.
#[derive(Clone)]
pub enum NodeTarget {
    /// At rest.
    Rest,
    /// At `f(X, t)`.
    Moving(NodeTargetFunction),
}

impl NodeTarget {
    /// Target of rest position `rest` at time `t` (m).
    pub fn at(&self, rest: &Vector3<f64>, t: f64) -> Vector3<f64> {
        match self {
            NodeTarget::Rest => *rest,
            NodeTarget::Moving(f) => f(rest, t),
        }
    }
}

impl fmt::Debug for NodeTarget {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            NodeTarget::Rest => write!(f, "Rest"),
            NodeTarget::Moving(_) => write!(f, "Moving(<function>)"),
        }
    }
}

/// Nodes whose positions are prescribed exactly (Dirichlet conditions, all three components).
#[derive(Clone, Debug)]
pub struct DirichletRegion {
    /// Node indices.
    pub nodes: Vec<usize>,
    /// Their prescribed positions.
    pub target: NodeTarget,
}

/// The half-space `{x : n·x ≥ offset}` (a floor when n = +y), enforced on nodes by a penalty
/// `κ/2 Σ_a v_a max(0, offset - n·x_a)²`, `κ = floor_factor · E_ref / L²`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FemFloor {
    /// Unit normal into the allowed side.
    pub normal: Vector3<f64>,
    /// Plane offset (m).
    pub offset: f64,
    /// Stiffness factor (dimensionless; 1e4 matches the reduced simulator's default).
    pub floor_factor: f64,
}

/// Everything acting on the model.
#[derive(Clone, Debug, Default)]
pub struct FemScene {
    /// Gravitational acceleration (m/s²), or none.
    pub gravity: Option<Vector3<f64>>,
    /// Dirichlet regions.
    pub dirichlet: Vec<DirichletRegion>,
    /// Optional floor.
    pub floor: Option<FemFloor>,
}

impl FemScene {
    /// Which of a model's `nodes` nodes the Dirichlet regions hold (`held[a]` for node a); the
    /// free DOFs are three per node not held.
    ///
    /// # Errors
    /// [`FemSetupError::NodeOutOfRange`] for a region naming a node past `nodes`,
    /// [`FemSetupError::NothingFree`] when every node is held.
    pub fn held_nodes(&self, nodes: usize) -> Result<Vec<bool>, FemSetupError> {
        let mut held = vec![false; nodes];
        for (region, d) in self.dirichlet.iter().enumerate() {
            for &node in &d.nodes {
                if node >= nodes {
                    return Err(FemSetupError::NodeOutOfRange {
                        region,
                        node,
                        nodes,
                    });
                }
                held[node] = true;
            }
        }
        if held.iter().all(|&h| h) {
            return Err(FemSetupError::NothingFree);
        }
        Ok(held)
    }

    /// The free DOFs of a model of `nodes` nodes under this scene: three per node no Dirichlet
    /// region holds (what [`crate::FemSimulator::free_dofs`] reports once built; known here
    /// without building the system, e.g. for a trajectory loaded from the cache).
    ///
    /// # Errors
    /// As [`Self::held_nodes`].
    pub fn free_dofs(&self, nodes: usize) -> Result<usize, FemSetupError> {
        let held = self.held_nodes(nodes)?;
        Ok(3 * held.iter().filter(|&&h| !h).count())
    }
}
