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
//! join Q a batch at a time, and w is re-solved by non-negative least squares
//! ([`optimize::nnls_normal`], warm-started) after each batch; candidates the solve leaves at
//! zero weight leave Q for good. Selection stops when the relative residual
//! `‖Σ_q w_q g_q − f‖ / ‖f‖` over all poses is at most [`CubatureParams::tolerance`] or Q holds
//! [`CubatureParams::max_points`] points. Candidates are ranked on an f32 copy of their force
//! columns (ranking only; weights, residual and errors are f64), and the Gram matrix of the
//! chosen columns is formed from small per-point factors instead of the columns
//! (`cubature_gram`: 4.6× fewer flops at m = 32).
//!
//! One cubature serves every scene on that shape and material; a scene may add poses of its own
//! ([`optimize_cubature_on`]).

use std::path::{Path, PathBuf};
use std::time::Instant;

use artifact::{ContentKeyBuilder, load_framed, save_framed};

use faer::{Accum, Mat, MatRef, Par};
use hyperelastic::{HyperelasticMaterial, LameParameters};
use nalgebra::{Matrix3, Rotation3, Unit, Vector3};
use optimize::{NnlsError, NnlsParams, NnlsWarmStart, nnls_normal};
use rand::seq::index::sample;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::cubature_gram::ForceGramFactors;
use crate::deformation_map::DeformationMap;
use crate::elastic_energy::weighted_elastic_gradient;
use crate::elastic_quadrature::{ElasticQuadrature, QuadratureError};
use crate::reduced_model::ReducedModel;

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
    /// Points the greedy selection chooses from, drawn at random (default 5000; every point
    /// when the model has fewer). Too few limit the error reachable with non-negative weights
    /// (`results/RESULTS.md`, "The cubature's candidate pool"). Memory:
    /// 4 · 12(m+1) · poses · candidates bytes (0.48 GB at m = 32).
    pub candidates: usize,
    /// Relative force error over the training poses (in the weighted norm of
    /// [`force_weights`]) at which selection stops (default 0.001). Lower values keep more points
    /// and follow the full quadrature more closely; the measurements that chose the default are in
    /// `results/RESULTS.md` ("The cubature's tolerance").
    pub tolerance: f64,
    /// Most points with positive weight the cubature may hold (default 2000).
    pub max_points: usize,
    /// Points added between weight solves while the cubature is small (default 16; later an
    /// eighth of the points it holds).
    pub batch: usize,
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
        candidates: 5000,
        tolerance: 0.001,
        max_points: 2000,
        batch: 16,
        validation_poses_per_amplitude: 3,
        seed: 0,
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
    /// normalized to `‖f_p‖ = 1`.
    pub training_error: f64,
    /// The same error on poses drawn independently of the training poses.
    pub validation_error: f64,
    /// Whether the tolerance was met (otherwise the point budget stopped selection).
    pub reached_tolerance: bool,
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

