//! A small fully connected network for the Simplicits baseline (design §3.9): forward pass,
//! reverse-mode gradients, PyTorch-default initialization, all in f64.
//!
//! Layout: `in → width → (hidden_layers × width→width) → out`, ELU after every layer but the
//! last, the output linear. A layer computes `Y = X Wᵀ + 1 bᵀ` on a batch `X` (`B × in`, one
//! sample per row), `W` being `out × in`. All parameters live in one flat vector (per layer: `W`
//! row-major, then `b`), which is what [`crate::adam::Adam`] updates.

use std::path::Path;

use faer::{Mat, MatRef};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::model_file::{self, ModelFileError};

/// Sizes of an [`Mlp`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct MlpShape {
    /// Inputs per sample (3 for a point).
    pub inputs: usize,
    /// Width of every hidden layer (Simplicits: 64).
    pub width: usize,
    /// Hidden `width → width` layers after the first `inputs → width` one (Simplicits: 6).
    pub hidden_layers: usize,
    /// Outputs per sample (the number of skinning weights m).
    pub outputs: usize,
}

impl MlpShape {
    /// design §3.9's network: 3 → 64 → 6 × (64 → 64) → m.
    pub fn simplicits(modes: usize) -> Self {
        MlpShape {
            inputs: 3,
            width: 64,
            hidden_layers: 6,
            outputs: modes,
        }
    }

    /// `(inputs, outputs)` of each linear layer, first to last.
    pub fn layer_sizes(&self) -> Vec<(usize, usize)> {
        let mut sizes = vec![(self.inputs, self.width)];
        sizes.extend(std::iter::repeat_n(
            (self.width, self.width),
            self.hidden_layers,
        ));
        sizes.push((self.width, self.outputs));
        sizes
    }

    /// Total number of parameters.
    pub fn parameter_count(&self) -> usize {
        self.layer_sizes().iter().map(|(i, o)| o * i + o).sum()
    }
}

/// Version written into saved networks.
pub const MLP_FORMAT_VERSION: u32 = 1;
const MAGIC: &[u8; 8] = b"FFMLP\0\0\0";

/// A fully connected ELU network with its parameters in one flat vector.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Mlp {
    shape: MlpShape,
    parameters: Vec<f64>,
}

/// What the forward pass keeps for the backward pass (each layer's input, the output), and the
/// backward pass's scratch. Reused from one batch to the next ([`Mlp::forward_into`],
/// [`Mlp::backward_into`]), it allocates nothing once its matrices have their sizes: a training
/// step then touches no fresh pages (fresh multi-megabyte buffers every step cost a quarter of
/// Simplicits' training time in page faults).
#[derive(Clone, Debug)]
pub struct Tape {
    inputs: Vec<Mat<f64>>,
    output: Mat<f64>,
    d_y: Mat<f64>,
    d_x: Mat<f64>,
}

impl Default for Tape {
    fn default() -> Self {
        Tape {
            inputs: Vec::new(),
            output: Mat::new(),
            d_y: Mat::new(),
            d_x: Mat::new(),
        }
    }
}

impl Tape {
    /// The outputs of the last forward pass (`B × outputs`).
    pub fn output(&self) -> MatRef<'_, f64> {
        self.output.as_ref()
    }
}

/// `y = X Wᵀ + 1 bᵀ`: one linear layer on a batch (`B × in` → `B × out`), into `y` (resized).
fn affine_into(x: MatRef<'_, f64>, w: MatRef<'_, f64>, b: &[f64], y: &mut Mat<f64>) {
    y.resize_with(x.nrows(), w.nrows(), |_, _| 0.0);
    faer::linalg::matmul::matmul(
        y.as_mut(),
        faer::Accum::Replace,
        x,
        w.transpose(),
        1.0,
        faer::get_global_parallelism(),
    );
    for (j, bias) in b.iter().enumerate() {
        for v in y.col_as_slice_mut(j) {
            *v += bias;
        }
    }
}

/// `ELU(x) = x` for `x > 0`, `eˣ − 1` otherwise.
fn elu(x: f64) -> f64 {
    if x > 0.0 { x } else { x.exp_m1() }
}

