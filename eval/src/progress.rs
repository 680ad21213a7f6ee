//! Progress bars on stderr for long work, silent with `--quiet` (or when stderr is not a
//! terminal, indicatif hides them itself).

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// Makes progress bars, or none when quiet.
#[derive(Clone, Copy, Debug, Default)]
pub struct Progress {
    /// No bars and no status lines.
    pub quiet: bool,
    /// No bars, status lines still shown (work running in parallel, whose bars would draw over
    /// each other).
    pub hide_bars: bool,
}

impl Progress {
    /// A bar of `len` steps labelled `label`.
    pub fn bar(&self, len: usize, label: impl Into<String>) -> ProgressBar {
        let bar = ProgressBar::new(len as u64);
        if self.quiet || self.hide_bars {
            bar.set_draw_target(ProgressDrawTarget::hidden());
        }
        bar.set_style(
            ProgressStyle::with_template(
                "{msg:>32} [{bar:30}] {pos}/{len} {elapsed_precise} (eta {eta})",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
        );
        bar.set_message(label.into());
        bar
    }

    /// The same, without bars.
    pub fn without_bars(self) -> Progress {
        Progress {
            hide_bars: true,
            ..self
        }
    }

    /// A status line on stderr (not on stdout, which holds results).
    pub fn status(&self, line: impl AsRef<str>) {
        if !self.quiet {
            eprintln!("{}", line.as_ref());
        }
    }
}

/// [`Progress`] behind the library's [`freeform::Progress`] trait: one bar per stage.
#[derive(Debug, Default)]
pub struct BarProgress {
    settings: Progress,
    bar: std::sync::Mutex<Option<ProgressBar>>,
}

impl BarProgress {
    /// Bars and status lines as `settings` says.
    pub fn new(settings: Progress) -> Self {
        BarProgress {
            settings,
            bar: std::sync::Mutex::new(None),
        }
    }

    fn with_bar(&self, f: impl FnOnce(&mut Option<ProgressBar>)) {
        let mut bar = self
            .bar
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        f(&mut bar);
    }
}

impl freeform::Progress for BarProgress {
    fn begin(&self, len: usize, label: &str) {
        self.with_bar(|bar| *bar = Some(self.settings.bar(len, label)));
    }

    fn advance(&self) {
        self.with_bar(|bar| {
            if let Some(bar) = bar {
                bar.inc(1);
            }
        });
    }

    fn finish(&self) {
        self.with_bar(|bar| {
            if let Some(bar) = bar.take() {
                bar.finish_and_clear();
            }
        });
    }

    fn status(&self, line: &str) {
        self.settings.status(line);
    }
}
