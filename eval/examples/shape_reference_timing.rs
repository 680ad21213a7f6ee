//! Where a shape's FEM reference spends its time: one boundary condition of Table 2 on the
//! reference mesh (graded by default, as `freeform-paper table 2 --fem-mesher graded`), stepped
//! without the cache, with Newton iterations, factorizations, line-search cuts and seconds
//! split into assembly (gradients and Hessians), solve (factorizations and triangular solves)
//! and line search (energies), per step and in total. Nothing is cached or scored.
//!
//! ```sh
//! cargo run --release -p eval --example shape_reference_timing -- \
//!     data/meshes/bunny.obj --boundary fix-side --steps 10 --tangent projected
//! ```
//! Options: `--boundary fix-side|pull-farthest|pull-boundary` (default fix-side), `--steps N`
//! (default 40, the tables'), `--tangent projected|exact-when-definite|exact-else-absolute` (default the mesher
//! choice's: exact-when-definite graded, projected uniform), `--ordering
//! amd|nested-dissection|smaller-factor` (the factorization's elimination order, default the
//! smaller factor of the two),
//! `--uniform` (the first tables' uniform lattices instead of the graded ones), `--shape-mesh`
//! (the shape's one mesh instead of the condition's own lattice, which is what the tables run
//! on graded lattices: Fix side's clamp face on a vertex plane, Pull farthest's balls' and Pull
//! boundary's slab faces' edges refined, `ShapeFemParams::condition_lattice`), `--max-iterations
//! N` (default the mesher choice's: 60 graded, 20 uniform), `--cells N` (the first lattice's
//! cells across, default 16 graded, 10 uniform), `--young E` (Pa; default the
//! catalogue's, 1e5 for an uncatalogued mesh); Newton as Table 2 runs the condition
//! (`ShapeFemParams::newton_for`: on graded lattices the Pulls, and Fix side on a stiff shape,
//! carry the factorization across steps; Fix side on a soft one factors afresh), or `--fresh`
//! (a fresh factorization every iteration) or `--reuse TOL` (the factorization carried across
//! iterations and steps while chord steps contract, at Newton tolerance TOL; 0 for
//! `fem_ref::reusing_reference_newton`'s 1e-8).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Parser;
use eval::shapes::boundary::{ShapeBoundary, ShapeBoundaryParams};
use eval::shapes::catalog::{SHAPE_DENSITY, SHAPE_POISSON_RATIO, catalog_entry};
use eval::shapes::reference::{
    ConditionLattice, ReferenceFactorReuse, ShapeFemParams, mesh_for_fem, mesh_through,
};
use fem_ref::FemSimulator;
use fem_ref::FillReducingOrdering;
use freeform::fem_reference::FemProblem;
use hyperelastic::{HessianTangent, MaterialSample, StableNeoHookean};
use optimize::NewtonParams;
use rkpm_core::read_triangle_mesh;

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum Condition {
    FixSide,
    PullFarthest,
    PullBoundary,
}

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum TangentArg {
    Projected,
    ExactWhenDefinite,
    ExactElseAbsolute,
}

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum OrderingArg {
    /// Approximate minimum degree.
    Amd,
    /// Nested dissection (METIS).
    NestedDissection,
    /// Whichever of the two leaves the smaller factor.
    SmallerFactor,
}

/// Command-line options.
#[derive(Parser)]
struct Args {
    /// A closed triangle mesh (STL, OBJ, PLY, OFF).
    mesh: PathBuf,
    /// Boundary condition.
    #[arg(long, value_enum, default_value_t = Condition::FixSide)]
    boundary: Condition,
    /// Steps of 0.01 s.
    #[arg(long, default_value_t = 40)]
    steps: usize,
    /// Element tangent of Newton's Hessian (default the mesher choice's: exact-when-definite
    /// graded, projected uniform).
    #[arg(long, value_enum)]
    tangent: Option<TangentArg>,
    /// Elimination order of the sparse Cholesky factorization.
    #[arg(long, value_enum, default_value_t = OrderingArg::SmallerFactor)]
    ordering: OrderingArg,
    /// Uniform lattices (the first tables' references) instead of graded ones.
    #[arg(long)]
    uniform: bool,
    /// Run on the shape's one mesh instead of the condition's own lattice (the same thing on
    /// uniform lattices).
    #[arg(long)]
    shape_mesh: bool,
    /// Newton iterations allowed per step.
    #[arg(long)]
    max_iterations: Option<usize>,
    /// Young's modulus (Pa).
    #[arg(long)]
    young: Option<f64>,
    /// Cells across the largest side of the first lattice tried (default the mesher
    /// choice's: 16 graded, 10 uniform); a coarser one makes a quick study of a large shape.
    #[arg(long)]
    cells: Option<usize>,
    /// Carry the factorization across iterations and steps while chord steps contract
    /// (`fem_ref::reusing_reference_newton`), at this Newton tolerance (its 1e-8 if 0).
    #[arg(long, conflicts_with = "fresh")]
    reuse: Option<f64>,
    /// A fresh factorization every Newton iteration, whatever Table 2 does for the condition.
    #[arg(long)]
    fresh: bool,
    /// Write every frame's node positions here (raw little-endian f64, frame after frame).
    #[arg(long)]
    save: Option<PathBuf>,
    /// Print the normalized MSE (mean |x − x'|² / L² over the nodes and frames, L = 1 m after
    /// normalization) and the largest node distance against frames written by `--save`.
    #[arg(long)]
    compare: Option<PathBuf>,
}

