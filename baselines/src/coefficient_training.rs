//! The optimization ablations of Table 3 (design §3.9): the RKPM coefficients c (K × m) of our
//! own skinning weights `W_j(X) = Σ_k ϕ_k(X) c_kj`, found by Adam instead of the eigen solve.
//!
//! Same kernels and shape functions as ours (farthest point sampling on the integration points,
//! the same radius rule and cutoff); only the way c is found changes. Two losses:
//!
//! - [`CoefficientLoss::RandomHandles`], the Simplicits loss on c:
//!   `0.1 · (V/B) Σ_points Σ_transforms [(1−r) Ψ_lin(F) + r Ψ_NH(F)] + 1e6 · mean((WᵀW − I)²)`,
//!   with the same random handle sets, ramp and weights as [`crate::SimplicitsParams`]. F is
//!   exact, not a finite difference: `F = I + Σ_j (Z_j[:, :3] W_j + (Z_j X̄) ∇W_jᵀ)`.
//! - [`CoefficientLoss::WeightHessian`], the eigenproblem's own objective with a penalty instead
//!   of the constraint: `tr(cᵀ H_w c) / s + 1e6 · mean((cᵀ𝓜c − I)²)`, where H_w and 𝓜 are Prop. 1's
//!   and Eq. 14's matrices and `s = max_i (λ_i + 4μ_i)` makes the energy term dimensionless
//!   (without it, at E = 5 MPa, the energy outweighs the penalty by 10³ and every column
//!   collapses to zero: the stationarity condition gives `|c_j|² ∝ 1 − λ_j/(2α)`). Its minimizer
//!   spans the constant field and the m lowest eigen-weights (in any rotation), so it trains
//!   m + 1 columns, rotates them by Rayleigh–Ritz in their span and drops the lowest, as the
//!   eigen solve drops the constant mode.
//!
//! Two kinds of integration points ([`TrainingPoints`]):
//! - `Grid`: the given integration points. The Hessian loss uses the full quadrature (H_w and
//!   𝓜 assembled once, exactly the matrices of our eigen solve); the handle loss draws
//!   `points_per_step` of them with replacement per step, as Simplicits does.
//! - `Random`: `points_per_step` fresh points per step, uniform in the solid as the points
//!   represent it (a point chosen with probability ∝ v_i, then a uniform position in the cube of
//!   volume v_i centred on it), each with volume `V / B`; shape functions evaluated anew.
//!
//! After the last step the columns are rotated within their span by Rayleigh–Ritz (the span,
//! which is all the simulator sees, is unchanged). c starts as PyTorch initializes a bias-free `K → m` linear layer (uniform in ±1/√K, seeded).
//! The result is an ordinary [`SkinningBasis`], simulated by the same code as ours.

use std::path::Path;
use std::time::Instant;

use faer::Mat;
use hyperelastic::{HyperelasticMaterial, LameParameters, LinearElastic, StableNeoHookean};
use nalgebra::{DMatrix, Matrix3, Vector3, Vector4};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use rkpm_core::{
    IntegrationPoints, KernelError, KernelParams, ShapeFunctionError, ShapeFunctionParams,
    ShapeFunctions, evaluate_shape_functions, place_kernels,
};
use serde::{Deserialize, Serialize};
use skin_eigen::{
    AssemblyError, BasisMetadata, SkinningBasis, WeightSpaceMatrices,
    assemble_weight_space_matrices,
};
use thiserror::Error;

use crate::adam::{Adam, AdamParams};
use crate::model_file::{self, ModelFileError};
use crate::simplicits::{StepLosses, random_handle_transforms};

/// Which objective Adam minimizes over c.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CoefficientLoss {
    /// The Simplicits random-handle elastic loss plus `mean((WᵀW − I)²)`.
    #[serde(alias = "RandomHandles")]
    RandomHandles,
    /// `tr(cᵀH_w c)/s` plus `mean((cᵀ𝓜c − I)²)`.
    #[serde(alias = "WeightHessian")]
    WeightHessian,
}

/// Where the losses are integrated.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TrainingPoints {
    /// Fresh uniform random points in the solid every step.
    #[serde(alias = "Random")]
    Random,
    /// The given (grid) integration points.
    #[serde(alias = "Grid")]
    Grid,
}

