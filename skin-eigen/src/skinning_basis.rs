//! The skinning basis: RKPM kernels plus eigenvector coefficients, evaluable anywhere and
//! saved to disk with a versioned header.

use std::borrow::Cow;
use std::path::Path;

use artifact::{ArtifactError, FrameError, decode_framed, encode_framed};
use nalgebra::{DMatrix, Vector3};
use rayon::prelude::*;
use rkpm_core::{
    Kernels, ShapeFunctionError, ShapeFunctionParams, ShapeFunctions, evaluate_shape_functions,
};
use serde::{Deserialize, Serialize};

use crate::build_point_weights::BuildPointWeights;
use crate::region_weight::RegionWeight;

/// Where [`SkinningBasis`]'s evaluation gets the shape functions of its kernels at a set of
/// points: evaluated afresh, or ones already at hand.
type ShapeSource<'a> =
    dyn Fn(&[Vector3<f64>]) -> Result<Cow<'a, ShapeFunctions>, ShapeFunctionError> + 'a;

/// File magic of a saved basis.
const MAGIC: [u8; 8] = *b"FFBASIS\0";
/// Format version; bump on any change of [`SkinningBasis`]'s serialized layout (2: the
/// shape-function options carry the kernel window; 3: region weights for exactly held regions;
/// 4: the shape-function options carry the reproduction tolerance; 5: the weight of a weighted
/// basis; 6: the shape-function options carry the polynomial reproduction).
pub const BASIS_FORMAT_VERSION: u32 = 6;

/// Saving or loading a basis failed.
#[derive(Debug, thiserror::Error)]
pub enum BasisFileError {
    /// I/O failure.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The underlying error.
        source: std::io::Error,
    },
    /// Not a basis file.
    #[error("{path}: not a FreeForm basis file (bad magic bytes)")]
    NotABasisFile {
        /// The file.
        path: String,
    },
    /// Written by an incompatible version.
    #[error(
        "{path}: basis format version {found}, this build reads version {expected}; rebuild the basis"
    )]
    IncompatibleVersion {
        /// The file.
        path: String,
        /// Version in the file.
        found: u32,
        /// Version this build understands.
        expected: u32,
    },
    /// Corrupt payload.
    #[error("{path}: corrupt basis data: {message}")]
    Corrupt {
        /// The file.
        path: String,
        /// Decoder message.
        message: String,
    },
}

/// How the basis was made, kept with it for reports and reproducibility.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BasisMetadata {
    /// The material model whose rest Hessian defined H_w (e.g. "stable Neo-Hookean").
    pub material: String,
    /// Number of integration points used for assembly.
    pub integration_points: usize,
    /// `λ_max(𝓜)/λ_min(𝓜)`.
    pub mass_condition_number: f64,
    /// Near-null mass directions discarded before the solve.
    pub discarded_mass_directions: usize,
    /// The dropped constant-mode eigenvalue (0 for a basis with held regions, which drops none).
    pub constant_eigenvalue: f64,
}

/// m skinning weight fields `W^j(X) = Σ_k ϕ_k(X) c_kj` (Sec. 3.2), plus the constant handle.
///
/// A basis built for R exactly held regions ([`crate::build_basis_with_regions`])
/// also carries R − 1 region weights between the constant handle and the modes: handle r
/// (1 ≤ r < R) is 1 on region r and 0 on the other regions, the modes vanish on every region,
/// and region 0's weight is the constant minus the others. Handles, in order:
/// `[1, a_1 … a_{R-1}, c_1 … c_m]`.
///
/// A weighted basis ([`crate::build_weighted_basis`]) multiplies its kernel sums by the region
/// weight w of [`RegionWeight`]: `W^j = w Σ_k ϕ_k c_kj` for the modes and
/// `a_r = g_r + w Σ_k ϕ_k b_kr` for the region handles, so the modes are exactly 0 and the region
/// handles exactly 1 or 0 on the regions, where no kernel is evaluated.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SkinningBasis {
    kernels: Kernels,
    shape_params: ShapeFunctionParams,
    /// c, K × m.
    coefficients: DMatrix<f64>,
    eigenvalues: Vec<f64>,
    /// Number R of held regions (0 for a free basis).
    held_regions: usize,
    /// Region weights a_1 … a_{R-1}, K × (R − 1) (no columns for a free basis).
    region_coefficients: DMatrix<f64>,
    /// The weight of a weighted basis (`None` otherwise).
    region_weight: Option<RegionWeight>,
    metadata: BasisMetadata,
    /// The weights at the build points ([`SkinningBasis::keep_weights_at_build_points`]).
    #[serde(skip)]
    at_build_points: BuildPointWeights,
}

