//! RKPM shape functions and their gradients (paper Eqs. 6-11, design §3.3).
//!
//! The paper's form is `ϕ_k(X) = φ_k(X) P(p_k)ᵀ C(X)` with `P(X) = [1, x, y, z]ᵀ`,
//! `M(X) C(X) = P(X)` and `M(X) = Σ_k φ_k(X) P(p_k) P(p_k)ᵀ` (Eqs. 7, 9-11). We evaluate the
//! equivalent *shifted and scaled* form
//!
//! ```text
//! b_k(X) = P((X - p_k) / s) = [1, (X - p_k)/s],   M̃(X) = Σ_k φ_k(X) b_k b_kᵀ,
//! M̃(X) C̃(X) = e₁,   ϕ_k(X) = φ_k(X) b_kᵀ C̃(X),
//! ```
//!
//! with `s` a local length (the largest radius among the kernels reaching X). Because
//! `b_k = A(X) P(p_k)` for an invertible affine `A(X)` when the basis is linear, both forms give
//! the same functions, but M̃ is O(1)-scaled and far better conditioned (tested against
//! [`shape_function_values_unshifted`]). [`ShapeFunctionParams::reproduction`] may extend P to
//! the quadratic monomials ([`crate::reproduction`]; 10 terms), and the formulas below hold
//! unchanged: with `∂_d b_k = D b_k` for any matrix D, the terms in D cancel from `∂_d ϕ_k` but
//! for `D e₁`, the constant part of ∂_d P, which is `u_d` for either basis.
//!
//! Gradients (with `u_d = e_{d+1}/s` the derivative of b_k along axis d):
//!
//! ```text
//! ∂_d M̃ C̃ = Σ_k [∂_dφ_k (b_k·C̃) b_k + φ_k ((b_k·C̃) u_d + (u_d·C̃) b_k)],
//! ∂_d C̃   = -M̃⁻¹ (∂_d M̃ C̃),
//! ∂_d ϕ_k = ∂_dφ_k (b_k·C̃) + φ_k (u_d·C̃) + φ_k (b_k·∂_d C̃),   ∂_dφ_k = -2 (X - p_k)_d / r_k² φ_k.
//! ```
//!
//! **Cutoff**: a kernel reaches X when `|X - p_k| < cutoff · r_k` (default 4, where the
//! Gaussian has fallen to e⁻¹⁶ ≈ 1.1e-7). The reproducing conditions stay exact for any cutoff
//! because M̃ is built from the same truncated set; the cutoff trades sparsity against
//! fidelity to the untruncated functions (the truncated kernel jumps by e^(-cutoff²) at the
//! cutoff sphere, and the correction C̃ amplifies that). Measured on a 2×1×1 box with 150
//! kernels against cutoff 6 (test `cutoff_changes_values_by_the_truncated_tail_only`):
//! max |Δϕ| = 1.2e-1 / 4.0e-3 / 5.1e-6 at cutoff 2 / 3 / 4, with 33 / 75 / 112 kernels per point.
//!
//! **Singularity**: M̃ is singular when fewer than 4 non-coplanar kernels reach X. We factor M̃
//! by Cholesky and report [`ShapeFunctionError::SingularMomentMatrix`] when it fails or when the
//! pivot ratio `(min L_ii / max L_ii)²` (a cheap reciprocal-condition estimate) falls below
//! `ShapeFunctionParams::min_reciprocal_condition`.
//!
//! **Accuracy**: the pivot ratio can overstate the conditioning. Near the edge of a compact
//! window (`∇φ/φ = 3 / ((2 − q) r)` for the cubic B-spline) a point that passes it can get
//! functions that reproduce linear fields only to 1e-2 (a sparse random layout widened on the
//! estimate alone: test
//! `a_point_that_passes_the_condition_estimate_but_reproduces_poorly_is_reported_and_widened`;
//! on the scorpion's compact kernels as placed, 4 of 47 092 points violate them by more than
//! 1e-6, 2 by more than 1e-3). So every point's functions are checked against the four
//! reproducing conditions in local units (length `s`),
//!
//! ```text
//! |Σ ϕ_k − 1|,  |Σ ϕ_k (p_k − X)| / s,  |Σ ∇ϕ_k| s,  ‖Σ (p_k − X) ∇ϕ_kᵀ − I‖_F,
//! ```
//!
//! and a point where the largest exceeds `ShapeFunctionParams::max_reproducing_error` is
//! reported ([`ShapeFunctionError::InaccurateReproduction`]) rather than returned.

