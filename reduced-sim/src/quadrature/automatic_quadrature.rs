//! The automatic choice between every point and an optimized cubature
//! ([`crate::QuadratureRule::Automatic`]): a cubature only when its training pays for itself
//! over the run it is for.
//!
//! Given the predicted elastic time of the rest of a run on every point, `T`, the cubature is
//! trained with a budget of half what it can still save, `T/2 · (1 − S/N)` for S points held
//! so far ([`CubatureBudget`], [`SAVING_SHARE`]); if it runs past that, the run keeps every
//! point. A cubature that is kept so saves at least what it cost, and the time spent on one
//! that is not stays below half the predicted time of the steps, so a prediction off by a
//! factor of two still does not make the choice a loss. A
//! note beside the cubature's cache file records a training that ran out of its budget, so a
//! later run of about the same length does not try again.

use std::path::PathBuf;
use std::time::Instant;

use hyperelastic::HyperelasticMaterial;
use serde::{Deserialize, Serialize};

use crate::model::elastic_quadrature::ElasticQuadrature;
use crate::model::reduced_model::ReducedModel;
use crate::quadrature::cubature::{
    CubatureBudget, CubatureCacheFile, CubatureError, CubatureParams, CubatureReport,
    optimize_cubature_within,
};

/// What [`crate::QuadratureRule::Automatic`] predicted and chose.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct QuadratureChoice {
    /// Steps the choice was made for (the rest of the run).
    pub planned_steps: usize,
    /// Predicted elastic time of the run on every point (s); 0 when a cached cubature was
    /// found and nothing was predicted.
    pub predicted_full_seconds: f64,
    /// Time the cubature's training was allowed for the points it held when it finished or
    /// stopped ([`CubatureBudget::seconds`], s).
    pub budget_seconds: f64,
    /// Time spent choosing: the prediction and the training, whether kept or abandoned (s).
    pub spent_seconds: f64,
    /// Whether the run integrates on the cubature (otherwise on every point).
    pub chose_cubature: bool,
    /// Whether training was skipped because the cache notes that an earlier attempt ran out of
    /// a budget at least half as large.
    #[serde(default)]
    pub noted_over_budget: bool,
}

impl QuadratureChoice {
    /// The choice of a run of `planned_steps` steps that found its cubature in the cache:
    /// nothing predicted or trained, `spent_seconds` spent looking.
    pub fn cached(planned_steps: usize, spent_seconds: f64) -> Self {
        QuadratureChoice {
            planned_steps,
            predicted_full_seconds: 0.0,
            budget_seconds: 0.0,
            spent_seconds,
            chose_cubature: true,
            noted_over_budget: false,
        }
    }
}

/// The share of what a cubature can still save that its training may spend.
pub const SAVING_SHARE: f64 = 0.5;

/// What [`cubature_if_it_pays`] found: the cubature, if it paid, and the choice.
#[derive(Clone, Debug)]
pub struct AutomaticCubature {
    /// The cubature and its report, when it was trained within its budget.
    pub cubature: Option<(ElasticQuadrature, CubatureReport)>,
    /// What was predicted and chosen.
    pub choice: QuadratureChoice,
}

/// Trains the cubature of `params` on `model` (which must integrate over every point) for the
/// rest of a run of `steps` steps whose elastic time on every point is predicted at
/// `predicted_seconds`, within the budget of the module docs; a trained cubature is saved to
/// `cache` when one is given (the caller looks for a cached one there first,
/// [`CubatureCacheFile::load`]), and a training that ran out of its budget is noted beside it.
/// `cache` is the file of this `model` and `params` ([`CubatureCacheFile::new`]); another's
/// would store this cubature under that model's key.
///
/// # Errors
/// [`CubatureError`] other than [`CubatureError::OverBudget`] (which means every point).
pub fn cubature_if_it_pays<M: HyperelasticMaterial>(
    model: &ReducedModel<M>,
    params: &CubatureParams,
    cache: Option<&CubatureCacheFile>,
    steps: usize,
    predicted_seconds: f64,
) -> Result<AutomaticCubature, CubatureError> {
    let start = Instant::now();
    let budget = CubatureBudget {
        full_run_seconds: SAVING_SHARE * predicted_seconds,
        full_points: model.elastic_point_count(),
    };
    let mut choice = QuadratureChoice {
        planned_steps: steps,
        predicted_full_seconds: predicted_seconds,
        budget_seconds: budget.seconds(0),
        spent_seconds: 0.0,
        chose_cubature: false,
        noted_over_budget: false,
    };
    // A note that training already ran out of its budget on a run predicted at least half as
    // long (predictions are timed, so they vary a little from run to run).
    let note = cache.map(over_budget_note_path);
    let noted = note
        .as_ref()
        .and_then(|path| std::fs::read_to_string(path).ok())
        .and_then(|text| text.trim().parse::<f64>().ok())
        .is_some_and(|noted_run| 2.0 * noted_run >= predicted_seconds);
    if noted {
        choice.noted_over_budget = true;
        choice.spent_seconds = start.elapsed().as_secs_f64();
        return Ok(AutomaticCubature {
            cubature: None,
            choice,
        });
    }
    match optimize_cubature_within(model, params, &budget) {
        Ok((quadrature, report)) => {
            choice.budget_seconds = budget.seconds(quadrature.len());
            let cubature = match cache {
                Some(file) => file.save(quadrature, report),
                None => (quadrature, report),
            };
            choice.spent_seconds = start.elapsed().as_secs_f64();
            choice.chose_cubature = true;
            Ok(AutomaticCubature {
                cubature: Some(cubature),
                choice,
            })
        }
        Err(CubatureError::OverBudget { budget, .. }) => {
            if let Some(path) = &note {
                // Best effort: without the note, the next run tries again.
                let _ = path
                    .parent()
                    .map_or(Ok(()), std::fs::create_dir_all)
                    .and_then(|()| std::fs::write(path, format!("{predicted_seconds:e}\n")));
            }
            choice.budget_seconds = budget;
            choice.spent_seconds = start.elapsed().as_secs_f64();
            Ok(AutomaticCubature {
                cubature: None,
                choice,
            })
        }
        Err(e) => Err(e),
    }
}

/// Where a training that ran out of its budget is noted (the run's predicted time in s, as
/// text): beside the cubature's cache file.
fn over_budget_note_path(cache: &CubatureCacheFile) -> PathBuf {
    cache.path().with_extension("over-budget")
}
