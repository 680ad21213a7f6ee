//! The Simplicits baseline (paper Sec. 3.1, design §3.9): skinning weights from an MLP trained on
//! random handle transforms, simulated by the same reduced simulator as ours.
//!
//! Training, per Adam step (defaults as in the authors' Kaolin release):
//! - `points_per_step` integration points drawn with replacement;
//! - `transforms_per_step` random handle sets, every entry of each `3 × 4` `Z_j` from
//!   `N(0, transform_std²)`;
//! - `L = elastic_weight · L_elastic + ortho_weight · L_ortho` with
//!   `L_elastic = (V/N) Σ_points Σ_transforms [(1−r) Ψ_lin(F) + r Ψ_NH(F)]`, `r = step/steps`,
//!   `F` by central differences of the LBS map `x(X) = X + Σ_j W_j(X) Z_j X̄` with step
//!   `fd_step` in unit-cube coordinates, and `L_ortho = mean((WᵀW − I)²)` over the `m × m`
//!   entries, W the raw outputs at the sampled points.
//!
//! The network sees the point mapped to the unit cube by the bounding box of the integration
//! points; the constant handle is prepended at simulation time ([`SimplicitsField`]).

use std::path::Path;
use std::time::Instant;

use faer::Mat;
use hyperelastic::{HyperelasticMaterial, LameParameters, LinearElastic, StableNeoHookean};
use nalgebra::{DMatrix, Matrix3, Vector3, Vector4};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use reduced_sim::SkinningField;
use rkpm_core::IntegrationPoints;
use serde::{Deserialize, Serialize};
use skin_eigen::SkinningWeights;
use thiserror::Error;

use crate::adam::{Adam, AdamParams};
use crate::mlp::{Mlp, MlpShape, Tape};
use crate::model_file::{self, ModelFileError};

/// Training options; defaults are design §3.9's.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SimplicitsParams {
    /// Skinning weights m learned by the network (default 16).
    pub modes: usize,
    /// Adam steps (default 10 000).
    pub steps: usize,
    /// Points sampled per step, with replacement (default 1000).
    pub points_per_step: usize,
    /// Random handle sets per step (default 10).
    pub transforms_per_step: usize,
    /// Standard deviation of each handle-transform entry (default 0.1).
    pub transform_std: f64,
    /// Adam learning rate (default 1e-3).
    pub learning_rate: f64,
    /// Weight of the elastic loss (default 0.1).
    pub elastic_weight: f64,
    /// Weight of the orthogonality loss (default 1e6).
    pub ortho_weight: f64,
    /// Central-difference step in unit-cube coordinates (default 3.2e-4).
    pub fd_step: f64,
    /// Seed of the initialization and of the sampling (default 0).
    pub seed: u64,
}

impl Default for SimplicitsParams {
    fn default() -> Self {
        SimplicitsParams {
            modes: 16,
            steps: 10_000,
            points_per_step: 1000,
            transforms_per_step: 10,
            transform_std: 0.1,
            learning_rate: 1e-3,
            elastic_weight: 0.1,
            ortho_weight: 1e6,
            fd_step: 3.2e-4,
            seed: 0,
        }
    }
}

/// Training or evaluation cannot proceed.
#[derive(Debug, Error, PartialEq)]
pub enum SimplicitsError {
    /// A parameter is out of range or the inputs do not match.
    #[error("invalid Simplicits input: {0}")]
    Invalid(String),
    /// A loss became NaN or infinite.
    #[error("training diverged at step {step}: loss {loss}")]
    Diverged {
        /// 0-based step.
        step: usize,
        /// The loss.
        loss: f64,
    },
    /// A query point has a NaN or infinite coordinate.
    #[error("query point {index} is not finite")]
    NonFinitePoint {
        /// Index of the point.
        index: usize,
    },
}

/// Losses of one training step.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct StepLosses {
    /// `L_elastic` (J).
    pub elastic: f64,
    /// `L_ortho` (dimensionless).
    pub ortho: f64,
    /// `elastic_weight · L_elastic + ortho_weight · L_ortho`.
    pub total: f64,
}

/// What training measured.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrainingReport {
    /// Wall time (s).
    pub seconds: f64,
    /// Losses of the first and the last step.
    pub first: StepLosses,
    /// Losses of the last step.
    pub last: StepLosses,
}

