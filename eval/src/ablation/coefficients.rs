//! The Table 3 coefficient ablations on the beam: our RKPM coefficients trained by Adam on the
//! same grid as our basis, cached on disk (see [`crate::model_cache`]).

use std::path::Path;

use baselines::{
    COEFFICIENTS_FORMAT_VERSION, CoefficientTrainingParams, TrainedCoefficients, train_coefficients,
};

use crate::EvalError;
use crate::beam_scenario::beam_basis_grid;
use crate::model_cache::{beam_model_path, load_or_train};
use freeform::terminal_progress::TerminalProgress;

/// A trained ablation basis and whether it came from the cache.
pub struct BeamCoefficients {
    /// The basis, its options and its training report.
    pub trained: TrainedCoefficients,
    /// Loaded from the cache.
    pub cached: bool,
}

/// Trains (or loads from `<cache>/coefficients/`) one ablation on the beam grid of about
/// `basis_points` points.
///
/// # Errors
/// [`EvalError::Coefficients`] if training fails (a cache that cannot be written is a warning).
pub fn train_beam_coefficients(
    params: &CoefficientTrainingParams,
    basis_points: usize,
    cache_dir: &Path,
    progress: &TerminalProgress,
) -> Result<BeamCoefficients, EvalError> {
    let path = beam_model_path(
        cache_dir,
        "coefficients",
        COEFFICIENTS_FORMAT_VERSION,
        &format!("{params:?}"),
        basis_points,
    )?;
    let label = format!("{} m = {}", params.label(), params.modes);
    let (trained, cached) = load_or_train(
        &path,
        &label,
        progress,
        |path| TrainedCoefficients::load(path),
        || {
            let (grid, lame) = beam_basis_grid(basis_points)?;
            let bar = progress.bar(params.steps, label.clone());
            let trained = train_coefficients(&grid, &lame, params, |step, losses| {
                bar.inc(1);
                if step % 100 == 0 {
                    bar.set_message(format!("{label} loss {:.3e}", losses.total));
                }
            })
            .map_err(|source| EvalError::Coefficients {
                what: label.clone(),
                source,
            })?;
            bar.finish_and_clear();
            Ok(trained)
        },
        |model, path| model.save(path),
    )?;
    Ok(BeamCoefficients { trained, cached })
}
