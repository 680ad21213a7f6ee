//! Progress bars on stderr for long work (feature `terminal`), silent with `--quiet`. Where a bar is not drawn
//! (stderr not a terminal, or work running in parallel), long work prints a line a minute
//! instead, so a log shows how far an hour-long reference has come.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, PoisonError};
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// How often a bar that is not drawn prints its progress as a line (none for work that ends
/// sooner).
pub const HIDDEN_BAR_LINE_INTERVAL: Duration = Duration::from_secs(60);

/// Makes progress bars on stderr, or none when quiet.
#[derive(Clone, Copy, Debug, Default)]
pub struct TerminalProgress {
    /// No bars and no status lines.
    pub quiet: bool,
    /// No bars, status lines still shown (work running in parallel, whose bars would draw over
    /// each other).
    pub hide_bars: bool,
}

impl TerminalProgress {
    /// A bar of `len` steps labelled `label`; not drawn, it prints a line every
    /// [`HIDDEN_BAR_LINE_INTERVAL`] (none with `quiet`).
    pub fn bar(&self, len: usize, label: impl Into<String>) -> StepBar {
        self.bar_with_lines_every(len, label, HIDDEN_BAR_LINE_INTERVAL)
    }

    fn bar_with_lines_every(
        &self,
        len: usize,
        label: impl Into<String>,
        interval: Duration,
    ) -> StepBar {
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
        let now = Instant::now();
        StepBar {
            bar,
            quiet: self.quiet,
            interval,
            started: now,
            last_line: Mutex::new(now),
            resumed: AtomicU64::new(0),
        }
    }

    /// The same, without bars.
    pub fn without_bars(self) -> TerminalProgress {
        TerminalProgress {
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

/// A progress bar of counted steps ([`TerminalProgress::bar`]); where it is not drawn, its progress
/// as a line on stderr at most every `interval`.
#[derive(Debug)]
pub struct StepBar {
    bar: ProgressBar,
    quiet: bool,
    interval: Duration,
    started: Instant,
    last_line: Mutex<Instant>,
    /// Steps done before this bar's work began ([`Self::resume_at`]).
    resumed: AtomicU64,
}

impl StepBar {
    /// `steps` more steps done.
    pub fn inc(&self, steps: u64) {
        self.bar.inc(steps);
        if let Some(line) = self.due_line() {
            eprintln!("{line}");
        }
    }

    /// Starts the bar at `done` steps that an earlier run did (a resumed FEM reference): they
    /// count as done but not in the time estimate of its lines.
    pub fn resume_at(&self, done: u64) {
        self.bar.set_position(done);
        self.bar.reset_eta();
        self.resumed.store(done, Ordering::Relaxed);
    }

    /// Relabels the bar (and its lines).
    pub fn set_message(&self, message: impl Into<String>) {
        self.bar.set_message(message.into());
    }

    /// Removes the bar.
    pub fn finish_and_clear(&self) {
        self.bar.finish_and_clear();
    }

    /// "label: 12/40 steps, 610 s, about 1420 s left" when the bar is not drawn, output is
    /// wanted and `interval` has passed since the last line (or the start).
    fn due_line(&self) -> Option<String> {
        if self.quiet || !self.bar.is_hidden() {
            return None;
        }
        let mut last = self
            .last_line
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        if last.elapsed() < self.interval {
            return None;
        }
        *last = Instant::now();
        let done = self.bar.position();
        let len = self.bar.length().unwrap_or(0);
        let elapsed = self.started.elapsed().as_secs_f64();
        let resumed = self.resumed.load(Ordering::Relaxed);
        let left = if done > resumed {
            format!(
                ", about {:.0} s left",
                elapsed / (done - resumed) as f64 * len.saturating_sub(done) as f64
            )
        } else {
            String::new()
        };
        Some(format!(
            "{}: {done}/{len} steps, {elapsed:.0} s{left}",
            self.bar.message()
        ))
    }
}

/// [`TerminalProgress`] behind the library's [`crate::Progress`] trait: one bar per stage.
#[derive(Debug, Default)]
pub struct BarProgress {
    settings: TerminalProgress,
    bar: Mutex<Option<StepBar>>,
}

impl BarProgress {
    /// Bars and status lines as `settings` says.
    pub fn new(settings: TerminalProgress) -> Self {
        BarProgress {
            settings,
            bar: Mutex::new(None),
        }
    }

    fn with_bar(&self, f: impl FnOnce(&mut Option<StepBar>)) {
        let mut bar = self.bar.lock().unwrap_or_else(PoisonError::into_inner);
        f(&mut bar);
    }
}

impl crate::Progress for BarProgress {
    fn begin(&self, len: usize, label: &str) {
        self.with_bar(|bar| *bar = Some(self.settings.bar(len, label)));
    }

    fn resume_at(&self, done: usize) {
        self.with_bar(|bar| {
            if let Some(bar) = bar {
                bar.resume_at(done as u64);
            }
        });
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_bar_that_is_not_drawn_prints_its_progress_once_its_interval_has_passed() {
        let hidden = TerminalProgress {
            quiet: false,
            hide_bars: true,
        };
        let bar = hidden.bar_with_lines_every(4, "FEM shape Fix side", Duration::ZERO);
        bar.inc(1);
        let line = bar.due_line().expect("a line is due");
        assert!(
            line.starts_with("FEM shape Fix side: 1/4 steps, "),
            "{line}"
        );
        assert!(line.contains("s left"), "{line}");
        bar.set_message("relabelled");
        assert!(bar.due_line().unwrap().starts_with("relabelled: 1/4"));
        let hour = Duration::from_secs(3600);
        assert_eq!(hidden.bar_with_lines_every(4, "x", hour).due_line(), None);
        let quiet = TerminalProgress {
            quiet: true,
            hide_bars: true,
        };
        assert_eq!(
            quiet
                .bar_with_lines_every(4, "x", Duration::ZERO)
                .due_line(),
            None
        );
    }

    #[test]
    fn a_resumed_bar_counts_earlier_steps_as_done_but_estimates_from_its_own() {
        let hidden = TerminalProgress {
            quiet: false,
            hide_bars: true,
        };
        let bar = hidden.bar_with_lines_every(40, "FEM skull", Duration::ZERO);
        bar.resume_at(30);
        let line = bar.due_line().expect("a line is due");
        assert!(line.starts_with("FEM skull: 30/40 steps, "), "{line}");
        assert!(!line.contains("left"), "no step of its own yet: {line}");
        bar.inc(1);
        let line = bar.due_line().expect("a line is due");
        assert!(line.starts_with("FEM skull: 31/40 steps, "), "{line}");
        assert!(line.contains("s left"), "{line}");
    }
}