use nalgebra::{Matrix3, Matrix4, SMatrix, SVector, Vector3, Vector4};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::kernels::{KernelWindow, Kernels};
use crate::reproduction::{
    LINEAR_TERMS, LinearBasis, PolynomialBasis, QUADRATIC_TERMS, QuadraticBasis, Reproduction,
};
use crate::spatial_index::SpatialIndex;

/// Options for [`evaluate_shape_functions`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShapeFunctionParams {
    /// Kernel support in units of its radius: kernel k reaches X when `|X - p_k| < cutoff·r_k`
    /// (default 4.0).
    pub cutoff: f64,
    /// Smallest accepted pivot-ratio estimate of the moment matrix's reciprocal condition number
    /// (default 1e-12).
    pub min_reciprocal_condition: f64,
    /// Largest accepted violation of the reproducing conditions at a point, dimensionless in the
    /// local length `s` (module docs; default 1e-6). On the shared shapes' bases the largest is
    /// 1.8e-7 (243015's widened compact kernels), most points 1e-14 … 1e-12; on sparse random
    /// layouts the violations run from round-off up to 6e-3 with no gap between.
    pub max_reproducing_error: f64,
    /// The kernel window (default the paper's Gaussian). A window of finite support reaches no
    /// farther than its support, whatever the cutoff.
    #[serde(default)]
    pub window: KernelWindow,
    /// The polynomials reproduced exactly (default [`Reproduction::Linear`], the paper's
    /// Eq. 7; [`Reproduction::Quadratic`] needs at least 10 kernels in reach of every point).
    /// Always written (saved bases are bincode, which cannot skip a field); read as linear
    /// when a text file leaves it out.
    #[serde(default)]
    pub reproduction: Reproduction,
}

impl Default for ShapeFunctionParams {
    fn default() -> Self {
        ShapeFunctionParams {
            cutoff: 4.0,
            min_reciprocal_condition: 1e-12,
            max_reproducing_error: 1e-6,
            window: KernelWindow::Gaussian,
            reproduction: Reproduction::Linear,
        }
    }
}

/// Shape functions could not be evaluated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ShapeFunctionError {
    /// The moment matrix M(X) is singular or too ill-conditioned at a query point: fewer than 4
    /// non-coplanar kernels reach it (a thin part, a sparse cloud, or a point outside the object).
    #[error(
        "singular RKPM moment matrix at query point {point} {position:?}: {kernels_in_reach} \
         kernels reach it, reciprocal condition estimate {reciprocal_condition:e} (RKPM needs \
         at least 4 kernels, 10 for quadratic reproduction, around a point in all three \
         directions: is a part thinner than the point spacing, the cloud too sparse, or the point \
         outside the object?)"
    )]
    SingularMomentMatrix {
        /// Index of the query point.
        point: usize,
        /// Its position.
        position: [f64; 3],
        /// How many kernels reach it within the cutoff.
        kernels_in_reach: usize,
        /// The pivot-ratio estimate (0 when the Cholesky factorization failed).
        reciprocal_condition: f64,
    },
    /// M(X) passed the condition estimate at a query point, but the functions found there do
    /// not reproduce linear fields to `ShapeFunctionParams::max_reproducing_error`: M(X) is
    /// nearer singular than the estimate shows (typically a point few compact kernels reach
    /// near the edge of their support).
    #[error(
        "inaccurate RKPM shape functions at query point {point} {position:?}: {kernels_in_reach} \
         kernels reach it and the reproducing conditions are violated by {reproducing_error:e} \
         (the moment matrix is nearly singular there: too few kernels reach the point)"
    )]
    InaccurateReproduction {
        /// Index of the query point.
        point: usize,
        /// Its position.
        position: [f64; 3],
        /// How many kernels reach it within the cutoff.
        kernels_in_reach: usize,
        /// The largest of the four dimensionless violations (module docs).
        reproducing_error: f64,
    },
    /// A parameter is out of range.
    #[error("invalid shape-function parameter `{name}` = {value}: must be positive and finite")]
    InvalidParameter {
        /// Parameter name.
        name: &'static str,
        /// The value given.
        value: f64,
    },
    /// A query point is NaN or infinite.
    #[error("query point {point} is not finite")]
    NonFiniteQuery {
        /// Index of the query point.
        point: usize,
    },
}

