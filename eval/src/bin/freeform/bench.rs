//! `freeform bench`: the error-vs-time sweep.

use crate::plot_or_warn;
use std::path::{Path, PathBuf};

use anyhow::Result;
use eval::bench::{BenchConfig, BenchMethod, bench_plot, run_bench, write_bench};
use eval::progress::Progress;

/// Runs the sweep and writes its CSV, Markdown and plot under `out`.
pub(crate) fn run(
    quick: bool,
    skip_simplicits: bool,
    skip_mpm: bool,
    cache: PathBuf,
    out: &Path,
    progress: &Progress,
) -> Result<()> {
    let mut config = if quick {
        BenchConfig::quick(cache)
    } else {
        BenchConfig::full(cache)
    };
    if skip_simplicits {
        config
            .runs
            .retain(|(_, method)| !matches!(method, BenchMethod::Simplicits(..)));
    }
    if skip_mpm {
        config
            .runs
            .retain(|(_, method)| !matches!(method, BenchMethod::Mpm(..)));
    }
    let results = run_bench(&config, progress)?;
    let (md, files) = write_bench(&results, &config, out)?;
    println!("{md}");
    for f in files {
        println!("wrote {}", f.display());
    }
    plot_or_warn(&bench_plot(&results, &config), &out.join("bench"));
    Ok(())
}
