//! The Simplicits baseline trained on the same integration points as our basis (the beam grid,
//! or a shape's), cached on disk (see [`crate::model_cache`]).

use std::path::Path;

use baselines::{SIMPLICITS_FORMAT_VERSION, SimplicitsParams, TrainedSimplicits, train_simplicits};

use hyperelastic::LameParameters;
use rkpm_core::IntegrationPoints;

use crate::EvalError;
use crate::beam_scenario::beam_basis_grid;
use crate::model_cache::{beam_model_path, load_or_train};
use freeform::terminal_progress::TerminalProgress;

/// A trained network and whether it came from the cache.
pub struct CachedSimplicits {
    /// The network, its options and its training report.
    pub trained: TrainedSimplicits,
    /// Loaded from the cache.
    pub cached: bool,
}

/// Trains (or loads from `<cache>/simplicits/`) the Simplicits network of the beam on the grid
/// of about `basis_points` points.
///
/// # Errors
/// [`EvalError::Simplicits`] if training fails (a cache that cannot be written is a warning).
pub fn train_beam_simplicits(
    params: &SimplicitsParams,
    basis_points: usize,
    cache_dir: &Path,
    progress: &TerminalProgress,
) -> Result<CachedSimplicits, EvalError> {
    let path = beam_model_path(
        cache_dir,
        "simplicits",
        SIMPLICITS_FORMAT_VERSION,
        &format!("{params:?}"),
        basis_points,
    )?;
    let (grid, lame) = beam_basis_grid(basis_points)?;
    train_cached_simplicits(&grid, &lame, params, &path, progress)
}

/// Trains (or loads from `path`) the Simplicits network of `params` on `points` with Lamé
/// parameters `lame` (one per point), showing a bar with the loss every 100 steps.
///
/// # Errors
/// [`EvalError::Simplicits`] if training fails (a cache that cannot be written is a warning).
pub fn train_cached_simplicits(
    points: &IntegrationPoints,
    lame: &[LameParameters],
    params: &SimplicitsParams,
    path: &Path,
    progress: &TerminalProgress,
) -> Result<CachedSimplicits, EvalError> {
    let (trained, cached) = load_or_train(
        path,
        &format!("Simplicits m = {}", params.modes),
        progress,
        |path| TrainedSimplicits::load(path),
        || {
            let bar = progress.bar(
                params.steps,
                format!("Simplicits training m={}", params.modes),
            );
            let (field, report) = train_simplicits(points, lame, params, |step, losses| {
                bar.inc(1);
                if step % 100 == 0 {
                    bar.set_message(format!(
                        "Simplicits m={} loss {:.3e}",
                        params.modes, losses.total
                    ));
                }
            })
            .map_err(|source| EvalError::Simplicits {
                what: format!("Simplicits m = {}", params.modes),
                source,
            })?;
            bar.finish_and_clear();
            Ok(TrainedSimplicits {
                field,
                params: *params,
                report,
            })
        },
        |model, path| model.save(path),
    )?;
    Ok(CachedSimplicits { trained, cached })
}