/// Version written into saved Simplicits models.
pub const SIMPLICITS_FORMAT_VERSION: u32 = 1;
const MAGIC: &[u8; 8] = b"FFSIMPL\0";

/// A trained field with what produced it, as saved and cached.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrainedSimplicits {
    /// The field.
    pub field: SimplicitsField,
    /// The options it was trained with.
    pub params: SimplicitsParams,
    /// What training measured.
    pub report: TrainingReport,
}

impl TrainedSimplicits {
    /// Saves (magic, format version, bincode), atomically.
    ///
    /// # Errors
    /// [`ModelFileError::Io`] naming the path.
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), ModelFileError> {
        model_file::save(path.as_ref(), MAGIC, SIMPLICITS_FORMAT_VERSION, self)
    }

    /// Loads what [`TrainedSimplicits::save`] wrote.
    ///
    /// # Errors
    /// [`ModelFileError`]: unreadable, wrong magic or version, or damaged.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, ModelFileError> {
        model_file::load(
            path.as_ref(),
            MAGIC,
            SIMPLICITS_FORMAT_VERSION,
            "Simplicits model",
        )
    }
}

/// A trained network as a skinning field: `W(X) = [1, mlp((X − min) / extent)]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SimplicitsField {
    mlp: Mlp,
    min: Vector3<f64>,
    extent: Vector3<f64>,
}

impl SimplicitsField {
    /// A field from a network and the box its inputs are normalized by.
    ///
    /// # Errors
    /// [`SimplicitsError::Invalid`] if the network does not take 3 inputs or a box side is not
    /// positive.
    pub fn new(mlp: Mlp, min: Vector3<f64>, extent: Vector3<f64>) -> Result<Self, SimplicitsError> {
        if mlp.shape().inputs != 3 || !extent.iter().all(|e| *e > 0.0 && e.is_finite()) {
            return Err(SimplicitsError::Invalid(format!(
                "need a 3-input network and a positive box, got {} inputs and extent {extent:?}",
                mlp.shape().inputs
            )));
        }
        Ok(SimplicitsField { mlp, min, extent })
    }

    /// The network.
    pub fn mlp(&self) -> &Mlp {
        &self.mlp
    }

    fn unit_cube(&self, points: &[Vector3<f64>]) -> Mat<f64> {
        Mat::from_fn(points.len(), 3, |i, d| {
            (points[i][d] - self.min[d]) / self.extent[d]
        })
    }
}

impl SkinningField for SimplicitsField {
    type Error = SimplicitsError;

    fn handles(&self) -> usize {
        self.mlp.shape().outputs + 1
    }

    fn evaluate(&self, points: &[Vector3<f64>]) -> Result<SkinningWeights, SimplicitsError> {
        if let Some(index) = points.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
            return Err(SimplicitsError::NonFinitePoint { index });
        }
        let (y, dy) = self
            .mlp
            .forward_with_input_derivatives(self.unit_cube(points).as_ref());
        let n = points.len();
        let m = self.mlp.shape().outputs;
        let weights = DMatrix::from_fn(n, m + 1, |i, j| if j == 0 { 1.0 } else { y[(i, j - 1)] });
        let gradients = std::array::from_fn(|d| {
            DMatrix::from_fn(n, m + 1, |i, j| {
                if j == 0 {
                    0.0
                } else {
                    dy[d][(i, j - 1)] / self.extent[d]
                }
            })
        });
        Ok(SkinningWeights { weights, gradients })
    }
}

/// `L_ortho = mean over the m × m entries of (WᵀW − I)²` and its gradient with respect to W
/// (`B × m`): `(4/m²) W (WᵀW − I)`.
pub fn ortho_loss(w: &Mat<f64>) -> (f64, Mat<f64>) {
    let m = w.ncols();
    let mut g = w.transpose() * w;
    for a in 0..m {
        g[(a, a)] -= 1.0;
    }
    let loss = (0..m)
        .flat_map(|a| (0..m).map(move |b| (a, b)))
        .map(|(a, b)| g[(a, b)] * g[(a, b)])
        .sum::<f64>()
        / (m * m) as f64;
    let gradient = w * &g * (4.0 / (m * m) as f64);
    (loss, gradient)
}