impl ShapeFunctionError {
    /// The same error with its query-point index mapped by `index` (for errors raised on a
    /// subset of a caller's points).
    pub fn renumbered(self, index: impl Fn(usize) -> usize) -> ShapeFunctionError {
        match self {
            ShapeFunctionError::SingularMomentMatrix {
                point,
                position,
                kernels_in_reach,
                reciprocal_condition,
            } => ShapeFunctionError::SingularMomentMatrix {
                point: index(point),
                position,
                kernels_in_reach,
                reciprocal_condition,
            },
            ShapeFunctionError::InaccurateReproduction {
                point,
                position,
                kernels_in_reach,
                reproducing_error,
            } => ShapeFunctionError::InaccurateReproduction {
                point: index(point),
                position,
                kernels_in_reach,
                reproducing_error,
            },
            ShapeFunctionError::NonFiniteQuery { point } => ShapeFunctionError::NonFiniteQuery {
                point: index(point),
            },
            other => other,
        }
    }

    /// The query point at which the shape functions do not exist, or not to the required
    /// accuracy ([`ShapeFunctionError::SingularMomentMatrix`],
    /// [`ShapeFunctionError::InaccurateReproduction`]): a point wider kernels may cover.
    pub fn uncovered_point(&self) -> Option<usize> {
        match self {
            ShapeFunctionError::SingularMomentMatrix { point, .. }
            | ShapeFunctionError::InaccurateReproduction { point, .. } => Some(*point),
            _ => None,
        }
    }
}

/// Shape functions of all kernels at a set of query points, in a compact sparse layout
/// (compressed rows: point → list of (kernel, ϕ, ∇ϕ)).
///
/// For query point i, `kernels(i)`, `values(i)` and `gradients(i)` are parallel slices over the
/// kernels that reach it, sorted by kernel index. Units: ϕ dimensionless, ∇ϕ in 1/m.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShapeFunctions {
    offsets: Vec<usize>,
    kernel_indices: Vec<u32>,
    values: Vec<f64>,
    gradients: Vec<Vector3<f64>>,
    kernel_count: usize,
}

impl ShapeFunctions {
    /// Number of query points.
    pub fn point_count(&self) -> usize {
        self.offsets.len() - 1
    }

    /// Number of kernels K the functions belong to.
    pub fn kernel_count(&self) -> usize {
        self.kernel_count
    }

    /// Number of stored (point, kernel) pairs.
    pub fn nonzeros(&self) -> usize {
        self.values.len()
    }

    /// Mean number of kernels reaching a query point.
    pub fn mean_kernels_per_point(&self) -> f64 {
        self.nonzeros() as f64 / self.point_count().max(1) as f64
    }

    /// Indices of the kernels reaching point i (ascending).
    pub fn kernels(&self, i: usize) -> &[u32] {
        &self.kernel_indices[self.offsets[i]..self.offsets[i + 1]]
    }

    /// `ϕ_k(X_i)` for the kernels of [`ShapeFunctions::kernels`].
    pub fn values(&self, i: usize) -> &[f64] {
        &self.values[self.offsets[i]..self.offsets[i + 1]]
    }

    /// `∇ϕ_k(X_i)` (1/m) for the kernels of [`ShapeFunctions::kernels`].
    pub fn gradients(&self, i: usize) -> &[Vector3<f64>] {
        &self.gradients[self.offsets[i]..self.offsets[i + 1]]
    }

