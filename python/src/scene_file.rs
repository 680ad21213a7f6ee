//! `freeform.simulate_scene_file`: a scene file run from Python.

use std::path::PathBuf;

use freeform::{
    ObjectsFile, Progress, SceneFile, Silent, simulate_objects,
    simulate_scene_file as run_scene_file,
};
use pyo3::prelude::*;

use crate::errors::{self, value_error};
use crate::progress::PythonProgress;
use crate::threads::with_threads;

/// Runs a scene file (TOML or JSON, one object or several) and writes its frames and
/// `summary.json` under `out_dir`; returns the summary as JSON text. Cubatures are cached
/// under `cache_dir` when given. `threads`: the threads it may use (all cores when None);
/// `progress`: a callable `progress(label, done, total)` (see [`PythonProgress`]).
#[pyfunction]
#[pyo3(signature = (path, out_dir, cache_dir = None, threads = None, progress = None))]
pub(crate) fn simulate_scene_file(
    py: Python<'_>,
    path: PathBuf,
    out_dir: PathBuf,
    cache_dir: Option<PathBuf>,
    threads: Option<usize>,
    progress: Option<Py<PyAny>>,
) -> PyResult<String> {
    let cache = cache_dir.as_deref();
    let progress: Box<dyn Progress> = match progress {
        None => Box::new(Silent),
        Some(callable) => Box::new(PythonProgress::new(callable)),
    };
    let progress = progress.as_ref();
    let summary = py.detach(|| {
        with_threads(threads, || -> PyResult<String> {
            let json = if ObjectsFile::describes(&path) {
                let file = ObjectsFile::load(&path).map_err(|e| errors::scene_file_error(&e))?;
                let report = simulate_objects(&file, &out_dir, cache, progress)
                    .map_err(|e| errors::simulate_error(&e))?;
                serde_json::to_string(&report)
            } else {
                let file = SceneFile::load(&path).map_err(|e| errors::scene_file_error(&e))?;
                let report = run_scene_file(&file, &out_dir, cache, progress)
                    .map_err(|e| errors::simulate_error(&e))?;
                serde_json::to_string(&report)
            };
            json.map_err(|e| value_error(&e))
        })
    })??;
    Ok(summary)
}
