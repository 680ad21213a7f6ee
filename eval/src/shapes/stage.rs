//! The stages of one shape's work, which a workflow engine schedules as separate tasks: each
//! leaves its results in the cache, and the last one reads them.

use serde::{Deserialize, Serialize};

/// One stage of a shape's work in the shapes study.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum ShapeStage {
    /// Train (and cache) the Simplicits network on the shape's basis points: the longest
    /// task (minutes to hours), independent of the FEM.
    Train,
    /// Run (and cache) the FEM reference of each boundary condition.
    Reference,
    /// Run (and cache) the 1.5× finer reference of each condition, when the study checks
    /// convergence (nothing otherwise): the longest FEM runs.
    Check,
    /// Score the rows from what the cache holds (our basis and the reduced runs, seconds to
    /// minutes; nothing trained or referenced): a shard of raw rows.
    Row,
}

impl ShapeStage {
    /// Every stage, in the order a shape needs them (`row` last; `train` and `reference` are
    /// independent of each other).
    pub const ALL: [ShapeStage; 4] = [
        ShapeStage::Train,
        ShapeStage::Reference,
        ShapeStage::Check,
        ShapeStage::Row,
    ];

    /// "train", "reference", "check" or "row".
    pub fn name(self) -> &'static str {
        match self {
            ShapeStage::Train => "train",
            ShapeStage::Reference => "reference",
            ShapeStage::Check => "check",
            ShapeStage::Row => "row",
        }
    }
}

/// What a run does with each shape: everything, one stage, or only estimate the references.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum ShapeWork {
    /// Every stage: a whole study.
    Everything,
    /// One stage.
    Stage(ShapeStage),
    /// Each reference's and check's DOFs and factor memory, from their meshes and symbolic
    /// analyses; nothing trained, run or scored ([`crate::shapes::study::estimate_references`]).
    Estimate,
}
