//! The elastic quadrature a model integrates its elastic energy with: which integration points,
//! with which non-negative weights, carry `E_el(z) ≈ Σ_{q ∈ Q} w_q Ψ(F_q(z))` (design §3.7).
//! Which quadrature a run uses is chosen by [`crate::QuadratureRule`].

use rand::SeedableRng;
use rand::seq::index::sample;
use rand_chacha::ChaCha8Rng;
use thiserror::Error;

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
    Dilatation(#[source] crate::model::projected_dilatation::ProjectedDilatationError),
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
