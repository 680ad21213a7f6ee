//! The shapes study as tasks of a workflow engine: the plan it schedules ([`TaskPlan`]) and
//! the receipt a task leaves when it has finished ([`Receipt`]).

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::shapes::boundary::ShapeBoundary;
use crate::shapes::catalog::{MaterialClass, catalog_entry};
use crate::shapes::config::ShapeStudyConfig;
use crate::shapes::result::{ShapeStudy, mesh_name};
use crate::shapes::shard::{Provenance, row_settings, settings_key};
use crate::shapes::stage::ShapeStage;
use freeform::fem_reference::ReferenceEstimate;

/// One shape of the plan.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlannedShape {
    /// Its index in table order (`--shard i/n` takes the indices `i`, `i + n`, …).
    pub index: usize,
    /// File name (what `--only` takes).
    pub name: String,
    /// The file.
    pub file: PathBuf,
    /// Young's modulus (Pa) the study gives it.
    pub youngs_modulus: f64,
    /// Its material class, if catalogued.
    pub class: Option<MaterialClass>,
}

/// One task: one stage of one shape, and the stages it waits for.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlannedTask {
    /// The shape's file name.
    pub shape: String,
    /// The stage.
    pub stage: ShapeStage,
    /// Stages of the same shape that must finish first.
    pub after: Vec<ShapeStage>,
}

/// What a workflow engine schedules for a shapes study.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TaskPlan {
    /// [`settings_key`] of the study.
    pub settings_key: String,
    /// The shapes, in table order.
    pub shapes: Vec<PlannedShape>,
    /// The boundary conditions every shape runs.
    pub boundaries: Vec<ShapeBoundary>,
    /// The stages each shape needs (`check` only when the study checks convergence, `train`
    /// only with the baseline).
    pub stages: Vec<ShapeStage>,
    /// Every (shape, stage) task with what it waits for.
    pub tasks: Vec<PlannedTask>,
    /// The study's [`row_settings`].
    pub settings: ShapeStudyConfig,
    /// With `--estimate`: what each reference and check needs ([`TaskPlan::with_estimates`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub estimates: Option<PlanEstimates>,
}

/// What one (shape, condition)'s `reference` and `check` tasks need, known before their
/// numeric work.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReferenceTaskEstimate {
    /// The shape's file name.
    pub shape: String,
    /// The condition.
    pub boundary: ShapeBoundary,
    /// The reference's DOFs and factor memory, if its mesh and scene could be built.
    pub reference: Option<ReferenceEstimate>,
    /// The convergence check's, when the study checks convergence.
    pub check: Option<ReferenceEstimate>,
    /// Why an estimate is missing.
    pub error: Option<String>,
}

/// The estimates of a plan, and the largest of them: what a scheduler sizes its memory by.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlanEstimates {
    /// One entry per (shape, condition), in table order.
    pub references: Vec<ReferenceTaskEstimate>,
    /// The most bytes any `reference` task's factors need.
    pub largest_reference_bytes: u64,
    /// The most bytes any `check` task's factors need (0 without checks).
    pub largest_check_bytes: u64,
    /// Tasks whose factors do not fit in the memory available where the estimate was made.
    pub too_large_here: Vec<String>,
}

impl TaskPlan {
    /// The plan of `config` (its `meshes` are the study's shapes).
    pub fn new(config: &ShapeStudyConfig) -> Self {
        let stages: Vec<ShapeStage> = ShapeStage::ALL
            .into_iter()
            .filter(|s| match s {
                ShapeStage::Train => config.simplicits.is_some(),
                ShapeStage::Check => config.check_convergence,
                _ => true,
            })
            .collect();
        let shapes: Vec<PlannedShape> = config
            .meshes
            .iter()
            .enumerate()
            .map(|(index, file)| {
                let name = mesh_name(file);
                let entry = catalog_entry(&name);
                PlannedShape {
                    index,
                    youngs_modulus: entry
                        .map_or(config.default_youngs_modulus, |e| e.class.youngs_modulus()),
                    class: entry.map(|e| e.class),
                    name,
                    file: file.clone(),
                }
            })
            .collect();
        let tasks = shapes
            .iter()
            .flat_map(|shape| {
                stages.iter().map(|&stage| PlannedTask {
                    shape: shape.name.clone(),
                    stage,
                    after: match stage {
                        ShapeStage::Check => vec![ShapeStage::Reference],
                        ShapeStage::Row => stages
                            .iter()
                            .copied()
                            .filter(|&s| s != ShapeStage::Row)
                            .collect(),
                        _ => Vec::new(),
                    },
                })
            })
            .collect();
        TaskPlan {
            settings_key: settings_key(config),
            shapes,
            boundaries: config.boundaries.clone(),
            stages,
            tasks,
            settings: row_settings(config),
            estimates: None,
        }
    }

    /// This plan with the estimates of `study` ([`crate::shapes::study::estimate_references`]
    /// of the plan's study).
    pub fn with_estimates(self, study: &ShapeStudy) -> Self {
        let references: Vec<ReferenceTaskEstimate> = study
            .shapes
            .iter()
            .flat_map(|shape| {
                let rows: Vec<ReferenceTaskEstimate> = shape
                    .rows
                    .iter()
                    .map(|row| ReferenceTaskEstimate {
                        shape: shape.name.clone(),
                        boundary: row.boundary,
                        reference: row.reference_estimate,
                        check: row.check_estimate,
                        error: row
                            .error
                            .clone()
                            .or_else(|| row.reference_check_error.clone()),
                    })
                    .collect();
                match &shape.error {
                    Some(e) if rows.is_empty() => vec![ReferenceTaskEstimate {
                        shape: shape.name.clone(),
                        boundary: ShapeBoundary::FixSide,
                        reference: None,
                        check: None,
                        error: Some(format!("the shape: {e}")),
                    }],
                    _ => rows,
                }
            })
            .collect();
        let largest = |pick: fn(&ReferenceTaskEstimate) -> Option<ReferenceEstimate>| {
            references
                .iter()
                .filter_map(pick)
                .map(|e| e.factor_bytes)
                .max()
                .unwrap_or(0)
        };
        let too_large_here = references
            .iter()
            .flat_map(|r| {
                [("reference", r.reference), ("check", r.check)]
                    .into_iter()
                    .filter(|(_, e)| e.is_some_and(|e| !e.fits_here))
                    .map(|(stage, _)| format!("{} {} {stage}", r.shape, r.boundary.name()))
            })
            .collect();
        TaskPlan {
            estimates: Some(PlanEstimates {
                largest_reference_bytes: largest(|r| r.reference),
                largest_check_bytes: largest(|r| r.check),
                too_large_here,
                references,
            }),
            ..self
        }
    }
}

/// What a task leaves when it has finished (written last, so its presence means the task's
/// outputs are complete).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Receipt {
    /// The shapes the task ran (file names).
    pub shapes: Vec<String>,
    /// Its stage, or `None` for every stage at once.
    pub stage: Option<ShapeStage>,
    /// The boundary conditions it ran.
    pub boundaries: Vec<ShapeBoundary>,
    /// Files it wrote besides the cache (a shard).
    pub wrote: Vec<PathBuf>,
    /// The cache it filled or read.
    pub cache_dir: PathBuf,
    /// [`settings_key`] of the study.
    pub settings_key: String,
    /// Where and when it ran.
    pub provenance: Provenance,
}
