//! Optimized cubature for the reduced elastic forces (An, Kim and James 2008, "Optimizing
//! cubature for efficient integration of subspace deformations"; design §3.7).
//!
//! Training poses `z_p` are drawn from the basis alone ([`training_poses`]): every handle gets a
//! random rotation (up to [`CubatureParams::max_rotation`]) and a random stretch, scaled so the
//! root-mean-square Green strain over the points is one of [`CubatureParams::amplitudes`]
//! (geometric levels from the smallest to the largest amplitude). For
//! each pose the full-quadrature reduced elastic force `f_p = Σ_i v_i g_i(z_p)` is the target,
//! with `g_i(z) = ∂Ψ(F_i(z))/∂z` the force density of point i (length 12(m+1)). Poses are
//! weighted by `1/‖f_p‖` so each counts equally. A cubature `(Q, w)` must satisfy
//!
//! ```text
//! Σ_{q ∈ Q} w_q g_q(z_p) ≈ f_p   for every p,   w ≥ 0,
//! ```
//!
//! found greedily: the candidates (a seeded pool of the points) most aligned with the residual
//! join Q a batch at a time (no two of a batch nearer than [`CubatureParams::batch_spacing`]
//! candidate spacings), and w is re-solved by non-negative least squares
//! ([`optimize::nnls_normal_carried`], warm-started, its factor carried from batch to batch)
//! after each batch; candidates the solve leaves at zero weight leave Q for good. Selection stops when the relative residual
//! `‖Σ_q w_q g_q − f‖ / ‖f‖` over all poses is at most [`CubatureParams::tolerance`] or Q holds
//! [`CubatureParams::max_points`] points. Both the candidates' correlations with the residual
//! (`ranking`, in f32: ranking only; weights, residual and errors are f64) and the Gram matrix
//! of the chosen columns (`cubature_gram`) are formed from small per-point factors (gradient
//! blocks and stresses) instead of the force columns.
//!
//! On a model with a projected dilatation ([`ReducedModel::with_projected_dilatation`]) the
//! target is that model's force, `Σ_i v_i G_i [P(F_i) + κ_i (p_i − (J_i − γ_i)) cof F_i]` with
//! `p = Π(J − γ)` projected over every point, and each candidate's column is its term of that
//! sum at the same p (the full model's, pose by pose): the volumes over every point are then an
//! exact cubature, as without the dilatation. The model integrated by the cubature projects
//! its pressure over the cubature's points; the validation error measures that model
//! ([`force_error`]).
//!
//! One cubature serves every scene on that shape and material; a scene may add poses of its own
//! ([`optimize_cubature_on`]).

use std::time::Instant;

use hyperelastic::HyperelasticMaterial;
use optimize::NnlsError;
use rand::SeedableRng;
use rand::seq::index::sample;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::model::elastic_quadrature::{ElasticQuadrature, QuadratureError};
use crate::model::reduced_model::ReducedModel;

mod cache;
mod candidates;
mod force_accuracy;
pub(crate) mod gram;
mod greedy;
mod ranking;
mod training;

pub use cache::{
    CubatureCacheFile, cubature_cache_path, load_cached_cubature, optimize_cubature_cached,
    save_cached_cubature,
};
pub use force_accuracy::{force_error, force_weights};
pub use training::training_poses;

use candidates::CandidateForces;
use greedy::select_greedily;
use ranking::ResidualCorrelation;

