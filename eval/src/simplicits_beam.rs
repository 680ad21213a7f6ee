//! The Simplicits baseline on the beam: trained on the same grid as our basis, cached on disk
//! (training takes minutes; the cache key is a hash of the grid, material and every training
//! option).

use std::path::Path;

use baselines::{SIMPLICITS_FORMAT_VERSION, SimplicitsParams, TrainedSimplicits, train_simplicits};
use fem_ref::TrajectoryKeyBuilder;

use crate::EvalError;
use crate::beam::beam_material;
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
    let (grid, lame) = beam_basis_grid(basis_points)?;
    let material = beam_material();
    let mut key = TrajectoryKeyBuilder::default();
    key.str("simplicits beam")
        .u64(SIMPLICITS_FORMAT_VERSION as u64)
        .u64(grid.len() as u64)
        .f64s(&[material.youngs_modulus, material.poisson_ratio])
        .str(&format!("{params:?}"));
    for p in grid.positions() {
        key.f64s(p.as_slice());
    }
    let path = cache_dir
        .join("simplicits")
        .join(format!("simplicits-{}.model", key.finish().hex()));
    if path.is_file() {
        match TrainedSimplicits::load(&path) {
            Ok(trained) => {
                progress.status(format!(
                    "Simplicits m = {}: loaded from the cache ({})",
                    params.modes,
                    path.display()
                ));
                return Ok(BeamSimplicits {
                    trained,
                    cached: true,
                });
            }
            Err(e) => progress.status(format!("ignoring a damaged cache entry: {e}")),
        }
    }
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
    let trained = TrainedSimplicits {
        field,
        params: *params,
        report,
    };
    if let Err(e) = trained.save(&path) {
        // The network is still good; only the cache entry is missing.
        progress.status(format!("warning: Simplicits network not cached: {e}"));
    }
    Ok(BeamSimplicits {
        trained,
        cached: false,
    })
}