/// Options of [`train_coefficients`]; the defaults are Simplicits' (design §3.9) and our basis's.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CoefficientTrainingParams {
    /// Skinning weights m (default 16).
    pub modes: usize,
    /// Kernel count and radius rule (default: ours, K = 1000).
    pub kernels: KernelParams,
    /// Shape-function cutoff (default: ours).
    pub shape_functions: ShapeFunctionParams,
    /// The objective.
    pub loss: CoefficientLoss,
    /// The integration points.
    pub points: TrainingPoints,
    /// Adam steps (default 10 000).
    pub steps: usize,
    /// Points per step where points are drawn (default 1000).
    pub points_per_step: usize,
    /// Random handle sets per step, handle loss only (default 10).
    pub transforms_per_step: usize,
    /// Standard deviation of each handle-transform entry (default 0.1).
    pub transform_std: f64,
    /// Adam learning rate (default 1e-3).
    pub learning_rate: f64,
    /// Weight of the energy term (default 0.1 for the handle loss; the Hessian term has
    /// weight 1 after its normalization by `s`).
    pub elastic_weight: f64,
    /// Weight of the orthogonality term (default 1e6).
    pub ortho_weight: f64,
    /// Seed of the initialization and of all sampling (default 0).
    pub seed: u64,
}

impl CoefficientTrainingParams {
    /// The defaults with the given loss and points.
    pub fn new(loss: CoefficientLoss, points: TrainingPoints) -> Self {
        CoefficientTrainingParams {
            modes: 16,
            kernels: KernelParams::default(),
            shape_functions: ShapeFunctionParams::default(),
            loss,
            points,
            steps: 10_000,
            points_per_step: 1000,
            transforms_per_step: 10,
            transform_std: 0.1,
            learning_rate: 1e-3,
            elastic_weight: 0.1,
            ortho_weight: 1e6,
            seed: 0,
        }
    }

    /// Short name for tables: "random-z + random points", "Hessian + grid points", …
    pub fn label(&self) -> &'static str {
        match (self.loss, self.points) {
            (CoefficientLoss::RandomHandles, TrainingPoints::Random) => "random-z + random points",
            (CoefficientLoss::RandomHandles, TrainingPoints::Grid) => "random-z + grid points",
            (CoefficientLoss::WeightHessian, TrainingPoints::Random) => "Hessian + random points",
            (CoefficientLoss::WeightHessian, TrainingPoints::Grid) => "Hessian + grid points",
        }
    }
}

/// Training cannot proceed.
#[derive(Debug, Error)]
pub enum CoefficientTrainingError {
    /// A parameter is out of range or the inputs do not match.
    #[error("invalid coefficient-training input: {0}")]
    Invalid(String),
    /// Kernel placement failed (e.g. K > N).
    #[error("kernel placement: {0}")]
    Kernels(#[from] KernelError),
    /// Shape functions could not be evaluated (at the grid or at a random batch).
    #[error("shape functions: {0}")]
    ShapeFunctions(#[from] ShapeFunctionError),
    /// H_w and 𝓜 could not be assembled.
    #[error("assembly: {0}")]
    Assembly(#[from] AssemblyError),
    /// A loss became NaN or infinite.
    #[error("training diverged at step {step}: loss {loss}")]
    Diverged {
        /// 0-based step.
        step: usize,
        /// The loss.
        loss: f64,
    },
}

/// What training measured.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CoefficientTrainingReport {
    /// Wall time, kernel placement and setup included (s).
    pub seconds: f64,
    /// Of which kernel placement, grid shape functions and assembly (s).
    pub setup_seconds: f64,
    /// Losses of the first step (`elastic` holds the energy term before weighting).
    pub first: StepLosses,
    /// Losses of the last step.
    pub last: StepLosses,
}

/// Version written into saved coefficient models (2: the shape-function options carry the
/// reproduction tolerance; 3: and the polynomial reproduction).
pub const COEFFICIENTS_FORMAT_VERSION: u32 = 3;
const MAGIC: &[u8; 8] = b"FFCOEFF\0";

/// A trained basis with what produced it, as saved and cached.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrainedCoefficients {
    /// The basis. Its columns are the trained span rotated by Rayleigh–Ritz on the last step's
    /// quadrature (𝓜-orthonormal there), and its `eigenvalues` the Ritz values, ascending:
    /// upper bounds of the true eigenvalues, equal only when training found the eigen subspace.
    pub basis: SkinningBasis,
    /// The options it was trained with.
    pub params: CoefficientTrainingParams,
    /// What training measured.
    pub report: CoefficientTrainingReport,
}

impl TrainedCoefficients {
    /// Saves (magic, format version, bincode), atomically.
    ///
    /// # Errors
    /// [`ModelFileError::Io`] naming the path.
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), ModelFileError> {
        model_file::save(path.as_ref(), MAGIC, COEFFICIENTS_FORMAT_VERSION, self)
    }