/// A standard normal sample (Box–Muller).
fn standard_normal(rng: &mut ChaCha8Rng) -> f64 {
    let u1: f64 = 1.0 - rng.random::<f64>(); // (0, 1]
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// `sets` random handle sets of `modes` transforms each, every entry of each row-major `3 × 4`
/// `Z_j` drawn from `N(0, std²)` (one step's draws, shared with the coefficient ablations).
pub(crate) fn random_handle_transforms(
    rng: &mut ChaCha8Rng,
    sets: usize,
    modes: usize,
    std: f64,
) -> Vec<Vec<[f64; 12]>> {
    (0..sets)
        .map(|_| {
            (0..modes)
                .map(|_| std::array::from_fn(|_| std * standard_normal(rng)))
                .collect()
        })
        .collect()
}

/// Central-difference deformation gradient of the displacement field `u`: column k is
/// `(u(X + h_k e_k) − u(X − h_k e_k)) / (2 h_k)`, plus the identity. `plus[k]`, `minus[k]` are
/// the displacements at the shifted points.
pub fn central_difference_deformation_gradient(
    plus: &[Vector3<f64>; 3],
    minus: &[Vector3<f64>; 3],
    steps: &Vector3<f64>,
) -> Matrix3<f64> {
    Matrix3::from_fn(|r, k| {
        let identity = if r == k { 1.0 } else { 0.0 };
        identity + (plus[k][r] - minus[k][r]) / (2.0 * steps[k])
    })
}

/// The fixed data of a training run.
pub struct Problem<'a> {
    /// Integration point positions (m).
    pub positions: &'a [Vector3<f64>],
    /// Lamé parameters per point.
    pub lame: &'a [LameParameters],
    /// Total volume V (m³).
    pub volume: f64,
    /// Physical central-difference step per axis (`fd_step` × box extent, m).
    pub h: Vector3<f64>,
    /// The options.
    pub params: &'a SimplicitsParams,
}

/// One step's random draws.
#[derive(Clone, Debug)]
pub struct Batch {
    /// Indices of the sampled points (with repetition).
    pub sample: Vec<usize>,
    /// Handle sets: `transforms[t][j]` is `Z_j` row-major (`3 × 4`).
    pub transforms: Vec<Vec<[f64; 12]>>,
    /// Linear-to-Neo-Hookean ramp r = step / steps.
    pub ratio: f64,
}

/// The network's buffers of one training step, kept from step to step so a step allocates no
/// large matrix ([`Problem::loss_and_gradient_with`]).
#[derive(Clone, Debug)]
pub struct StepBuffers {
    tape: Tape,
    d_y: Mat<f64>,
    /// ∂loss/∂parameters of the last step (length [`Mlp::parameters`]).
    pub gradient: Vec<f64>,
}

impl Default for StepBuffers {
    fn default() -> Self {
        StepBuffers {
            tape: Tape::default(),
            d_y: Mat::new(),
            gradient: Vec::new(),
        }
    }
}

