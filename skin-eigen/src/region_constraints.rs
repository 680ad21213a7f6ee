//! Skinning weights for exactly held regions: one weight per region, 1 on its region
//! and 0 on the others, and m eigenmodes that vanish on every region.
//!
//! With regions Ω_0 … Ω_{R-1}, each given by rest points X_p (those that must be held: the
//! simulation's integration points in the region, and as many more as the region should be
//! held on), and `C` the P × K matrix of shape function values `ϕ_k(X_p)` at all of them:
//!
//! ```text
//! region weights  a_r = argmin aᵀ H_w a   subject to  C a = δ_r        (harmonic extension)
//! modes           H_w c = λ 𝓜 c  for c in null(C),   cᵀ𝓜c = I        (Eq. 15 restricted)
//! ```
//!
//! `δ_r` is 1 at the points of Ω_r and 0 at the others. Because constants carry no H_w energy
//! and satisfy `C 1 = 1`, the region weights sum to one everywhere: `Σ_r a_r = 1` (the
//! reproducing condition of the RKPM kernels turns the all-ones coefficient vector into the
//! constant function). A basis can therefore keep the constant handle and R − 1 region weights;
//! the weight of Ω_0 is `1 − Σ_{r≥1} a_r`.
//!
//! Method (dense): the SVD `C = U Σ Vᵀ`; the null space `N` is spanned by the right singular
//! vectors with `σ ≤ null_tolerance · σ_max` (and those beyond min(P, K)). The modes solve the
//! pencil `(NᵀH_wN, Nᵀ𝓜N)` by the mass-rank-reduced method of [`crate::solve_skinning_modes`];
//! each region weight is `a_r = a_p − N (NᵀH_wN)⁻¹ NᵀH_w a_p` with `a_p = V Σ⁺ Uᵀ δ_r` the
//! least-norm fit of `C a = δ_r` (SVD of C rather than eigenvectors of CᵀC, whose squared
//! condition number amplified round-off into 1e-3 errors of `Σ_r a_r = 1` in the middle of a
//! bar).
//!
//! RKPM weights do not interpolate: a weight that vanishes on a region also stays small over a
//! band about one kernel radius beyond it.

use faer::linalg::solvers::Solve;
use faer::{Mat, MatRef, Side};
use nalgebra::Vector3;
use rkpm_core::{Kernels, ShapeFunctionError, ShapeFunctionParams, evaluate_shape_functions};
use serde::{Deserialize, Serialize};

use crate::assembly::WeightSpaceMatrices;
use crate::generalized_eigen::{EigenError, EigenParams, smallest_generalized_eigenpairs};

/// Options for [`solve_constrained_modes`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RegionConstraintParams {
    /// Directions with singular value of C at most `null_tolerance · σ_max(C)` count as vanishing
    /// on the regions (default 1e-7: weights then vanish there to about 1e-7 of their size, and
    /// the fit of the region weights amplifies round-off by at most 1e7).
    pub null_tolerance: f64,
    /// The largest error `|C a_r − δ_r|` the region weights may have (default 1e-6); larger means
    /// the kernels cannot tell the regions apart (regions that touch, or a region too small for
    /// any kernel to single out).
    pub max_region_weight_error: f64,
}

impl Default for RegionConstraintParams {
    fn default() -> Self {
        RegionConstraintParams {
            null_tolerance: 1e-7,
            max_region_weight_error: 1e-6,
        }
    }
}

/// The regions do not fit, or the constrained problem could not be solved.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RegionError {
    /// No region was given.
    #[error("exact constraints need at least one region")]
    NoRegions,
    /// Every point lies in a held region: nothing is left to deform.
    #[error("every integration point lies in a held region; no free part is left to deform")]
    NoFreePoints,
    /// A region holds no point.
    #[error("region {region} holds no integration point")]
    EmptyRegion {
        /// Its index.
        region: usize,
    },
    /// The shape functions could not be evaluated at a region point (outside the kernels'
    /// reach, or not finite).
    #[error("region points: {0}")]
    ShapeFunctions(#[from] ShapeFunctionError),
    /// The kernels cannot make a weight that is 1 on one region and 0 on the others.
    #[error(
        "region {region}: the best weight is off by {error:e} on the regions (limit {limit:e}); the regions are too close for the kernels to separate them"
    )]
    NotSeparable {
        /// The region.
        region: usize,
        /// `max |C a_r − δ_r|`.
        error: f64,
        /// [`RegionConstraintParams::max_region_weight_error`].
        limit: f64,
    },
    /// The H_w-minimizing extension of the region weights has no unique solution.
    #[error(
        "the {directions} free weight directions leave H_w singular; no unique smooth region weight"
    )]
    SingularExtension {
        /// Dimension of the free space.
        directions: usize,
    },
    /// The restricted eigen solve failed (e.g. fewer free directions than modes).
    #[error("eigen solve on the weights that vanish on the regions: {0}")]
    Eigen(#[from] EigenError),
}