    /// The shape functions multiplied by a per-point scalar field w: `w(X_i) ϕ_k(X_i)` with
    /// gradients `w ∇ϕ_k + ϕ_k ∇w` (the product rule). `factors[i]` is `(w(X_i), ∇w(X_i))`
    /// (w dimensionless, ∇w in 1/m); the sparsity pattern is kept, zero products included.
    ///
    /// # Panics
    /// If `factors` does not have one entry per point.
    pub fn multiplied(&self, factors: &[(f64, Vector3<f64>)]) -> ShapeFunctions {
        assert_eq!(factors.len(), self.point_count(), "one factor per point");
        let mut values = Vec::with_capacity(self.values.len());
        let mut gradients = Vec::with_capacity(self.gradients.len());
        for (i, &(w, grad_w)) in factors.iter().enumerate() {
            for (&phi, grad_phi) in self.values(i).iter().zip(self.gradients(i)) {
                values.push(w * phi);
                gradients.push(grad_phi * w + grad_w * phi);
            }
        }
        ShapeFunctions {
            offsets: self.offsets.clone(),
            kernel_indices: self.kernel_indices.clone(),
            values,
            gradients,
            kernel_count: self.kernel_count,
        }
    }

    /// Interpolates nodal scalars: `u(X_i) = Σ_k ϕ_k(X_i) c_k` and `∇u(X_i) = Σ_k ∇ϕ_k(X_i) c_k`.
    ///
    /// # Panics
    /// If `nodal.len()` differs from the kernel count.
    pub fn interpolate(&self, i: usize, nodal: &[f64]) -> (f64, Vector3<f64>) {
        assert_eq!(nodal.len(), self.kernel_count, "one nodal value per kernel");
        self.kernels(i)
            .iter()
            .zip(self.values(i))
            .zip(self.gradients(i))
            .fold((0.0, Vector3::zeros()), |(u, g), ((&k, &phi), grad)| {
                (u + phi * nodal[k as usize], g + grad * nodal[k as usize])
            })
    }
}

/// Largest violation over a set of points of the four reproducing conditions (design §3.3),
/// made dimensionless with a length `L`. All are round-off small wherever M(X) is invertible.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ReproducingErrors {
    /// `max |Σ_k ϕ_k - 1|`.
    pub partition_of_unity: f64,
    /// `max |Σ_k ϕ_k p_k - X| / L`.
    pub linear: f64,
    /// `max |Σ_k ∇ϕ_k| · L`.
    pub gradient_sum: f64,
    /// `max |Σ_k p_k ∇ϕ_kᵀ - I|` (Frobenius).
    pub gradient_linear: f64,
}

impl ReproducingErrors {
    /// The largest of the four.
    pub fn max(&self) -> f64 {
        self.partition_of_unity
            .max(self.linear)
            .max(self.gradient_sum)
            .max(self.gradient_linear)
    }
}

impl ShapeFunctions {
    /// Checks the reproducing conditions at the points the functions were evaluated at.
    ///
    /// # Panics
    /// If `queries` or `kernels` do not match the ones used to evaluate `self`.
    pub fn reproducing_errors(
        &self,
        kernels: &Kernels,
        queries: &[Vector3<f64>],
        length: f64,
    ) -> ReproducingErrors {
        assert_eq!(
            queries.len(),
            self.point_count(),
            "one query per evaluated point"
        );
        assert_eq!(
            kernels.len(),
            self.kernel_count,
            "the kernels the functions belong to"
        );
        let mut e = ReproducingErrors::default();
        for (i, x) in queries.iter().enumerate() {
            let ReproducingSums {
                sum,
                first,
                grad_sum,
                grad_first,
            } = ReproducingSums::new(
                &Vector3::zeros(),
                kernels,
                self.kernels(i),
                self.values(i),
                self.gradients(i),
            );
            e.partition_of_unity = e.partition_of_unity.max((sum - 1.0).abs());
            e.linear = e.linear.max((first - x).norm() / length);
            e.gradient_sum = e.gradient_sum.max(grad_sum.norm() * length);
            e.gradient_linear = e
                .gradient_linear
                .max((grad_first - Matrix3::identity()).norm());
        }
        e
    }
}

