//! `freeform demo`: the paper's beam Bend (design §4.1) against the FEM ground truth, with the
//! library's defaults (the held end by a weighted basis, the projected volumetric term, a
//! cubature of 40 000 points) and with the paper's setting (a pin penalty on the plain basis,
//! every one of 5000 points), built from the library layer alone.

use std::path::Path;
use std::time::Instant;

use anyhow::Result;
use artifact::write_atomically;

use crate::line_plot::{LinePlot, Series};
use fem_ref::{ElementOrder, FillReducingOrdering, TetMesh};
use freeform::fem_reference::{FemProblem, FemRun, run_fem};
use freeform::frames::unstructured_grid_vtk;
use freeform::metrics::{TrajectoryErrors, trajectory_errors};
use freeform::terminal_progress::{BarProgress, TerminalProgress};
use freeform::{
    BasisSpec, Constraint, Motion, PressureSpace, RecordedRun, Region, SceneSpec, Simulation,
    SimulationSpec, run_recorded,
};
use hyperelastic::{HessianTangent, MaterialField, MaterialSample, StableNeoHookean};
use nalgebra::Vector3;
use optimize::NewtonParams;
use rkpm_core::{IntegrationPoints, sample_box_grid};
use skin_eigen::{BasisParams, SkinningBasis, build_basis};

/// The beam's rest box (m): 5 m × 1 m × 1 m.
const BEAM_MIN: Vector3<f64> = Vector3::new(0.0, 0.0, 0.0);
const BEAM_MAX: Vector3<f64> = Vector3::new(5.0, 1.0, 1.0);
/// Backward-Euler step (s).
const TIME_STEP: f64 = 0.01;

/// The beam's material: E = 5 MPa, ν = 0.45, ρ = 1000 kg/m³.
fn beam_material() -> MaterialSample {
    MaterialSample {
        youngs_modulus: 5e6,
        poisson_ratio: 0.45,
        density: 1000.0,
    }
}

/// The Bend: gravity along −y, the end x ≤ 0.5 m held at rest.
fn bend_scene() -> SceneSpec {
    SceneSpec {
        gravity: Some(Vector3::new(0.0, -9.8, 0.0)),
        constraints: vec![Constraint {
            region: Region::Below {
                axis: 0,
                value: 0.5,
            },
            motion: Motion::Rest,
        }],
        ..SceneSpec::default()
    }
}

/// What the demo runs.
struct DemoSize {
    modes: usize,
    kernels: usize,
    /// Grid points of the defaults' basis and simulation.
    default_points: usize,
    /// Grid points of the paper's basis, then of its simulation.
    paper_points: (usize, usize),
    steps: usize,
    /// FEM elements across the 1 m side.
    fem_cells_per_metre: usize,
}

impl DemoSize {
    /// m = 16, K = 1000; the defaults on ≈40k points, the paper's basis on ≈20k and its
    /// simulation on 5000; 100 steps, FEM P2 res 6.
    const FULL: DemoSize = DemoSize {
        modes: 16,
        kernels: 1000,
        default_points: BasisSpec::DEFAULT_POINTS,
        paper_points: (20_000, 5000),
        steps: 100,
        fem_cells_per_metre: 6,
    };
    /// Seconds: m = 6, K = 200, 20 steps, FEM P2 res 2.
    const QUICK: DemoSize = DemoSize {
        modes: 6,
        kernels: 200,
        default_points: 3000,
        paper_points: (3000, 1000),
        steps: 20,
        fem_cells_per_metre: 2,
    };

    /// The basis builder's options: m and K, the rest default.
    fn basis_params(&self) -> BasisParams {
        BasisParams::default()
            .with_modes(self.modes)
            .with_kernels(self.kernels)
    }

    fn fem_label(&self) -> String {
        format!("P2 res {}", self.fem_cells_per_metre)
    }
}

/// The defaults' model: the weighted basis of the held end, its integration points and the
/// pressure space of the projected volumetric term.
struct DefaultModel {
    basis: SkinningBasis,
    points: IntegrationPoints,
    pressure: Option<PressureSpace>,
}

impl DefaultModel {
    fn build(size: &DemoSize, scene: &SceneSpec) -> Result<Self> {
        let spec = SimulationSpec::default();
        let points = beam_grid(size.default_points)?;
        let lame = vec![beam_material().lame_parameters()?; points.len()];
        let (basis, _, shared) = spec.pins.build_basis_sharing(
            scene,
            &points,
            &lame,
            points.positions(),
            &[],
            size.basis_params(),
        )?;
        let pressure = spec
            .pressure
            .map(|params| {
                PressureSpace::build(
                    scene,
                    spec.pins,
                    &points,
                    &lame,
                    size.basis_params(),
                    &params,
                    shared.as_ref(),
                )
            })
            .transpose()?;
        Ok(DefaultModel {
            basis,
            points,
            pressure,
        })
    }
}