/// Result of [`solve_constrained_modes`].
#[derive(Clone, Debug)]
pub struct ConstrainedModes {
    /// Region weights `a_r`, K × R (column r: 1 on Ω_r, 0 on the other regions).
    pub region_coefficients: Mat<f64>,
    /// Mode coefficients c, K × m, vanishing on every region, `cᵀ𝓜c = I`.
    pub coefficients: Mat<f64>,
    /// λ_1 ≤ … ≤ λ_m of the restricted pencil.
    pub eigenvalues: Vec<f64>,
    /// Dimension of null(C) (free weight directions before the mass-rank reduction).
    pub null_space_dimension: usize,
    /// `max_r max_p |(C a_r − δ_r)_p|`.
    pub max_region_weight_error: f64,
    /// `max_{p,j} |(C c)_pj|`: how far the modes are from vanishing on the regions.
    pub max_mode_value_on_regions: f64,
    /// `max_ij |(cᵀ𝓜c − I)_ij|`.
    pub orthonormality_error: f64,
    /// `max_j |Nᵀ(H_w c_j − λ_j 𝓜 c_j)| / (|H_w|_F |c_j|)`, the residual of the restricted pencil.
    pub max_relative_residual: f64,
    /// `λ_max / λ_min` of `Nᵀ𝓜N` (∞ when singular).
    pub mass_condition_number: f64,
    /// Near-null mass directions of `Nᵀ𝓜N` discarded.
    pub discarded_mass_directions: usize,
}

