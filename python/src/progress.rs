//! Progress reported to a Python callable.

use freeform::Progress;
use pyo3::prelude::*;

/// Progress handed to a Python callable `progress(label, done, total)`: a stage's label with
/// the units done and its length, or a status line with `done` and `total` None. An exception
/// the callable raises is printed and the work goes on.
pub(crate) struct PythonProgress {
    callable: Py<PyAny>,
    /// The current stage's label, units done and length.
    stage: std::sync::Mutex<(String, usize, usize)>,
}

impl PythonProgress {
    /// Progress handed to `callable`.
    pub(crate) fn new(callable: Py<PyAny>) -> Self {
        PythonProgress {
            callable,
            stage: Default::default(),
        }
    }

    /// Calls `progress(label, done, total)`.
    pub(crate) fn call(&self, label: &str, done: Option<usize>, total: Option<usize>) {
        Python::attach(|py| {
            if let Err(e) = self.callable.call1(py, (label, done, total)) {
                e.print(py);
            }
        });
    }
}

impl Progress for PythonProgress {
    fn begin(&self, len: usize, label: &str) {
        if let Ok(mut stage) = self.stage.lock() {
            *stage = (label.to_string(), 0, len);
        }
        self.call(label, Some(0), Some(len));
    }

    fn advance(&self) {
        let Ok(mut stage) = self.stage.lock() else {
            return;
        };
        stage.1 += 1;
        let (label, done, len) = stage.clone();
        drop(stage);
        self.call(&label, Some(done), Some(len));
    }

    fn status(&self, line: &str) {
        self.call(line, None, None);
    }
}
