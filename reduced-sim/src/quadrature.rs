//! The elastic quadrature: which integration points, with which non-negative weights, carry the
//! elastic energy `E_el(z) ≈ Σ_{q ∈ Q} w_q Ψ(F_q(z))` (design §3.7).
//!
//! Mass, gravity, pins and the floor always use every integration point with its volume; only
//! the elastic energy, its gradient and its Hessian (the cost of a step) move to the quadrature.
//! Three kinds:
//! - every point with its volume ([`ElasticQuadrature::full`], the paper's setting and the
//!   default of a [`crate::ReducedModel`]);
//! - a random subset, volumes rescaled to the total ([`ElasticQuadrature::random_subset`]);
//! - an optimized cubature (An, Kim and James 2008; [`crate::cubature`]).
//!
//! [`QuadratureRule::Automatic`] chooses between the first and the last for a run of known
//! length: a cubature only when its training pays for itself in the run's steps
//! ([`crate::elastic_cost`]).

use hyperelastic::HyperelasticMaterial;
use rand::SeedableRng;
use rand::seq::index::sample;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use thiserror::Error;

use std::path::Path;
use std::time::Instant;

use crate::automatic_quadrature::{QuadratureChoice, cubature_if_it_pays};
use crate::cubature::{
    CubatureError, CubatureParams, CubatureReport, load_cached_cubature, optimize_cubature,
    optimize_cubature_cached,
};
use crate::elastic_cost::{ElasticCost, PlannedRun};
use crate::reduced_model::ReducedModel;

/// A quadrature that cannot be used.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum QuadratureError {
    /// No point carries weight.
    #[error("the elastic quadrature has no points")]
    Empty,
    /// Points and weights differ in number.
    #[error("{points} quadrature points but {weights} weights")]
    Count {
        /// Points given.
        points: usize,
        /// Weights given.
        weights: usize,
    },
    /// A weight is negative or not finite.
    #[error("quadrature weight {index} must be finite and non-negative, got {weight} m³")]
    Weight {
        /// Position in the quadrature.
        index: usize,
        /// The weight.
        weight: f64,
    },
    /// The projected volumetric term cannot be set up on the quadrature's points (its pressure
    /// functions are linearly dependent there).
    #[error("the projected dilatation on the quadrature points")]
    Dilatation(#[source] crate::projected_dilatation::ProjectedDilatationError),
    /// A point index is not an integration point of the model.
    #[error("quadrature point {point} is not one of the model's {points} integration points")]
    OutOfRange {
        /// The bad index.
        point: usize,
        /// Integration points of the model.
        points: usize,
    },
    /// The same point appears twice.
    #[error("integration point {point} appears twice in the quadrature")]
    Duplicate {
        /// The repeated index.
        point: usize,
    },
    /// A random subset larger than the set it is drawn from.
    #[error("a random subset of {requested} points was asked of {available} integration points")]
    SubsetTooLarge {
        /// Points asked for.
        requested: usize,
        /// Points available.
        available: usize,
    },
}

/// Quadrature points (indices into a model's integration points, ascending) and their weights
/// w_q (m³, ≥ 0).
#[derive(Clone, Debug, PartialEq)]
pub struct ElasticQuadrature {
    points: Vec<usize>,
    weights: Vec<f64>,
}

impl ElasticQuadrature {
    /// A quadrature from points and weights; sorted by point index.
    ///
    /// # Errors
    /// [`QuadratureError`]: empty, counts differ, a weight negative or non-finite, a point
    /// repeated. (Indices are checked against a model by
    /// [`crate::ReducedModel::with_elastic_quadrature`].)
    pub fn new(points: Vec<usize>, weights: Vec<f64>) -> Result<Self, QuadratureError> {
        if points.len() != weights.len() {
            return Err(QuadratureError::Count {
                points: points.len(),
                weights: weights.len(),
            });
        }
        if points.is_empty() {
            return Err(QuadratureError::Empty);
        }
        if let Some((index, &weight)) = weights
            .iter()
            .enumerate()
            .find(|(_, w)| !(w.is_finite() && **w >= 0.0))
        {
            return Err(QuadratureError::Weight { index, weight });
        }
        let mut pairs: Vec<(usize, f64)> = points.into_iter().zip(weights).collect();
        pairs.sort_by_key(|&(p, _)| p);
        if let Some(pair) = pairs.windows(2).find(|pair| pair[0].0 == pair[1].0) {
            return Err(QuadratureError::Duplicate { point: pair[0].0 });
        }
        let (points, weights) = pairs.into_iter().unzip();
        Ok(ElasticQuadrature { points, weights })
    }

    /// Every point with its volume: the exact sum over the integration points.
    ///
    /// # Errors
    /// [`QuadratureError`] for no points or an invalid volume.
    pub fn full(volumes: &[f64]) -> Result<Self, QuadratureError> {
        ElasticQuadrature::new((0..volumes.len()).collect(), volumes.to_vec())
    }

    /// `count` points drawn uniformly without replacement (seeded), each weighted by its volume
    /// times `V / V_subset` so that the weights sum to the total volume V.
    ///
    /// # Errors
    /// [`QuadratureError`] for `count` 0 or larger than the number of points, or invalid volumes.
    pub fn random_subset(
        volumes: &[f64],
        count: usize,
        seed: u64,
    ) -> Result<Self, QuadratureError> {
        if count > volumes.len() {
            return Err(QuadratureError::SubsetTooLarge {
                requested: count,
                available: volumes.len(),
            });
        }
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let points: Vec<usize> = sample(&mut rng, volumes.len(), count).into_vec();
        let total: f64 = volumes.iter().sum();
        let subset: f64 = points.iter().map(|&i| volumes[i]).sum();
        let scale = if subset > 0.0 { total / subset } else { 0.0 };
        let weights = points.iter().map(|&i| volumes[i] * scale).collect();
        ElasticQuadrature::new(points, weights)
    }

    /// Indices of the quadrature points, ascending.
    pub fn points(&self) -> &[usize] {
        &self.points
    }

    /// Their weights w_q (m³).
    pub fn weights(&self) -> &[f64] {
        &self.weights
    }

    /// Number of quadrature points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Never true (a quadrature has at least one point); for clippy's `len_without_is_empty`.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Σ w_q (m³).
    pub fn total_weight(&self) -> f64 {
        self.weights.iter().sum()
    }
}

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
    /// An optimized cubature ([`crate::cubature`]).
    Cubature(CubatureParams),
    /// Every point, or an optimized cubature with these options when it pays for itself
    /// ([`crate::automatic_quadrature`]): a cached cubature is used as it is; otherwise the
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
    /// one is given ([`crate::cubature::optimize_cubature_cached`]).
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
                if let Some((quadrature, report)) =
                    cache_dir.and_then(|dir| load_cached_cubature(&model, params, dir))
                {
                    let choice =
                        QuadratureChoice::cached(planned.steps, start.elapsed().as_secs_f64());
                    return finish(model, "cubature", quadrature, Some(report), Some(choice));
                }
                let predicted = ElasticCost::measure(&model).run(planned);
                let outcome =
                    cubature_if_it_pays(&model, params, cache_dir, planned.steps, predicted)?;
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