    /// Loads what [`TrainedCoefficients::save`] wrote.
    ///
    /// # Errors
    /// [`ModelFileError`]: unreadable, wrong magic or version, or damaged.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, ModelFileError> {
        model_file::load(
            path.as_ref(),
            MAGIC,
            COEFFICIENTS_FORMAT_VERSION,
            "trained coefficients",
        )
    }
}

/// Integration points one loss evaluation sums over: rows of a shape-function table, each with
/// its rest position (m), volume (m³) and material.
pub struct QuadratureBatch<'a> {
    /// Shape functions at (a superset of) the points.
    pub shape: &'a ShapeFunctions,
    /// Which rows of `shape` (repetition allowed).
    pub rows: Vec<usize>,
    /// Rest position of each row's point.
    pub positions: Vec<Vector3<f64>>,
    /// Volume of each row's point.
    pub volumes: Vec<f64>,
    /// Material of each row's point.
    pub lame: Vec<LameParameters>,
}

impl QuadratureBatch<'_> {
    /// `(k, ϕ_k, ∇ϕ_k)` of the kernels reaching the point of batch row `r`.
    fn entries(&self, r: usize) -> impl Iterator<Item = (usize, f64, &Vector3<f64>)> {
        let row = self.rows[r];
        self.shape
            .kernels(row)
            .iter()
            .zip(self.shape.values(row))
            .zip(self.shape.gradients(row))
            .map(|((&k, &phi), dphi)| (k as usize, phi, dphi))
    }

    /// `W_i` (m) and `∇W_i` (m × 3, per mode) at row `r` for row-major `c` (K × m).
    fn weights_at(&self, r: usize, c: &[f64], m: usize) -> (Vec<f64>, Vec<Vector3<f64>>) {
        let mut w = vec![0.0; m];
        let mut grad = vec![Vector3::zeros(); m];
        for (k, phi, dphi) in self.entries(r) {
            let ck = &c[k * m..(k + 1) * m];
            for j in 0..m {
                w[j] += phi * ck[j];
                grad[j] += dphi * ck[j];
            }
        }
        (w, grad)
    }

    /// Adds `Σ_r ϕ_k(X_r) d_w[r][j] + ∇ϕ_k(X_r) · d_grad[r][j]` into `gradient[k·m + j]`, rows
    /// in order (so the sum is deterministic).
    fn scatter(&self, per_row: &[(Vec<f64>, Vec<Vector3<f64>>)], m: usize, gradient: &mut [f64]) {
        for (r, (d_w, d_grad)) in per_row.iter().enumerate() {
            for (k, phi, dphi) in self.entries(r) {
                let g = &mut gradient[k * m..(k + 1) * m];
                for j in 0..m {
                    g[j] += phi * d_w[j] + dphi.dot(&d_grad[j]);
                }
            }
        }
    }

    /// `(H_w c, 𝓜 c)` of this quadrature (both K × m), without forming H_w or 𝓜:
    /// `H_w c = Σ_i v_i (λ_i+4μ_i) ∇ϕ(X_i) ∇W(X_i)ᵀ`, `𝓜 c = Σ_i v_i ϕ(X_i) W(X_i)ᵀ`.
    pub fn weight_forms(&self, c: &[f64], m: usize) -> (Mat<f64>, Mat<f64>) {
        let per_row: Vec<(Vec<f64>, Vec<Vector3<f64>>)> = (0..self.rows.len())
            .into_par_iter()
            .map(|r| {
                let (w, grad) = self.weights_at(r, c, m);
                let v = self.volumes[r];
                let s = v * self.lame[r].weight_space_hessian_modulus();
                (
                    w.iter().map(|x| v * x).collect(),
                    grad.iter().map(|g| g * s).collect(),
                )
            })
            .collect();
        let k = self.shape.kernel_count();
        let mut mass = vec![0.0; k * m];
        let mut hessian = vec![0.0; k * m];
        for (r, (vw, sg)) in per_row.iter().enumerate() {
            for (k, phi, dphi) in self.entries(r) {
                let base = k * m;
                for j in 0..m {
                    mass[base + j] += phi * vw[j];
                    hessian[base + j] += dphi.dot(&sg[j]);
                }
            }
        }
        (
            Mat::from_fn(k, m, |a, j| hessian[a * m + j]),
            Mat::from_fn(k, m, |a, j| mass[a * m + j]),
        )
    }
}