/// Training poses z (length 12(m+1) each) from the basis alone, seeded by `params.seed`:
/// `poses_per_amplitude` random handle poses for each amplitude, then `field_poses` twists and
/// bends, as described in the module docs and [`CubatureParams`].
///
/// # Errors
/// [`CubatureError::Params`] for an amplitude that is not finite and positive.
pub fn training_poses<M: HyperelasticMaterial>(
    model: &ReducedModel<M>,
    params: &CubatureParams,
) -> Result<Vec<Vec<f64>>, CubatureError> {
    let amplitudes = params.amplitudes();
    let (poses_per_amplitude, max_rotation, seed) =
        (params.poses_per_amplitude, params.max_rotation, params.seed);
    check_pose_ranges(params, &amplitudes)?;
    let map = model.deformation_map();
    let layout = map.layout();
    let n4 = layout.block_len();
    // Strain is measured on a subset of points (cheap and plenty for an RMS).
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let probe = map.subset(&sample(&mut rng, map.len(), map.len().min(200)).into_vec());
    // RMS of each handle's weight, so every handle's transform moves points comparably.
    let weight_scale: Vec<f64> = (0..layout.handles())
        .map(|j| {
            let sum: f64 = (0..probe.len())
                .map(|i| probe.position_row(i)[4 * j + 3].powi(2))
                .sum();
            (sum / probe.len() as f64).sqrt().max(1e-12)
        })
        .collect();
    let extent = model.bounds().largest_side();
    let mut poses = Vec::with_capacity(amplitudes.len() * poses_per_amplitude);
    for amplitude in amplitudes {
        for _ in 0..poses_per_amplitude {
            let mut direction = vec![0.0; layout.len()];
            for (j, scale) in weight_scale.iter().enumerate().skip(1) {
                let axis = random_unit(&mut rng);
                let angle = rng.random_range(-max_rotation..=max_rotation);
                let stretch = Matrix3::from_fn(|_, _| 0.3 * normal(&mut rng));
                let a = Rotation3::from_axis_angle(&axis, angle).matrix()
                    * (Matrix3::identity() + stretch)
                    - Matrix3::identity();
                for r in 0..3 {
                    for c in 0..3 {
                        direction[layout.index(j, r, c)] = a[(r, c)] / scale;
                    }
                    direction[layout.index(j, r, 3)] = 0.3 * extent * normal(&mut rng) / scale;
                }
            }
            let t = scale_to_strain(&probe, &direction, amplitude);
            poses.push(direction.iter().map(|d| d * t).collect());
        }
    }
    let center = model.bounds().center();
    for k in 0..params.field_poses {
        let axis = random_unit(&mut rng);
        let twist = k % 2 == 0;
        // A bend turns slabs across `axis` about a perpendicular axis; a twist about `axis`.
        let turn_axis = if twist {
            axis
        } else {
            let other = random_unit(&mut rng);
            Unit::new_normalize(axis.cross(&other))
        };
        let total = if twist {
            rng.random_range(-params.max_twist..=params.max_twist)
        } else {
            rng.random_range(-params.max_bend..=params.max_bend)
        };
        let displacement: Vec<Vector3<f64>> = model
            .rest_positions()
            .iter()
            .map(|x| {
                let r = x - center;
                let angle = total * r.dot(&axis) / extent;
                Rotation3::from_axis_angle(&turn_axis, angle) * r - r
            })
            .collect();
        poses.push(model.project_field(&displacement));
    }
    debug_assert!(poses.iter().all(|p: &Vec<f64>| p.len() == 3 * n4));
    Ok(poses)
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

    let map = model.deformation_map();
    let n = map.len();
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed.wrapping_add(1));
    let mut pool: Vec<usize> = if params.candidates >= n {
        (0..n).collect()
    } else {
        sample(&mut rng, n, params.candidates).into_vec()
    };
    pool.sort_unstable();
    let pool_map = map.subset(&pool);
    let pool_lame: Vec<LameParameters> = pool.iter().map(|&i| model.lame_parameters()[i]).collect();

    // Targets, weighted and normalized per pose, and the candidates' force columns with the
    // same scaling.
    let omega = force_weights(model, params.time_step);
    let weigh = |f: Vec<f64>| -> Vec<f64> { f.iter().zip(&omega).map(|(f, w)| f * w).collect() };
    let targets: Vec<Vec<f64>> = poses
        .iter()
        .map(|z| weigh(model.elastic_gradient(z)))
        .collect();
    check_budget(0)?;
    let norms: Vec<f64> = targets.iter().map(|f| norm(f)).collect();
    let kept: Vec<usize> = (0..poses.len()).filter(|&p| norms[p] > 0.0).collect();
    if kept.is_empty() {
        return Err(CubatureError::NoForce);
    }
    let d = layout.len();
    let rows = kept.len() * d;
    let b: Vec<f64> = kept
        .iter()
        .flat_map(|&p| {
            let scale = norms[p];
            targets[p].iter().map(move |f| f / scale)
        })
        .collect();
    // Column c holds, pose after pose, candidate c's weighted, normalized force density.
    // Per candidate, two small products over all poses at once: the strains
    // `[F_k − I]_k = Z_allᵀ G_c` (`3K × 3`, Z_all the `4(m+1) × 3K` poses side by side), then
    // the force densities `[g_k]_k = G_c S` (`4(m+1) × 3K`, S[s, 3k + r] = P_k[r, s]), which
    // is the column's layout.
    let n4 = layout.block_len();
    let material = model.material();
    let z_all: Vec<f64> = kept
        .iter()
        .flat_map(|&p| poses[p].iter().copied())
        .collect();
    let z_all = MatRef::from_column_major_slice(&z_all, n4, 3 * kept.len());
    let scale: Vec<f64> = kept
        .iter()
        .flat_map(|&p| {
            let norm = norms[p];
            omega.iter().map(move |w| w / norm)
        })
        .collect();
    // Candidate c's stresses at every pose: `3 × 3K`, `[(s, 3k + r)] = P_k[r, s]`.
    let stresses_of = |c: usize| -> Mat<f64> {
        let g_c = MatRef::from_column_major_slice(pool_map.gradient_block(c), n4, 3);
        let mut strain = Mat::<f64>::zeros(3 * kept.len(), 3);
        faer::linalg::matmul::matmul(
            strain.as_mut(),
            Accum::Replace,
            z_all.transpose(),
            g_c,
            1.0,
            Par::Seq,
        );
        let mut stresses = Mat::<f64>::zeros(3, 3 * kept.len());
        for k in 0..kept.len() {
            let f = Matrix3::from_fn(|r, s| strain[(3 * k + r, s)] + f64::from(u8::from(r == s)));
            let p = material.first_piola_kirchhoff(&pool_lame[c], &f);
            for r in 0..3 {
                for s in 0..3 {
                    stresses[(s, 3 * k + r)] = p[(r, s)];
                }
            }
        }
        stresses
    };
    // Candidate c's column, in f64 (`rows` entries), from its stresses.
    let force_column = |c: usize, stresses: MatRef<'_, f64>, column: &mut [f64]| {
        faer::linalg::matmul::matmul(
            faer::MatMut::from_column_major_slice_mut(column, n4, 3 * kept.len()),
            Accum::Replace,
            MatRef::from_column_major_slice(pool_map.gradient_block(c), n4, 3),
            stresses,
            1.0,
            Par::Seq,
        );
        for (x, s) in column.iter_mut().zip(&scale) {
            *x *= s;
        }
    };
    // Every candidate's column in f32 (only to rank candidates by their correlation with the
    // residual: half the memory and memory traffic of f64) and its norm in f64; the columns
    // that join the cubature are formed again in f64 for the weights.
    let mut columns = vec![0.0_f32; rows * pool.len()];
    let column_norms: Vec<f64> = columns
        .par_chunks_mut(rows)
        .enumerate()
        .map_init(
            || vec![0.0; rows],
            |scratch, (c, column)| {
                force_column(c, stresses_of(c).as_ref(), scratch);
                for (x, &y) in column.iter_mut().zip(scratch.iter()) {
                    *x = y as f32;
                }
                norm(scratch)
            },
        )
        .collect();
    check_budget(0)?;
    let a = MatRef::from_column_major_slice(&columns, rows, pool.len());
    let b_norm = norm(&b);

    // Greedy selection with warm-started NNLS.
    let mut selected: Vec<usize> = Vec::new();
    let mut in_set = vec![false; pool.len()];
    let mut gram = Mat::<f64>::zeros(0, 0);
    let pose_scales: Vec<f64> = kept.iter().map(|&p| 1.0 / norms[p]).collect();
    let mut gram_factors = ForceGramFactors::new(n4, kept.len());
    let mut atb: Vec<f64> = Vec::new();
    let mut weights: Vec<f64> = Vec::new();
    let mut residual = b.clone();
    let mut selected_columns: Vec<f64> = Vec::new();
    // Blocks of 16: the same KKT solution, far fewer factorizations at a thousand points.
    let nnls_params = NnlsParams {
        block: 16,
        ..NnlsParams::default()
    };
    loop {
        let error = norm(&residual) / b_norm;
        let support = weights.iter().filter(|&&w| w > 0.0).count();
        if error <= params.tolerance || support >= params.max_points || selected.len() >= pool.len()
        {
            break;
        }
        check_budget(weights.iter().filter(|&&w| w > 0.0).count())?;
        // Correlations Aᵀr of every candidate with the residual, as one product.
        let residual32: Vec<f32> = residual.iter().map(|&r| r as f32).collect();
        let mut correlation = Mat::<f32>::zeros(pool.len(), 1);
        faer::linalg::matmul::matmul(
            correlation.as_mut(),
            Accum::Replace,
            a.transpose(),
            MatRef::from_column_major_slice(&residual32, rows, 1),
            1.0,
            Par::rayon(0),
        );
        let mut scores: Vec<(usize, f64)> = (0..pool.len())
            .filter(|&c| !in_set[c] && column_norms[c] > 0.0)
            .map(|c| (c, f64::from(correlation[(c, 0)]) / column_norms[c]))
            .filter(|&(_, s)| s > 0.0)
            .collect();
        if scores.is_empty() {
            break;
        }
        // Batches grow with the set (an eighth of it), so the weight solves stay few.
        let take = params
            .batch
            .max(support / 8)
            .min(params.max_points - support);
        scores.sort_by(|x, y| y.1.total_cmp(&x.1));
        let added: Vec<usize> = scores.iter().take(take).map(|&(c, _)| c).collect();
        let old = selected.len();
        selected.extend_from_slice(&added);
        for &c in &added {
            in_set[c] = true;
        }
        selected_columns.resize((old + added.len()) * rows, 0.0);
        let added_stresses: Vec<Mat<f64>> = added.par_iter().map(|&c| stresses_of(c)).collect();
        selected_columns[old * rows..]
            .par_chunks_mut(rows)
            .zip(&added)
            .zip(&added_stresses)
            .for_each(|((column, &c), stresses)| force_column(c, stresses.as_ref(), column));
        for (&c, stresses) in added.iter().zip(&added_stresses) {
            gram_factors.push(
                pool_map.gradient_block(c),
                &omega,
                stresses.as_ref(),
                &pose_scales,
            );
        }
        let k = selected.len();
        // The new Gram columns [A_S]ᵀ A_new from the points' factors (`cubature_gram`).
        let cross = gram_factors.cross(old);
        let mut grown = Mat::<f64>::zeros(k, k);
        for j in 0..old {
            for i in 0..old {
                grown[(i, j)] = gram[(i, j)];
            }
        }
        for j in old..k {
            for i in 0..k {
                grown[(i, j)] = cross[(i, j - old)];
                grown[(j, i)] = cross[(i, j - old)];
            }
            atb.push(dot(&selected_columns[j * rows..(j + 1) * rows], &b));
        }
        gram = grown;
        weights.resize(k, 0.0);
        let free: Vec<bool> = (0..k).map(|i| i >= old).collect();
        let start = NnlsWarmStart {
            x: &weights,
            free: &free,
        };
        weights = nnls_normal(gram.as_ref(), &atb, Some(start), &nnls_params)?.x;
        // Candidates the weight solve left at zero leave the set for good (they stay marked, so
        // they are not chosen again): the Gram matrix and later solves only carry the support.
        let keep: Vec<usize> = (0..k).filter(|&i| weights[i] > 0.0).collect();
        if keep.len() < k {
            gram = Mat::from_fn(keep.len(), keep.len(), |i, j| gram[(keep[i], keep[j])]);
            atb = keep.iter().map(|&i| atb[i]).collect();
            weights = keep.iter().map(|&i| weights[i]).collect();
            selected = keep.iter().map(|&i| selected[i]).collect();
            // In place: mostly the newest columns leave, so little moves.
            for (to, &from) in keep.iter().enumerate() {
                if to != from {
                    selected_columns.copy_within(from * rows..(from + 1) * rows, to * rows);
                }
            }
            selected_columns.truncate(keep.len() * rows);
            gram_factors.retain(&keep);
        }
        // r = b − A_S w, as one product.
        residual.copy_from_slice(&b);
        faer::linalg::matmul::matmul(
            faer::MatMut::from_column_major_slice_mut(&mut residual, rows, 1),
            Accum::Add,
            MatRef::from_column_major_slice(&selected_columns, rows, weights.len()),
            MatRef::from_column_major_slice(&weights, weights.len(), 1),
            -1.0,
            Par::rayon(0),
        );
    }
    let training_error = norm(&residual) / b_norm;
    let (points, weights): (Vec<usize>, Vec<f64>) = selected
        .iter()
        .zip(&weights)
        .filter(|&(_, &w)| w > 0.0)
        .map(|(&c, &w)| (pool[c], w))
        .unzip();
    let quadrature = ElasticQuadrature::new(points, weights)?;
    let validation_error = force_error(model, &quadrature, &validation, &omega);
    let total_volume: f64 = model.volumes().iter().sum();
    let report = CubatureReport {
        points: quadrature.len(),
        training_poses: kept.len(),
        training_error,
        validation_error,
        reached_tolerance: training_error <= params.tolerance,
        weight_over_volume: quadrature.total_weight() / total_volume,
        seconds: start.elapsed().as_secs_f64(),
        cached: false,
        cache_warning: None,
    };
    Ok((quadrature, report))
}