/// Weights and weight gradients at a set of points, with the constant handle first:
/// column 0 is W⁰ ≡ 1 (∇W⁰ = 0), then the region weights of a basis with held regions (see
/// [`SkinningBasis`]), then the m eigen-weights.
#[derive(Clone, Debug, PartialEq)]
pub struct SkinningWeights {
    /// W, N × (m + 1) (dimensionless).
    pub weights: DMatrix<f64>,
    /// ∇W, one N × (m + 1) matrix per axis x, y, z (1/m).
    pub gradients: [DMatrix<f64>; 3],
}

impl SkinningBasis {
    /// A basis from its parts.
    ///
    /// # Panics
    /// If `coefficients` does not have one row per kernel and one column per eigenvalue.
    pub fn new(
        kernels: Kernels,
        shape_params: ShapeFunctionParams,
        coefficients: DMatrix<f64>,
        eigenvalues: Vec<f64>,
        metadata: BasisMetadata,
    ) -> Self {
        assert_eq!(
            coefficients.nrows(),
            kernels.len(),
            "one coefficient row per kernel"
        );
        assert_eq!(
            coefficients.ncols(),
            eigenvalues.len(),
            "one coefficient column per mode"
        );
        let region_coefficients = DMatrix::zeros(kernels.len(), 0);
        SkinningBasis {
            kernels,
            shape_params,
            coefficients,
            eigenvalues,
            held_regions: 0,
            region_coefficients,
            region_weight: None,
            metadata,
            at_build_points: BuildPointWeights::default(),
        }
    }

    /// The same basis with R = `region_coefficients.ncols() + 1` held regions: the region
    /// weights a_1 … a_{R-1} (K × (R − 1)) go between the constant handle and the modes, which
    /// must vanish on every region (see [`crate::build_basis_with_regions`]).
    ///
    /// # Panics
    /// If `region_coefficients` does not have one row per kernel.
    pub fn with_held_regions(mut self, region_coefficients: DMatrix<f64>) -> Self {
        assert_eq!(
            region_coefficients.nrows(),
            self.kernels.len(),
            "one region coefficient row per kernel"
        );
        self.held_regions = region_coefficients.ncols() + 1;
        self.region_coefficients = region_coefficients;
        self.at_build_points = BuildPointWeights::default();
        self
    }

    /// The same basis weighted by `weight` (see [`SkinningBasis`]): its R − 1 region
    /// coefficients must already be set ([`SkinningBasis::with_held_regions`]).
    ///
    /// # Panics
    /// If `weight` does not have one region per held region.
    pub fn with_region_weight(mut self, weight: RegionWeight) -> Self {
        assert_eq!(
            weight.regions().len(),
            self.region_coefficients.ncols() + 1,
            "one weight region per held region"
        );
        self.held_regions = weight.regions().len();
        self.region_weight = Some(weight);
        self.at_build_points = BuildPointWeights::default();
        self
    }

    /// The region weight of a weighted basis.
    pub fn region_weight(&self) -> Option<&RegionWeight> {
        self.region_weight.as_ref()
    }

