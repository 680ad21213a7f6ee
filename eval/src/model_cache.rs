//! Trained models (Simplicits networks of the beam and the shapes, the Table 3 coefficient
//! ablations) cached on disk: training takes minutes, and the key is a hash of the grid, the
//! material and every training option, so a cached model is only reused for identical inputs.

use hyperelastic::MaterialSample;
use std::path::{Path, PathBuf};

use baselines::ModelFileError;
use fem_ref::trajectory_key_builder;
use rkpm_core::IntegrationPoints;

use crate::EvalError;
use crate::beam::beam_material;
use crate::beam::reduced::beam_basis_grid;
use crate::progress::Progress;

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
    progress: &Progress,
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
    progress: &Progress,
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
