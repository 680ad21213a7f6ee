//! The elastic quadrature: which integration points, with which non-negative weights, carry the
//! elastic energy `E_el(z) ≈ Σ_{q ∈ Q} w_q Ψ(F_q(z))` (design §3.7).
//!
//! Mass, gravity, pins and the floor always use every integration point with its volume; only
//! the elastic energy, its gradient and its Hessian (the cost of a step) move to the quadrature.
//! Three kinds:
//! - every point with its volume ([`ElasticQuadrature::full`], the paper's setting and the
//!   default of a [`crate::ReducedModel`]);
//! - a random subset, volumes rescaled to the total ([`ElasticQuadrature::random_subset`]);
//! - an optimized cubature (An, Kim and James 2008; [`crate::quadrature::cubature`]).
//!
//! [`QuadratureRule::Automatic`] chooses between the first and the last for a run of known
//! length: a cubature only when its training pays for itself in the run's steps
//! ([`crate::quadrature::elastic_cost`]).

use hyperelastic::HyperelasticMaterial;
use serde::{Deserialize, Serialize};

use std::path::Path;
use std::time::Instant;

use crate::model::reduced_model::ReducedModel;
use crate::quadrature::automatic_quadrature::{QuadratureChoice, cubature_if_it_pays};
use crate::quadrature::cubature::{
    CubatureCacheFile, CubatureError, CubatureParams, CubatureReport, optimize_cubature,
    optimize_cubature_cached,
};
use crate::quadrature::elastic_cost::{ElasticCost, PlannedRun};

pub use crate::model::elastic_quadrature::{ElasticQuadrature, QuadratureError};

/// How to choose the elastic quadrature of a model: a typed option for scene files, the CLI
/// and the experiments.
///
/// The default is an optimized cubature with [`CubatureParams::DEFAULT`], chosen against the
/// converged FEM on the beam (`results/RESULTS.md`, "The default quadrature").
/// [`QuadratureRule::PAPER`] is the paper's setting.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum QuadratureRule {
    /// Every integration point with its volume (the paper's setting).
    Full,
    /// `points` integration points drawn at random (seeded), volumes rescaled to the total.
    RandomSubset {
        /// Points kept.
        points: usize,
        /// Seed of the draw.
        seed: u64,
    },
    /// An optimized cubature ([`crate::quadrature::cubature`]).
    Cubature(CubatureParams),
    /// Every point, or an optimized cubature with these options when it pays for itself
    /// ([`crate::quadrature::automatic_quadrature`]): a cached cubature is used as it is; otherwise the
    /// elastic time of the run on every point is predicted and the cubature is trained with a
    /// budget of half what it can still save, and if training runs past the budget, the run
    /// uses every point (and a note in the cache spares a later run of about the same length
    /// the attempt). [`QuadratureRule::apply_for_run`] predicts up front from timed
    /// evaluations ([`ElasticCost`], [`PlannedRun`]); a caller that steps can predict better
    /// from the first steps, as `freeform`'s runner does. With no planned run it is
    /// [`QuadratureRule::Cubature`]. The choice depends on this machine's speed;
    /// [`QuadratureReport::choice`] says what was predicted and chosen.
    Automatic(CubatureParams),
}

/// Which quadrature a model integrates its elastic energy with, and what choosing it cost.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct QuadratureReport {
    /// The quadrature used: "full", "random_subset" or "cubature" (an
    /// [`QuadratureRule::Automatic`] rule reports the one it chose).
    pub kind: String,
    /// Points the elastic energy is evaluated at.
    pub points: usize,
    /// The cubature optimization's report, for a cubature.
    pub cubature: Option<CubatureReport>,
    /// What [`QuadratureRule::Automatic`] predicted and chose (`None` for the other rules).
    #[serde(default)]
    pub choice: Option<QuadratureChoice>,
}

impl Default for QuadratureRule {
    fn default() -> Self {
        QuadratureRule::Cubature(CubatureParams::DEFAULT)
    }
}

impl QuadratureRule {
    /// The paper's setting: every integration point with its volume.
    pub const PAPER: QuadratureRule = QuadratureRule::Full;