/// One batch row of the random-handle loss: its energy `v Σ_t Ψ(F_t)` (J), the derivatives
/// with respect to W (m) and ∇W (m × 3), and W itself (for the orthogonality term).
struct HandleLossRow {
    energy: f64,
    d_w: Vec<f64>,
    d_grad: Vec<Vector3<f64>>,
    w: Vec<f64>,
}

/// The random-handle loss and its gradient with respect to row-major c (K × m).
///
/// `transforms[t][j]` is `Z_j` row-major (3 × 4); `ratio` the linear-to-Neo-Hookean ramp.
/// Energy term `(Σ_r v_r Σ_t Ψ_r(F))`, orthogonality `mean((WᵀW − I)²)` over the batch's raw W.
#[allow(non_snake_case)]
pub fn random_handle_loss(
    c: &[f64],
    m: usize,
    batch: &QuadratureBatch,
    transforms: &[Vec<[f64; 12]>],
    ratio: f64,
    params: &CoefficientTrainingParams,
) -> (StepLosses, Vec<f64>) {
    let b = batch.rows.len();
    // Per row: energy, ∂E/∂W (m), ∂E/∂∇W (m × 3), and W for the orthogonality term.
    let per_row: Vec<HandleLossRow> = (0..b)
        .into_par_iter()
        .map(|r| {
            let (w, grad) = batch.weights_at(r, c, m);
            let x = batch.positions[r];
            let bar = Vector4::new(x.x, x.y, x.z, 1.0);
            let p = &batch.lame[r];
            let v = batch.volumes[r];
            let mut energy = 0.0;
            let mut d_w = vec![0.0; m];
            let mut d_grad = vec![Vector3::zeros(); m];
            for z in transforms {
                // Z_j[:, :3] and Z_j X̄ per mode.
                let linear: Vec<Matrix3<f64>> = z
                    .iter()
                    .map(|zj| Matrix3::from_fn(|a, d| zj[4 * a + d]))
                    .collect();
                let moved: Vec<Vector3<f64>> = z
                    .iter()
                    .map(|zj| {
                        Vector3::from_fn(|a, _| {
                            zj[4 * a] * bar[0]
                                + zj[4 * a + 1] * bar[1]
                                + zj[4 * a + 2] * bar[2]
                                + zj[4 * a + 3]
                        })
                    })
                    .collect();
                let mut F = Matrix3::identity();
                for j in 0..m {
                    F += linear[j] * w[j] + moved[j] * grad[j].transpose();
                }
                energy += v
                    * ((1.0 - ratio) * LinearElastic.energy_density(p, &F)
                        + ratio * StableNeoHookean.energy_density(p, &F));
                let P = (LinearElastic.first_piola_kirchhoff(p, &F) * (1.0 - ratio)
                    + StableNeoHookean.first_piola_kirchhoff(p, &F) * ratio)
                    * v;
                for j in 0..m {
                    d_w[j] += P.dot(&linear[j]);
                    d_grad[j] += P.transpose() * moved[j];
                }
            }
            HandleLossRow {
                energy,
                d_w,
                d_grad,
                w,
            }
        })
        .collect();
    let elastic: f64 = per_row.iter().map(|r| r.energy).sum();
    let w = Mat::from_fn(b, m, |r, j| per_row[r].w[j]);
    let (ortho, d_ortho) = crate::simplicits::ortho_loss(&w);
    let scaled: Vec<(Vec<f64>, Vec<Vector3<f64>>)> = per_row
        .iter()
        .enumerate()
        .map(|(r, HandleLossRow { d_w, d_grad, .. })| {
            (
                (0..m)
                    .map(|j| params.elastic_weight * d_w[j] + params.ortho_weight * d_ortho[(r, j)])
                    .collect(),
                d_grad.iter().map(|g| g * params.elastic_weight).collect(),
            )
        })
        .collect();
    let mut gradient = vec![0.0; c.len()];
    batch.scatter(&scaled, m, &mut gradient);
    (
        StepLosses {
            elastic,
            ortho,
            total: params.elastic_weight * elastic + params.ortho_weight * ortho,
        },
        gradient,
    )
}

