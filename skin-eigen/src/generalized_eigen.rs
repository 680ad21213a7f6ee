//! The generalized eigenproblem `H_w c = λ 𝓜 c` for the smallest pairs (Eq. 15).

use faer::{Mat, MatRef, Side};
use serde::{Deserialize, Serialize};

use crate::assembly::WeightSpaceMatrices;

/// Options for [`solve_skinning_modes`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct EigenParams {
    /// Number m of skinning weights to keep after the constant mode (default 16).
    pub modes: usize,
    /// Directions of 𝓜 with eigenvalue below `mass_rank_tolerance · λ_max(𝓜)` are discarded
    /// before the solve (default 1e-13): overlapping smooth kernels make 𝓜 nearly singular, and
    /// those directions carry no resolvable function.
    pub mass_rank_tolerance: f64,
}

impl Default for EigenParams {
    fn default() -> Self {
        EigenParams {
            modes: 16,
            mass_rank_tolerance: 1e-13,
        }
    }
}

/// The eigen solve failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EigenError {
    /// More modes requested than the (rank-reduced) problem has.
    #[error(
        "asked for {requested} modes (+1 constant) but only {available} independent kernel directions exist"
    )]
    TooManyModes {
        /// m requested.
        requested: usize,
        /// Directions available after discarding near-null mass directions.
        available: usize,
    },
    /// Zero modes requested.
    #[error("at least one skinning mode must be requested")]
    NoModes,
    /// 𝓜 is not positive (no point touches the kernels, or all volumes are zero).
    #[error("the mass matrix has no positive eigenvalue (largest {largest:e})")]
    DegenerateMass {
        /// Its largest eigenvalue.
        largest: f64,
    },
    /// The dense eigen solver did not converge.
    #[error("the dense symmetric eigen solver did not converge on a {size}×{size} problem")]
    NoConvergence {
        /// Problem size.
        size: usize,
    },
    /// The matrices are not square or differ in size.
    #[error("mass is {mass}×{mass} but the Hessian is {hessian}×{hessian}")]
    ShapeMismatch {
        /// Mass size.
        mass: usize,
        /// Hessian size.
        hessian: usize,
    },
}

/// Result of [`solve_skinning_modes`].
#[derive(Clone, Debug)]
pub struct EigenSolution {
    /// λ_1 ≤ … ≤ λ_m, the constant mode dropped (Pa/m²·… units of H_w/𝓜).
    pub eigenvalues: Vec<f64>,
    /// Coefficients c (K × m), columns 𝓜-orthonormal: `cᵀ𝓜c = I`.
    pub coefficients: Mat<f64>,
    /// The dropped smallest eigenvalue (≈ 0: the constant mode).
    pub constant_eigenvalue: f64,
    /// `λ_max(𝓜) / λ_min(𝓜)` before any direction was discarded (∞ if λ_min ≤ 0).
    pub mass_condition_number: f64,
    /// How many near-null directions of 𝓜 were discarded.
    pub discarded_mass_directions: usize,
    /// `max_j |H_w c_j - λ_j 𝓜 c_j| / (|H_w|_F |c_j|)`.
    pub max_relative_residual: f64,
    /// `max_ij |(cᵀ𝓜c - I)_ij|`.
    pub orthonormality_error: f64,
}

/// Solves `H_w c = λ 𝓜 c` for the m + 1 smallest pairs, drops the first (the constant mode,
/// λ ≈ 0) and returns the next m, 𝓜-orthonormal (Eq. 15, design §3.5).
///
/// Method (dense, K up to a few thousand): `𝓜 = Q D Qᵀ`; keep the directions with
/// `d_i > tol · d_max`; with `B = Q_r D_r^{-1/2}` solve the standard problem
/// `(Bᵀ H_w B) y = λ y` and map back `c = B y`, so `cᵀ𝓜c = yᵀy = I` holds by construction
/// even when 𝓜 is ill-conditioned. Cost: two dense symmetric eigendecompositions of size K.
///
/// # Errors
/// [`EigenError`] for m = 0, m + 1 larger than the usable directions, a degenerate mass
/// matrix, mismatched sizes, or solver non-convergence.
pub fn solve_skinning_modes(
    matrices: &WeightSpaceMatrices,
    params: &EigenParams,
) -> Result<EigenSolution, EigenError> {
    solve_modes_dropping(matrices, params, 1)
}

/// [`solve_skinning_modes`] keeping the smallest pair: the m smallest pairs of a problem with
/// no constant mode (weights held on an interface, [`crate::build_basis_with_interface`]).
///
/// # Errors
/// As [`solve_skinning_modes`].
pub(crate) fn solve_modes_keeping_first(
    matrices: &WeightSpaceMatrices,
    params: &EigenParams,
) -> Result<EigenSolution, EigenError> {
    solve_modes_dropping(matrices, params, 0)
}

