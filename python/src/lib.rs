//! Python bindings of FreeForm: the extension module `freeform._native`, re-exported by the
//! pure-Python package `freeform` (`python/freeform/__init__.py`).
//!
//! Conventions at the boundary: SI units, float64, points as `(n, 3)` arrays. Long calls
//! (a basis, a simulation) release the GIL. Errors are `FreeFormError` subclasses
//! (`errors`), `FileNotFoundError` for a missing file, `ValueError` for an argument of the
//! wrong shape, with the whole chain of causes in the message.

mod arrays;
mod basis;
mod errors;
mod frames;
mod geometry;
mod material;
mod outputs;
mod points;
mod preview;
mod progress;
mod scene;
mod scene_file;
mod simulation;
mod splats;
mod threads;

use pyo3::prelude::*;

/// The extension module.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<geometry::PyGeometry>()?;
    m.add_class::<points::PyIntegrationPoints>()?;
    m.add_class::<material::PyMaterial>()?;
    m.add_class::<basis::PyBasis>()?;
    m.add_class::<simulation::PySimulation>()?;
    m.add_class::<scene::PyScene>()?;
    m.add_class::<splats::PySplats>()?;
    m.add_class::<frames::PyFrameWriter>()?;
    m.add_function(wrap_pyfunction!(basis::build_basis, m)?)?;
    m.add_function(wrap_pyfunction!(scene_file::simulate_scene_file, m)?)?;
    m.add_function(wrap_pyfunction!(preview::render_preview, m)?)?;
    errors::register(m)?;
    Ok(())
}
