//! `freeform-paper bench`: the error-vs-time sweep.

use crate::plot_or_warn;
use crate::preset_args::PresetArgs;
use std::path::Path;

use anyhow::Result;
use eval::bench::{BenchConfig, bench_plot, run_bench, write_bench};
use eval::presets::{StudyKind, set_folder};
use freeform::terminal_progress::TerminalProgress;

/// Runs the sweep of `preset` (default `bench`, `--quick` `bench-quick`) and writes its CSV,
/// Markdown and plot under `out`.
pub(crate) fn run(
    preset: &PresetArgs,
    cache: &Path,
    out: &Path,
    progress: &TerminalProgress,
) -> Result<()> {
    let config: BenchConfig = preset.load("bench")?.config(StudyKind::Bench, |table| {
        set_folder(table, "cache_dir", cache)
    })?;
    let results = run_bench(&config, progress)?;
    let (md, files) = write_bench(&results, &config, out)?;
    println!("{md}");
    for f in files {
        println!("wrote {}", f.display());
    }
    plot_or_warn(&bench_plot(&results, &config), &out.join("bench"));
    Ok(())
}
