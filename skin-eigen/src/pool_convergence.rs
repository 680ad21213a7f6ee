//! Whether an integration pool is fine enough for its kernels: the weight-space eigenvalues
//! with the same kernels integrated on the pool and on a finer one (design §3.3; issue 61's
//! "a pool verified converged": doubling it changes the first 2m eigenvalues by < 1e-3).
//!
//! The kernels are placed from the coarser pool (as [`crate::build_basis`] places them) and
//! widened to cover both pools, so the two eigenproblems differ only in how 𝓜 and H_w are
//! integrated.

use hyperelastic::LameParameters;
use rkpm_core::{IntegrationPoints, evaluate_shape_functions};
use serde::{Deserialize, Serialize};

use crate::assembly::assemble_weight_space_matrices;
use crate::basis_builder::{BasisError, BasisParams, placed_kernels_and_shape_functions};
use crate::generalized_eigen::{EigenParams, solve_skinning_modes};

/// What [`pool_convergence`] measured.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PoolConvergence {
    /// Points of the pool the basis is built on.
    pub points: usize,
    /// Points of the finer pool.
    pub finer_points: usize,
    /// Kernels (after widening to cover both pools).
    pub kernels: usize,
    /// The first `count` eigenvalues λᵢ on the pool (ascending, the constant left out).
    pub eigenvalues: Vec<f64>,
    /// The same on the finer pool.
    pub finer_eigenvalues: Vec<f64>,
    /// max_i |λᵢ − λᵢ'| / λᵢ' over the first `count`.
    pub max_relative_change: f64,
}

impl PoolConvergence {
    /// Whether no eigenvalue moved by more than `tolerance` (relative).
    pub fn converged(&self, tolerance: f64) -> bool {
        self.max_relative_change <= tolerance
    }
}

/// The first `count` weight-space eigenvalues with one set of kernels integrated on `points`
/// (with `materials`, one per point) and on `finer` (with `finer_materials`), and their largest
/// relative change. `count` is typically 2m; it must be below the kernel count.
///
/// # Errors
/// [`BasisError`] from kernel placement, shape functions, assembly or either eigen solve (a
/// material slice of the wrong length is [`BasisError::Assembly`]).
pub fn pool_convergence(
    points: &IntegrationPoints,
    materials: &[LameParameters],
    finer: &IntegrationPoints,
    finer_materials: &[LameParameters],
    params: &BasisParams,
    count: usize,
) -> Result<PoolConvergence, BasisError> {
    let (_, kernels, _, shape) =
        placed_kernels_and_shape_functions(points, &[finer.positions()], params)?;
    let finer_shape =
        evaluate_shape_functions(&kernels, finer.positions(), &params.shape_functions)?;
    let eigen = EigenParams {
        modes: count,
        ..params.eigen
    };
    let coarse = assemble_weight_space_matrices(&shape, points.volumes(), materials)?;
    let eigenvalues = solve_skinning_modes(&coarse, &eigen)?.eigenvalues;
    let fine = assemble_weight_space_matrices(&finer_shape, finer.volumes(), finer_materials)?;
    let finer_eigenvalues = solve_skinning_modes(&fine, &eigen)?.eigenvalues;
    let max_relative_change = eigenvalues
        .iter()
        .zip(&finer_eigenvalues)
        .map(|(a, b)| (a - b).abs() / b.abs())
        .fold(0.0, f64::max);
    Ok(PoolConvergence {
        points: points.len(),
        finer_points: finer.len(),
        kernels: kernels.len(),
        eigenvalues,
        finer_eigenvalues,
        max_relative_change,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;
    use rkpm_core::sample_box_grid;

    fn box_grid(spacing: f64) -> IntegrationPoints {
        sample_box_grid(Vector3::zeros(), Vector3::new(2.0, 0.5, 0.5), spacing).unwrap()
    }

    fn check(coarse: f64, fine: f64) -> PoolConvergence {
        let lame = LameParameters::from_young_poisson(1e5, 0.3).unwrap();
        let (a, b) = (box_grid(coarse), box_grid(fine));
        let params = BasisParams::default().with_kernels(60).with_modes(4);
        pool_convergence(
            &a,
            &vec![lame; a.len()],
            &b,
            &vec![lame; b.len()],
            &params,
            8,
        )
        .unwrap()
    }

    #[test]
    fn a_dense_pool_moves_the_eigenvalues_less_than_a_sparse_one_when_doubled() {
        // The same kernels on 8× the points (spacing halved) each time.
        let sparse = check(0.125, 0.0625);
        let dense = check(0.0625, 0.03125);
        assert_eq!(sparse.eigenvalues.len(), 8);
        assert!(
            dense.eigenvalues.iter().all(|l| *l > 0.0),
            "{:?}",
            dense.eigenvalues
        );
        // First order in the spacing at least (the grid's boundary cells): halving it should
        // about halve the change.
        assert!(
            dense.max_relative_change < 0.75 * sparse.max_relative_change,
            "{} vs {}",
            dense.max_relative_change,
            sparse.max_relative_change
        );
        assert!(dense.converged(dense.max_relative_change));
        assert!(!sparse.converged(dense.max_relative_change));
    }

    #[test]
    fn the_same_pool_twice_changes_nothing() {
        let same = check(0.1, 0.1);
        assert!(same.max_relative_change < 1e-10, "{same:?}");
    }
}