fn main() -> Result<()> {
    let args = Args::parse();
    let surface = read_triangle_mesh(&args.mesh)
        .with_context(|| format!("reading {}", args.mesh.display()))?
        .normalized()
        .0;
    let file_name = args
        .mesh
        .file_name()
        .map_or(String::new(), |n| n.to_string_lossy().into_owned());
    let youngs_modulus = args.young.unwrap_or_else(|| {
        catalog_entry(&file_name).map_or(1e5, |entry| entry.class.youngs_modulus())
    });
    let mut params = if args.uniform {
        ShapeFemParams::default()
    } else {
        ShapeFemParams::graded()
    };
    if let Some(cells) = args.cells {
        params.first_cells_across = cells;
    }
    if let Some(n) = args.max_iterations {
        params.newton.max_iterations = n;
    }
    let mesh_start = Instant::now();
    let (lattice_mesh, report) = mesh_for_fem(&surface, &params)?;
    let (tets, _) = lattice_mesh.largest_component();
    let volume_error = (tets.volume() - report.surface_volume) / report.surface_volume;
    println!(
        "{file_name}: {} tets, volume {:+.2}%, meshed in {:.1} s",
        tets.tets().len(),
        100.0 * volume_error,
        mesh_start.elapsed().as_secs_f64()
    );
    let boundary = match args.boundary {
        Condition::FixSide => ShapeBoundary::FixSide,
        Condition::PullFarthest => ShapeBoundary::PullFarthest,
        Condition::PullBoundary => ShapeBoundary::PullBoundary,
    };
    let boundary_params = ShapeBoundaryParams::default();
    let scene = boundary.scene(&surface, tets.vertices(), &boundary_params);
    // The condition's own lattice, as Table 2 meshes it (`eval::shapes::study`).
    let condition = if args.shape_mesh {
        ConditionLattice::default()
    } else {
        params.condition_lattice(boundary, &scene)
    };
    let tets = if condition.is_plain() {
        tets
    } else {
        let mesh_start = Instant::now();
        let length = surface.bounding_box().largest_side();
        let cells = (length / report.cell_size).round() as usize;
        let (own, summary, cells) = mesh_through(&surface, &params, cells, length, &condition)?;
        println!(
            "{} on its own lattice: {} tets at {cells} cells across, volume {:+.2}%, meshed in \
             {:.1} s",
            boundary.title(),
            summary.tets,
            100.0 * summary.relative_volume_error,
            mesh_start.elapsed().as_secs_f64()
        );
        own
    };
    let (newton, tangent) = newton_and_tangent(&args, &params, boundary, youngs_modulus);
    let (mut sim, _) = FemProblem {
        tets,
        order: params.order,
        material: MaterialSample {
            youngs_modulus,
            poisson_ratio: SHAPE_POISSON_RATIO,
            density: SHAPE_DENSITY,
        },
        scene: &scene,
        time_step: boundary_params.time_step,
        newton,
        tangent,
        ordering: match args.ordering {
            OrderingArg::Amd => FillReducingOrdering::ApproximateMinimumDegree,
            OrderingArg::NestedDissection => FillReducingOrdering::NestedDissection,
            OrderingArg::SmallerFactor => FillReducingOrdering::SmallerFactor,
        },
        failed_step_halvings: params.failed_step_halvings,
        steps: args.steps,
    }
    .simulator()?;
    println!(
        "{} {}, E = {youngs_modulus:e} Pa, {:?} tangent, Newton {:?}: {} free DOFs, {} matrix \
         nonzeros, {} factor nonzeros ({:?})",
        boundary.title(),
        if args.uniform { "uniform" } else { "graded" },
        tangent,
        newton,
        sim.free_dofs(),
        sim.matrix_nonzeros(),
        sim.factor_nonzeros(),
        args.ordering,
    );
    let frames = step_table(&mut sim, args.steps)?;
    save_and_compare(&args, &frames)?;
    Ok(())
}

