//! Whether the basis's integration pool is converged for each kernel count: the first 2m
//! weight-space eigenvalues (m the study's largest) with the same kernels on the basis grid and
//! on a grid of twice the points ([`skin_eigen::pool_convergence`]).

use serde::{Deserialize, Serialize};
use skin_eigen::{PoolConvergence, pool_convergence};

use crate::EvalError;
use crate::beam_scenario::beam_basis_grid;
use crate::convergence::config::ConvergenceConfig;
use crate::reduced_settings::ReducedSettings;

/// The largest relative change of the first 2m eigenvalues a converged pool allows when its
/// points are doubled (issue 61).
pub const POOL_TOLERANCE: f64 = 1e-3;

/// One kernel count's pool check.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PoolCheckRow {
    /// Kernels K asked for.
    pub kernels: usize,
    /// Eigenvalues compared (2 × the study's largest m, or fewer when K is smaller).
    pub eigenvalues: usize,
    /// What the check measured.
    pub check: PoolConvergence,
    /// `check.max_relative_change ≤` [`POOL_TOLERANCE`].
    pub converged: bool,
}

/// The pool check at each of `config.kernels` on the beam's basis grid of
/// `config.settings.basis_points` points against one of twice as many.
///
/// # Errors
/// [`EvalError::Sampling`] for the grids, [`EvalError::Basis`] from the eigen solves.
pub(crate) fn pool_checks(config: &ConvergenceConfig) -> Result<Vec<PoolCheckRow>, EvalError> {
    let largest_m = config.modes.iter().copied().max().unwrap_or(1);
    let (grid, lame) = beam_basis_grid(config.settings.basis_points)?;
    let (finer, finer_lame) = beam_basis_grid(2 * config.settings.basis_points)?;
    config
        .kernels
        .iter()
        .map(|&kernels| {
            let eigenvalues = (2 * largest_m).min(kernels.saturating_sub(2));
            let params = ReducedSettings {
                kernels,
                modes: largest_m.min(eigenvalues),
                ..config.settings
            }
            .basis_params();
            let check = pool_convergence(&grid, &lame, &finer, &finer_lame, &params, eigenvalues)
                .map_err(EvalError::Basis)?;
            Ok(PoolCheckRow {
                kernels,
                eigenvalues,
                converged: check.converged(POOL_TOLERANCE),
                check,
            })
        })
        .collect()
}
