#![doc = include_str!("../README.md")]

use std::path::PathBuf;

use anyhow::Result;
use clap::{Parser, Subcommand};
use freeform::terminal_progress::TerminalProgress;

mod basis;
mod demo;
mod line_plot;
mod mesh;
mod output_frames;
mod preview;
mod render;
mod simulate;
mod viewer_page;

#[derive(Parser)]
#[command(
    name = "freeform",
    version,
    about = "Mesh-free reduced-order elastodynamics from RKPM skinning eigenmodes"
)]
struct Cli {
    /// No progress bars or status lines (results still go to stdout).
    #[arg(long, global = true)]
    quiet: bool,
    /// Output folder for results and frames.
    #[arg(long, global = true, default_value = "freeform-out")]
    out: PathBuf,
    /// Cache folder (FEM trajectories, cubatures); default `$FREEFORM_CACHE` or
    /// `freeform-cache`.
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
        /// Integration points the basis is built on (grid points inside a mesh; at most this
        /// many cloud points); `--points` is read as this.
        #[arg(long, visible_alias = "points", default_value_t = 30_000)]
        basis_points: usize,
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
    /// Run a scene file (TOML or JSON; `docs/scene-files.md`) and write per-frame PLY and VTK.
    Simulate {
        /// The scene file.
        scene: PathBuf,
        /// Write the stress into the VTK frames and `points_NNNNN.vtk` (Cauchy tensor,
        /// principal and von Mises stress, Pa), whatever the scene file's `simulation.stress`.
        #[arg(long)]
        stress: bool,
        /// The largest `view.html` to write (MB); frames are dropped evenly past it.
        #[arg(long, default_value_t = 100.0)]
        view_max_mb: f64,
    },
    /// Write `OUT_DIR/view.html`: one file that plays a `simulate` run's frames in a browser,
    /// offline (surfaces, points or splats, the floor and colliders, a colour bar).
    View {
        /// The run's output folder (`<out>/<scene stem>`).
        dir: PathBuf,
        /// The largest file to write (MB); frames are dropped evenly past it.
        #[arg(long, default_value_t = 100.0)]
        max_mb: f64,
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
        Command::Demo { quick, json } => demo::run(quick, json, &cli.out, &cache, &progress),
        Command::Basis {
            geometry,
            modes,
            kernels,
            basis_points,
            young,
            poisson,
            save,
        } => basis::run(
            &geometry,
            basis::BasisOptions {
                modes,
                kernels,
                basis_points,
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
        Command::Simulate {
            scene,
            stress,
            view_max_mb,
        } => simulate::run(
            &scene,
            &simulate::SimulateOptions {
                stress,
                viewer: viewer_params(view_max_mb)?,
            },
            &cli.out,
            &cache,
            progress,
        ),
        Command::View { dir, max_mb } => {
            let report = viewer_page::view(&dir, &viewer_params(max_mb)?)?;
            simulate::print_viewer(&report);
            Ok(())
        }
        Command::Render { files, options } => render::run(&files, &options, &cli.out),
    }
}

/// The viewer's parameters for a limit of `max_mb` MB.
fn viewer_params(max_mb: f64) -> Result<viewer_page::ViewerParams> {
    if !(max_mb.is_finite() && max_mb > 0.0) {
        anyhow::bail!("the page's size limit must be a positive number of MB, not {max_mb}");
    }
    Ok(viewer_page::ViewerParams {
        max_bytes: (max_mb * 1e6) as usize,
    })
}
