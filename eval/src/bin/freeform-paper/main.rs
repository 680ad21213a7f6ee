//! `freeform-paper`: the paper's experiments (design §4, `docs/reproduce.md`). The user's
//! commands (demo, simulate, basis, mesh, render) are the `freeform` binary of `freeform-cli`.
//!
//! ```sh
//! cargo run --release --bin freeform-paper -- table 1 5 6 --quick   # beam tables, minutes
//! cargo run --release --bin freeform-paper -- table 2 7 --meshes data/meshes --only spot
//! cargo run --release --bin freeform-paper -- bench                 # error vs time on the beam
//! ```
//! Results go under `--out` (default `freeform-out/`), caches under `--cache` (default
//! `freeform-cache/` or `$FREEFORM_CACHE`; safe to delete).

use std::path::{Path, PathBuf};

use anyhow::Result;
use clap::{Parser, Subcommand};
use eval::report::plot::{PlotSpec, write_plot};
use freeform::terminal_progress::TerminalProgress;
use preset_args::PresetArgs;

mod bench;
mod convergence;
mod merge;
mod pins;
mod preset_args;
mod presets;
mod shape_tasks;
mod stress;
mod table;

#[derive(Parser)]
#[command(
    name = "freeform-paper",
    version,
    about = "The FreeForm paper's experiments: tables, the error-vs-time bench, the pin sweep, the stress suite"
)]
struct Cli {
    /// No progress bars or status lines (results still go to stdout).
    #[arg(long, global = true)]
    quiet: bool,
    /// Output folder for tables, plots and frames.
    #[arg(long, global = true, default_value = "freeform-out")]
    out: PathBuf,
    /// Cache folder (FEM trajectories); default `$FREEFORM_CACHE` or `freeform-cache`.
    #[arg(long, global = true)]
    cache: Option<PathBuf>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Reproduce paper tables: 1 (MSE vs FEM), 3 (training ablations), 4 (grid vs random
    /// simulation points), 5 (ms per step), 6 (basis fitting residual) on the beam; 2 (MSE and
    /// max error) and 7 (basis fitting residual) on the meshes in --meshes. Tables 1, 5, 6 share
    /// one run, as do 3 and 4, and 2 and 7 (`table 2 7 --meshes DIR`).
    Table {
        /// Table numbers.
        #[arg(required = true, num_args = 1..)]
        numbers: Vec<u32>,
        #[command(flatten)]
        options: Box<table::TableOptions>,
    },
    /// Numerical stress suite: extreme ν, stiffness contrast, large dt, fast twists, a 10 m/s
    /// impact, extreme m and K, degenerate sampling (preset `stress`). Exits non-zero if any
    /// case produces a non-finite value or panics.
    Stress {
        #[command(flatten)]
        preset: PresetArgs,
        /// Print JSON instead of Markdown.
        #[arg(long)]
        json: bool,
    },
    /// Pin sweep: the beam tests at several Poisson ratios and m, every pin factor under both
    /// pin moduli (λ + 2μ, E) and the exact pins, against the FEM at the same material
    /// (preset `pins`; `--set factors=[]` runs the exact pins alone); writes pins.md and
    /// pins.json.
    Pins {
        #[command(flatten)]
        preset: PresetArgs,
        /// Print JSON instead of Markdown.
        #[arg(long)]
        json: bool,
    },
    /// Convergence study: the beam's error against m for each boundary treatment and ν, with
    /// the subspace's best approximations (preset `convergence`, `--quick` for minutes); writes
    /// convergence.md, convergence.json and plots.
    Convergence {
        #[command(flatten)]
        preset: PresetArgs,
        /// Print one JSON row per run instead of Markdown.
        #[arg(long)]
        json: bool,
    },
    /// Error-vs-time sweep on the beam Bend (preset `bench`); writes CSV and a log-log plot
    /// with the Pareto front.
    Bench {
        #[command(flatten)]
        preset: PresetArgs,
    },
    /// Tables 2 and 7 from shards (`table 2 7 … --shard-out FILE`, any number, any order),
    /// row by row: refuses shards of different settings or one row with two different results,
    /// and heads the tables **Partial** with the missing shapes and rows named. The shard
    /// holding the most rows heads the merge (its settings head the tables).
    Merge {
        /// Shard files.
        #[arg(required = true, num_args = 1..)]
        shards: Vec<PathBuf>,
        /// Print JSON instead of Markdown.
        #[arg(long)]
        json: bool,
    },
    /// Shards from Tables 2 rendered before shards existed (`table2.json`, the whole-table
    /// run first): a row a later table scored replaces an earlier table's copy; one shard per
    /// table with rows left, named after the table's folder, written to --shard-dir.
    ImportTables {
        /// Rendered `table2.json` files.
        #[arg(required = true, num_args = 1..)]
        tables: Vec<PathBuf>,
        /// Where the shards go.
        #[arg(long, value_name = "DIR")]
        shard_dir: PathBuf,
    },
    /// List the committed presets, or print one (with any `--set` applied) as TOML: a starting
    /// point for a `--config` file of your own.
    Presets {
        /// The preset to print.
        name: Option<String>,
        /// Changes to apply before printing, as in the experiment commands.
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
    },
}

fn main() {
    let cli = Cli::parse();
    if let Err(e) = run(cli) {
        eprintln!("error: {}", freeform::failure_chain(e.as_ref()));
        std::process::exit(1);
    }
}

fn run(cli: Cli) -> Result<()> {
    let progress = TerminalProgress {
        quiet: cli.quiet,
        ..Default::default()
    };
    let cache = cli
        .cache
        .clone()
        .unwrap_or_else(freeform::default_cache_dir);
    match cli.command {
        Command::Table { numbers, options } => {
            table::run(&numbers, *options, &cli.out, &cache, &progress)
        }
        Command::Stress { preset, json } => stress::run(&preset, json, &cli.out, &progress),
        Command::Pins { preset, json } => pins::run(&preset, json, &cache, &cli.out, &progress),
        Command::Convergence { preset, json } => {
            convergence::run(&preset, json, &cache, &cli.out, &progress)
        }
        Command::Bench { preset } => bench::run(&preset, &cache, &cli.out, &progress),
        Command::Merge { shards, json } => merge::run(&shards, json, &cli.out),
        Command::ImportTables { tables, shard_dir } => merge::import_tables(&tables, &shard_dir),
        Command::Presets { name, set } => presets::run(name.as_deref(), &set),
    }
}

/// Draws a figure; a failure (e.g. no TrueType font for the text) is a warning, since the
/// numbers it shows are already written.
fn plot_or_warn(spec: &PlotSpec, base: &Path) -> Vec<PathBuf> {
    write_plot(spec, base).unwrap_or_else(|e| {
        eprintln!("warning: {e} (the data are in the CSV/JSON files)");
        Vec::new()
    })
}