impl Mlp {
    /// A network with PyTorch's default `nn.Linear` initialization: every weight and bias
    /// uniform in `±1/√fan_in`, drawn from a ChaCha8 stream seeded with `seed`.
    pub fn new(shape: MlpShape, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut parameters = Vec::with_capacity(shape.parameter_count());
        for (fan_in, fan_out) in shape.layer_sizes() {
            let bound = 1.0 / (fan_in as f64).sqrt();
            for _ in 0..fan_out * fan_in + fan_out {
                parameters.push(rng.random_range(-bound..bound));
            }
        }
        Mlp { shape, parameters }
    }

    /// Sizes.
    pub fn shape(&self) -> MlpShape {
        self.shape
    }

    /// All parameters (per layer: `W` row-major `out × in`, then `b`).
    pub fn parameters(&self) -> &[f64] {
        &self.parameters
    }

    /// All parameters, for an optimizer.
    pub fn parameters_mut(&mut self) -> &mut [f64] {
        &mut self.parameters
    }

    /// Per layer: (weight `out × in`, bias) views into the flat vector.
    fn layers(&self) -> Vec<(MatRef<'_, f64>, &[f64])> {
        let mut offset = 0;
        self.shape
            .layer_sizes()
            .into_iter()
            .map(|(fan_in, fan_out)| {
                let w = &self.parameters[offset..offset + fan_out * fan_in];
                let b = &self.parameters
                    [offset + fan_out * fan_in..offset + fan_out * fan_in + fan_out];
                offset += fan_out * fan_in + fan_out;
                (MatRef::from_row_major_slice(w, fan_out, fan_in), b)
            })
            .collect()
    }

    /// Outputs (`B × outputs`) for a batch of inputs (`B × inputs`).
    ///
    /// # Panics
    /// If `x` does not have `inputs` columns.
    pub fn forward(&self, x: MatRef<'_, f64>) -> Mat<f64> {
        self.forward_with_tape(x).0
    }

    /// [`Mlp::forward`], keeping what [`Mlp::backward`] needs.
    ///
    /// # Panics
    /// If `x` does not have `inputs` columns.
    pub fn forward_with_tape(&self, x: MatRef<'_, f64>) -> (Mat<f64>, Tape) {
        let mut tape = Tape::default();
        self.forward_into(x, &mut tape);
        (std::mem::replace(&mut tape.output, Mat::new()), tape)
    }

    /// [`Mlp::forward_with_tape`] into `tape`, reusing its matrices: the outputs are then
    /// [`Tape::output`]. The same values as a fresh tape.
    ///
    /// # Panics
    /// If `x` does not have `inputs` columns.
    pub fn forward_into(&self, x: MatRef<'_, f64>, tape: &mut Tape) {
        assert_eq!(x.ncols(), self.shape.inputs, "input width");
        let layers = self.layers();
        let last = layers.len() - 1;
        tape.inputs.resize_with(layers.len(), Mat::new);
        tape.inputs[0].resize_with(x.nrows(), x.ncols(), |_, _| 0.0);
        tape.inputs[0].copy_from(x);
        for (l, (w, b)) in layers.iter().enumerate() {
            let (before, after) = tape.inputs.split_at_mut(l + 1);
            let y = if l < last {
                &mut after[0]
            } else {
                &mut tape.output
            };
            affine_into(before[l].as_ref(), *w, b, y);
            if l < last {
                // The tape keeps only activated values: ELU's derivative is 1 where the output
                // is positive and output + 1 (= eˣ) elsewhere.
                for j in 0..y.ncols() {
                    for v in y.col_as_slice_mut(j) {
                        *v = elu(*v);
                    }
                }
            }
        }
    }

