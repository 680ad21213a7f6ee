//! Trained models (Simplicits networks of the beam and the shapes, the Table 3 coefficient
//! ablations) cached on disk: training takes minutes, and the key is a hash of the grid, the
//! material and every training option, so a cached model is only reused for identical inputs.

use hyperelastic::MaterialSample;
use std::path::{Path, PathBuf};

use baselines::ModelFileError;
use fem_ref::trajectory_key_builder;
use rkpm_core::IntegrationPoints;

use crate::EvalError;
use crate::beam_scenario::{beam_basis_grid, beam_material};
use freeform::terminal_progress::TerminalProgress;

/// `<cache>/<folder>/<folder>-<hash>.model` for a model of the beam grid of about
/// `basis_points` points, trained with `options` (their `Debug` form) by a file format of
/// `format_version`.
///
/// # Errors
/// [`EvalError::Sampling`] or [`EvalError::Material`] when the grid cannot be built.
pub fn beam_model_path(
    cache_dir: &Path,
    folder: &str,
    format_version: u32,
    options: &str,
    basis_points: usize,
) -> Result<PathBuf, EvalError> {
    let (grid, _) = beam_basis_grid(basis_points)?;
    // "simplicits beam", … (the key of the networks cached before this module existed).
    Ok(model_path(
        cache_dir,
        folder,
        &format!("{folder} beam"),
        format_version,
        options,
        &grid,
        &beam_material(),
    ))
}

/// `<cache>/<folder>/<folder>-<hash>.model` for a model trained on `points` (every position
/// enters the key) of `material`, with `options` (their `Debug` form) by a file format of
/// `format_version`; `subject` names what is modelled ("simplicits beam", "simplicits shape").
pub fn model_path(
    cache_dir: &Path,
    folder: &str,
    subject: &str,
    format_version: u32,
    options: &str,
    points: &IntegrationPoints,
    material: &MaterialSample,
) -> PathBuf {
    // The trajectory cache's key domain, as since the first cached model: another domain
    // would orphan every cached network.
    let mut key = trajectory_key_builder();
    key.str(subject)
        .u64(format_version as u64)
        .u64(points.len() as u64)
        .f64s(&[material.youngs_modulus, material.poisson_ratio])
        .str(options);
    for p in points.positions() {
        key.f64s(p.as_slice());
    }
    cache_dir
        .join(folder)
        .join(format!("{folder}-{}.model", key.finish().hex()))
}

/// Loads `path` if it holds a valid model, with a status line saying so. Returns `None` when
/// there is no file, or when the file does not load (reported as a damaged cache entry, and
/// left where it is).
pub fn load_cached<T>(
    path: &Path,
    label: &str,
    progress: &TerminalProgress,
    load: impl FnOnce(&Path) -> Result<T, ModelFileError>,
) -> Option<T> {
    if !path.is_file() {
        return None;
    }
    match load(path) {
        Ok(model) => {
            progress.status(format!(
                "{label}: loaded from the cache ({})",
                path.display()
            ));
            Some(model)
        }
        Err(e) => {
            progress.status(format!("ignoring a damaged cache entry: {e}"));
            None
        }
    }
}

/// Loads `path` if it holds a valid model ([`load_cached`]), else trains one and saves it
/// there (a save that fails is a warning: the model is still returned). Returns the model and
/// whether it came from the cache.
///
/// # Errors
/// Whatever `train` returns.
pub fn load_or_train<T>(
    path: &Path,
    label: &str,
    progress: &TerminalProgress,
    load: impl FnOnce(&Path) -> Result<T, ModelFileError>,
    train: impl FnOnce() -> Result<T, EvalError>,
    save: impl FnOnce(&T, &Path) -> Result<(), ModelFileError>,
) -> Result<(T, bool), EvalError> {
    if let Some(model) = load_cached(path, label, progress, load) {
        return Ok((model, true));
    }
    let model = train()?;
    if let Err(e) = save(&model, path) {
        progress.status(format!("warning: {label} not cached: {e}"));
    }
    Ok((model, false))
}

#[cfg(test)]
mod tests {
    use super::*;
    use test_support::fixtures::scratch_dir;

    const QUIET: TerminalProgress = TerminalProgress {
        quiet: true,
        hide_bars: true,
    };

    /// A "model" that is a number written as text.
    fn read_number(path: &Path) -> Result<u32, ModelFileError> {
        let text = std::fs::read_to_string(path).map_err(|source| ModelFileError::Io {
            path: path.display().to_string(),
            source,
        })?;
        text.trim()
            .parse()
            .map_err(|e: std::num::ParseIntError| ModelFileError::Format {
                path: path.display().to_string(),
                what: "number",
                version: 1,
                reason: e.to_string(),
            })
    }

    fn write_number(n: &u32, path: &Path) -> Result<(), ModelFileError> {
        std::fs::write(path, n.to_string()).map_err(|source| ModelFileError::Io {
            path: path.display().to_string(),
            source,
        })
    }

    #[test]
    fn load_cached_reads_a_valid_model_and_gives_none_for_a_missing_or_damaged_one_left_as_it_is() {
        let path = scratch_dir("model-cache-load-cached").join("n.model");
        assert_eq!(load_cached(&path, "n", &QUIET, read_number), None);
        std::fs::write(&path, "damaged").unwrap();
        assert_eq!(load_cached(&path, "n", &QUIET, read_number), None);
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "damaged");
        std::fs::write(&path, "42").unwrap();
        assert_eq!(load_cached(&path, "n", &QUIET, read_number), Some(42));
    }

    #[test]
    fn load_or_train_trains_only_what_the_cache_lacks_and_replaces_a_damaged_entry() {
        let path = scratch_dir("model-cache-load-or-train").join("n.model");
        let train = |n: u32| move || Ok(n);
        let first = load_or_train(&path, "n", &QUIET, read_number, train(7), write_number);
        assert_eq!(first.unwrap(), (7, false));
        // Cached now: the trainer is not called (it would give another number).
        let second = load_or_train(&path, "n", &QUIET, read_number, train(8), write_number);
        assert_eq!(second.unwrap(), (7, true));
        std::fs::write(&path, "damaged").unwrap();
        let retrained = load_or_train(&path, "n", &QUIET, read_number, train(9), write_number);
        assert_eq!(retrained.unwrap(), (9, false));
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "9");
    }
}