/// Grid points filling the beam, about `n` of them.
fn beam_grid(n: usize) -> Result<IntegrationPoints> {
    let spacing = ((BEAM_MAX - BEAM_MIN).product() / n.max(1) as f64).cbrt();
    Ok(sample_box_grid(BEAM_MIN, BEAM_MAX, spacing)?)
}

/// FEM steps timed in this run when the reference came from the cache (its stored time is of
/// whatever machine computed it): the speed ratio is then of one run.
const FEM_TIMING_STEPS: usize = 10;

/// The FEM problem of the Bend on `scene` (P2, `size`'s resolution).
fn fem_problem<'a>(size: &DemoSize, scene: &'a SceneSpec) -> Result<FemProblem<'a>> {
    let r = size.fem_cells_per_metre;
    Ok(FemProblem {
        tets: TetMesh::cuboid(BEAM_MIN, BEAM_MAX, [5 * r, r, r])?,
        order: ElementOrder::Quadratic,
        material: beam_material(),
        scene,
        time_step: TIME_STEP,
        newton: NewtonParams::default(),
        tangent: HessianTangent::ProjectedPsd,
        ordering: FillReducingOrdering::default(),
        failed_step_halvings: 0,
        steps: size.steps,
    })
}

/// The FEM ground truth of the Bend (cached in `cache`) and its seconds per step measured in
/// this run: the run's own, or [`FEM_TIMING_STEPS`] fresh steps when it came from the cache.
fn fem_reference(size: &DemoSize, cache: &Path, progress: &BarProgress) -> Result<(FemRun, f64)> {
    let scene = bend_scene();
    let problem = fem_problem(size, &scene)?;
    let reference = run_fem(
        &problem,
        &format!("Bend {}", size.fem_label()),
        cache,
        progress,
    )?;
    reference.check_converged(NewtonParams::default().max_iterations)?;
    if !reference.cached {
        let seconds = reference.seconds_per_step;
        return Ok((reference, seconds));
    }
    let (mut fem, _) = problem.simulator()?;
    let timed = FEM_TIMING_STEPS.min(size.steps);
    let start = Instant::now();
    for _ in 0..timed {
        fem.step()?;
    }
    let seconds = start.elapsed().as_secs_f64() / timed.max(1) as f64;
    Ok((reference, seconds))
}

