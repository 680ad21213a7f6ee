//! How long work reports its progress to whoever runs it, without the library knowing about
//! terminals: a trait the caller implements (a progress bar, a log line, a GUI), and
//! [`Silent`].

/// Receives progress from long work. Every method has an empty default.
pub trait Progress: Sync {
    /// A stage of `len` units named `label` begins.
    fn begin(&self, _len: usize, _label: &str) {}
    /// One more unit of the current stage is done.
    fn advance(&self) {}
    /// The current stage resumes with `done` units already done by an earlier run (a FEM
    /// reference resumed from its checkpoint): they count as done but not in time estimates.
    fn resume_at(&self, _done: usize) {}
    /// The current stage is over.
    fn finish(&self) {}
    /// A one-line status message (e.g. "basis: m = 16, K = 1000").
    fn status(&self, _line: &str) {}
}

/// Reports nothing.
#[derive(Clone, Copy, Debug, Default)]
pub struct Silent;

impl Progress for Silent {}