/// File kind and format version of cached cubatures. The version is part of the cache key:
/// bump it whenever the optimization changes its result (2: zero-weight candidates leave the
/// greedy set; 3: the targets from the one-pass elastic gradient and the residual as one
/// product, which round differently; 4: the approximations' F from the targets' SIMD kernel
/// and the Gram columns from per-point factors, which round differently again).
const CUBATURE_MAGIC: &[u8] = b"FREEFORM-CUBATURE";
const CUBATURE_FORMAT_VERSION: u32 = 4;

/// A cached cubature: its points, weights and the report of its optimization.
#[derive(Serialize, Deserialize)]
struct CachedCubature {
    points: Vec<usize>,
    weights: Vec<f64>,
    report: CubatureReport,
}

/// Where [`optimize_cubature_cached`] keeps the cubature of `model` and `params`:
/// `<cache_dir>/cubature/cubature-<hash>.bin`, the hash of everything that determines it (the
/// deformation map's G at every point, volumes, densities, Lamé parameters, the material's
/// name, every option).
pub fn cubature_cache_path<M: HyperelasticMaterial>(
    model: &ReducedModel<M>,
    params: &CubatureParams,
    cache_dir: &Path,
) -> PathBuf {
    let mut key = ContentKeyBuilder::new(CUBATURE_MAGIC, u64::from(CUBATURE_FORMAT_VERSION));
    let map = model.deformation_map();
    key.u64(map.layout().handles() as u64)
        .f64s(map.gradient_matrix_slice())
        .f64s(model.volumes())
        .f64s(model.densities())
        .str(model.material().name())
        .str(&format!("{params:?}"));
    for l in model.lame_parameters() {
        key.f64s(&[l.lambda(), l.mu()]);
    }
    cache_dir
        .join("cubature")
        .join(format!("cubature-{}.bin", key.finish().hex()))
}