/// Newton's options and the material tangent the flags ask for (default: Table 2's for the
/// condition).
fn newton_and_tangent(
    args: &Args,
    params: &ShapeFemParams,
    boundary: ShapeBoundary,
    youngs_modulus: f64,
) -> (NewtonParams, HessianTangent) {
    let newton = match args.reuse {
        None if args.fresh => params.newton,
        None => params.newton_for(boundary, youngs_modulus),
        Some(tolerance) => {
            // Table 2's reusing Newton for the condition, at the tolerance asked.
            let reusing = ShapeFemParams {
                factor_reuse: ReferenceFactorReuse::Every,
                ..*params
            }
            .newton_for(boundary, youngs_modulus);
            NewtonParams {
                tolerance: if tolerance > 0.0 {
                    tolerance
                } else {
                    reusing.tolerance
                },
                ..reusing
            }
        }
    };
    let tangent = match args.tangent {
        None => params.tangent,
        Some(TangentArg::Projected) => HessianTangent::ProjectedPsd,
        Some(TangentArg::ExactWhenDefinite) => HessianTangent::ExactWhenDefinite,
        Some(TangentArg::ExactElseAbsolute) => HessianTangent::ExactElseAbsolute,
    };
    (newton, tangent)
}

/// Steps `sim` `steps` times, printing a row per step and the means; returns every frame's node
/// positions, flattened.
fn step_table(sim: &mut FemSimulator<StableNeoHookean>, steps: usize) -> Result<Vec<f64>> {
    println!(
        "\n| step | iterations | factorizations | chord steps | cuts | assembly s | solve s | line search s | step s |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    let (mut iterations, mut factorizations, mut chords, mut cuts) = (0, 0, 0, 0);
    let mut frames: Vec<f64> = Vec::new();
    let (mut assembly, mut solve, mut line_search, mut total) = (0.0, 0.0, 0.0, 0.0);
    for step in 1..=steps {
        let start = Instant::now();
        let report = sim.step().with_context(|| format!("step {step}"))?;
        let seconds = start.elapsed().as_secs_f64();
        frames.extend(sim.positions().iter().flat_map(|p| [p.x, p.y, p.z]));
        let t = report.timings;
        println!(
            "| {step} | {} | {} | {} | {} | {:.3} | {:.3} | {:.3} | {seconds:.3} |{}",
            report.iterations,
            report.hessian_assemblies,
            report.lagged_steps,
            report.line_search_cuts,
            t.assembly,
            t.solve,
            t.line_search,
            if report.converged() {
                ""
            } else {
                " not converged"
            }
        );
        iterations += report.iterations;
        factorizations += report.hessian_assemblies;
        chords += report.lagged_steps;
        cuts += report.line_search_cuts;
        (assembly, solve, line_search, total) = (
            assembly + t.assembly,
            solve + t.solve,
            line_search + t.line_search,
            total + seconds,
        );
    }
    let n = steps.max(1) as f64;
    println!(
        "| per step | {:.2} | {:.2} | {:.2} | {:.2} | {:.3} | {:.3} | {:.3} | {:.3} |",
        iterations as f64 / n,
        factorizations as f64 / n,
        chords as f64 / n,
        cuts as f64 / n,
        assembly / n,
        solve / n,
        line_search / n,
        total / n
    );
    Ok(frames)
}

/// `--save` and `--compare` on the run's `frames`.
fn save_and_compare(args: &Args, frames: &[f64]) -> Result<()> {
    if let Some(path) = &args.save {
        let bytes: Vec<u8> = frames.iter().flat_map(|v| v.to_le_bytes()).collect();
        std::fs::write(path, bytes).with_context(|| format!("writing {}", path.display()))?;
    }
    if let Some(path) = &args.compare {
        let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
        let other: Vec<f64> = bytes
            .chunks_exact(8)
            .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
            .collect();
        anyhow::ensure!(
            other.len() == frames.len(),
            "{} holds {} values, this run {}",
            path.display(),
            other.len(),
            frames.len()
        );
        let squared: Vec<f64> = frames
            .chunks_exact(3)
            .zip(other.chunks_exact(3))
            .map(|(a, b)| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum())
            .collect();
        let mse = squared.iter().sum::<f64>() / squared.len().max(1) as f64;
        let largest = squared.iter().copied().fold(0.0, f64::max).sqrt();
        println!(
            "against {}: MSE {mse:.3e}, largest {largest:.3e}",
            path.display()
        );
    }
    Ok(())
}