/// Region weights and the m modes that vanish on the regions (module docs for the method).
/// `matrices` are 𝓜 and H_w of `kernels` with shape functions `shape_params`; `regions` are the
/// rest points (m) of each region.
///
/// # Errors
/// [`RegionError`]: no region, an empty region, a region point the kernels do not reach,
/// regions the kernels cannot separate, or a failed eigen solve (m larger than the free
/// directions).
pub fn solve_constrained_modes(
    matrices: &WeightSpaceMatrices,
    kernels: &Kernels,
    shape_params: &ShapeFunctionParams,
    regions: &[Vec<Vector3<f64>>],
    eigen: &EigenParams,
    params: &RegionConstraintParams,
) -> Result<ConstrainedModes, RegionError> {
    if regions.is_empty() {
        return Err(RegionError::NoRegions);
    }
    if let Some(region) = regions.iter().position(Vec::is_empty) {
        return Err(RegionError::EmptyRegion { region });
    }
    if eigen.modes == 0 {
        return Err(EigenError::NoModes.into());
    }
    let k = kernels.len();
    let region_points: Vec<Vector3<f64>> = regions.iter().flatten().copied().collect();
    let shape = evaluate_shape_functions(kernels, &region_points, shape_params)?;
    let rows: Vec<usize> = regions
        .iter()
        .enumerate()
        .flat_map(|(r, points)| std::iter::repeat_n(r, points.len()))
        .collect();
    let mut c = Mat::<f64>::zeros(rows.len(), k);
    for row in 0..rows.len() {
        for (&kernel, &phi) in shape.kernels(row).iter().zip(shape.values(row)) {
            c[(row, kernel as usize)] = phi;
        }
    }

    // C = U Σ Vᵀ (full V): null(C) is spanned by the columns of V with σ ≤ tol · σ_max and
    // those beyond min(P, K).
    let svd = c.svd().map_err(|_| EigenError::NoConvergence { size: k })?;
    let sigma: Vec<f64> = svd.S().column_vector().iter().copied().collect();
    let (svd_u, svd_v) = (svd.U(), svd.V());
    let largest = sigma.iter().copied().fold(0.0, f64::max);
    let kept: Vec<usize> = (0..sigma.len())
        .filter(|&i| sigma[i] > params.null_tolerance * largest)
        .collect();
    let null: Vec<usize> = (0..k).filter(|i| !kept.contains(i)).collect();
    let n = Mat::from_fn(k, null.len(), |i, j| svd_v[(i, null[j])]);

    // The usable null space: V (K × r), Vᵀ𝓜V = I, VᵀH_wV = diag(λ).
    let (mass, hessian) = (&matrices.mass, &matrices.hessian);
    let reduced_mass = symmetric(&(n.transpose() * mass * &n));
    let reduced_hessian = symmetric(&(n.transpose() * hessian * &n));
    let pencil = smallest_generalized_eigenpairs(
        reduced_mass.as_ref(),
        reduced_hessian.as_ref(),
        eigen.modes,
        eigen.modes,
        eigen.mass_rank_tolerance,
    )?;
    let coefficients = &n * &pencil.vectors;
    let eigenvalues = pencil.values[..eigen.modes].to_vec();

    // Region weights: a_p = V Σ⁻¹ Uᵀ δ_r over the kept singular directions (the least-norm
    // fit of C a = δ_r), plus the H_w-minimizing correction a_p − N (NᵀH_wN)⁻¹ NᵀH_w a_p.
    let free_hessian = symmetric(&(n.transpose() * hessian * &n));
    let free_factor =
        free_hessian
            .llt(Side::Lower)
            .map_err(|_| RegionError::SingularExtension {
                directions: null.len(),
            })?;
    let mut region_coefficients = Mat::<f64>::zeros(k, regions.len());
    for r in 0..regions.len() {
        let delta = Mat::from_fn(rows.len(), 1, |row, _| f64::from(rows[row] == r));
        let mut particular = Mat::<f64>::zeros(k, 1);
        for &i in &kept {
            let coefficient = (0..rows.len())
                .map(|row| svd_u[(row, i)] * delta[(row, 0)])
                .sum::<f64>()
                / sigma[i];
            for a in 0..k {
                particular[(a, 0)] += coefficient * svd_v[(a, i)];
            }
        }
        let mut y = n.transpose() * (hessian * &particular);
        free_factor.solve_in_place(y.as_mut());
        let a = particular - &n * y;
        region_coefficients.col_mut(r).copy_from(a.col(0));
    }

    let on_regions = &c * &region_coefficients;
    let mut max_region_weight_error = 0.0_f64;
    for r in 0..regions.len() {
        let error = (0..rows.len())
            .map(|row| (on_regions[(row, r)] - f64::from(rows[row] == r)).abs())
            .fold(0.0, f64::max);
        if !(error <= params.max_region_weight_error) {
            return Err(RegionError::NotSeparable {
                region: r,
                error,
                limit: params.max_region_weight_error,
            });
        }
        max_region_weight_error = max_region_weight_error.max(error);
    }
    let modes_on_regions = &c * &coefficients;
    let max_mode_value_on_regions = max_abs(modes_on_regions.as_ref());
    let hc = hessian * &coefficients;
    let mc = mass * &coefficients;
    let h_norm = hessian.norm_l2();
    let max_relative_residual = (0..eigen.modes)
        .map(|j| {
            let residual = Mat::from_fn(k, 1, |i, _| hc[(i, j)] - eigenvalues[j] * mc[(i, j)]);
            (n.transpose() * residual).norm_l2() / (h_norm * coefficients.col(j).norm_l2())
        })
        .fold(0.0, f64::max);
    let gram = coefficients.transpose() * mc;
    let orthonormality_error = (0..eigen.modes)
        .flat_map(|i| (0..eigen.modes).map(move |j| (i, j)))
        .map(|(i, j)| (gram[(i, j)] - f64::from(i == j)).abs())
        .fold(0.0, f64::max);
    Ok(ConstrainedModes {
        region_coefficients,
        coefficients,
        eigenvalues,
        null_space_dimension: null.len(),
        max_region_weight_error,
        max_mode_value_on_regions,
        orthonormality_error,
        max_relative_residual,
        mass_condition_number: pencil.mass_condition_number,
        discarded_mass_directions: pencil.discarded_mass_directions,
    })
}

fn symmetric(a: &Mat<f64>) -> Mat<f64> {
    Mat::from_fn(a.nrows(), a.ncols(), |i, j| 0.5 * (a[(i, j)] + a[(j, i)]))
}

fn max_abs(a: MatRef<'_, f64>) -> f64 {
    (0..a.ncols())
        .flat_map(|j| (0..a.nrows()).map(move |i| (i, j)))
        .map(|(i, j)| a[(i, j)].abs())
        .fold(0.0, f64::max)
}