/// [`optimize_cubature`], cached under `cache_dir` by content ([`cubature_cache_path`]): a
/// cached cubature is loaded (its report says `cached`), a missing or unreadable one is
/// optimized and saved. A cubature that cannot be saved is still returned, with the reason in
/// its report's `cache_warning`.
///
/// # Errors
/// As [`optimize_cubature`].
pub fn optimize_cubature_cached<M: HyperelasticMaterial>(
    model: &ReducedModel<M>,
    params: &CubatureParams,
    cache_dir: &Path,
) -> Result<(ElasticQuadrature, CubatureReport), CubatureError> {
    if let Some(cached) = load_cached_cubature(model, params, cache_dir) {
        return Ok(cached);
    }
    let (quadrature, report) = optimize_cubature(model, params)?;
    Ok(save_cached_cubature(
        model, params, cache_dir, quadrature, report,
    ))
}

/// The cubature of `model` and `params` cached under `cache_dir`, if there is a readable one
/// that fits the model (its report says `cached`).
pub fn load_cached_cubature<M: HyperelasticMaterial>(
    model: &ReducedModel<M>,
    params: &CubatureParams,
    cache_dir: &Path,
) -> Option<(ElasticQuadrature, CubatureReport)> {
    let path = cubature_cache_path(model, params, cache_dir);
    let n = model.volumes().len();
    let cached = load_framed::<CachedCubature>(&path, CUBATURE_MAGIC, CUBATURE_FORMAT_VERSION)
        .ok()
        .flatten()
        .filter(|cached| cached.points.iter().all(|&p| p < n))?;
    let quadrature = ElasticQuadrature::new(cached.points, cached.weights).ok()?;
    let report = CubatureReport {
        cached: true,
        ..cached.report
    };
    Some((quadrature, report))
}