/// The sums of the four reproducing conditions at one point, the centres taken relative to an
/// origin o: `Σϕ_k`, `Σϕ_k (p_k − o)`, `Σ∇ϕ_k`, `Σ(p_k − o)∇ϕ_kᵀ`.
struct ReproducingSums {
    sum: f64,
    first: Vector3<f64>,
    grad_sum: Vector3<f64>,
    grad_first: Matrix3<f64>,
}

impl ReproducingSums {
    /// The sums over the kernels `indices` with values `values` and gradients `gradients`.
    fn new(
        origin: &Vector3<f64>,
        kernels: &Kernels,
        indices: &[u32],
        values: &[f64],
        gradients: &[Vector3<f64>],
    ) -> Self {
        let (mut sum, mut first) = (0.0, Vector3::zeros());
        let (mut grad_sum, mut grad_first) = (Vector3::zeros(), Matrix3::zeros());
        for ((&k, &phi), g) in indices.iter().zip(values).zip(gradients) {
            let d = kernels.centers()[k as usize] - origin;
            sum += phi;
            first += d * phi;
            grad_sum += g;
            grad_first += d * g.transpose();
        }
        ReproducingSums {
            sum,
            first,
            grad_sum,
            grad_first,
        }
    }
}

/// Shape functions and gradients at one point, for the kernels in reach (sorted by index).
struct PointShapeFunctions {
    kernels: Vec<u32>,
    values: Vec<f64>,
    gradients: Vec<Vector3<f64>>,
    /// The length `s` of the shifted-and-scaled form (m).
    local_length: f64,
}

impl PointShapeFunctions {
    /// The largest of the four reproducing-condition violations at `x`, in units of the local
    /// length `s` and with centres taken relative to `x` (module docs).
    fn reproducing_error(&self, x: &Vector3<f64>, kernels: &Kernels) -> f64 {
        let s = self.local_length;
        let ReproducingSums {
            sum,
            first,
            grad_sum,
            grad_first,
        } = ReproducingSums::new(x, kernels, &self.kernels, &self.values, &self.gradients);
        let errors = [
            (sum - 1.0).abs(),
            first.norm() / s,
            grad_sum.norm() * s,
            (grad_first - Matrix3::identity()).norm(),
        ];
        // NaN (an overflowed gradient) is kept, and rejected by the caller's comparison.
        if errors.iter().any(|e| e.is_nan()) {
            f64::NAN
        } else {
            errors.into_iter().fold(0.0, f64::max)
        }
    }
}

/// Evaluates ϕ_k and ∇ϕ_k of every kernel at every query point (parallel over points).
///
/// # Errors
/// [`ShapeFunctionError::SingularMomentMatrix`] naming the first offending point (lowest index);
/// [`ShapeFunctionError::NonFiniteQuery`]; [`ShapeFunctionError::InvalidParameter`].
pub fn evaluate_shape_functions(
    kernels: &Kernels,
    queries: &[Vector3<f64>],
    params: &ShapeFunctionParams,
) -> Result<ShapeFunctions, ShapeFunctionError> {
    let per_point: Vec<PointShapeFunctions> = evaluate_each(kernels, queries, params)?
        .into_iter()
        .collect::<Result<_, _>>()?;
    let mut offsets = Vec::with_capacity(queries.len() + 1);
    offsets.push(0);
    let nnz: usize = per_point.iter().map(|p| p.kernels.len()).sum();
    let (mut kernel_indices, mut values, mut gradients) = (
        Vec::with_capacity(nnz),
        Vec::with_capacity(nnz),
        Vec::with_capacity(nnz),
    );
    for p in per_point {
        kernel_indices.extend(p.kernels);
        values.extend(p.values);
        gradients.extend(p.gradients);
        offsets.push(values.len());
    }
    Ok(ShapeFunctions {
        offsets,
        kernel_indices,
        values,
        gradients,
        kernel_count: kernels.len(),
    })
}

