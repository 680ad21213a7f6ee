//! A beam run that failed: what the tables say in place of its row.

use serde::{Deserialize, Serialize};

use crate::beam_scenario::BeamTest;

/// A (test, m) run that failed: the study goes on with the others and the tables name it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FailedBeamRow {
    /// Bend or Twist.
    pub test: BeamTest,
    /// Modes.
    pub m: usize,
    /// The error and its causes ([`freeform::failure_chain`]).
    pub error: String,
}