/// Saves a freshly optimized cubature of `model` and `params` under `cache_dir` and returns
/// it; when it cannot be saved, the reason goes into the report's `cache_warning`.
pub fn save_cached_cubature<M: HyperelasticMaterial>(
    model: &ReducedModel<M>,
    params: &CubatureParams,
    cache_dir: &Path,
    quadrature: ElasticQuadrature,
    mut report: CubatureReport,
) -> (ElasticQuadrature, CubatureReport) {
    let path = cubature_cache_path(model, params, cache_dir);
    let entry = CachedCubature {
        points: quadrature.points().to_vec(),
        weights: quadrature.weights().to_vec(),
        report: report.clone(),
    };
    let saved = path
        .parent()
        .map_or(Ok(()), std::fs::create_dir_all)
        .map_err(|e| e.to_string())
        .and_then(|()| {
            save_framed(&path, CUBATURE_MAGIC, CUBATURE_FORMAT_VERSION, &entry)
                .map_err(|e| e.to_string())
        });
    if let Err(why) = saved {
        report.cache_warning = Some(format!("{}: {why}", path.display()));
    }
    (quadrature, report)
}

/// The weights `ω_k = 1/sqrt(H_kk)` of the force components, with `H = M_z/h² + K₀` the
/// step system at rest (K₀ the exact elastic Hessian at z = 0, M_z the reduced mass matrix,
/// h = `time_step` in s): a force error δf moves a Newton step by about `H⁻¹ δf`, whose
/// Jacobi approximation is `diag(ω)² δf`.
pub fn force_weights<M: HyperelasticMaterial>(model: &ReducedModel<M>, time_step: f64) -> Vec<f64> {
    let layout = model.deformation_map().layout();
    let stiffness = model.elastic_hessian(&layout.rest(), hyperelastic::Tangent::Exact);
    let mass = model.mass_block();
    let n4 = layout.block_len();
    (0..layout.len())
        .map(|k| {
            let h = stiffness[(k, k)] + mass[(k % n4, k % n4)] / (time_step * time_step);
            if h > 0.0 { 1.0 / h.sqrt() } else { 0.0 }
        })
        .collect()
}

