//! The thread count a call or an object's steps run with (a fixed count gives bit-identical
//! results run to run).

use std::sync::Arc;

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::errors::value_error;

/// Runs `work` on a rayon pool of `threads` threads (all cores when `None`).
///
/// # Errors
/// As [`thread_pool`].
pub(crate) fn with_threads<T: Send>(
    threads: Option<usize>,
    work: impl FnOnce() -> T + Send,
) -> PyResult<T> {
    Ok(on_pool(thread_pool(threads)?.as_deref(), work))
}

/// A pool of `threads` threads for an object's calls to run on, or `None` for rayon's global
/// pool (all cores).
///
/// # Errors
/// `ValueError` for zero threads or a pool that cannot be built.
pub(crate) fn thread_pool(threads: Option<usize>) -> PyResult<Option<Arc<rayon::ThreadPool>>> {
    match threads {
        None => Ok(None),
        Some(0) => Err(PyValueError::new_err("threads must be at least 1")),
        Some(n) => rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .map(|pool| Some(Arc::new(pool)))
            .map_err(|e| value_error(&e)),
    }
}

/// Runs `work` on `pool`, or on the global pool without one.
pub(crate) fn on_pool<T: Send>(
    pool: Option<&rayon::ThreadPool>,
    work: impl FnOnce() -> T + Send,
) -> T {
    match pool {
        Some(pool) => pool.install(work),
        None => work(),
    }
}
