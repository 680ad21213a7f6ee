//! The Simplicits baseline on the beam: trained on the same grid as our basis, cached on disk
//! (see [`crate::model_cache`]).

use std::path::Path;

use baselines::{SIMPLICITS_FORMAT_VERSION, SimplicitsParams, TrainedSimplicits, train_simplicits};

use crate::EvalError;
use crate::model_cache::{beam_model_path, load_or_train};
use crate::progress::Progress;
use crate::reduced_beam::beam_basis_grid;

/// A trained beam network and whether it came from the cache.
pub struct BeamSimplicits {
    /// The network, its options and its training report.
    pub trained: TrainedSimplicits,
    /// Loaded from the cache.
    pub cached: bool,
}

/// Trains (or loads from `<cache>/simplicits/`) the Simplicits network of the beam on the grid
/// of about `basis_points` points.
///
/// # Errors
/// [`EvalError::Basis`] if training fails (a cache that cannot be written is a warning).
pub fn train_beam_simplicits(
    params: &SimplicitsParams,
    basis_points: usize,
    cache_dir: &Path,
    progress: &Progress,
) -> Result<BeamSimplicits, EvalError> {
    let path = beam_model_path(
        cache_dir,
        "simplicits",
        SIMPLICITS_FORMAT_VERSION,
        &format!("{params:?}"),
        basis_points,
    )?;
    let (trained, cached) = load_or_train(
        &path,
        &format!("Simplicits m = {}", params.modes),
        progress,
        |path| TrainedSimplicits::load(path),
        || {
            let (grid, lame) = beam_basis_grid(basis_points)?;
            let bar = progress.bar(
                params.steps,
                format!("Simplicits training m={}", params.modes),
            );
            let (field, report) = train_simplicits(&grid, &lame, params, |step, losses| {
                bar.inc(1);
                if step % 100 == 0 {
                    bar.set_message(format!(
                        "Simplicits m={} loss {:.3e}",
                        params.modes, losses.total
                    ));
                }
            })
            .map_err(|e| EvalError::Basis(format!("Simplicits training: {e}")))?;
            bar.finish_and_clear();
            Ok(TrainedSimplicits {
                field,
                params: *params,
                report,
            })
        },
        |model, path| model.save(path),
    )?;
    Ok(BeamSimplicits { trained, cached })
}
