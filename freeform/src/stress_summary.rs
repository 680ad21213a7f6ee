//! The stress of a run over the frames it wrote.

use serde::{Deserialize, Serialize};

/// The stress of a run over its written frames (`simulation.stress = true`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StressSummary {
    /// Largest von Mises stress at an integration point (Pa).
    pub max_von_mises: f64,
    /// Largest von Mises stress at an output vertex or cloud point (Pa).
    pub max_von_mises_output: f64,
    /// The most points (integration and output together) with det F ≤ 0 in one frame.
    pub most_inverted: usize,
}