/// The Hessian loss `tr(cᵀ H_w c)/s + ortho_weight · mean((cᵀ𝓜c − I)²)` and its gradient
/// `2 H_w c / s + ortho_weight · (4/m²) 𝓜c (cᵀ𝓜c − I)`, from `hc = H_w c` and `mc = 𝓜 c`
/// (K × m) and row-major c.
pub fn weight_hessian_loss(
    c: &[f64],
    hc: &Mat<f64>,
    mc: &Mat<f64>,
    scale: f64,
    ortho_weight: f64,
) -> (StepLosses, Vec<f64>) {
    let (k, m) = (hc.nrows(), hc.ncols());
    let cm = Mat::from_fn(k, m, |a, j| c[a * m + j]);
    let energy: f64 = (0..m)
        .map(|j| (0..k).map(|a| cm[(a, j)] * hc[(a, j)]).sum::<f64>())
        .sum::<f64>()
        / scale;
    let mut gram = cm.transpose() * mc;
    for j in 0..m {
        gram[(j, j)] -= 1.0;
    }
    // Symmetrize against round-off: cᵀ𝓜c is symmetric in exact arithmetic.
    let gram = Mat::from_fn(m, m, |a, b| 0.5 * (gram[(a, b)] + gram[(b, a)]));
    let ortho = gram.norm_l2().powi(2) / (m * m) as f64;
    let d_ortho = mc * &gram * (4.0 / (m * m) as f64);
    let mut gradient = vec![0.0; k * m];
    for a in 0..k {
        for j in 0..m {
            gradient[a * m + j] = 2.0 * hc[(a, j)] / scale + ortho_weight * d_ortho[(a, j)];
        }
    }
    (
        StepLosses {
            elastic: energy,
            ortho,
            total: energy + ortho_weight * ortho,
        },
        gradient,
    )
}

/// Draws `count` uniform points in the solid the integration points represent: point i with
/// probability `v_i / V`, then uniform in the axis-aligned cube of volume `v_i` centred on it.
/// Returns the positions and the source indices.
pub fn sample_in_cells(
    points: &IntegrationPoints,
    count: usize,
    rng: &mut ChaCha8Rng,
) -> (Vec<Vector3<f64>>, Vec<usize>) {
    let cumulative: Vec<f64> = points
        .volumes()
        .iter()
        .scan(0.0, |acc, v| {
            *acc += v;
            Some(*acc)
        })
        .collect();
    let total = cumulative.last().copied().unwrap_or(0.0);
    (0..count)
        .map(|_| {
            let u = rng.random::<f64>() * total;
            let i = cumulative
                .partition_point(|&c| c <= u)
                .min(points.len() - 1);
            let side = points.volumes()[i].cbrt();
            let jitter = Vector3::from_fn(|_, _| (rng.random::<f64>() - 0.5) * side);
            (points.positions()[i] + jitter, i)
        })
        .unzip()
}