/// Options of the cubature optimization.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct CubatureParams {
    /// Smallest root-mean-square Green strain of a group of training poses (default 0.02).
    pub smallest_amplitude: f64,
    /// Largest one (default 0.6: a 648° twist of the beam shears it about this much).
    pub largest_amplitude: f64,
    /// Groups of poses, at amplitudes spaced geometrically between the two (default 4).
    pub amplitude_levels: usize,
    /// Training poses per amplitude (default 10).
    pub poses_per_amplitude: usize,
    /// Largest rotation angle of a handle's random transform (rad, default π).
    pub max_rotation: f64,
    /// Training poses that are smooth twists and bends of the whole body about random axes
    /// through its centre, projected onto the subspace (mass-weighted least squares), half of
    /// each (default 20): they carry the large local rotations that random handle transforms
    /// do not.
    pub field_poses: usize,
    /// Largest total twist across the body's extent (rad, default 4π: the beam Twist turns its
    /// end by 3.6π).
    pub max_twist: f64,
    /// Largest total bend across the body's extent (rad, default π).
    pub max_bend: f64,
    /// Time step (s, default 0.01) of the step system `H = M_z/h² + K₀` whose diagonal weighs
    /// the force components: component k is scaled by `1/sqrt(H_kk)`, so errors in soft
    /// directions, which move the solution most, count most.
    pub time_step: f64,
    /// Points the greedy selection chooses from, drawn at random (default 10 000; every point
    /// when the model has fewer). Too few limit the error reachable with non-negative weights
    /// (`results/RESULTS.md`, "The cubature's candidate pool"; 5000 of 40 000 points stop short
    /// of the default tolerance; the report's `stop` is then [`CubatureStop::Candidates`]). Memory:
    /// 4 · (12(m+1) + 18 · poses) · candidates bytes (30 MB at m = 32 with 60 poses).
    pub candidates: usize,
    /// Relative force error over the training poses (in the weighted norm of
    /// [`force_weights`]) at which selection stops (default 0.001). Lower values keep more points
    /// and follow the full quadrature more closely; the measurements that chose the default are in
    /// `results/RESULTS.md` ("The cubature's tolerance").
    pub tolerance: f64,
    /// Most points with positive weight the cubature may hold (default 4000): a bound on the
    /// cost, not the stopping rule ([`CubatureParams::tolerance`] is). At 2000 it stopped the
    /// m = 64 beam short of the tolerance (`results/RESULTS.md`, "fourteenth part").
    pub max_points: usize,
    /// Points added between weight solves while the cubature is small (default 16; later an
    /// eighth of the points it holds).
    pub batch: usize,
    /// How far apart the points of one batch must be, in candidate spacings `(V / C)^(1/3)`
    /// (V the model's volume, C the candidates; default 2, ≥ 0; 0 lets neighbours join in the
    /// same batch). The candidates most correlated with the residual are often neighbours with
    /// nearly equal columns, of which the weight solve keeps one: batches spread out this way
    /// reach the tolerance in fewer weight solves (`results/RESULTS.md`, "tenth part").
    pub batch_spacing: f64,
    /// Poses per amplitude not used for training, on which the error is also reported
    /// (default 3).
    pub validation_poses_per_amplitude: usize,
    /// Seed of poses and candidates (default 0).
    pub seed: u64,
}

impl CubatureParams {
    /// The documented defaults, usable in constants.
    pub const DEFAULT: CubatureParams = CubatureParams {
        smallest_amplitude: 0.02,
        largest_amplitude: 0.6,
        amplitude_levels: 4,
        poses_per_amplitude: 10,
        max_rotation: std::f64::consts::PI,
        field_poses: 20,
        max_twist: 4.0 * std::f64::consts::PI,
        max_bend: std::f64::consts::PI,
        time_step: 0.01,
        candidates: 10_000,
        tolerance: 0.001,
        max_points: 4000,
        batch: 16,
        batch_spacing: 2.0,
        validation_poses_per_amplitude: 3,
        seed: 0,
    };

    /// Few training poses (two levels of two, two field poses): for unit tests.
    #[cfg(test)]
    pub(crate) const FEW_POSES: CubatureParams = CubatureParams {
        amplitude_levels: 2,
        poses_per_amplitude: 2,
        field_poses: 2,
        ..CubatureParams::DEFAULT
    };

    /// The amplitudes of the pose groups: `amplitude_levels` values from the smallest to the
    /// largest, geometrically spaced.
    pub fn amplitudes(&self) -> Vec<f64> {
        let levels = self.amplitude_levels;
        if levels <= 1 {
            return vec![self.largest_amplitude; levels];
        }
        let ratio = self.largest_amplitude / self.smallest_amplitude;
        (0..levels)
            .map(|k| self.smallest_amplitude * ratio.powf(k as f64 / (levels - 1) as f64))
            .collect()
    }
}

impl Default for CubatureParams {
    fn default() -> Self {
        CubatureParams::DEFAULT
    }
}

