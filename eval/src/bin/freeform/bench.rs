//! `freeform bench`: the error-vs-time sweep.

use crate::plot_or_warn;
use std::path::{Path, PathBuf};

use anyhow::Result;
use eval::bench::{BenchConfig, BenchMethod, bench_plot, run_bench, write_bench};
use eval::progress::Progress;

/// Options of `freeform bench`.
#[derive(clap::Args)]
pub(crate) struct BenchOptions {
    /// One-minute sweep.
    #[arg(long)]
    quick: bool,
    /// Leave out the Simplicits baseline (its networks train for about 10 min per m on 2 cores
    /// the first time, then are cached).
    #[arg(long)]
    skip_simplicits: bool,
    /// Leave out the MPM baseline (Δx = 0.2 and 0.1 m: about 10 min on 2 cores the first time,
    /// then cached, shared with Table 1).
    #[arg(long)]
    skip_mpm: bool,
    /// Leave out the SPH baseline (spacing 0.2 and 0.1 m: about 20 s on 2 cores the first
    /// time, then cached, shared with Table 1).
    #[arg(long)]
    skip_sph: bool,
}

/// Runs the sweep and writes its CSV, Markdown and plot under `out`.
pub(crate) fn run(
    BenchOptions {
        quick,
        skip_simplicits,
        skip_mpm,
        skip_sph,
    }: BenchOptions,
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
    if skip_sph {
        config
            .runs
            .retain(|(_, method)| !matches!(method, BenchMethod::Sph(..)));
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
