//! Iterative generalized eigen solve for large K: shift-and-invert block subspace iteration
//! with Rayleigh-Ritz on the sparse 𝓜 and H_w.

use faer::linalg::solvers::Solve;
use faer::sparse::linalg::matmul::sparse_dense_matmul;
use faer::sparse::{SparseColMat, Triplet};
use faer::{Accum, Mat, Par, Side};
use serde::{Deserialize, Serialize};

use crate::generalized_eigen::{
    EigenError, EigenParams, EigenSolution, Pencil, smallest_generalized_eigenpairs,
};
use crate::sparse_assembly::SparseWeightSpaceMatrices;

/// Options of the iterative solver.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SubspaceParams {
    /// Converged when every wanted pair has `|H_w c - λ𝓜c| / (|H_w|_F |c|)` below this
    /// (default 1e-12).
    pub tolerance: f64,
    /// Iteration cap (default 300).
    pub max_iterations: usize,
    /// Block size beyond the m + 1 wanted vectors (default: m + 1 more), which speeds up
    /// convergence: the error of pair i falls by `(λ_i + σ)/(λ_p + σ)` per iteration.
    pub extra_vectors: Option<usize>,
}

impl Default for SubspaceParams {
    fn default() -> Self {
        SubspaceParams {
            tolerance: 1e-12,
            max_iterations: 300,
            extra_vectors: None,
        }
    }
}

/// Solves `H_w c = λ𝓜c` for the m + 1 smallest pairs on sparse matrices and drops the
/// constant one, like [`crate::solve_skinning_modes`].
///
/// Method: factor `A = H_w + σ𝓜` once (sparse Cholesky, σ = 1e-6 · tr H_w / tr 𝓜 makes it
/// positive definite despite the constant null vector), then repeat `Y = A⁻¹ 𝓜 X` followed by
/// Rayleigh-Ritz (the dense reduced method on `YᵀH_wY`, `Yᵀ𝓜Y`), which keeps X
/// 𝓜-orthonormal. The block starts from a deterministic pseudo-random matrix.
///
/// # Errors
/// [`EigenError::NoModes`], [`EigenError::TooManyModes`], [`EigenError::NoConvergence`] when
/// the factorization fails or the iteration cap is reached (with the size in the error).
pub fn solve_skinning_modes_iteratively(
    matrices: &SparseWeightSpaceMatrices,
    params: &EigenParams,
    subspace: &SubspaceParams,
) -> Result<EigenSolution, EigenError> {
    let (mass, hessian) = (&matrices.mass, &matrices.hessian);
    let k = mass.nrows();
    if params.modes == 0 {
        return Err(EigenError::NoModes);
    }
    let wanted = params.modes + 1;
    let block = (wanted + subspace.extra_vectors.unwrap_or(wanted)).min(k);
    if wanted > block {
        return Err(EigenError::TooManyModes {
            requested: params.modes,
            available: k.saturating_sub(1),
        });
    }
    let trace = |m: &SparseColMat<usize, f64>| -> f64 {
        (0..k)
            .map(|j| {
                let (rows, vals) = (m.as_ref().row_idx_of_col_raw(j), m.as_ref().val_of_col(j));
                rows.iter()
                    .zip(vals)
                    .filter(|(r, _)| **r == j)
                    .map(|(_, v)| *v)
                    .sum::<f64>()
            })
            .sum()
    };
    let shift = 1e-6 * trace(hessian) / trace(mass);
    let mut triplets = Vec::new();
    for (matrix, factor) in [(hessian, 1.0), (mass, shift)] {
        for j in 0..k {
            let (rows, vals) = (
                matrix.as_ref().row_idx_of_col_raw(j),
                matrix.as_ref().val_of_col(j),
            );
            triplets.extend(
                rows.iter()
                    .zip(vals)
                    .map(|(&i, &v)| Triplet::new(i, j, factor * v)),
            );
        }
    }
    let shifted = SparseColMat::<usize, f64>::try_new_from_triplets(k, k, &triplets)
        .map_err(|_| EigenError::NoConvergence { size: k })?;
    let llt = shifted
        .sp_cholesky(Side::Lower)
        .map_err(|_| EigenError::NoConvergence { size: k })?;
    let h_norm = hessian
        .as_ref()
        .val()
        .iter()
        .map(|v| v * v)
        .sum::<f64>()
        .sqrt();
    let apply = |m: &SparseColMat<usize, f64>, x: &Mat<f64>| {
        let mut out = Mat::zeros(k, x.ncols());
        sparse_dense_matmul(
            out.as_mut(),
            Accum::Replace,
            m.as_ref(),
            x.as_ref(),
            1.0,
            Par::rayon(0),
        );
        out
    };
    let mut state = 0x853C49E6748FEA9Bu64;
    let mut x = Mat::from_fn(k, block, |_, _| {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    });
    for _ in 0..subspace.max_iterations {
        let mut y = apply(mass, &x);
        llt.solve_in_place(y.as_mut());
        let (hy, my) = (apply(hessian, &y), apply(mass, &y));
        let (reduced_h, reduced_m) = (y.transpose() * &hy, y.transpose() * &my);
        let ritz = smallest_generalized_eigenpairs(
            reduced_m.as_ref(),
            reduced_h.as_ref(),
            block,
            wanted,
            params.mass_rank_tolerance,
        )?;
        // Ritz vectors: the whole block goes on to the next iteration.
        x = &y * &ritz.vectors;
        let wanted_ritz = ritz.vectors.subcols(0, wanted);
        let (hc, mc) = (&hy * wanted_ritz, &my * wanted_ritz);
        let c = x.subcols(0, wanted);
        let converged = (0..wanted).all(|j| {
            let r: f64 = (0..k)
                .map(|i| (hc[(i, j)] - ritz.values[j] * mc[(i, j)]).powi(2))
                .sum();
            r.sqrt() <= subspace.tolerance * h_norm * c.col(j).norm_l2()
        });
        if converged {
            let pencil = Pencil {
                vectors: c.to_owned(),
                ..ritz
            };
            let mut solution = EigenSolution::from_pencil(pencil, 1, &hc, &mc, h_norm);
            solution.mass_condition_number = f64::NAN;
            return Ok(solution);
        }
    }
    Err(EigenError::NoConvergence { size: k })
}