/// What the optimization found and what it cost.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CubatureReport {
    /// Points in the cubature (those with positive weight).
    pub points: usize,
    /// Training poses used.
    pub training_poses: usize,
    /// Relative force error over the training poses, `‖Σ_q w_q g_q − f‖ / ‖f‖` with every pose
    /// normalized to `‖f_p‖ = 1` (with a projected dilatation, `g_q` at the full model's
    /// pressure: the columns the weights were fit to).
    pub training_error: f64,
    /// The error on poses drawn independently of the training poses, of the model integrated
    /// by the cubature ([`force_error`]).
    pub validation_error: f64,
    /// Whether the tolerance was met (otherwise `stop` says what stopped selection).
    pub reached_tolerance: bool,
    /// What stopped the selection.
    #[serde(default)]
    pub stop: CubatureStop,
    /// Σ w_q over Σ v_i: how far the weights are from a volume-preserving quadrature.
    pub weight_over_volume: f64,
    /// Wall time of pose generation, selection and weight solves (s), as first optimized.
    pub seconds: f64,
    /// Whether this cubature was loaded from a cache ([`optimize_cubature_cached`]).
    #[serde(default)]
    pub cached: bool,
    /// Why a freshly optimized cubature could not be saved to the cache, if it could not (it
    /// is still used).
    #[serde(default)]
    pub cache_warning: Option<String>,
}

/// What stopped the greedy selection of a cubature.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CubatureStop {
    /// The training error reached [`CubatureParams::tolerance`].
    #[default]
    Tolerance,
    /// The cubature holds [`CubatureParams::max_points`] points.
    PointBudget,
    /// No candidate left is positively correlated with the residual, or every candidate has
    /// been tried: a larger [`CubatureParams::candidates`] pool can reach lower.
    Candidates,
}

impl CubatureStop {
    /// What stopped the selection, in words (for reports).
    pub fn describe(self) -> &'static str {
        match self {
            CubatureStop::Tolerance => "it reached its tolerance",
            CubatureStop::PointBudget => "it holds its most points (`max_points`)",
            CubatureStop::Candidates => {
                "no candidate left improves it (a larger `candidates` pool can go lower)"
            }
        }
    }
}

/// The cubature could not be optimized.
#[derive(Debug, Error)]
pub enum CubatureError {
    /// An option is out of range.
    #[error("invalid cubature option: {0}")]
    Params(String),
    /// The model already integrates over a cubature or subset: train on the full model.
    #[error("the model already has an elastic quadrature; optimize a cubature on the full model")]
    NotFull,
    /// Every training pose has zero elastic force (a basis with no deformable handle).
    #[error("the training poses have no elastic force: the basis has no deformable handle")]
    NoForce,
    /// The optimization ran past its time budget ([`optimize_cubature_within`]) and stopped.
    #[error(
        "the cubature optimization stopped after {seconds:.2} s, past its budget of {budget:.2} s"
    )]
    OverBudget {
        /// Time spent when it stopped (s).
        seconds: f64,
        /// The budget for the points it held then (s).
        budget: f64,
    },
    /// The weight solve failed.
    #[error("cubature weights: {0}")]
    Nnls(#[from] NnlsError),
    /// The weights do not make a valid quadrature (no positive weight).
    #[error(transparent)]
    Quadrature(#[from] QuadratureError),
}

/// Optimizes a cubature on the basis's own training poses ([`training_poses`] with `params`).
///
/// # Errors
/// [`CubatureError`]: invalid options, a model that already has a quadrature, no force, or a
/// failed weight solve.
pub fn optimize_cubature<M: HyperelasticMaterial>(
    model: &ReducedModel<M>,
    params: &CubatureParams,
) -> Result<(ElasticQuadrature, CubatureReport), CubatureError> {
    optimize_cubature_on(model, &[], params)
}

/// Optimizes a cubature on the basis's training poses plus `extra_poses` (e.g. frames of a
/// scene, each of length 12(m+1)).
///
/// # Errors
/// [`CubatureError`]: invalid options or pose lengths, a model that already has a quadrature,
/// no force, or a failed weight solve.
pub fn optimize_cubature_on<M: HyperelasticMaterial>(
    model: &ReducedModel<M>,
    extra_poses: &[Vec<f64>],
    params: &CubatureParams,
) -> Result<(ElasticQuadrature, CubatureReport), CubatureError> {
    optimize(model, extra_poses, params, None)
}

/// How long a cubature's training may run: no longer than the cubature can still save over a
/// run, `T(S) = full_run_seconds · (1 − S/N)` with S the points it holds so far (a cubature
/// only grows while training, so S bounds its final size from below) and N the model's points.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CubatureBudget {
    /// Predicted elastic time of the run on every point (s), e.g.
    /// [`crate::ElasticCost::run`].
    pub full_run_seconds: f64,
    /// Points of the full quadrature, N.
    pub full_points: usize,
}