/// The relative force error of `quadrature` on `poses` in the `weights` norm (one weight per
/// component of z, e.g. [`force_weights`]; all ones for the plain norm), each pose normalized
/// to unit force: `sqrt(Σ_p ‖ω∘(f̃_p − f_p)‖² / ‖ω∘f_p‖² / #poses)` with f the full-quadrature
/// force and f̃ the quadrature's. Poses with zero force are skipped.
///
/// # Panics
/// If `model` already has a quadrature, or a quadrature point is out of range.
pub fn force_error<M: HyperelasticMaterial>(
    model: &ReducedModel<M>,
    quadrature: &ElasticQuadrature,
    poses: &[Vec<f64>],
    weights: &[f64],
) -> f64 {
    assert!(
        model.elastic_quadrature().is_none(),
        "force errors are measured against the full model"
    );
    let map = model.deformation_map().subset(quadrature.points());
    let lame: Vec<LameParameters> = quadrature
        .points()
        .iter()
        .map(|&i| model.lame_parameters()[i])
        .collect();
    let mut sum = 0.0;
    let mut count = 0usize;
    for z in poses {
        let full: Vec<f64> = model
            .elastic_gradient(z)
            .iter()
            .zip(weights)
            .map(|(f, w)| f * w)
            .collect();
        let reference = norm(&full);
        if reference == 0.0 {
            continue;
        }
        let approx = weighted_elastic_gradient(
            model.material(),
            &map,
            &lame,
            quadrature.weights(),
            &map.deformation_gradients(z),
        );
        let diff: Vec<f64> = approx
            .iter()
            .zip(&full)
            .zip(weights)
            .map(|((a, f), w)| a * w - f)
            .collect();
        sum += (norm(&diff) / reference).powi(2);
        count += 1;
    }
    if count == 0 {
        0.0
    } else {
        (sum / count as f64).sqrt()
    }
}

