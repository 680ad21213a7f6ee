//! `freeform`: the FreeForm command line (DESIGN 4, 5).
//!
//! ```sh
//! cargo run --release -- demo               # beam Bend vs the FEM ground truth, in minutes
//! cargo run --release -- table 1 --quick    # a paper table (1, 3, 4, 5, 6), reduced configuration
//! cargo run --release -- bench              # error-vs-time sweep and its plot
//! cargo run --release -- basis bunny.obj --modes 16
//! cargo run --release -- simulate scene.toml
//! cargo run --release -- mesh bunny.obj --volume-target 0.01
//! ```
//! Results go under `--out` (default `freeform-out/`), caches under `--cache` (default
//! `freeform-cache/` or `$FREEFORM_CACHE`; safe to delete).

use std::path::{Path, PathBuf};

use anyhow::Result;
use clap::{Parser, Subcommand};
use eval::progress::Progress;
use eval::report::plot::{PlotSpec, write_plot};

mod basis;
mod bench;
mod demo;
mod mesh;
mod pins;
mod render;
mod simulate;
mod stress;
mod table;

#[derive(Parser)]
#[command(
    name = "freeform",
    version,
    about = "Mesh-free reduced-order elastodynamics from RKPM skinning eigenmodes: experiments and tools"
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
    /// Beam Bend: build a basis, simulate, compare with the (cached) FEM ground truth.
    Demo {
        /// Tiny configuration (seconds): m = 6, K = 200, 20 steps, FEM P2 res 2.
        #[arg(long)]
        quick: bool,
        /// Print the result as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Build and save a basis from a closed mesh (OBJ/STL/PLY) or a point cloud / 3DGS PLY.
    Basis {
        /// Geometry file.
        geometry: PathBuf,
        /// Modes m.
        #[arg(long, default_value_t = 16)]
        modes: usize,
        /// Kernels K.
        #[arg(long, default_value_t = 1000)]
        kernels: usize,
        /// Integration points (grid points inside a mesh; at most this many cloud points).
        #[arg(long, default_value_t = 30_000)]
        points: usize,
        /// Young's modulus (Pa).
        #[arg(long, default_value_t = 1e5)]
        young: f64,
        /// Poisson ratio.
        #[arg(long, default_value_t = 0.45)]
        poisson: f64,
        /// Where to save (default `<out>/<file stem>.basis`).
        #[arg(long)]
        save: Option<PathBuf>,
    },
    /// Tetrahedralize a closed surface (OBJ/STL/PLY) and write the tet mesh as VTK.
    Mesh {
        /// The surface.
        surface: PathBuf,
        /// Lattice cells across the largest bounding-box side (the first try with
        /// --volume-target).
        #[arg(long, default_value_t = 32)]
        cells: usize,
        /// Refine the lattice (×1.5, up to 128 cells) until the volume is within this fraction
        /// of the surface's, e.g. 0.01.
        #[arg(long)]
        volume_target: Option<f64>,
        /// Grade the lattice: refine it near the surface by up to this many halvings where the
        /// signed distance departs from linear (thin parts, curvature; tolerance 0.05).
        #[arg(long)]
        graded: Option<usize>,
        /// Keep the file's units (default: scale so the largest side is 1).
        #[arg(long)]
        keep_units: bool,
    },
    /// Draw 3DGS files (e.g. frame 0 and the last frame of a splat scene) to PNG with a CPU
    /// splatting preview, one camera framing the first file: `<out>/render/<stem>.png`.
    Render {
        /// 3DGS PLY files.
        #[arg(required = true, num_args = 1..)]
        files: Vec<PathBuf>,
        #[command(flatten)]
        options: render::RenderOptions,
    },
    /// Run a scene file (TOML or JSON; see `freeform::scene_file`) and write per-frame PLY and VTK.
    Simulate {
        /// The scene file.
        scene: PathBuf,
        /// Write the stress into the VTK frames and `points_NNNNN.vtk` (Cauchy tensor,
        /// principal and von Mises stress, Pa), whatever the scene file's `simulation.stress`.
        #[arg(long)]
        stress: bool,
    },
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
    /// impact, extreme m and K, degenerate sampling. Exits non-zero if any case produces a
    /// non-finite value or panics.
    Stress {
        /// A subset that runs in under a minute.
        #[arg(long)]
        quick: bool,
        /// Print JSON instead of Markdown.
        #[arg(long)]
        json: bool,
    },
    /// Pin sweep (issue 25): the beam tests at several Poisson ratios and m, every pin factor
    /// under both pin moduli (λ + 2μ, E) and the exact pins, against the FEM at the same
    /// material; prints MSE and pin drift per run and writes pins.md / pins.json.
    Pins {
        /// ν ∈ {0.3, 0.49}, m = 16, 100 Bend steps, FEM P2 res 4 (minutes).
        #[arg(long)]
        quick: bool,
        /// Print JSON instead of Markdown.
        #[arg(long)]
        json: bool,
        /// Run only the exact pins (no penalty factors).
        #[arg(long)]
        exact_only: bool,
    },
    /// Error-vs-time sweep on the beam Bend; writes CSV and a log-log plot with the Pareto front.
    Bench {
        #[command(flatten)]
        options: bench::BenchOptions,
    },
}

fn main() {
    let cli = Cli::parse();
    if let Err(e) = run(cli) {
        eprintln!("error: {}", eval::failure_chain(e.as_ref()));
        std::process::exit(1);
    }
}

fn run(cli: Cli) -> Result<()> {
    let progress = Progress {
        quiet: cli.quiet,
        ..Default::default()
    };
    let cache = cli.cache.clone().unwrap_or_else(eval::default_cache_dir);
    match cli.command {
        Command::Demo { quick, json } => demo::run(quick, json, &cli.out, &cache, &progress),
        Command::Basis {
            geometry,
            modes,
            kernels,
            points,
            young,
            poisson,
            save,
        } => basis::run(
            &geometry,
            basis::BasisOptions {
                modes,
                kernels,
                points,
                young,
                poisson,
            },
            save.unwrap_or_else(|| {
                let stem = geometry.file_stem().unwrap_or_default().to_string_lossy();
                cli.out.join(format!("{stem}.basis"))
            }),
            &progress,
        ),
        Command::Mesh {
            surface,
            cells,
            volume_target,
            graded,
            keep_units,
        } => mesh::run(
            &surface,
            &mesh::MeshOptions {
                cells,
                volume_target,
                graded,
                keep_units,
            },
            &cli.out,
        ),
        Command::Simulate { scene, stress } => {
            simulate::run(&scene, stress, &cli.out, &cache, progress)
        }
        Command::Render { files, options } => render::run(&files, &options, &cli.out),
        Command::Table { numbers, options } => {
            table::run(&numbers, *options, &cli.out, &cache, &progress)
        }
        Command::Stress { quick, json } => stress::run(quick, json, &cli.out, &progress),
        Command::Pins {
            quick,
            json,
            exact_only,
        } => pins::run(quick, json, exact_only, cache, &cli.out, &progress),
        Command::Bench { options } => bench::run(options, cache, &cli.out, &progress),
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