/// Runs the demo and prints (or writes as JSON) its result.
pub(crate) fn run(
    quick: bool,
    json: bool,
    out: &Path,
    cache: &Path,
    progress: &TerminalProgress,
) -> Result<()> {
    let start = Instant::now();
    let size = if quick {
        DemoSize::QUICK
    } else {
        DemoSize::FULL
    };
    let steps = size.steps;
    let bars = BarProgress::new(*progress);
    let (reference, fem_seconds_per_step) = fem_reference(&size, cache, &bars)?;
    progress.status(format!(
        "bases: m = {}, K = {}, the defaults' on ≈{} grid points (weighted), the paper's on ≈{}",
        size.modes, size.kernels, size.default_points, size.paper_points.0
    ));
    let scene = bend_scene();
    let basis_start = Instant::now();
    let defaults = DefaultModel::build(&size, &scene)?;
    let basis_seconds = basis_start.elapsed().as_secs_f64();
    let paper_grid = beam_grid(size.paper_points.0)?;
    let lame = vec![beam_material().lame_parameters()?; paper_grid.len()];
    let (paper_basis, _, _) = build_basis(&paper_grid, &lame, &size.basis_params())?;
    let paper_points = beam_grid(size.paper_points.1)?;

    let material = MaterialField::Uniform(beam_material());
    // The library's defaults (a scene file's: weighted basis, projected term, cubature, Hessian
    // reuse), then the paper's setting beside them.
    let spec = SimulationSpec::default();
    let library = Simulation::new(
        &defaults.basis,
        &defaults.points,
        &material,
        StableNeoHookean,
        &scene,
    )
    .with_params(spec.simulation_params())
    .with_pin_hold(spec.pins)
    .with_pressure(defaults.pressure.as_ref())
    .with_cache_dir(Some(cache));
    let paper_spec = SimulationSpec::paper();
    let paper = Simulation::new(
        &paper_basis,
        &paper_points,
        &material,
        StableNeoHookean,
        &scene,
    )
    .with_params(paper_spec.simulation_params())
    .with_quadrature(paper_spec.quadrature);
    let vertices = reference.vertices().to_vec();
    let label = |what: &str| format!("FreeForm Bend m={} {what}", size.modes);
    let ours = run_recorded(&library, &vertices, steps, &label("defaults"), &bars)?;
    let theirs = run_recorded(&paper, &vertices, steps, &label("paper"), &bars)?;

    let length = (BEAM_MAX - BEAM_MIN).max();
    let fem_frames = reference.vertex_frames();
    let errors = trajectory_errors(&ours.frames[1..], &fem_frames[1..], length)?;
    let paper_errors = trajectory_errors(&theirs.frames[1..], &fem_frames[1..], length)?;

    let tip = TipTrace::new(&vertices);
    let ours_tip = tip.trace(&ours.frames);
    let fem_tip = tip.trace(&fem_frames);
    let dir = out.join("demo");
    let frames_written = write_vtk_frames(&dir, &reference, &ours.frames, &fem_frames, steps)?;
    write_tip_csv(&dir, &ours_tip, &fem_tip)?;
    let plot = LinePlot {
        title: format!(
            "Beam Bend: tip y displacement (m = {}, K = {})",
            size.modes, size.kernels
        ),
        x_label: "time (s)",
        y_label: "mean y displacement of the x = 5 face (m)",
        series: vec![
            Series {
                label: format!("FEM {} (ground truth)", size.fem_label()),
                points: &fem_tip,
                colour: "#1f77b4",
            },
            Series {
                label: format!("FreeForm m = {}", size.modes),
                points: &ours_tip,
                colour: "#d62728",
            },
        ],
    };
    write_atomically(&dir.join("tip_displacement.svg"), plot.svg().as_bytes())?;

    let quadrature = &ours.report.quadrature;
    let seconds = start.elapsed().as_secs_f64();
    let summary = serde_json::json!({
        "test": "bend",
        "steps": steps,
        "m": size.modes,
        "kernels": size.kernels,
        "simulation_points": ours.report.simulation_points,
        "fem": size.fem_label(),
        "fem_dofs": reference.dofs,
        "fem_cached": reference.cached,
        "normalized_mse": errors.normalized_mse,
        "normalized_max": errors.normalized_max,
        "ours_ms_per_step": ours.report.ms_per_step,
        "fem_ms_per_step": 1e3 * fem_seconds_per_step,
        "basis_seconds": basis_seconds,
        "tip_y_final": {"ours": ours_tip.last().map(|p| p.1), "fem": fem_tip.last().map(|p| p.1)},
        "tip_y_half_time": {"ours": ours_tip[steps / 2].1, "fem": fem_tip[steps / 2].1},
        "unconverged_steps": ours.report.unconverged_steps,
        "quadrature": {"kind": quadrature.kind, "points": quadrature.points},
        "hessians_per_step": ours.report.hessians_per_step,
        "paper_setting": {
            "normalized_mse": paper_errors.normalized_mse,
            "normalized_max": paper_errors.normalized_max,
            "ours_ms_per_step": theirs.report.ms_per_step,
            "hessians_per_step": theirs.report.hessians_per_step,
            "unconverged_steps": theirs.report.unconverged_steps,
        },
        "wall_seconds": seconds,
    });
    write_atomically(
        &dir.join("summary.json"),
        serde_json::to_string_pretty(&summary)?.as_bytes(),
    )?;
    if json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
        return Ok(());
    }
    let report = DemoReport {
        size: &size,
        reference: &reference,
        ours: &ours,
        paper: &theirs,
        errors: &errors,
        paper_errors: &paper_errors,
        vertices: vertices.len(),
        tip: (ours_tip[steps].1, fem_tip[steps].1),
        basis_seconds,
        fem_seconds_per_step,
    };
    report.print();
    println!(
        "wrote {frames_written} VTK frames (ours and FEM), tip_displacement.svg and .csv, and \
         summary.json to {}; total {seconds:.1} s",
        dir.display()
    );
    Ok(())
}

/// The mean y displacement of the vertices on the beam's free end face x = 5 m, per frame.
struct TipTrace<'a> {
    vertices: &'a [Vector3<f64>],
    /// Indices of the vertices on the face.
    face: Vec<usize>,
}

impl<'a> TipTrace<'a> {
    fn new(vertices: &'a [Vector3<f64>]) -> Self {
        let face = (0..vertices.len())
            .filter(|&i| (vertices[i].x - BEAM_MAX.x).abs() < 1e-9)
            .collect();
        TipTrace { vertices, face }
    }