impl Problem<'_> {
    /// The step's losses and their gradient with respect to the network parameters.
    pub fn loss_and_gradient(
        &self,
        field: &SimplicitsField,
        batch: &Batch,
    ) -> (StepLosses, Vec<f64>) {
        let mut buffers = StepBuffers::default();
        let losses = self.loss_and_gradient_with(field, batch, &mut buffers);
        (losses, buffers.gradient)
    }

    /// [`Problem::loss_and_gradient`] with the gradient left in `buffers.gradient`, reusing
    /// `buffers`' matrices (the same values).
    #[allow(non_snake_case)]
    pub fn loss_and_gradient_with(
        &self,
        field: &SimplicitsField,
        batch: &Batch,
        buffers: &mut StepBuffers,
    ) -> StepLosses {
        let Batch {
            sample,
            transforms,
            ratio,
        } = batch;
        let (positions, lame, h, params) = (self.positions, self.lame, self.h, self.params);
        let (b, m) = (sample.len(), field.mlp.shape().outputs);
        let (min, extent) = (field.min, field.extent);
        let ratio = *ratio;
        // Stencil rows: block 0 the points, block 1 + 2k / 2 + 2k the ± shifts along axis k.
        let stencil = |row: usize| -> Vector3<f64> {
            let (block, i) = (row / b, row % b);
            let mut x = positions[sample[i]];
            if block > 0 {
                let k = (block - 1) / 2;
                x[k] += if block % 2 == 1 { h[k] } else { -h[k] };
            }
            x
        };
        let inputs = Mat::from_fn(7 * b, 3, |row, d| (stencil(row)[d] - min[d]) / extent[d]);
        field.mlp.forward_into(inputs.as_ref(), &mut buffers.tape);
        let y = buffers.tape.output();

        let w = Mat::from_fn(b, m, |i, j| y[(i, j)]);
        let (ortho, d_ortho) = ortho_loss(&w);

        // Elastic loss and its derivative with respect to the outputs at the 6 shifted points,
        // per sampled point in parallel, summed in index order.
        let per_point: Vec<(f64, Vec<[f64; 6]>)> = (0..b)
            .into_par_iter()
            .map(|i| {
                // Compiled for the widest SIMD the CPU has ([`PointTerms`]); the arithmetic is
                // the same, so are the results.
                pulp::Arch::new().dispatch(PointTerms {
                    lame: &lame[sample[i]],
                    xs: std::array::from_fn(|s| stencil((s + 1) * b + i)),
                    weights: (0..m)
                        .map(|j| std::array::from_fn(|s| y[((s + 1) * b + i, j)]))
                        .collect(),
                    transforms,
                    h,
                    ratio,
                })
            })
            .collect();
        let scale = self.volume / b as f64;
        let elastic = scale * per_point.iter().map(|(e, _)| e).sum::<f64>();
        let total = params.elastic_weight * elastic + params.ortho_weight * ortho;
        let d_y = &mut buffers.d_y;
        d_y.resize_with(7 * b, m, |_, _| 0.0);
        for j in 0..m {
            for (row, v) in d_y.col_as_slice_mut(j).iter_mut().enumerate() {
                let (block, i) = (row / b, row % b);
                *v = if block == 0 {
                    params.ortho_weight * d_ortho[(i, j)]
                } else {
                    params.elastic_weight * scale * per_point[i].1[j][block - 1]
                };
            }
        }
        buffers.gradient.resize(field.mlp.parameters().len(), 0.0);
        field.mlp.backward_into(
            &mut buffers.tape,
            buffers.d_y.as_ref(),
            &mut buffers.gradient,
        );
        StepLosses {
            elastic,
            ortho,
            total,
        }
    }
}

/// Trains a Simplicits network on the object given by its integration points and per-point
/// Lamé parameters. `progress(step, losses)` is called after every step.
///
/// # Errors
/// [`SimplicitsError::Invalid`] for empty or mismatched inputs or zero sizes;
/// [`SimplicitsError::Diverged`] if a loss becomes non-finite.
#[allow(non_snake_case)]
pub fn train_simplicits(
    points: &IntegrationPoints,
    lame: &[LameParameters],
    params: &SimplicitsParams,
    mut progress: impl FnMut(usize, &StepLosses),
) -> Result<(SimplicitsField, TrainingReport), SimplicitsError> {
    let start = Instant::now();
    let positions = points.positions();
    if positions.is_empty() || lame.len() != positions.len() {
        return Err(SimplicitsError::Invalid(format!(
            "{} points and {} material entries",
            positions.len(),
            lame.len()
        )));
    }
    if params.modes == 0 || params.steps == 0 || params.points_per_step == 0 {
        return Err(SimplicitsError::Invalid(
            "modes, steps and points_per_step must be positive".into(),
        ));
    }
    let Some(bbox) = rkpm_core::Aabb::from_points(positions) else {
        return Err(SimplicitsError::Invalid("no points".into()));
    };
    let extent = bbox.extent().map(|e| if e > 0.0 { e } else { 1.0 });
    let mut field = SimplicitsField::new(
        Mlp::new(MlpShape::simplicits(params.modes), params.seed),
        bbox.min,
        extent,
    )?;
    let mut adam = Adam::new(
        field.mlp.parameters().len(),
        AdamParams {
            learning_rate: params.learning_rate,
            ..AdamParams::default()
        },
    );
    if !(params.transform_std >= 0.0 && params.transform_std.is_finite()) {
        return Err(SimplicitsError::Invalid(format!(
            "transform_std {} must be finite and non-negative",
            params.transform_std
        )));
    }
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed.wrapping_add(1));
    let (b, m, t) = (
        params.points_per_step,
        params.modes,
        params.transforms_per_step,
    );
    let problem = Problem {
        positions,
        lame,
        volume: points.total_volume(),
        h: extent * params.fd_step,
        params,
    };
    let mut first = None;
    let mut last = None;
    let mut buffers = StepBuffers::default();
    for step in 0..params.steps {
        let ratio = step as f64 / params.steps as f64;
        let sample: Vec<usize> = (0..b)
            .map(|_| rng.random_range(0..positions.len()))
            .collect();
        let transforms = random_handle_transforms(&mut rng, t, m, params.transform_std);
        let batch = Batch {
            sample,
            transforms,
            ratio,
        };
        let losses = problem.loss_and_gradient_with(&field, &batch, &mut buffers);
        if !losses.total.is_finite() {
            return Err(SimplicitsError::Diverged {
                step,
                loss: losses.total,
            });
        }
        adam.step(field.mlp.parameters_mut(), &buffers.gradient);
        first.get_or_insert(losses);
        last = Some(losses);
        progress(step, &losses);
    }
    let (Some(first), Some(last)) = (first, last) else {
        return Err(SimplicitsError::Invalid("no steps".into()));
    };
    Ok((
        field,
        TrainingReport {
            seconds: start.elapsed().as_secs_f64(),
            first,
            last,
        },
    ))
}