/// Trains the coefficients of m skinning weights on the object given by its integration points
/// and per-point Lamé parameters. `progress(step, losses)` is called after every step.
///
/// # Errors
/// [`CoefficientTrainingError::Invalid`] for empty or mismatched inputs or zero sizes;
/// kernel, shape-function and assembly errors by phase; [`CoefficientTrainingError::Diverged`]
/// if a loss becomes non-finite.
pub fn train_coefficients(
    points: &IntegrationPoints,
    lame: &[LameParameters],
    params: &CoefficientTrainingParams,
    mut progress: impl FnMut(usize, &StepLosses),
) -> Result<TrainedCoefficients, CoefficientTrainingError> {
    let start = Instant::now();
    if points.is_empty() || lame.len() != points.len() {
        return Err(CoefficientTrainingError::Invalid(format!(
            "{} points and {} material entries",
            points.len(),
            lame.len()
        )));
    }
    if params.modes == 0 || params.steps == 0 || params.points_per_step == 0 {
        return Err(CoefficientTrainingError::Invalid(
            "modes, steps and points_per_step must be positive".into(),
        ));
    }
    for (name, value) in [
        ("transform_std", params.transform_std),
        ("learning_rate", params.learning_rate),
        ("elastic_weight", params.elastic_weight),
        ("ortho_weight", params.ortho_weight),
    ] {
        if !(value.is_finite() && value >= 0.0) {
            return Err(CoefficientTrainingError::Invalid(format!(
                "{name} = {value} must be finite and non-negative"
            )));
        }
    }
    // The Hessian objective, like the eigen solve, is minimized by the constant field first
    // (zero energy); it trains m + 1 columns and drops the lowest, as the eigen solve does.
    let dropped = match params.loss {
        CoefficientLoss::RandomHandles => 0,
        CoefficientLoss::WeightHessian => 1,
    };
    let m = params.modes + dropped;
    let kernels = place_kernels(points.positions(), &params.kernels)?;
    let k = kernels.len();
    if m >= k {
        return Err(CoefficientTrainingError::Invalid(format!(
            "m = {} modes need more than {k} kernels",
            params.modes
        )));
    }
    let scale = lame
        .iter()
        .map(|p| p.weight_space_hessian_modulus())
        .fold(0.0, f64::max);
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
    let bound = 1.0 / (k as f64).sqrt();
    let mut c: Vec<f64> = (0..k * m)
        .map(|_| bound * (2.0 * rng.random::<f64>() - 1.0))
        .collect();

    // Fixed-grid data: shape functions at every point, and for the Hessian loss the matrices.
    let grid_shape = match params.points {
        TrainingPoints::Grid => Some(evaluate_shape_functions(
            &kernels,
            points.positions(),
            &params.shape_functions,
        )?),
        TrainingPoints::Random => None,
    };
    let matrices: Option<WeightSpaceMatrices> = match (&grid_shape, params.loss) {
        (Some(shape), CoefficientLoss::WeightHessian) => Some(assemble_weight_space_matrices(
            shape,
            points.volumes(),
            lame,
        )?),
        _ => None,
    };
    let setup_seconds = start.elapsed().as_secs_f64();

    let volume = points.total_volume();
    let b = params.points_per_step;
    let mut adam = Adam::new(
        k * m,
        AdamParams {
            learning_rate: params.learning_rate,
            ..AdamParams::default()
        },
    );
    let (mut first, mut last) = (None, None);
    let mut ritz_pairs = None;
    for step in 0..params.steps {
        // This step's points: the assembled grid quadrature, draws from the grid, or fresh
        // random points.
        let random_shape;
        let quadrature = match (&matrices, &grid_shape) {
            (Some(matrices), _) => StepQuadrature::Assembled(matrices),
            (None, Some(shape)) => {
                let rows: Vec<usize> = (0..b).map(|_| rng.random_range(0..points.len())).collect();
                StepQuadrature::Batch(QuadratureBatch {
                    shape,
                    positions: rows.iter().map(|&i| points.positions()[i]).collect(),
                    volumes: vec![volume / b as f64; b],
                    lame: rows.iter().map(|&i| lame[i]).collect(),
                    rows,
                })
            }
            (None, None) => {
                let (positions, sources) = sample_in_cells(points, b, &mut rng);
                random_shape =
                    evaluate_shape_functions(&kernels, &positions, &params.shape_functions)?;
                StepQuadrature::Batch(QuadratureBatch {
                    shape: &random_shape,
                    rows: (0..b).collect(),
                    positions,
                    volumes: vec![volume / b as f64; b],
                    lame: sources.iter().map(|&i| lame[i]).collect(),
                })
            }
        };
        let (losses, gradient) = match (&quadrature, params.loss) {
            (StepQuadrature::Assembled(matrices), _) => {
                let cm = Mat::from_fn(k, m, |a, j| c[a * m + j]);
                let hc = &matrices.hessian * &cm;
                let mc = &matrices.mass * &cm;
                weight_hessian_loss(&c, &hc, &mc, scale, params.ortho_weight)
            }
            (StepQuadrature::Batch(batch), CoefficientLoss::WeightHessian) => {
                let (hc, mc) = batch.weight_forms(&c, m);
                weight_hessian_loss(&c, &hc, &mc, scale, params.ortho_weight)
            }
            (StepQuadrature::Batch(batch), CoefficientLoss::RandomHandles) => {
                let transforms = random_handle_transforms(
                    &mut rng,
                    params.transforms_per_step,
                    m,
                    params.transform_std,
                );
                let ratio = step as f64 / params.steps as f64;
                random_handle_loss(&c, m, batch, &transforms, ratio, params)
            }
        };
        if !losses.total.is_finite() {
            return Err(CoefficientTrainingError::Diverged {
                step,
                loss: losses.total,
            });
        }
        adam.step(&mut c, &gradient);
        first.get_or_insert(losses);
        last = Some(losses);
        progress(step, &losses);
        if step + 1 == params.steps {
            ritz_pairs = rayleigh_ritz(&c, m, &quadrature);
        }
    }
    let (Some(first), Some(last)) = (first, last) else {
        return Err(CoefficientTrainingError::Invalid("no steps".into()));
    };

    // Rayleigh–Ritz in the trained span (columns rotated to the small generalized eigenvectors,
    // ascending), then the lowest, near-constant one dropped for the Hessian loss.
    let (ritz_values, ritz_vectors) = ritz_pairs.ok_or_else(|| {
        CoefficientTrainingError::Invalid("the trained columns are linearly dependent".into())
    })?;
    let trained = DMatrix::from_fn(k, m, |a, j| c[a * m + j]);
    let rotated = trained * ritz_vectors;
    let coefficients = rotated.columns(dropped, params.modes).into_owned();
    let eigenvalues = ritz_values[dropped..].to_vec();
    let metadata = BasisMetadata {
        material: format!(
            "trained coefficients ({}), Table 3 ablation",
            params.label()
        ),
        integration_points: points.len(),
        mass_condition_number: f64::NAN,
        discarded_mass_directions: 0,
        constant_eigenvalue: f64::NAN,
    };
    let basis = SkinningBasis::new(
        kernels,
        params.shape_functions,
        coefficients,
        eigenvalues,
        metadata,
    );
    Ok(TrainedCoefficients {
        basis,
        params: *params,
        report: CoefficientTrainingReport {
            seconds: start.elapsed().as_secs_f64(),
            setup_seconds,
            first,
            last,
        },
    })
}