    /// `(t, mean y displacement)` of each of `frames` (positions at every vertex).
    fn trace(&self, frames: &[Vec<Vector3<f64>>]) -> Vec<(f64, f64)> {
        frames
            .iter()
            .enumerate()
            .map(|(step, frame)| {
                let y = self
                    .face
                    .iter()
                    .map(|&i| frame[i].y - self.vertices[i].y)
                    .sum::<f64>()
                    / self.face.len() as f64;
                (step as f64 * TIME_STEP, y)
            })
            .collect()
    }
}

/// VTK frames of both solutions on the FEM mesh, every tenth of the run; returns how many.
fn write_vtk_frames(
    dir: &Path,
    reference: &FemRun,
    ours: &[Vec<Vector3<f64>>],
    fem: &[Vec<Vector3<f64>>],
    steps: usize,
) -> Result<usize> {
    let vertices = reference.vertices();
    let tets = reference.mesh.tet_mesh().tets();
    let every = (steps / 10).max(1);
    let mut written = 0;
    for step in (0..=steps).step_by(every) {
        for (name, frames) in [("freeform", ours), ("fem", fem)] {
            let path = dir.join(format!("{name}_{step:04}.vtk"));
            let time = step as f64 * TIME_STEP;
            let vtk = unstructured_grid_vtk(&frames[step], vertices, tets, time, None);
            write_atomically(&path, vtk.as_bytes())?;
            written += 1;
        }
    }
    Ok(written)
}

/// `tip_displacement.csv`: time (s), ours and the FEM's tip y displacement (m).
fn write_tip_csv(dir: &Path, ours: &[(f64, f64)], fem: &[(f64, f64)]) -> Result<()> {
    let mut csv = String::from("time_s,freeform_tip_y_m,fem_tip_y_m\n");
    for ((t, y), (_, y_fem)) in ours.iter().zip(fem) {
        csv += &format!("{t:.4},{y:.9e},{y_fem:.9e}\n");
    }
    write_atomically(&dir.join("tip_displacement.csv"), csv.as_bytes())?;
    Ok(())
}

/// What the demo prints.
struct DemoReport<'a> {
    size: &'a DemoSize,
    reference: &'a FemRun,
    ours: &'a RecordedRun,
    paper: &'a RecordedRun,
    errors: &'a TrajectoryErrors,
    paper_errors: &'a TrajectoryErrors,
    vertices: usize,
    /// Final tip y displacement, ours and the FEM's (m).
    tip: (f64, f64),
    basis_seconds: f64,
    /// The FEM's seconds per step measured in this run.
    fem_seconds_per_step: f64,
}

impl DemoReport<'_> {
    fn print(&self) {
        let (ours, paper, reference) = (&self.ours.report, &self.paper.report, self.reference);
        println!(
            "FreeForm beam Bend, {} steps of {TIME_STEP} s: m = {}, K = {}, {} simulation \
             points; elastic energy on {} {} points, {:.2} Hessians per step",
            self.size.steps,
            self.size.modes,
            self.size.kernels,
            ours.simulation_points,
            ours.quadrature.points,
            ours.quadrature.kind,
            ours.hessians_per_step
        );
        println!(
            "ground truth: FEM {} ({} DOFs){}",
            self.size.fem_label(),
            reference.dofs,
            if reference.cached {
                format!(
                    ", from the cache; its ms/step below timed over {FEM_TIMING_STEPS} fresh steps"
                )
            } else {
                String::new()
            }
        );
        println!(
            "normalized MSE {:.3e}, normalized max error {:.3e} (at {} FEM vertices, L = 5 m)",
            self.errors.normalized_mse, self.errors.normalized_max, self.vertices
        );
        println!(
            "tip y at t = {:.2} s: ours {:.4} m, FEM {:.4} m",
            self.size.steps as f64 * TIME_STEP,
            self.tip.0,
            self.tip.1
        );
        println!(
            "time: basis {:.2} s, ours {:.2} ms/step, FEM {:.1} ms/step ({:.0}× ours); {} \
             unconverged steps",
            self.basis_seconds,
            ours.ms_per_step,
            1e3 * self.fem_seconds_per_step,
            1e3 * self.fem_seconds_per_step / ours.ms_per_step,
            ours.unconverged_steps
        );
        println!(
            "the paper's setting (a pin penalty on the plain basis, every one of {} points, a \
             fresh projected Hessian every iteration): normalized MSE {:.3e}, max {:.3e}, {:.2} \
             ms/step ({:.1}× the default step's time)",
            paper.simulation_points,
            self.paper_errors.normalized_mse,
            self.paper_errors.normalized_max,
            paper.ms_per_step,
            paper.ms_per_step / ours.ms_per_step
        );
    }
}
