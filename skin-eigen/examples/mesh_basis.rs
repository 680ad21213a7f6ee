//! Builds the skinning basis of a mesh (normalized to a unit largest side) or of the beam and
//! prints the per-phase timing report; optionally saves it.
//!
//! ```sh
//! cargo run --release -p skin-eigen --example mesh_basis -- --mesh data/meshes/32770.stl --kernels 1000 --modes 32
//! ```
//! Options: `--mesh PATH` (default: the 5×1×1 m beam), `--points N` (default 30000),
//! `--kernels K` (default 1000), `--modes m` (default 32), `--young E` (Pa, default 1e5),
//! `--solver auto|dense|iterative` (default auto: dense up to K = 3000), `--save PATH`.

use std::time::Instant;

use hyperelastic::LameParameters;
use nalgebra::Vector3;
use rkpm_core::{GridSamplingParams, KernelParams, TriangleMesh, read_triangle_mesh, sample_grid};
use skin_eigen::{BasisParams, EigenParams, EigenSolverChoice, SubspaceParams, build_basis};

/// Eigen solver choice on the command line.
#[derive(Clone, Copy, clap::ValueEnum)]
enum Solver {
    /// Dense up to K = 3000, iterative above.
    Auto,
    /// Dense generalized eigen solve.
    Dense,
    /// Sparse shift-invert subspace iteration.
    Iterative,
}

/// Command-line options.
#[derive(clap::Parser)]
struct Args {
    /// A closed mesh (default: the 5×1×1 m beam).
    #[arg(long = "mesh")]
    mesh_path: Option<String>,
    /// Integration points.
    #[arg(long = "points", default_value_t = 30_000)]
    target_points: usize,
    /// Kernels K.
    #[arg(long = "kernels", default_value_t = 1000)]
    count: usize,
    /// Modes m.
    #[arg(long, default_value_t = 32)]
    modes: usize,
    /// Young's modulus (Pa).
    #[arg(long, default_value_t = 1e5)]
    young: f64,
    /// Where to save the basis.
    #[arg(long)]
    save: Option<String>,
    /// Eigen solver.
    #[arg(long, value_enum, default_value_t = Solver::Auto)]
    solver: Solver,
}

fn run() -> Result<(), String> {
    let Args {
        mesh_path,
        target_points,
        count,
        modes,
        young,
        save,
        solver,
    } = clap::Parser::parse();
    let solver = match solver {
        Solver::Auto => EigenSolverChoice::Auto,
        Solver::Dense => EigenSolverChoice::Dense,
        Solver::Iterative => EigenSolverChoice::Iterative(SubspaceParams::default()),
    };

    let t = Instant::now();
    let (mesh, label) = match &mesh_path {
        Some(path) => (
            read_triangle_mesh(path)
                .map_err(|e| e.to_string())?
                .normalized()
                .0,
            path.clone(),
        ),
        None => (
            TriangleMesh::cuboid(Vector3::zeros(), Vector3::new(5.0, 1.0, 1.0)),
            "beam 5×1×1 m".into(),
        ),
    };
    let points =
        sample_grid(&mesh, &GridSamplingParams { target_points }).map_err(|e| e.to_string())?;
    let sampling = t.elapsed().as_secs_f64();
    let lame = LameParameters::from_young_poisson(young, 0.45).map_err(|e| e.to_string())?;
    let params = BasisParams {
        kernels: KernelParams {
            count,
            ..Default::default()
        },
        eigen: EigenParams {
            modes,
            ..Default::default()
        },
        solver,
        ..Default::default()
    };
    let (basis, report, _) =
        build_basis(&points, &vec![lame; points.len()], &params).map_err(|e| e.to_string())?;
    let t = report.timings;
    println!(
        "{label}: {} points, K = {}, m = {modes}, {:.1} kernels/point",
        report.integration_points, report.kernels, report.mean_kernels_per_point
    );
    println!(
        "cond(𝓜) = {:.2e} ({} directions discarded), eigen residual {:.1e}, |cᵀ𝓜c - I| = {:.1e}",
        report.mass_condition_number,
        report.discarded_mass_directions,
        report.eigen_relative_residual,
        report.orthonormality_error
    );
    println!(
        "timings (s): sampling {sampling:.3} | FPS {:.3} | shape functions {:.3} | assembly {:.3} | eigen solve {:.3} | basis total {:.3}",
        t.kernel_placement,
        t.shape_functions,
        t.assembly,
        t.eigen_solve,
        t.total()
    );
    if let Some(path) = save {
        basis.save(&path).map_err(|e| e.to_string())?;
        println!("saved {path}");
    }
    Ok(())
}

fn main() {
    if let Err(message) = run() {
        eprintln!("error: {message}");
        std::process::exit(1);
    }
}