impl CubatureBudget {
    /// `T(S)` in s for a cubature of `points` points (0 once it holds N or more).
    pub fn seconds(&self, points: usize) -> f64 {
        let kept = points as f64 / self.full_points.max(1) as f64;
        self.full_run_seconds * (1.0 - kept).max(0.0)
    }
}

/// [`optimize_cubature`] that gives up once it has spent more than `budget` allows for the
/// points it holds: it looks at the clock between its stages and between greedy batches, so
/// it stops within one batch of the budget.
///
/// # Errors
/// [`CubatureError::OverBudget`] when the budget runs out, otherwise as [`optimize_cubature`].
pub fn optimize_cubature_within<M: HyperelasticMaterial>(
    model: &ReducedModel<M>,
    params: &CubatureParams,
    budget: &CubatureBudget,
) -> Result<(ElasticQuadrature, CubatureReport), CubatureError> {
    optimize(model, &[], params, Some(budget))
}

/// The optimization of the module docs, stopped with [`CubatureError::OverBudget`] once it has
/// spent more than `budget` allows, if one is given.
fn optimize<M: HyperelasticMaterial>(
    model: &ReducedModel<M>,
    extra_poses: &[Vec<f64>],
    params: &CubatureParams,
    budget: Option<&CubatureBudget>,
) -> Result<(ElasticQuadrature, CubatureReport), CubatureError> {
    let start = Instant::now();
    let check_budget = |points: usize| match budget {
        Some(budget) if start.elapsed().as_secs_f64() > budget.seconds(points) => {
            Err(CubatureError::OverBudget {
                seconds: start.elapsed().as_secs_f64(),
                budget: budget.seconds(points),
            })
        }
        _ => Ok(()),
    };
    check_params(params)?;
    if model.elastic_quadrature().is_some() {
        return Err(CubatureError::NotFull);
    }
    let layout = model.deformation_map().layout();
    if let Some(p) = extra_poses.iter().find(|p| p.len() != layout.len()) {
        return Err(CubatureError::Params(format!(
            "a scene pose has length {}, expected {}",
            p.len(),
            layout.len()
        )));
    }
    let mut poses = training_poses(model, params)?;
    poses.extend_from_slice(extra_poses);
    let validation = training_poses(
        model,
        &CubatureParams {
            poses_per_amplitude: params.validation_poses_per_amplitude,
            field_poses: 2 * params.validation_poses_per_amplitude,
            seed: params.seed.wrapping_add(0x9e37_79b9_7f4a_7c15),
            ..*params
        },
    )?;

    let n = model.deformation_map().len();
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed.wrapping_add(1));
    let mut pool: Vec<usize> = if params.candidates >= n {
        (0..n).collect()
    } else {
        sample(&mut rng, n, params.candidates).into_vec()
    };
    pool.sort_unstable();

    // Targets, weighted and normalized per pose, and the candidates' force columns with the
    // same scaling.
    let omega = force_weights(model, params.time_step);
    let (targets, coefficients) = weighted_targets(model, &poses, &omega);
    check_budget(0)?;
    let norms: Vec<f64> = targets.iter().map(|f| norm(f)).collect();
    let kept: Vec<usize> = (0..poses.len()).filter(|&p| norms[p] > 0.0).collect();
    if kept.is_empty() {
        return Err(CubatureError::NoForce);
    }
    let b: Vec<f64> = kept
        .iter()
        .flat_map(|&p| {
            let scale = norms[p];
            targets[p].iter().map(move |f| f / scale)
        })
        .collect();
    let kept_poses: Vec<&[f64]> = kept.iter().map(|&p| poses[p].as_slice()).collect();
    let kept_norms: Vec<f64> = kept.iter().map(|&p| norms[p]).collect();
    let kept_coefficients: Vec<Vec<f64>> = kept
        .iter()
        .filter_map(|&p| coefficients[p].clone())
        .collect();
    let candidates = CandidateForces::new(
        model,
        &pool,
        &kept_poses,
        &kept_norms,
        &omega,
        &kept_coefficients,
    );
    let pose_scales: Vec<f64> = kept_norms.iter().map(|norm| 1.0 / norm).collect();
    let mut ranking = ResidualCorrelation::new(&candidates, &omega, &pose_scales);
    check_budget(0)?;
    let selection = select_greedily(
        &candidates,
        &mut ranking,
        &b,
        &omega,
        &pose_scales,
        params,
        &check_budget,
    )?;
    let training_error = norm(&selection.residual) / norm(&b);
    let (points, weights): (Vec<usize>, Vec<f64>) = selection
        .selected
        .iter()
        .zip(&selection.weights)
        .filter(|&(_, &w)| w > 0.0)
        .map(|(&c, &w)| (pool[c], w))
        .unzip();
    let quadrature = ElasticQuadrature::new(points, weights)?;
    let validation_error = force_error(model, &quadrature, &validation, &omega)?;
    let total_volume: f64 = model.volumes().iter().sum();
    let report = CubatureReport {
        points: quadrature.len(),
        training_poses: kept.len(),
        training_error,
        validation_error,
        reached_tolerance: training_error <= params.tolerance,
        stop: selection.stop,
        weight_over_volume: quadrature.total_weight() / total_volume,
        seconds: start.elapsed().as_secs_f64(),
        cached: false,
        cache_warning: None,
    };
    Ok((quadrature, report))
}