/// One sampled point's elastic terms of [`Problem::loss_and_gradient_with`]: its energy summed
/// over the handle sets and `∂/∂W_j` at its six shifted copies (`[j][s]`). A
/// [`pulp::WithSimd`] with an `inline(always)` body, so that all of it is compiled inside the
/// dispatched, SIMD-enabled function (a closure's body is not inlined there).
struct PointTerms<'a> {
    lame: &'a LameParameters,
    /// The point's six shifted copies (m): ±h along x, y, z.
    xs: [Vector3<f64>; 6],
    /// The network's weights at the six copies: `weights[j][s]`.
    weights: Vec<[f64; 6]>,
    transforms: &'a [Vec<[f64; 12]>],
    h: Vector3<f64>,
    ratio: f64,
}

impl pulp::WithSimd for PointTerms<'_> {
    type Output = (f64, Vec<[f64; 6]>);

    #[inline(always)]
    #[allow(non_snake_case)]
    fn with_simd<S: pulp::Simd>(self, _: S) -> Self::Output {
        let PointTerms {
            lame: p,
            xs,
            weights,
            transforms,
            h,
            ratio,
        } = self;
        let m = weights.len();
        let bars: [Vector4<f64>; 6] = xs.map(|x| Vector4::new(x.x, x.y, x.z, 1.0));
        let mut energy = 0.0;
        // images[j][s] = Z_j X̄_s, the handle's affine image of shifted point s: shared by
        // the displacement u_s = Σ_j W_j Z_j X̄_s and its derivative in W_j.
        let mut images = vec![[Vector3::<f64>::zeros(); 6]; m];
        // d_w[j][s]: ∂(elastic sum)/∂W_j at shifted point s.
        let mut d_w = vec![[0.0; 6]; m];
        for z in transforms {
            for (image, zj) in images.iter_mut().zip(z) {
                for (s, bar) in bars.iter().enumerate() {
                    image[s] = Vector3::from_fn(|r, _| {
                        zj[4 * r] * bar[0]
                            + zj[4 * r + 1] * bar[1]
                            + zj[4 * r + 2] * bar[2]
                            + zj[4 * r + 3]
                    });
                }
            }
            let u: [Vector3<f64>; 6] = std::array::from_fn(|s| {
                let mut u = Vector3::zeros();
                for (w, image) in weights.iter().zip(&images) {
                    u += image[s] * w[s];
                }
                u
            });
            let F = central_difference_deformation_gradient(
                &[u[0], u[2], u[4]],
                &[u[1], u[3], u[5]],
                &h,
            );
            energy += (1.0 - ratio) * LinearElastic.energy_density(p, &F)
                + ratio * StableNeoHookean.energy_density(p, &F);
            let P = LinearElastic.first_piola_kirchhoff(p, &F) * (1.0 - ratio)
                + StableNeoHookean.first_piola_kirchhoff(p, &F) * ratio;
            for s in 0..6 {
                let k = s / 2;
                let sign = if s % 2 == 0 { 1.0 } else { -1.0 };
                // ∂Ψ/∂u_s = ± P[:, k] / (2 h_k); u_s = Σ_j W_j Z_j X̄_s.
                let d_u = P.column(k) * (sign / (2.0 * h[k]));
                for (d, image) in d_w.iter_mut().zip(&images) {
                    d[s] += d_u.dot(&image[s]);
                }
            }
        }
        (energy, d_w)
    }
}