    /// "full", "random_subset", "cubature" or "automatic".
    pub fn name(&self) -> &'static str {
        match self {
            QuadratureRule::Full => "full",
            QuadratureRule::RandomSubset { .. } => "random_subset",
            QuadratureRule::Cubature(_) => "cubature",
            QuadratureRule::Automatic(_) => "automatic",
        }
    }

    /// `model` (which must integrate over every point) with this rule's quadrature set.
    ///
    /// # Errors
    /// [`CubatureError`]: the model already has a quadrature, the subset is larger than the
    /// model, or the cubature optimization failed.
    pub fn apply<M: HyperelasticMaterial>(
        &self,
        model: ReducedModel<M>,
    ) -> Result<(ReducedModel<M>, QuadratureReport), CubatureError> {
        self.apply_for_run(model, None, None)
    }

    /// [`QuadratureRule::apply`], with a cubature loaded from (or saved to) `cache_dir` when
    /// one is given ([`crate::quadrature::cubature::optimize_cubature_cached`]).
    ///
    /// # Errors
    /// As [`QuadratureRule::apply`].
    pub fn apply_cached<M: HyperelasticMaterial>(
        &self,
        model: ReducedModel<M>,
        cache_dir: Option<&Path>,
    ) -> Result<(ReducedModel<M>, QuadratureReport), CubatureError> {
        self.apply_for_run(model, cache_dir, None)
    }

    /// [`QuadratureRule::apply_cached`] for `planned` ([`PlannedRun`]), which
    /// [`QuadratureRule::Automatic`] weighs (the other rules ignore it).
    ///
    /// # Errors
    /// As [`QuadratureRule::apply`]; a cubature abandoned for its budget is not an error.
    pub fn apply_for_run<M: HyperelasticMaterial>(
        &self,
        model: ReducedModel<M>,
        cache_dir: Option<&Path>,
        planned: Option<&PlannedRun>,
    ) -> Result<(ReducedModel<M>, QuadratureReport), CubatureError> {
        if model.elastic_quadrature().is_some() {
            return Err(CubatureError::NotFull);
        }
        let every_point = |model: ReducedModel<M>, choice| {
            let report = QuadratureReport {
                kind: QuadratureRule::Full.name().to_string(),
                points: model.elastic_point_count(),
                cubature: None,
                choice,
            };
            Ok((model, report))
        };
        let (quadrature, cubature, choice) = match self {
            QuadratureRule::Full => return every_point(model, None),
            QuadratureRule::RandomSubset { points, seed } => (
                ElasticQuadrature::random_subset(model.volumes(), *points, *seed)?,
                None,
                None,
            ),
            QuadratureRule::Cubature(params) => {
                let (quadrature, report) = cubature(&model, params, cache_dir)?;
                (quadrature, Some(report), None)
            }
            QuadratureRule::Automatic(params) => {
                let Some(planned) = planned else {
                    let (quadrature, report) = cubature(&model, params, cache_dir)?;
                    return finish(model, "cubature", quadrature, Some(report), None);
                };
                let start = Instant::now();
                let cache = cache_dir.map(|dir| CubatureCacheFile::new(&model, params, dir));
                if let Some((quadrature, report)) = cache.as_ref().and_then(|file| file.load()) {
                    let choice =
                        QuadratureChoice::cached(planned.steps, start.elapsed().as_secs_f64());
                    return finish(model, "cubature", quadrature, Some(report), Some(choice));
                }
                let predicted = ElasticCost::measure(&model).run(planned);
                let outcome =
                    cubature_if_it_pays(&model, params, cache.as_ref(), planned.steps, predicted)?;
                let mut choice = outcome.choice;
                choice.spent_seconds = start.elapsed().as_secs_f64();
                match outcome.cubature {
                    Some((quadrature, report)) => (quadrature, Some(report), Some(choice)),
                    None => return every_point(model, Some(choice)),
                }
            }
        };
        let kind = match cubature {
            Some(_) => "cubature",
            None => self.name(),
        };
        finish(model, kind, quadrature, cubature, choice)
    }
}

/// The cubature of `params` on `model`, through the cache when there is one.
fn cubature<M: HyperelasticMaterial>(
    model: &ReducedModel<M>,
    params: &CubatureParams,
    cache_dir: Option<&Path>,
) -> Result<(ElasticQuadrature, CubatureReport), CubatureError> {
    match cache_dir {
        Some(dir) => optimize_cubature_cached(model, params, dir),
        None => optimize_cubature(model, params),
    }
}

/// `model` with `quadrature` set, and the report naming its `kind`.
fn finish<M: HyperelasticMaterial>(
    model: ReducedModel<M>,
    kind: &str,
    quadrature: ElasticQuadrature,
    cubature: Option<CubatureReport>,
    choice: Option<QuadratureChoice>,
) -> Result<(ReducedModel<M>, QuadratureReport), CubatureError> {
    let report = QuadratureReport {
        kind: kind.to_string(),
        points: quadrature.len(),
        cubature,
        choice,
    };
    let model = model.with_elastic_quadrature(quadrature)?;
    Ok((model, report))
}