/// Every query point at which the moment matrix M(X) is singular or too ill-conditioned, or
/// the functions do not reproduce linear fields to the required accuracy (the points
/// [`evaluate_shape_functions`] rejects), each as its
/// [`ShapeFunctionError::SingularMomentMatrix`] or
/// [`ShapeFunctionError::InaccurateReproduction`], in increasing point order; empty when the
/// shape functions exist everywhere.
///
/// # Errors
/// [`ShapeFunctionError::NonFiniteQuery`]; [`ShapeFunctionError::InvalidParameter`].
pub fn singular_queries(
    kernels: &Kernels,
    queries: &[Vector3<f64>],
    params: &ShapeFunctionParams,
) -> Result<Vec<ShapeFunctionError>, ShapeFunctionError> {
    let mut singular = Vec::new();
    for point in evaluate_each(kernels, queries, params)? {
        match point {
            Ok(_) => {}
            Err(e) if e.uncovered_point().is_some() => singular.push(e),
            Err(e) => return Err(e),
        }
    }
    Ok(singular)
}

/// The shape functions at each query point (parallel over points), or why they do not exist
/// there; the outer error is a parameter out of range.
fn evaluate_each(
    kernels: &Kernels,
    queries: &[Vector3<f64>],
    params: &ShapeFunctionParams,
) -> Result<Vec<Result<PointShapeFunctions, ShapeFunctionError>>, ShapeFunctionError> {
    for (name, value) in [
        ("cutoff", params.cutoff),
        ("min_reciprocal_condition", params.min_reciprocal_condition),
        ("max_reproducing_error", params.max_reproducing_error),
    ] {
        if !(value.is_finite() && value > 0.0) {
            return Err(ShapeFunctionError::InvalidParameter { name, value });
        }
    }
    let index = SpatialIndex::new(kernels.centers());
    let cutoff = params.cutoff.min(params.window.support());
    let search_radius = cutoff * kernels.radii().iter().copied().fold(0.0, f64::max);
    Ok(queries
        .par_iter()
        .enumerate()
        .map(|(i, x)| {
            if !x.iter().all(|c| c.is_finite()) {
                return Err(ShapeFunctionError::NonFiniteQuery { point: i });
            }
            let mut reach: Vec<u32> = index
                .within(x, search_radius)
                .into_iter()
                .filter(|&(k, d)| d < cutoff * kernels.radii()[k])
                .map(|(k, _)| k as u32)
                .collect();
            reach.sort_unstable();
            let position = [x.x, x.y, x.z];
            let kernels_in_reach = reach.len();
            let functions = match params.reproduction {
                Reproduction::Linear => evaluate_at::<LINEAR_TERMS, LinearBasis>(
                    x,
                    kernels,
                    params.window,
                    reach,
                    params.min_reciprocal_condition,
                ),
                Reproduction::Quadratic => evaluate_at::<QUADRATIC_TERMS, QuadraticBasis>(
                    x,
                    kernels,
                    params.window,
                    reach,
                    params.min_reciprocal_condition,
                ),
            }
            .map_err(|reciprocal_condition| {
                ShapeFunctionError::SingularMomentMatrix {
                    point: i,
                    position,
                    kernels_in_reach,
                    reciprocal_condition,
                }
            })?;
            let reproducing_error = functions.reproducing_error(x, kernels);
            if !(reproducing_error <= params.max_reproducing_error) {
                return Err(ShapeFunctionError::InaccurateReproduction {
                    point: i,
                    position,
                    kernels_in_reach,
                    reproducing_error,
                });
            }
            Ok(functions)
        })
        .collect())
}