/// The factor t making the RMS Green strain `‖(FᵀF − I)/2‖_F` of `t·direction` over the
/// probe points equal `amplitude` (bisection on a monotone-enough function, t in
/// [1e-12, 1e6]).
fn scale_to_strain(probe: &DeformationMap, direction: &[f64], amplitude: f64) -> f64 {
    let strain = |t: f64| {
        let z: Vec<f64> = direction.iter().map(|d| d * t).collect();
        let f = probe.deformation_gradients(&z);
        let sum: f64 = f
            .iter()
            .map(|f| (0.5 * (f.transpose() * f - Matrix3::identity())).norm_squared())
            .sum();
        (sum / f.len().max(1) as f64).sqrt()
    };
    // Bracket [t/2, t] by doubling or halving from 1.
    let mut hi = 1.0;
    if strain(hi) < amplitude {
        while strain(hi) < amplitude && hi < 1e6 {
            hi *= 2.0;
        }
    } else {
        while strain(0.5 * hi) >= amplitude && hi > 1e-12 {
            hi *= 0.5;
        }
    }
    let mut lo = 0.5 * hi;
    // 20 halvings of a bracket [t, 2t] give t to 1e-6 relative: plenty for a pose amplitude.
    for _ in 0..20 {
        let mid = 0.5 * (lo + hi);
        if strain(mid) < amplitude {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
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

/// A direction uniform on the sphere.
fn random_unit(rng: &mut ChaCha8Rng) -> Unit<Vector3<f64>> {
    loop {
        let v = Vector3::new(normal(rng), normal(rng), normal(rng));
        if v.norm() > 1e-6 {
            return Unit::new_normalize(v);
        }
    }
}

/// A standard normal sample (Box–Muller).
fn normal(rng: &mut ChaCha8Rng) -> f64 {
    let u: f64 = rng.random_range(f64::MIN_POSITIVE..1.0);
    let v: f64 = rng.random_range(0.0..1.0);
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn norm(a: &[f64]) -> f64 {
    dot(a, a).sqrt()
}