    /// Outputs and their derivatives with respect to each input coordinate (forward mode): the
    /// outputs `Y` (`B × outputs`) and `∂Y/∂x_d` (`B × outputs`) for `d = 0..inputs`.
    ///
    /// # Panics
    /// If `x` does not have `inputs` columns.
    pub fn forward_with_input_derivatives(&self, x: MatRef<'_, f64>) -> (Mat<f64>, Vec<Mat<f64>>) {
        assert_eq!(x.ncols(), self.shape.inputs, "input width");
        let layers = self.layers();
        let last = layers.len() - 1;
        let mut current = x.to_owned();
        let mut tangents: Vec<Mat<f64>> = (0..self.shape.inputs)
            .map(|d| Mat::from_fn(x.nrows(), x.ncols(), |_, j| if j == d { 1.0 } else { 0.0 }))
            .collect();
        for (l, (w, b)) in layers.iter().enumerate() {
            let mut y = Mat::new();
            affine_into(current.as_ref(), *w, b, &mut y);
            for t in &mut tangents {
                *t = &*t * w.transpose();
            }
            current = y;
            if l < last {
                for t in &mut tangents {
                    *t = Mat::from_fn(t.nrows(), t.ncols(), |i, j| {
                        let pre = current[(i, j)];
                        t[(i, j)] * if pre > 0.0 { 1.0 } else { pre.exp() }
                    });
                }
                current =
                    Mat::from_fn(
                        current.nrows(),
                        current.ncols(),
                        |i, j| elu(current[(i, j)]),
                    );
            }
        }
        (current, tangents)
    }

    /// Gradient of a scalar loss with respect to every parameter (same layout as
    /// [`Mlp::parameters`]), given `d_output = ∂loss/∂outputs` (`B × outputs`) and the tape of
    /// the forward pass that produced those outputs.
    ///
    /// # Panics
    /// If `d_output`'s shape does not match the tape's batch and the output width.
    pub fn backward(&self, tape: &Tape, d_output: MatRef<'_, f64>) -> Vec<f64> {
        let mut gradient = vec![0.0; self.parameters.len()];
        let (mut d_y, mut d_x) = (Mat::new(), Mat::new());
        self.backward_with(&tape.inputs, d_output, &mut gradient, &mut d_y, &mut d_x);
        gradient
    }

    /// [`Mlp::backward`] into `gradient` (length [`Mlp::parameters`]), with the tape of the
    /// forward pass ([`Mlp::forward_into`]) also holding the backward pass's scratch.
    ///
    /// # Panics
    /// If `d_output`'s shape does not match the tape's batch and the output width, or
    /// `gradient` has the wrong length.
    pub fn backward_into(&self, tape: &mut Tape, d_output: MatRef<'_, f64>, gradient: &mut [f64]) {
        let Tape {
            inputs, d_y, d_x, ..
        } = tape;
        self.backward_with(inputs, d_output, gradient, d_y, d_x);
    }

    /// The backward pass over the layer inputs `inputs` of a forward pass, with `d_y` and
    /// `d_x` as scratch (resized as needed).
    fn backward_with(
        &self,
        inputs: &[Mat<f64>],
        d_output: MatRef<'_, f64>,
        gradient: &mut [f64],
        d_y: &mut Mat<f64>,
        d_x: &mut Mat<f64>,
    ) {
        assert_eq!(gradient.len(), self.parameters.len(), "gradient length");
        let layers = self.layers();
        let sizes = self.shape.layer_sizes();
        let mut offsets = Vec::with_capacity(sizes.len());
        let mut offset = 0;
        for (fan_in, fan_out) in &sizes {
            offsets.push(offset);
            offset += fan_out * fan_in + fan_out;
        }
        assert_eq!(d_output.ncols(), self.shape.outputs, "output width");
        d_y.resize_with(d_output.nrows(), d_output.ncols(), |_, _| 0.0);
        d_y.copy_from(d_output);
        for l in (0..layers.len()).rev() {
            let (w, _) = layers[l];
            let x = &inputs[l];
            assert_eq!(d_y.nrows(), x.nrows(), "batch size");
            let (fan_in, fan_out) = sizes[l];
            // dW = dYᵀ X (out × in), db = Σ_rows dY.
            let d_w = d_y.transpose() * x;
            let g = &mut gradient[offsets[l]..offsets[l] + fan_out * fan_in + fan_out];
            for o in 0..fan_out {
                for i in 0..fan_in {
                    g[o * fan_in + i] = d_w[(o, i)];
                }
                g[fan_out * fan_in + o] = (0..d_y.nrows()).map(|r| d_y[(r, o)]).sum();
            }
            if l > 0 {
                // dX = dY W, then through the previous layer's ELU, whose output is x.
                d_x.resize_with(d_y.nrows(), w.ncols(), |_, _| 0.0);
                faer::linalg::matmul::matmul(
                    d_x.as_mut(),
                    faer::Accum::Replace,
                    d_y.as_ref(),
                    w,
                    1.0,
                    faer::get_global_parallelism(),
                );
                for j in 0..d_x.ncols() {
                    for (d, &activated) in d_x.col_as_slice_mut(j).iter_mut().zip(x.col_as_slice(j))
                    {
                        if activated <= 0.0 {
                            *d *= activated + 1.0;
                        }
                    }
                }
                std::mem::swap(d_y, d_x);
            }
        }
    }