/// The `m + dropped` smallest pairs, the first `dropped` left out.
fn solve_modes_dropping(
    matrices: &WeightSpaceMatrices,
    params: &EigenParams,
    dropped: usize,
) -> Result<EigenSolution, EigenError> {
    let (mass, hessian) = (&matrices.mass, &matrices.hessian);
    let k = mass.nrows();
    if mass.ncols() != k || hessian.nrows() != k || hessian.ncols() != k {
        return Err(EigenError::ShapeMismatch {
            mass: k,
            hessian: hessian.nrows(),
        });
    }
    if params.modes == 0 {
        return Err(EigenError::NoModes);
    }
    let count = params.modes + dropped;
    let pencil = smallest_generalized_eigenpairs(
        mass.as_ref(),
        hessian.as_ref(),
        count,
        count,
        params.mass_rank_tolerance,
    )?;
    let hc = hessian * &pencil.vectors;
    let mc = mass * &pencil.vectors;
    Ok(EigenSolution::from_pencil(
        pencil,
        dropped,
        &hc,
        &mc,
        hessian.norm_l2(),
    ))
}

/// The largest λ of `A x = λ B x` on the range of `B` (both symmetric, B positive
/// semi-definite; directions of B below `1e-10 · λ_max(B)` are left out): a trace or inverse
/// inequality's constant, such as Nitsche's `∫_Γ |∂_N u|² ≤ C a(u, u)`. `None` when B has no
/// positive eigenvalue or a solve fails.
pub fn largest_eigenvalue_on_range(a: MatRef<'_, f64>, b: MatRef<'_, f64>) -> Option<f64> {
    let (values, vectors) = scaled_self_adjoint_eigen(b)?;
    let largest = values.iter().copied().fold(0.0, f64::max);
    if largest <= 0.0 {
        return None;
    }
    let kept: Vec<usize> = (0..values.len())
        .filter(|&i| values[i] > 1e-10 * largest)
        .collect();
    let scaled = Mat::<f64>::from_fn(values.len(), kept.len(), |r, c| {
        vectors[(r, kept[c])] / values[kept[c]].sqrt()
    });
    let reduced = scaled.transpose() * a * &scaled;
    let reduced = Mat::<f64>::from_fn(kept.len(), kept.len(), |i, j| {
        0.5 * (reduced[(i, j)] + reduced[(j, i)])
    });
    let (values, _) = scaled_self_adjoint_eigen(reduced.as_ref())?;
    Some(values.into_iter().fold(0.0, f64::max))
}

/// The `count` smallest pairs of `H y = λ M y` (M symmetric positive semi-definite, H
/// symmetric) by the mass-rank-reduced dense method of [`solve_skinning_modes`], with the
/// vectors M-orthonormal. Shared by the dense path and the Rayleigh-Ritz step of the iterative
/// path.
pub(crate) struct Pencil {
    /// All computed eigenvalues (ascending), the first `count` used.
    pub values: Vec<f64>,
    /// The first `count` eigenvectors (n × count).
    pub vectors: Mat<f64>,
    pub mass_condition_number: f64,
    pub discarded_mass_directions: usize,
}

///
/// Returns `min(count, rank)` pairs; fails with [`EigenError::TooManyModes`] when the rank kept
/// is below `required`.
pub(crate) fn smallest_generalized_eigenpairs(
    mass: MatRef<'_, f64>,
    hessian: MatRef<'_, f64>,
    count: usize,
    required: usize,
    mass_rank_tolerance: f64,
) -> Result<Pencil, EigenError> {
    let k = mass.nrows();
    let (d, q) = scaled_self_adjoint_eigen(mass).ok_or(EigenError::NoConvergence { size: k })?;
    let (d_min, d_max) = (d[0], d[k - 1]);
    if !(d_max > 0.0) {
        return Err(EigenError::DegenerateMass { largest: d_max });
    }
    let mass_condition_number = if d_min > 0.0 {
        d_max / d_min
    } else {
        f64::INFINITY
    };
    let keep: Vec<usize> = (0..k)
        .filter(|&i| d[i] > mass_rank_tolerance * d_max)
        .collect();
    let r = keep.len();
    if required > r {
        return Err(EigenError::TooManyModes {
            requested: required.saturating_sub(1),
            available: r.saturating_sub(1),
        });
    }
    let count = count.min(r);
    let b = Mat::from_fn(k, r, |row, col| q[(row, keep[col])] / d[keep[col]].sqrt());
    let reduced = b.transpose() * hessian * &b;
    // Symmetrize away round-off before the symmetric solver.
    let reduced = Mat::from_fn(r, r, |i, j| 0.5 * (reduced[(i, j)] + reduced[(j, i)]));
    let (values, vectors) =
        scaled_self_adjoint_eigen(reduced.as_ref()).ok_or(EigenError::NoConvergence { size: r })?;
    Ok(Pencil {
        values,
        vectors: &b * vectors.subcols(0, count),
        mass_condition_number,
        discarded_mass_directions: k - r,
    })
}

