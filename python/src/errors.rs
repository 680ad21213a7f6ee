//! The Python exceptions of the bindings, and which Rust error becomes which.
//!
//! Every error the library reports is a `FreeFormError` (a `ValueError`, so code that caught
//! `ValueError` keeps working) of one subclass per stage: `GeometryError` (reading or
//! sampling a shape), `BasisError` (building or evaluating a basis), `SceneError` (a scene or
//! its settings), `StepError` (a step that failed, with `.step`), `FileFormatError` (a file
//! that is not what it claims). A missing file is Python's own `FileNotFoundError`, a file
//! that cannot be written an `OSError`. Each message carries the whole chain of causes.

use freeform::{
    GeometryError as LibraryGeometryError, RunError, SceneFileError, SimulateError, SplatFileError,
    failure_chain,
};
use pyo3::create_exception;
use pyo3::exceptions::{PyFileNotFoundError, PyOSError, PyValueError};
use pyo3::prelude::*;
use rkpm_core::GeometryReadError;

create_exception!(
    _native,
    FreeFormError,
    PyValueError,
    "An error FreeForm reports (a ValueError): its message names the problem and its causes."
);
create_exception!(
    _native,
    GeometryError,
    FreeFormError,
    "A shape that cannot be read or sampled (an open mesh, no points inside, NaN coordinates)."
);
create_exception!(
    _native,
    BasisError,
    FreeFormError,
    "A basis that cannot be built or evaluated (m >= K, a point outside every kernel)."
);
create_exception!(
    _native,
    SceneError,
    FreeFormError,
    "A scene or simulation setting that cannot be used (a region that holds no point, a bad value)."
);
create_exception!(
    _native,
    StepError,
    FreeFormError,
    "A time step that failed; `.step` is the step (1-based) when known."
);
create_exception!(
    _native,
    FileFormatError,
    FreeFormError,
    "A file that is not of the format it claims (a corrupt PLY, a basis file of another version)."
);

/// `ValueError` with `error`'s chain of causes.
pub(crate) fn value_error(error: &dyn std::error::Error) -> PyErr {
    PyValueError::new_err(failure_chain(error))
}

/// `class(message)` with `error`'s chain of causes as the message.
pub(crate) fn raise<E: pyo3::PyTypeInfo>(error: &dyn std::error::Error) -> PyErr {
    PyErr::new::<E, _>(failure_chain(error))
}

/// A `StepError` for step `step` (1-based): its message the chain of causes, `.step` set.
pub(crate) fn step_error(step: Option<usize>, error: &dyn std::error::Error) -> PyErr {
    Python::attach(|py| {
        let err = StepError::new_err(failure_chain(error));
        if let Err(e) = err.value(py).setattr("step", step) {
            return e;
        }
        err
    })
}

/// A geometry error: `FileNotFoundError` for a missing file, `FileFormatError` for one that
/// cannot be parsed, `GeometryError` otherwise (an open mesh, sampling).
pub(crate) fn geometry_error(error: &LibraryGeometryError) -> PyErr {
    match error {
        LibraryGeometryError::Missing { .. } => raise::<PyFileNotFoundError>(error),
        LibraryGeometryError::Unreadable { .. } => raise::<FileFormatError>(error),
        LibraryGeometryError::Read(read) => match read {
            GeometryReadError::Io { .. } => raise::<PyOSError>(error),
            GeometryReadError::UnsupportedFormat { .. }
            | GeometryReadError::Parse { .. }
            | GeometryReadError::MissingProperty { .. }
            | GeometryReadError::NoData { .. }
            | GeometryReadError::NonTriangleFace { .. } => raise::<FileFormatError>(error),
            _ => raise::<GeometryError>(error),
        },
        LibraryGeometryError::Sampling(_) => raise::<GeometryError>(error),
    }
}

/// A splat file's error: `FileNotFoundError`, `FileFormatError`, or `OSError` for one that
/// cannot be written.
pub(crate) fn splat_error(error: &SplatFileError) -> PyErr {
    match error {
        SplatFileError::Read { source, .. } if source.kind() == std::io::ErrorKind::NotFound => {
            raise::<PyFileNotFoundError>(error)
        }
        SplatFileError::Read { .. } | SplatFileError::Write(_) => raise::<PyOSError>(error),
        SplatFileError::CountMismatch { .. } => raise::<PyValueError>(error),
        _ => raise::<FileFormatError>(error),
    }
}

/// A scene file's error: `FileNotFoundError`, `OSError`, or `SceneError` for one that does
/// not parse or has a bad value.
pub(crate) fn scene_file_error(error: &SceneFileError) -> PyErr {
    match error {
        SceneFileError::Read { source, .. } if source.kind() == std::io::ErrorKind::NotFound => {
            raise::<PyFileNotFoundError>(error)
        }
        SceneFileError::Read { .. } => raise::<PyOSError>(error),
        _ => raise::<SceneError>(error),
    }
}

/// A scene-file run's error, by the stage that failed.
pub(crate) fn simulate_error(error: &SimulateError) -> PyErr {
    match error {
        SimulateError::Geometry(e) => geometry_error(e),
        SimulateError::Basis(_) | SimulateError::OutputMap(_) => raise::<BasisError>(error),
        SimulateError::Run(RunError::Step { step, .. })
        | SimulateError::ObjectStep { step, .. } => step_error(Some(*step), error),
        SimulateError::Splats(e) => splat_error(e),
        SimulateError::Write(_) => raise::<PyOSError>(error),
        _ => raise::<SceneError>(error),
    }
}

/// Adds the exception classes to the module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("FreeFormError", py.get_type::<FreeFormError>())?;
    m.add("GeometryError", py.get_type::<GeometryError>())?;
    m.add("BasisError", py.get_type::<BasisError>())?;
    m.add("SceneError", py.get_type::<SceneError>())?;
    m.add("StepError", py.get_type::<StepError>())?;
    m.add("FileFormatError", py.get_type::<FileFormatError>())?;
    Ok(())
}