/// The shifted-and-scaled evaluation at one point with the basis `B` of `N` terms
/// ([`crate::reproduction`]); `Err(rcond)` when the moment matrix is singular (0 when fewer
/// than N kernels reach the point or it does not factor). The gradients use `u_d = e_{d+1}/s`
/// for `∂_d b_k` whatever the basis: only ∂P's constant part enters them (module docs).
#[allow(non_snake_case)]
fn evaluate_at<const N: usize, B: PolynomialBasis<N>>(
    x: &Vector3<f64>,
    kernels: &Kernels,
    window: KernelWindow,
    reach: Vec<u32>,
    min_rcond: f64,
) -> Result<PointShapeFunctions, f64> {
    let n = reach.len();
    if n < N {
        return Err(0.0);
    }
    let s = reach
        .iter()
        .map(|&k| kernels.radii()[k as usize])
        .fold(0.0, f64::max);
    let mut phi = Vec::with_capacity(n);
    let mut grad_phi = Vec::with_capacity(n);
    let mut b = Vec::with_capacity(n);
    let mut M = SMatrix::<f64, N, N>::zeros();
    for &k in &reach {
        let (p, r) = (kernels.centers()[k as usize], kernels.radii()[k as usize]);
        let d = x - p;
        let (f, grad_f) = window.value_and_gradient(&d, r);
        let bk = B::at(&d, s);
        M += f * bk * bk.transpose();
        phi.push(f);
        grad_phi.push(grad_f);
        b.push(bk);
    }
    let chol = M.cholesky().ok_or(0.0)?;
    let diag = chol.l_dirty().diagonal();
    let rcond = (diag.min() / diag.max()).powi(2);
    if !(rcond >= min_rcond) {
        return Err(rcond);
    }
    let C = chol.solve(&unit_vector::<N>(0, 1.0));
    let bc: Vec<f64> = b.iter().map(|bk| bk.dot(&C)).collect();
    let mut dC = [SVector::<f64, N>::zeros(); 3];
    for (d, dCd) in dC.iter_mut().enumerate() {
        let u = unit_vector::<N>(d + 1, 1.0 / s);
        let uc = u.dot(&C);
        let dMC: SVector<f64, N> = (0..n)
            .map(|j| b[j] * (grad_phi[j][d] * bc[j] + phi[j] * uc) + u * (phi[j] * bc[j]))
            .sum();
        *dCd = -chol.solve(&dMC);
    }
    let values = (0..n).map(|j| phi[j] * bc[j]).collect();
    let gradients = (0..n)
        .map(|j| {
            Vector3::from_fn(|d, _| {
                grad_phi[j][d] * bc[j] + phi[j] * C[d + 1] / s + phi[j] * b[j].dot(&dC[d])
            })
        })
        .collect();
    Ok(PointShapeFunctions {
        kernels: reach,
        values,
        gradients,
        local_length: s,
    })
}

/// `value · e_i` in N dimensions.
fn unit_vector<const N: usize>(i: usize, value: f64) -> SVector<f64, N> {
    let mut e = SVector::<f64, N>::zeros();
    e[i] = value;
    e
}

/// The paper's literal, unshifted form (Eqs. 7, 9-11): `ϕ_k(X) = φ_k(X) P(p_k)ᵀ M(X)⁻¹ P(X)`,
/// `M(X) = Σ_k φ_k(X) P(p_k) P(p_k)ᵀ`, for the kernels `reach` (values only).
///
/// Kept as the reference for verifying [`evaluate_shape_functions`]; it is badly conditioned
/// far from the origin and is not used by the pipeline. Returns `None` when M(X) is singular.
pub fn shape_function_values_unshifted(
    x: &Vector3<f64>,
    kernels: &Kernels,
    window: KernelWindow,
    reach: &[u32],
) -> Option<Vec<f64>> {
    let basis = |p: &Vector3<f64>| Vector4::new(1.0, p.x, p.y, p.z);
    let weights: Vec<f64> = reach
        .iter()
        .map(|&k| {
            let (p, r) = (kernels.centers()[k as usize], kernels.radii()[k as usize]);
            window.value(&(x - p), r)
        })
        .collect();
    let moment: Matrix4<f64> = reach
        .iter()
        .zip(&weights)
        .map(|(&k, &w)| {
            let pk = basis(&kernels.centers()[k as usize]);
            w * pk * pk.transpose()
        })
        .sum();
    let c = moment.try_inverse()? * basis(x);
    Some(
        reach
            .iter()
            .zip(&weights)
            .map(|(&k, &w)| w * basis(&kernels.centers()[k as usize]).dot(&c))
            .collect(),
    )
}