    /// Number m of eigen-weights (the constant handle not counted, as in the paper).
    pub fn modes(&self) -> usize {
        self.eigenvalues.len()
    }

    /// Number R of exactly held regions the basis was built for (0 for a free basis). Handles
    /// `0 … R − 1` then carry the regions' transforms: region 0 moves with handle 0 alone,
    /// region r ≥ 1 with handles 0 and r.
    pub fn held_regions(&self) -> usize {
        self.held_regions
    }

    /// Region weights a_1 … a_{R-1} (K × (R − 1); no columns for a free basis).
    pub fn region_coefficients(&self) -> &DMatrix<f64> {
        &self.region_coefficients
    }

    /// Number of handles the simulator uses: m + 1, plus R − 1 region weights for a basis with
    /// held regions.
    pub fn handles(&self) -> usize {
        self.modes() + 1 + self.region_coefficients.ncols()
    }

    /// The kernels.
    pub fn kernels(&self) -> &Kernels {
        &self.kernels
    }

    /// Coefficients c (K × m), `cᵀ𝓜c = I`.
    pub fn coefficients(&self) -> &DMatrix<f64> {
        &self.coefficients
    }

    /// Eigenvalues λ_1..λ_m of `H_w c = λ𝓜c`, ascending.
    pub fn eigenvalues(&self) -> &[f64] {
        &self.eigenvalues
    }

    /// How the basis was made.
    pub fn metadata(&self) -> &BasisMetadata {
        &self.metadata
    }

    /// W and ∇W at arbitrary points, constant handle first. At the points the basis was built
    /// on, the weights kept from the build when it kept them ([`SkinningBasis::keeps_weights_at`]:
    /// a plain basis or one with held regions always does, a weighted basis when its build was
    /// told it would be evaluated there): the same values, computed once.
    ///
    /// # Errors
    /// [`ShapeFunctionError`] when a point is not reached by enough kernels (far outside the
    /// object) or is not finite.
    pub fn evaluate(&self, points: &[Vector3<f64>]) -> Result<SkinningWeights, ShapeFunctionError> {
        if let Some(kept) = self.at_build_points.at(points) {
            return Ok(kept.clone());
        }
        self.evaluate_from(points, &|query| self.fresh_shape_functions(query), None)
    }

    /// Whether the basis keeps its weights at exactly `points` (its build points, when the
    /// build kept them), so that [`SkinningBasis::evaluate`] there evaluates nothing.
    pub fn keeps_weights_at(&self, points: &[Vector3<f64>]) -> bool {
        self.at_build_points.at(points).is_some()
    }

    /// Keeps the weights at `points`, the points the basis was built on, for later evaluations
    /// there; `shape` are the shape functions of the basis's kernels at `shape_points` (every
    /// build point, or for a weighted basis those outside the regions), as the build computed
    /// them; `factors`, for a weighted basis, its weight `(w, ∇w)` at every point of `points`
    /// if the build has it (else it is evaluated). The kept weights are those
    /// [`SkinningBasis::evaluate`] computes at `points`, to the bit: the shape functions at a
    /// point depend on that point alone.
    ///
    /// # Errors
    /// [`ShapeFunctionError`] as [`SkinningBasis::evaluate`]; nothing is kept then.
    pub(crate) fn keep_weights_at_build_points(
        &mut self,
        points: &[Vector3<f64>],
        shape_points: &[Vector3<f64>],
        shape: &ShapeFunctions,
        factors: Option<&[(f64, Vector3<f64>)]>,
    ) -> Result<(), ShapeFunctionError> {
        let weights = self.evaluate_from(
            points,
            &|query| {
                if query == shape_points {
                    Ok(Cow::Borrowed(shape))
                } else {
                    self.fresh_shape_functions(query)
                }
            },
            factors,
        )?;
        self.at_build_points = BuildPointWeights::new(points.to_vec(), weights);
        Ok(())
    }