/// The full model's elastic force at each pose weighted by `omega` (`ω ∘ f_p`), and with a
/// projected dilatation its pressure coefficients p̂ there, which shift every candidate's
/// stress as they shift the target's (`None` without one). All poses at once
/// ([`ReducedModel::elastic_gradients`]).
fn weighted_targets<M: HyperelasticMaterial>(
    model: &ReducedModel<M>,
    poses: &[Vec<f64>],
    omega: &[f64],
) -> (Vec<Vec<f64>>, Vec<Option<Vec<f64>>>) {
    let many = model.many_pose_gradients(poses);
    let targets = many
        .gradients
        .iter()
        .map(|f| f.iter().zip(omega).map(|(f, w)| f * w).collect())
        .collect();
    let coefficients = if many.pressure_coefficients.is_empty() {
        vec![None; poses.len()]
    } else {
        many.pressure_coefficients.into_iter().map(Some).collect()
    };
    (targets, coefficients)
}

/// The ranges the pose generator samples from must be finite (and amplitudes positive, angles
/// non-negative): checked before any is drawn.
fn check_pose_ranges(params: &CubatureParams, amplitudes: &[f64]) -> Result<(), CubatureError> {
    if let Some(a) = amplitudes.iter().find(|a| !(a.is_finite() && **a > 0.0)) {
        return Err(CubatureError::Params(format!(
            "amplitudes must be finite and positive, got {a}"
        )));
    }
    let angles = [
        ("max_rotation", params.max_rotation),
        ("max_twist", params.max_twist),
        ("max_bend", params.max_bend),
    ];
    match angles.iter().find(|(_, v)| !(v.is_finite() && *v >= 0.0)) {
        Some((name, value)) => Err(CubatureError::Params(format!(
            "{name} must be finite and non-negative, got {value} rad"
        ))),
        None => Ok(()),
    }
}

fn check_params(params: &CubatureParams) -> Result<(), CubatureError> {
    let problem = if params.amplitude_levels == 0 || params.poses_per_amplitude == 0 {
        Some("at least one amplitude and one pose per amplitude are needed".to_string())
    } else if !(params.tolerance.is_finite() && params.tolerance > 0.0) {
        Some(format!(
            "the tolerance must be positive, got {}",
            params.tolerance
        ))
    } else if params.max_points == 0 || params.batch == 0 || params.candidates == 0 {
        Some("max_points, batch and candidates must be at least 1".to_string())
    } else if !(params.batch_spacing.is_finite() && params.batch_spacing >= 0.0) {
        Some(format!(
            "batch_spacing must be finite and at least 0, got {}",
            params.batch_spacing
        ))
    } else if !(params.time_step.is_finite() && params.time_step > 0.0) {
        Some(format!(
            "time_step must be positive, got {} s",
            params.time_step
        ))
    } else {
        None
    };
    problem.map_or(Ok(()), |p| Err(CubatureError::Params(p)))
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn norm(a: &[f64]) -> f64 {
    dot(a, a).sqrt()
}
