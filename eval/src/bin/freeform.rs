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

use optimize::NewtonParams;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use eval::ablation_study::{AblationStudyConfig, run_ablation_study};
use eval::ablation_tables::{table3, table4};
use eval::beam::{BEAM_MAX, BeamTest};
use eval::beam_study::{BeamStudyConfig, beam_length_scale, run_beam_study};
use eval::bench::{BenchConfig, bench_plot, run_bench, write_bench};
use eval::fem_reference::{FemResolution, run_fem_beam};
use eval::metrics::trajectory_errors;
use eval::output::{unstructured_grid_vtk, write_atomically};
use eval::plot::{AxisScale, PlotSpec, Series, write_plot};
use eval::progress::Progress;
use eval::reduced_beam::{ReducedSettings, build_beam_basis, run_reduced_beam};
use eval::scene_file::{SceneFile, run_scene_file};
use eval::shape_study::{ShapeStudyConfig, mesh_files, run_shape_study};
use eval::shape_tables::{table2, table7};
use eval::stress::{StressConfig, run_stress, stress_markdown};
use eval::tables::{table1, table5, table6, twist_error_plot, write_table};
use fem_ref::{
    ElementOrder, LatticeMesherParams, VolumeTarget, tetrahedralize, tetrahedralize_to_volume,
};
use hyperelastic::LameParameters;
use nalgebra::Vector3;
use rkpm_core::{
    GeometryReadError, GridSamplingParams, PointCloudSamplingParams, read_point_cloud,
    read_triangle_mesh, sample_grid, sample_point_cloud,
};
use skin_eigen::{BasisParams, build_basis};

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
        /// Keep the file's units (default: scale so the largest side is 1).
        #[arg(long)]
        keep_units: bool,
    },
    /// Run a scene file (TOML or JSON; see `eval::scene_file`) and write per-frame PLY and VTK.
    Simulate {
        /// The scene file.
        scene: PathBuf,
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
        options: TableOptions,
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
    /// Error-vs-time sweep on the beam Bend; writes CSV and a log-log plot with the Pareto front.
    Bench {
        /// One-minute sweep.
        #[arg(long)]
        quick: bool,
    },
}

fn main() {
    let cli = Cli::parse();
    if let Err(e) = run(cli) {
        eprintln!("error: {}", error_chain(&e));
        std::process::exit(1);
    }
}

/// The error and its causes on one line, skipping a cause whose text its parent already shows
/// (our error enums print their source inside their own message).
fn error_chain(e: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if !line.contains(&text) {
            if !line.is_empty() {
                line += ": ";
            }
            line += &text;
        }
    }
    line
}