    /// The shape functions of the basis's kernels at `points`, evaluated.
    fn fresh_shape_functions(
        &self,
        points: &[Vector3<f64>],
    ) -> Result<Cow<'static, ShapeFunctions>, ShapeFunctionError> {
        evaluate_shape_functions(&self.kernels, points, &self.shape_params).map(Cow::Owned)
    }

    /// [`SkinningBasis::evaluate`] with the shape functions from `shape_at` and, for a
    /// weighted basis, its weight at `points` from `factors` when given.
    fn evaluate_from(
        &self,
        points: &[Vector3<f64>],
        shape_at: &ShapeSource<'_>,
        factors: Option<&[(f64, Vector3<f64>)]>,
    ) -> Result<SkinningWeights, ShapeFunctionError> {
        if let Some(weight) = &self.region_weight {
            return self.evaluate_weighted(weight, points, shape_at, factors);
        }
        let shape = shape_at(points)?;
        let (n, handles) = (points.len(), self.handles());
        let sums = self.kernel_sums(&shape);
        let weights = DMatrix::from_fn(n, handles, |i, j| match j {
            0 => 1.0,
            _ => sums[i * (handles - 1) + j - 1].0,
        });
        let gradients = std::array::from_fn(|d| {
            DMatrix::from_fn(n, handles, |i, j| match j {
                0 => 0.0,
                _ => sums[i * (handles - 1) + j - 1].1[d],
            })
        });
        Ok(SkinningWeights { weights, gradients })
    }

    /// [`SkinningBasis::evaluate`] for a weighted basis: kernels are evaluated only at the
    /// points outside every region; inside region r the modes are 0 and handle r is 1.
    fn evaluate_weighted(
        &self,
        weight: &RegionWeight,
        points: &[Vector3<f64>],
        shape_at: &ShapeSource<'_>,
        factors: Option<&[(f64, Vector3<f64>)]>,
    ) -> Result<SkinningWeights, ShapeFunctionError> {
        if let Some(point) = points.iter().position(|x| !x.iter().all(|v| v.is_finite())) {
            return Err(ShapeFunctionError::NonFiniteQuery { point });
        }
        let (n, handles) = (points.len(), self.handles());
        let first_mode = 1 + self.region_coefficients.ncols();
        let evaluated: Vec<(f64, Vector3<f64>)>;
        let factors = match factors {
            Some(factors) => factors,
            None => {
                evaluated = points.iter().map(|x| weight.weight(x)).collect();
                &evaluated
            }
        };
        let free: Vec<usize> = (0..n).filter(|&i| factors[i].0 > 0.0).collect();
        let free_points: Vec<Vector3<f64>> = free.iter().map(|&i| points[i]).collect();
        let shape = shape_at(&free_points).map_err(|e| e.renumbered(|p| free[p]))?;
        let mut weights = DMatrix::zeros(n, handles);
        let mut gradients = [
            DMatrix::zeros(n, handles),
            DMatrix::zeros(n, handles),
            DMatrix::zeros(n, handles),
        ];
        for i in 0..n {
            weights[(i, 0)] = 1.0;
            for j in 1..first_mode {
                let (g, grad_g) = weight.blend(j, &points[i]);
                weights[(i, j)] = g;
                for (d, grads) in gradients.iter_mut().enumerate() {
                    grads[(i, j)] = grad_g[d];
                }
            }
        }
        let sums = self.kernel_sums(&shape);
        for (q, &i) in free.iter().enumerate() {
            let (w, grad_w) = factors[i];
            for j in 1..handles {
                let (sum, grad_sum) = sums[q * (handles - 1) + j - 1];
                weights[(i, j)] += w * sum;
                let grad = grad_sum * w + grad_w * sum;
                for (d, grads) in gradients.iter_mut().enumerate() {
                    grads[(i, j)] += grad[d];
                }
            }
        }
        Ok(SkinningWeights { weights, gradients })
    }

    /// Per point q of `shape`, for every handle j ≥ 1, the kernel sum `Σ_k ϕ_k(X_q) a_kj` and
    /// its gradient `Σ_k ∇ϕ_k(X_q) a_kj` (a: the region coefficients, then the modes'), summed
    /// in kernel order; entry `q · (handles − 1) + j − 1`. Parallel over points.
    fn kernel_sums(&self, shape: &ShapeFunctions) -> Vec<(f64, Vector3<f64>)> {
        let columns = self.handles() - 1;
        let regions = self.region_coefficients.ncols();
        // Row-major K × (handles − 1): a kernel's coefficients side by side.
        let table: Vec<f64> = (0..self.kernels.len())
            .flat_map(|k| {
                (0..columns).map(move |j| match j.checked_sub(regions) {
                    None => self.region_coefficients[(k, j)],
                    Some(mode) => self.coefficients[(k, mode)],
                })
            })
            .collect();
        let mut sums = vec![(0.0, Vector3::zeros()); shape.point_count() * columns];
        sums.par_chunks_mut(columns.max(1))
            .enumerate()
            .for_each(|(q, row)| {
                for ((&k, &phi), grad) in shape
                    .kernels(q)
                    .iter()
                    .zip(shape.values(q))
                    .zip(shape.gradients(q))
                {
                    let c = &table[k as usize * columns..(k as usize + 1) * columns];
                    for ((sum, grad_sum), &c) in row.iter_mut().zip(c) {
                        *sum += phi * c;
                        *grad_sum += grad * c;
                    }
                }
            });
        sums
    }

    /// Writes the basis (magic, format version, bincode payload) atomically
    /// ([`artifact::write_atomically`]).
    ///
    /// # Errors
    /// [`BasisFileError::Io`].
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), BasisFileError> {
        let path = path.as_ref();
        artifact::write_atomically(path, &encode_framed(&MAGIC, BASIS_FORMAT_VERSION, self))
            .map_err(|e| match e {
                ArtifactError::Io { path, source } => BasisFileError::Io {
                    path: path.display().to_string(),
                    source,
                },
                ArtifactError::Format { path, source } => BasisFileError::Corrupt {
                    path: path.display().to_string(),
                    message: source.to_string(),
                },
            })
    }

    /// Reads a basis written by [`SkinningBasis::save`].
    ///
    /// # Errors
    /// [`BasisFileError`] for unreadable files, wrong magic, another format version, or a
    /// corrupt payload.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, BasisFileError> {
        let path = path.as_ref();
        let name = path.display().to_string();
        let bytes = std::fs::read(path).map_err(|source| BasisFileError::Io {
            path: name.clone(),
            source,
        })?;
        let basis: SkinningBasis =
            decode_framed(&bytes, &MAGIC, BASIS_FORMAT_VERSION).map_err(|e| match e {
                FrameError::WrongMagic { .. } => {
                    BasisFileError::NotABasisFile { path: name.clone() }
                }
                FrameError::WrongVersion { found, expected } => {
                    BasisFileError::IncompatibleVersion {
                        path: name.clone(),
                        found,
                        expected,
                    }
                }
                FrameError::Corrupt(message) => BasisFileError::Corrupt {
                    path: name.clone(),
                    message,
                },
            })?;
        if basis.coefficients.nrows() != basis.kernels.len()
            || basis.coefficients.ncols() != basis.eigenvalues.len()
            || basis.region_coefficients.nrows() != basis.kernels.len()
            || basis.region_coefficients.ncols() != basis.held_regions.saturating_sub(1)
            || basis
                .region_weight
                .as_ref()
                .is_some_and(|w| w.regions().len() != basis.held_regions)
        {
            return Err(BasisFileError::Corrupt {
                path: name,
                message: "inconsistent sizes".into(),
            });
        }
        Ok(basis)
    }
}