    /// Saves the network (magic, format version, bincode), atomically.
    ///
    /// # Errors
    /// [`ModelFileError::Io`] naming the path.
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), ModelFileError> {
        model_file::save(path.as_ref(), MAGIC, MLP_FORMAT_VERSION, self)
    }

    /// Loads a network saved by [`Mlp::save`].
    ///
    /// # Errors
    /// [`ModelFileError`]: unreadable, wrong magic or version, damaged, or parameters that do
    /// not match the stored shape.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, ModelFileError> {
        let path = path.as_ref();
        let mlp: Mlp = model_file::load(path, MAGIC, MLP_FORMAT_VERSION, "MLP")?;
        if mlp.parameters.len() != mlp.shape.parameter_count() {
            return Err(ModelFileError::Format {
                path: path.display().to_string(),
                what: "MLP",
                version: MLP_FORMAT_VERSION,
                reason: format!(
                    "{} parameters for a shape that needs {}",
                    mlp.parameters.len(),
                    mlp.shape.parameter_count()
                ),
            });
        }
        Ok(mlp)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small() -> Mlp {
        Mlp::new(
            MlpShape {
                inputs: 3,
                width: 5,
                hidden_layers: 2,
                outputs: 4,
            },
            7,
        )
    }

    fn batch(rows: usize, seed: u64) -> Mat<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        Mat::from_fn(rows, 3, |_, _| rng.random_range(-1.5..1.5))
    }

    #[test]
    fn backward_matches_central_differences_of_a_weighted_output_sum() {
        let mut mlp = small();
        let x = batch(9, 1);
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let c = Mat::from_fn(9, 4, |_, _| rng.random_range(-1.0..1.0));
        let loss = |m: &Mlp| {
            let y = m.forward(x.as_ref());
            (0..9)
                .flat_map(|i| (0..4).map(move |j| (i, j)))
                .map(|(i, j)| c[(i, j)] * y[(i, j)])
                .sum::<f64>()
        };
        let (_, tape) = mlp.forward_with_tape(x.as_ref());
        let gradient = mlp.backward(&tape, c.as_ref());
        let h = 1e-6;
        let mut worst: f64 = 0.0;
        for (k, analytic) in gradient.iter().enumerate() {
            let p = mlp.parameters()[k];
            mlp.parameters_mut()[k] = p + h;
            let up = loss(&mlp);
            mlp.parameters_mut()[k] = p - h;
            let down = loss(&mlp);
            mlp.parameters_mut()[k] = p;
            let fd = (up - down) / (2.0 * h);
            worst = worst.max((fd - analytic).abs() / (1.0 + fd.abs()));
        }
        assert!(worst < 1e-7, "worst relative gradient error {worst:e}");
    }

    #[test]
    fn input_derivatives_match_central_differences() {
        let mlp = small();
        let x = batch(6, 4);
        let (y, tangents) = mlp.forward_with_input_derivatives(x.as_ref());
        assert_eq!(y, mlp.forward(x.as_ref()));
        let h = 1e-6;
        for (d, tangent) in tangents.iter().enumerate() {
            let shifted = |s: f64| {
                let mut xs = x.clone();
                for i in 0..xs.nrows() {
                    xs[(i, d)] += s;
                }
                mlp.forward(xs.as_ref())
            };
            let (up, down) = (shifted(h), shifted(-h));
            for i in 0..6 {
                for j in 0..4 {
                    let fd = (up[(i, j)] - down[(i, j)]) / (2.0 * h);
                    assert!((fd - tangent[(i, j)]).abs() < 1e-7 * (1.0 + fd.abs()));
                }
            }
        }
    }

    #[test]
    fn elu_is_identity_above_zero_and_exp_minus_one_below() {
        assert_eq!(elu(0.0), 0.0);
        assert_eq!(elu(2.5), 2.5);
        assert!((elu(-1e-9) + 1e-9).abs() < 1e-17);
        assert!((elu(-2.0) - ((-2.0f64).exp() - 1.0)).abs() < 1e-15);
    }

    #[test]
    fn initialization_follows_pytorch_bounds_and_is_seeded() {
        let shape = MlpShape::simplicits(16);
        assert_eq!(
            shape.parameter_count(),
            3 * 64 + 64 + 6 * (64 * 64 + 64) + 64 * 16 + 16
        );
        let a = Mlp::new(shape, 3);
        assert_eq!(a, Mlp::new(shape, 3));
        assert_ne!(a, Mlp::new(shape, 4));
        let mut offset = 0;
        for (fan_in, fan_out) in shape.layer_sizes() {
            let bound = 1.0 / (fan_in as f64).sqrt();
            let layer = &a.parameters()[offset..offset + fan_out * fan_in + fan_out];
            assert!(layer.iter().all(|p| p.abs() < bound));
            // Uniform on ±bound: the largest magnitude is close to the bound.
            let largest = layer.iter().fold(0.0_f64, |m, p| m.max(p.abs()));
            assert!(largest > 0.8 * bound, "{largest} vs {bound}");
            offset += fan_out * fan_in + fan_out;
        }
    }

    #[test]
    fn adam_training_of_a_small_network_lowers_a_regression_loss_deterministically() {
        use crate::adam::{Adam, AdamParams};
        let shape = MlpShape {
            inputs: 3,
            width: 16,
            hidden_layers: 2,
            outputs: 1,
        };
        let x = batch(64, 9);
        let target = Mat::from_fn(64, 1, |i, _| (x[(i, 0)] + 0.5 * x[(i, 1)]).sin());
        let train = |steps: usize| {
            let mut mlp = Mlp::new(shape, 1);
            let mut adam = Adam::new(
                mlp.parameters().len(),
                AdamParams {
                    learning_rate: 1e-2,
                    ..AdamParams::default()
                },
            );
            let mut losses = Vec::new();
            for _ in 0..steps {
                let (y, tape) = mlp.forward_with_tape(x.as_ref());
                let residual = &y - &target;
                losses.push((0..64).map(|i| residual[(i, 0)].powi(2)).sum::<f64>() / 64.0);
                let d_y = Mat::from_fn(64, 1, |i, _| 2.0 * residual[(i, 0)] / 64.0);
                let g = mlp.backward(&tape, d_y.as_ref());
                adam.step(mlp.parameters_mut(), &g);
            }
            (mlp, losses)
        };
        let (a, losses) = train(400);
        assert!(
            losses[399] < 0.02 * losses[0],
            "loss {} → {}",
            losses[0],
            losses[399]
        );
        let (b, _) = train(400);
        assert_eq!(a, b, "training is deterministic");
    }

    #[test]
    fn saved_network_reloads_to_identical_outputs_and_bad_files_are_named() {
        let mlp = Mlp::new(MlpShape::simplicits(6), 11);
        let dir = std::env::temp_dir().join(format!("freeform-mlp-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("net.mlp");
        mlp.save(&path).unwrap();
        let back = Mlp::load(&path).unwrap();
        let x = batch(20, 5);
        assert_eq!(mlp.forward(x.as_ref()), back.forward(x.as_ref()));
        std::fs::write(&path, b"not a network").unwrap();
        let message = Mlp::load(&path).unwrap_err().to_string();
        assert!(
            message.contains("net.mlp") && message.contains("magic"),
            "{message}"
        );
    }
}