fn run(cli: Cli) -> Result<()> {
    let progress = Progress {
        quiet: cli.quiet,
        ..Default::default()
    };
    let cache = cli.cache.clone().unwrap_or_else(eval::default_cache_dir);
    match cli.command {
        Command::Demo { quick, json } => demo(quick, json, &cli.out, &cache, &progress),
        Command::Basis {
            geometry,
            modes,
            kernels,
            points,
            young,
            poisson,
            save,
        } => basis(
            &geometry,
            BasisOptions {
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
            keep_units,
        } => mesh(&surface, cells, volume_target, keep_units, &cli.out),
        Command::Simulate { scene } => {
            let file = SceneFile::load(&scene)?;
            let stem = scene.file_stem().unwrap_or_default().to_string_lossy();
            let out = cli.out.join(stem.as_ref());
            let report = run_scene_file(&file, &out, &progress)?;
            println!(
                "{} frames written to {} (PLY + VTK); basis {:.2} s, {:.2} ms/step, {} unconverged \
                 steps, final max displacement {:.4} m",
                report.frames_written,
                out.display(),
                report.basis_seconds,
                report.ms_per_step,
                report.unconverged_steps,
                report.final_max_displacement
            );
            Ok(())
        }
        Command::Table { numbers, options } => {
            table(&numbers, options, &cli.out, &cache, &progress)
        }
        Command::Stress { quick, json } => {
            let config = if quick {
                StressConfig::quick()
            } else {
                StressConfig::full()
            };
            let bar = progress.bar(config.cases.len(), "stress cases");
            let outcomes = run_stress(&config, |o| {
                bar.inc(1);
                bar.set_message(o.case.name.clone());
            });
            bar.finish_and_clear();
            let md = stress_markdown(&outcomes);
            let value = serde_json::to_value(&outcomes)?;
            let dir = cli.out.join("stress");
            std::fs::create_dir_all(&dir)?;
            eval::output::write_atomically(&dir.join("stress.md"), md.as_bytes())?;
            eval::output::write_atomically(
                &dir.join("stress.json"),
                serde_json::to_string_pretty(&value)?.as_bytes(),
            )?;
            if json {
                println!("{}", serde_json::to_string_pretty(&value)?);
            } else {
                println!("{md}\nwrote {}", dir.display());
            }
            let bad: Vec<&str> = outcomes
                .iter()
                .filter(|o| !o.acceptable())
                .map(|o| o.case.name.as_str())
                .collect();
            if !bad.is_empty() {
                bail!(
                    "{} stress case(s) produced non-finite values or panicked: {}",
                    bad.len(),
                    bad.join(", ")
                );
            }
            Ok(())
        }
        Command::Bench { quick } => {
            let config = if quick {
                BenchConfig::quick(cache)
            } else {
                BenchConfig::full(cache)
            };
            let results = run_bench(&config, &progress)?;
            let (md, files) = write_bench(&results, &config, &cli.out)?;
            println!("{md}");
            for f in files {
                println!("wrote {}", f.display());
            }
            plot_or_warn(&bench_plot(&results, &config), &cli.out.join("bench"));
            Ok(())
        }
    }
}

/// Options of `freeform table`.
#[derive(clap::Args)]
struct TableOptions {
    /// Reduced configuration (minutes instead of tens of minutes).
    #[arg(long)]
    quick: bool,
    /// Print JSON instead of Markdown.
    #[arg(long)]
    json: bool,
    /// Leave out the Simplicits baseline (its training takes about 16 min per m on 2 cores
    /// the first time; networks are cached).
    #[arg(long)]
    skip_simplicits: bool,
    /// Only these modes (comma-separated), instead of the paper's 6, 9, 16, 32 (tables 3
    /// and 4: one m, default 16).
    #[arg(long, value_delimiter = ',')]
    modes: Option<Vec<usize>>,
    /// Tables 2 and 7: the folder of closed meshes (OBJ/STL/PLY), e.g. the shared
    /// `data/meshes`.
    #[arg(long)]
    meshes: Option<PathBuf>,
    /// Tables 2 and 7: only the mesh with this file name or stem.
    #[arg(long)]
    only: Option<String>,
    /// Tables 2 and 7: Young's modulus (Pa) of a mesh not in the shared-mesh catalog.
    #[arg(long, default_value_t = eval::shape_catalog::DEFAULT_SHAPE_YOUNGS_MODULUS)]
    young: f64,
    /// Tables 2 and 7: shapes run at the same time.
    #[arg(long, default_value_t = 1)]
    jobs: usize,
    /// Tables 2 and 7: mesh the FEM reference on this lattice (cells across L) instead of
    /// refining from 10 up to 16 cells until the volume is within 5%.
    #[arg(long)]
    fem_cells: Option<usize>,
    /// Train Simplicits for this many Adam steps instead of the configuration's (the
    /// paper's 10 000 in a full run): networks are cached per step count.
    #[arg(long)]
    simplicits_steps: Option<usize>,
}

fn table(
    numbers: &[u32],
    TableOptions {
        quick,
        json,
        skip_simplicits,
        modes,
        meshes,
        only,
        young,
        jobs,
        fem_cells,
        simplicits_steps,
    }: TableOptions,
    out: &Path,
    cache: &Path,
    progress: &Progress,
) -> Result<()> {
    if let Some(n) = numbers.iter().find(|n| !matches!(n, 1..=7)) {
        bail!("there is no table {n}: the paper's tables are 1 to 7");
    }
    if simplicits_steps == Some(0) {
        bail!("--simplicits-steps must be at least 1");
    }
    let mut config = if quick {
        BeamStudyConfig::quick(cache.to_path_buf())
    } else {
        BeamStudyConfig::full(cache.to_path_buf())
    };
    if numbers.iter().all(|&n| n == 5) {
        // Timing only needs the Bend.
        config.tests = vec![BeamTest::Bend];
    }
    if let Some(modes) = &modes {
        if modes.contains(&0) {
            bail!("--modes: every m must be at least 1");
        }
        config.modes = modes.clone();
    }
    let wants = |group: &[u32]| numbers.iter().any(|n| group.contains(n));
    if let Some(steps) = simplicits_steps
        && let Some(params) = &mut config.simplicits
    {
        params.steps = steps;
    }
    let mut rendered = Vec::new();
    if wants(&[2, 7]) {
        let Some(dir) = &meshes else {
            bail!("tables 2 and 7 need --meshes DIR (e.g. the shared data/meshes folder)");
        };
        if !(young > 0.0 && young.is_finite()) {
            bail!("--young must be a positive number of pascals, got {young}");
        }
        let files = mesh_files(dir, only.as_deref())?;
        let mut shapes = if quick {
            ShapeStudyConfig::quick(files, cache.to_path_buf())
        } else {
            ShapeStudyConfig::full(files, cache.to_path_buf())
        };
        shapes.default_youngs_modulus = young;
        shapes.jobs = jobs;
        if let Some(cells) = fem_cells {
            if cells == 0 {
                bail!("--fem-cells must be at least 1");
            }
            shapes.fem.first_cells_across = cells;
            shapes.fem.max_cells_across = cells;
        }
        if let Some(modes) = &modes {
            match modes.as_slice() {
                [m] => shapes.settings.modes = *m,
                _ => bail!("tables 2 and 7 use one m: give --modes a single value"),
            }
        }
        match (skip_simplicits, &mut shapes.simplicits, simplicits_steps) {
            (true, simplicits, _) => *simplicits = None,
            (false, Some(params), Some(steps)) => params.steps = steps,
            _ => {}
        }
        let total = shapes.meshes.len();
        let finished = std::sync::atomic::AtomicUsize::new(0);
        let study = run_shape_study(&shapes, progress, |shape| {
            let k = finished.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            progress.status(format!("[{k}/{total} shapes] {} finished", shape.name));
        })?;
        progress.status(format!(
            "shape study: {total} shape(s) in {:.0} s",
            study.seconds
        ));
        for &number in numbers.iter().filter(|n| matches!(n, 2 | 7)) {
            rendered.push(if number == 2 {
                table2(&study)
            } else {
                table7(&study)
            });
        }
    }
    if wants(&[3, 4]) {
        if skip_simplicits {
            bail!("tables 3 and 4 compare against Simplicits; drop --skip-simplicits for them");
        }
        let m = match modes.as_deref() {
            None => 16,
            Some([m]) => *m,
            Some(_) => bail!("tables 3 and 4 study one m: give --modes a single value"),
        };
        let ablation = AblationStudyConfig {
            coefficient_ablations: wants(&[3]),
            sampling_ablation: wants(&[4]),
            ..AblationStudyConfig::full(BeamStudyConfig {
                modes: vec![m],
                ..config.clone()
            })
        };
        let study = run_ablation_study(&ablation, progress)?;
        for &number in numbers.iter().filter(|n| matches!(n, 3 | 4)) {
            rendered.push(if number == 3 {
                table3(&study)
            } else {
                table4(&study)
            });
        }
    }
    if wants(&[1, 5, 6]) {
        if skip_simplicits {
            config.simplicits = None;
        }
        let study = run_beam_study(&config, progress)?;
        if wants(&[1])
            && let Some(spec) = twist_error_plot(&study)
        {
            for f in plot_or_warn(&spec, &out.join("twist_error_per_frame")) {
                progress.status(format!("wrote {}", f.display()));
            }
        }
        for &number in numbers.iter().filter(|n| matches!(n, 1 | 5 | 6)) {
            rendered.push(match number {
                1 => table1(&study),
                5 => table5(&study),
                _ => table6(&study),
            });
        }
    }
    let mut rendered_json = Vec::new();
    for table in rendered {
        let files = write_table(&table, out)?;
        if json {
            rendered_json.push(table.json);
        } else {
            println!("{}", table.markdown);
            for f in files {
                println!("wrote {}", f.display());
            }
            println!();
        }
    }
    if json {
        let value = if rendered_json.len() == 1 {
            rendered_json.remove(0)
        } else {
            serde_json::Value::Array(rendered_json)
        };
        println!("{}", serde_json::to_string_pretty(&value)?);
    }
    Ok(())
}

fn mesh(
    path: &Path,
    cells: usize,
    volume_target: Option<f64>,
    keep_units: bool,
    out: &Path,
) -> Result<()> {
    let surface = read_triangle_mesh(path)?;
    let surface = if keep_units {
        surface
    } else {
        surface.normalized().0
    };
    let params = LatticeMesherParams {
        cells_across: cells,
        ..Default::default()
    };
    let (tets, report) = match volume_target {
        None => tetrahedralize(&surface, &params)?,
        Some(max_relative_error) => tetrahedralize_to_volume(
            &surface,
            &params,
            &VolumeTarget {
                max_relative_error,
                ..Default::default()
            },
        )?,
    };
    let stem = path.file_stem().unwrap_or_default().to_string_lossy();
    let file = out.join(format!("{stem}.vtk"));
    write_atomically(
        &file,
        unstructured_grid_vtk(tets.vertices(), tets.vertices(), tets.tets(), 0.0).as_bytes(),
    )?;
    let q = &report.quality;
    println!(
        "{}: {} cells across (h = {:.4}), {} vertices, {} tetrahedra\n\
         volume {:.6} vs surface {:.6} ({:+.3}%)\n\
         dihedral angles {:.1}°–{:.1}°; boundary vertices {} ({} moved part way, {} kept off \
         the surface to protect quality)\n\
         {:.2} s; wrote {}",
        path.display(),
        (1.0 / report.cell_size * surface.bounding_box().largest_side()).round(),
        report.cell_size,
        report.vertices,
        report.tets,
        report.mesh_volume,
        report.surface_volume,
        100.0 * report.relative_volume_error,
        q.min_dihedral_degrees,
        q.max_dihedral_degrees,
        report.boundary_vertices,
        report.boundary_vertices_held_back[0],
        report.boundary_vertices_held_back[1],
        report.seconds,
        file.display()
    );
    Ok(())
}

/// Draws a figure; a failure (e.g. no TrueType font for the text) is a warning, since the
/// numbers it shows are already written.
fn plot_or_warn(spec: &PlotSpec, base: &Path) -> Vec<PathBuf> {
    write_plot(spec, base).unwrap_or_else(|e| {
        eprintln!("warning: {e} (the data are in the CSV/JSON files)");
        Vec::new()
    })
}

struct BasisOptions {
    modes: usize,
    kernels: usize,
    points: usize,
    young: f64,
    poisson: f64,
}

fn basis(geometry: &Path, o: BasisOptions, save: PathBuf, progress: &Progress) -> Result<()> {
    if !geometry.is_file() {
        bail!("{}: no such file", geometry.display());
    }
    let points = match read_triangle_mesh(geometry) {
        Ok(mesh) => sample_grid(
            &mesh.normalized().0,
            &GridSamplingParams {
                target_points: o.points,
            },
        )?,
        // Only a file without faces is a point cloud: an open or broken mesh is an error, not
        // a cloud of its vertices.
        Err(mesh_error @ GeometryReadError::NoData { .. }) => {
            let cloud = read_point_cloud(geometry).with_context(|| {
                format!("not a closed triangle mesh ({mesh_error}) and not a point cloud")
            })?;
            sample_point_cloud(
                &cloud,
                &PointCloudSamplingParams {
                    max_points: o.points,
                    ..Default::default()
                },
            )?
        }
        Err(mesh_error) => return Err(mesh_error.into()),
    };
    let lame = LameParameters::from_young_poisson(o.young, o.poisson)
        .with_context(|| format!("--young {} --poisson {}", o.young, o.poisson))?;
    progress.status(format!(
        "{}: {} integration points, K = {}, m = {}",
        geometry.display(),
        points.len(),
        o.kernels,
        o.modes
    ));
    let params = BasisParams::default()
        .with_modes(o.modes)
        .with_kernels(o.kernels);
    let (basis, report, _) = build_basis(&points, &vec![lame; points.len()], &params)?;
    if let Some(dir) = save.parent()
        && !dir.as_os_str().is_empty()
    {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    basis.save(&save)?;
    let t = &report.timings;
    println!(
        "basis: m = {}, K = {}, N = {} points, {:.1} kernels/point\n\
         time: kernels {:.2} s, shape functions {:.2} s, assembly {:.2} s, eigen solve {:.2} s, total {:.2} s\n\
         eigenvalues (first 4): {:?}\nsaved to {}",
        basis.modes(),
        report.kernels,
        report.integration_points,
        report.mean_kernels_per_point,
        t.kernel_placement,
        t.shape_functions,
        t.assembly,
        t.eigen_solve,
        t.total(),
        &basis.eigenvalues()[..basis.eigenvalues().len().min(4)],
        save.display()
    );
    Ok(())
}

fn demo(quick: bool, json: bool, out: &Path, cache: &Path, progress: &Progress) -> Result<()> {
    let start = Instant::now();
    let (settings, steps, fem) = if quick {
        (
            ReducedSettings {
                modes: 6,
                kernels: 200,
                basis_points: 3000,
                simulation_points: 1000,
                ..ReducedSettings::default()
            },
            20,
            FemResolution {
                order: ElementOrder::Quadratic,
                cells_per_metre: 2,
            },
        )
    } else {
        (ReducedSettings::default(), 100, FemResolution::GROUND_TRUTH)
    };
    let test = BeamTest::Bend;
    let reference = run_fem_beam(test, fem, NewtonParams::default(), steps, cache, progress)?;
    reference.check_converged(NewtonParams::default().max_iterations)?;
    progress.status(format!(
        "basis: m = {}, K = {}, ≈{} grid points",
        settings.modes, settings.kernels, settings.basis_points
    ));
    let basis = build_beam_basis(&settings)?;
    let vertices = reference.vertices().to_vec();
    let run = run_reduced_beam(test, &basis.basis, &settings, &vertices, steps, progress)?;
    let fem_frames = reference.vertex_frames();
    let errors = trajectory_errors(&run.frames[1..], &fem_frames[1..], beam_length_scale())?;

    // Tip: mean y displacement of the vertices on the end face x = 5.
    let tip: Vec<usize> = (0..vertices.len())
        .filter(|&i| (vertices[i].x - BEAM_MAX.x).abs() < 1e-9)
        .collect();
    let tip_y = |frame: &[Vector3<f64>]| {
        tip.iter().map(|&i| frame[i].y - vertices[i].y).sum::<f64>() / tip.len() as f64
    };
    let times: Vec<f64> = (0..=steps).map(|s| s as f64 * 0.01).collect();
    let ours_tip: Vec<(f64, f64)> = times
        .iter()
        .zip(&run.frames)
        .map(|(&t, f)| (t, tip_y(f)))
        .collect();
    let fem_tip: Vec<(f64, f64)> = times
        .iter()
        .zip(&fem_frames)
        .map(|(&t, f)| (t, tip_y(f)))
        .collect();
    let dir = out.join("demo");
    let tets = reference.mesh.tet_mesh().tets();
    let every = (steps / 10).max(1);
    let mut frames_written = 0;
    for step in (0..=steps).step_by(every) {
        for (name, frames) in [("freeform", &run.frames), ("fem", &fem_frames)] {
            let path = dir.join(format!("{name}_{step:04}.vtk"));
            write_atomically(
                &path,
                unstructured_grid_vtk(&frames[step], &vertices, tets, times[step]).as_bytes(),
            )?;
            frames_written += 1;
        }
    }
    let seconds = start.elapsed().as_secs_f64();
    let summary = serde_json::json!({
        "test": "bend",
        "steps": steps,
        "m": settings.modes,
        "kernels": settings.kernels,
        "simulation_points": run.simulation_points,
        "fem": fem.label(),
        "fem_dofs": reference.dofs,
        "fem_cached": reference.cached,
        "normalized_mse": errors.normalized_mse,
        "normalized_max": errors.normalized_max,
        "ours_ms_per_step": run.ms_per_step,
        "fem_ms_per_step": 1e3 * reference.seconds_per_step,
        "basis_seconds": basis.seconds,
        "tip_y_final": {"ours": ours_tip.last().map(|p| p.1), "fem": fem_tip.last().map(|p| p.1)},
        "unconverged_steps": run.unconverged_steps,
        "wall_seconds": seconds,
    });
    write_atomically(
        &dir.join("summary.json"),
        serde_json::to_string_pretty(&summary)?.as_bytes(),
    )?;
    let tip_plot = PlotSpec {
        title: format!(
            "Beam Bend: tip y displacement (m = {}, K = {})",
            settings.modes, settings.kernels
        ),
        x_label: "time (s)".into(),
        y_label: "mean y displacement of the x = 5 face (m)".into(),
        scale: AxisScale::Linear,
        series: vec![
            Series {
                label: format!("FEM {} (ground truth)", fem.label()),
                points: fem_tip.clone(),
                line: true,
                color: 0,
            },
            Series {
                label: format!("FreeForm m = {}", settings.modes),
                points: ours_tip.clone(),
                line: true,
                color: 1,
            },
        ],
    };
    let plot = plot_or_warn(&tip_plot, &dir.join("tip_displacement"));
    if json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        println!(
            "FreeForm beam Bend, {steps} steps of 0.01 s: m = {}, K = {}, {} simulation points",
            settings.modes, settings.kernels, run.simulation_points
        );
        println!(
            "ground truth: FEM {} ({} DOFs){}",
            fem.label(),
            reference.dofs,
            if reference.cached {
                ", from the cache"
            } else {
                ""
            }
        );
        println!(
            "normalized MSE {:.3e}, normalized max error {:.3e} (at {} FEM vertices, L = 5 m)",
            errors.normalized_mse,
            errors.normalized_max,
            vertices.len()
        );
        println!(
            "tip y at t = {:.2} s: ours {:.4} m, FEM {:.4} m",
            times[steps], ours_tip[steps].1, fem_tip[steps].1
        );
        println!(
            "time: basis {:.2} s, ours {:.2} ms/step, FEM {:.1} ms/step ({:.0}× ours); {} unconverged steps",
            basis.seconds,
            run.ms_per_step,
            1e3 * reference.seconds_per_step,
            1e3 * reference.seconds_per_step / run.ms_per_step,
            run.unconverged_steps
        );
        for p in plot {
            println!("wrote {}", p.display());
        }
        println!(
            "wrote {frames_written} VTK frames (ours and FEM, every {every} steps) and summary.json to {}; total {seconds:.1} s",
            dir.display()
        );
    }
    Ok(())
}