impl EigenSolution {
    /// The modes of a basis with held regions in this form (no constant mode was dropped:
    /// `constant_eigenvalue` is 0).
    pub(crate) fn from_constrained(modes: crate::region_constraints::ConstrainedModes) -> Self {
        EigenSolution {
            eigenvalues: modes.eigenvalues,
            coefficients: modes.coefficients,
            constant_eigenvalue: 0.0,
            mass_condition_number: modes.mass_condition_number,
            discarded_mass_directions: modes.discarded_mass_directions,
            max_relative_residual: modes.max_relative_residual,
            orthonormality_error: modes.orthonormality_error,
        }
    }

    /// Drops the first `dropped` pairs of a pencil solution (1: the constant mode; 0 for a
    /// weighted basis, which has none) and measures the accuracy from `hc = H_w c`, `mc = 𝓜 c`
    /// (all `count` columns) and `|H_w|_F`.
    pub(crate) fn from_pencil(
        pencil: Pencil,
        dropped: usize,
        hc: &Mat<f64>,
        mc: &Mat<f64>,
        h_norm: f64,
    ) -> Self {
        let modes = pencil.vectors.ncols() - dropped;
        let coefficients = pencil.vectors.subcols(dropped, modes).to_owned();
        let eigenvalues: Vec<f64> = pencil.values[dropped..dropped + modes].to_vec();
        let (hc, mc) = (hc.subcols(dropped, modes), mc.subcols(dropped, modes));
        let max_relative_residual = (0..modes)
            .map(|j| {
                let r: f64 = (0..coefficients.nrows())
                    .map(|i| (hc[(i, j)] - eigenvalues[j] * mc[(i, j)]).powi(2))
                    .sum();
                r.sqrt() / (h_norm * coefficients.col(j).norm_l2())
            })
            .fold(0.0, f64::max);
        let gram = coefficients.transpose() * mc;
        let orthonormality_error = (0..modes)
            .flat_map(|i| (0..modes).map(move |j| (i, j)))
            .map(|(i, j)| (gram[(i, j)] - if i == j { 1.0 } else { 0.0 }).abs())
            .fold(0.0, f64::max);
        EigenSolution {
            eigenvalues,
            coefficients,
            constant_eigenvalue: if dropped > 0 { pencil.values[0] } else { 0.0 },
            mass_condition_number: pencil.mass_condition_number,
            discarded_mass_directions: pencil.discarded_mass_directions,
            max_relative_residual,
            orthonormality_error,
        }
    }
}

/// Eigenvalues (ascending) and eigenvectors of a symmetric matrix, computed on `A / max|a_ij|`
/// and scaled back.
///
/// Why: faer 0.24.4's `self_adjoint_eigen` loses accuracy on matrices of large norm. Measured
/// on a reduced beam problem (200×200, ‖A‖ ≈ 9e9): residual max|AU - UΛ| = 3.4e5 (4e-5 relative
/// to λ_max) unscaled, 5e-15 relative after scaling by any factor from 1e-10 to 1e-3 (nalgebra:
/// 3e-15). Returns `None` when the solver does not converge or the matrix is not finite.
pub(crate) fn scaled_self_adjoint_eigen(a: MatRef<'_, f64>) -> Option<(Vec<f64>, Mat<f64>)> {
    let n = a.nrows();
    let scale = (0..n)
        .flat_map(|j| (0..n).map(move |i| (i, j)))
        .map(|(i, j)| a[(i, j)].abs())
        .fold(0.0, f64::max);
    if !(scale.is_finite()) {
        return None;
    }
    let scale = if scale > 0.0 { scale } else { 1.0 };
    let scaled = Mat::from_fn(n, n, |i, j| a[(i, j)] / scale);
    let eigen = scaled.self_adjoint_eigen(Side::Lower).ok()?;
    let values = eigen
        .S()
        .column_vector()
        .iter()
        .map(|v| v * scale)
        .collect();
    Some((values, eigen.U().to_owned()))
}