/// The points one training step integrates over.
enum StepQuadrature<'a> {
    /// H_w and 𝓜 assembled on all grid points (Hessian loss on the grid).
    Assembled(&'a WeightSpaceMatrices),
    /// A drawn or random batch.
    Batch(QuadratureBatch<'a>),
}

/// Rayleigh–Ritz on a step's quadrature: the pairs `(θ, y)` of `(cᵀH_w c) y = θ (cᵀ𝓜c) y`,
/// θ ascending, y as columns normalized so the rotated columns `c y` are 𝓜-orthonormal. `None`
/// when `cᵀ𝓜c` is not positive definite (linearly dependent columns).
fn rayleigh_ritz(
    c: &[f64],
    m: usize,
    quadrature: &StepQuadrature,
) -> Option<(Vec<f64>, DMatrix<f64>)> {
    let k = c.len() / m;
    let cm = Mat::from_fn(k, m, |a, j| c[a * m + j]);
    let (hc, mc) = match quadrature {
        StepQuadrature::Assembled(matrices) => (&matrices.hessian * &cm, &matrices.mass * &cm),
        StepQuadrature::Batch(batch) => batch.weight_forms(c, m),
    };
    let small = |x: &Mat<f64>| {
        let p = cm.transpose() * x;
        DMatrix::from_fn(m, m, |a, b| 0.5 * (p[(a, b)] + p[(b, a)]))
    };
    let (a, b) = (small(&hc), small(&mc));
    let l = b.cholesky()?.l();
    let l_inv = l.clone().try_inverse()?;
    let reduced = &l_inv * a * l_inv.transpose();
    let eigen = nalgebra::SymmetricEigen::new((&reduced + reduced.transpose()) * 0.5);
    let mut order: Vec<usize> = (0..m).collect();
    order.sort_by(|&i, &j| eigen.eigenvalues[i].total_cmp(&eigen.eigenvalues[j]));
    let vectors = l_inv.transpose() * &eigen.eigenvectors;
    Some((
        order.iter().map(|&i| eigen.eigenvalues[i]).collect(),
        DMatrix::from_fn(m, m, |r, j| vectors[(r, order[j])]),
    ))
}
