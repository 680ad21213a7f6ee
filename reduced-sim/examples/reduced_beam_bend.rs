//! The beam Bend scene of design §4.1 on the reduced simulator: a 5 m × 1 m × 1 m beam
//! (E = 5 MPa, ν = 0.45, ρ = 1000 kg/m³) with x ≤ 0.5 m pinned, bending under gravity
//! (9.8 m/s² along -y), 100 steps of h = 0.01 s.
//!
//! ```sh
//! cargo run --release -p reduced-sim --example reduced_beam_bend -- --modes 16 --json
//! ```
//! Options: `--modes m` (default 16), `--kernels K` (default 1000), `--basis-points N` (grid
//! points the basis is built on, default 20000), `--points N` (simulation points, default
//! 5000), `--steps S` (default 100), `--tolerance T` (Newton, default 1e-6), `--pin-factor F`
//! and `--pin-modulus young|p-wave` (default the library's, [`PenaltyParams::default`]),
//! `--full-quadrature` and `--fresh-hessians` (the paper's setting instead of the library's
//! default cubature and Hessian reuse), `--exact-tangent`, `--exact` (hold the pinned end
//! exactly, [`Scene::held`], instead of by the penalty) with `--exact-inset METRES`, `--json`.
//!
//! Output: `tip_y` at t = 0.5 s and 1.0 s — the y displacement (m) of the end face x = 5,
//! averaged over an 11 × 11 lattice of points on it — plus ms per step (and its split into
//! assembly / solve / line search), mean Newton iterations, the largest drift of the pinned
//! points (`max_pin_deviation`), of the exactly held ones (`max_held_deviation`) and of every
//! point of the clamped end x ≤ 0.5 (`end_drift`), all in m.

use hyperelastic::MaterialSample;
use std::time::Instant;

use hyperelastic::{LameParameters, StableNeoHookean};
use nalgebra::Vector3;
use optimize::{NewtonParams, NewtonTimings};
use reduced_sim::{
    DeformationMap, HessianTangent, PenaltyParams, PinModulus, PinTarget, PinnedRegion,
    QuadratureRule, ReducedModel, Scene, SimulationParams, Simulator,
};
use rkpm_core::{KernelWindow, place_kernels, sample_box_grid};
use skin_eigen::{BasisParams, RegionConstraintParams, build_basis, build_basis_with_regions};

/// Command-line options.
#[derive(clap::Parser)]
struct Args {
    /// Machine-readable output.
    #[arg(long)]
    json: bool,
    /// Modes m.
    #[arg(long, default_value_t = 16)]
    modes: usize,
    /// Kernels K.
    #[arg(long, default_value_t = 1000)]
    kernels: usize,
    /// Grid points the basis is built on.
    #[arg(long, default_value_t = 20_000)]
    basis_points: usize,
    /// Simulation points.
    #[arg(long = "points", default_value_t = 5000)]
    sim_points: usize,
    /// Steps of 0.01 s.
    #[arg(long, default_value_t = 100)]
    steps: usize,
    /// Newton tolerance.
    #[arg(long, default_value_t = NewtonParams::default().tolerance)]
    tolerance: f64,
    /// Pin penalty factor.
    #[arg(long, default_value_t = PenaltyParams::default().pin_factor)]
    pin_factor: f64,
    /// The modulus the pin penalty scales with (default the library's).
    #[arg(long, value_enum)]
    pin_modulus: Option<PinModulusChoice>,
    /// Integrate the elastic energy on every point (the paper's setting) instead of the
    /// library's default cubature.
    #[arg(long)]
    full_quadrature: bool,
    /// Assemble a fresh Hessian every Newton iteration (the paper's setting) instead of the
    /// library's default reuse.
    #[arg(long)]
    fresh_hessians: bool,
    /// Assemble the exact material tangent instead of the PSD-projected one (a step whose
    /// Hessian is then not positive definite fails with a named error).
    #[arg(long)]
    exact_tangent: bool,
    /// Hold the pinned end exactly (a basis built for it, `Scene::held`) instead of by the
    /// penalty.
    #[arg(long)]
    exact: bool,
    /// With `--exact`: hold x ≤ 0.5 − inset (m) exactly and the band up to 0.5 by the penalty
    /// (default 1.5 median kernel radii).
    #[arg(long)]
    exact_inset: Option<f64>,
}

/// `--pin-modulus`.
#[derive(Clone, Copy, clap::ValueEnum)]
enum PinModulusChoice {
    /// Young's modulus E.
    Young,
    /// λ + 2μ.
    PWave,
}

const BEAM_MIN: Vector3<f64> = Vector3::new(0.0, 0.0, 0.0);
const BEAM_MAX: Vector3<f64> = Vector3::new(5.0, 1.0, 1.0);

/// Spacing of a box grid with about `n` cells.
fn spacing_for(n: usize) -> f64 {
    (5.0 / n as f64).cbrt()
}

/// The basis grid, the simulation points, the basis (built for the clamped end when `--exact`)
/// and the exact hold's inset (m; 0 for the penalty).
struct BeamBasis {
    basis_grid: rkpm_core::IntegrationPoints,
    points: rkpm_core::IntegrationPoints,
    basis: skin_eigen::SkinningBasis,
    inset: f64,
}

fn build_beam_basis(args: &Args, lame: LameParameters) -> Result<BeamBasis, String> {
    let basis_grid = sample_box_grid(BEAM_MIN, BEAM_MAX, spacing_for(args.basis_points))
        .map_err(|e| e.to_string())?;
    let points = sample_box_grid(BEAM_MIN, BEAM_MAX, spacing_for(args.sim_points))
        .map_err(|e| e.to_string())?;
    let mut params = BasisParams::default()
        .with_modes(args.modes)
        .with_kernels(args.kernels);
    // Exact pins: compact kernels, and the clamped end held on x ≤ 0.5 − inset (by default 1.5
    // median kernel radii, as `eval`'s EXACT_INSET_KERNEL_RADII), the band beyond by the penalty.
    let mut inset = 0.0;
    if args.exact {
        params.shape_functions.window = KernelWindow::CubicBSpline;
        inset = match args.exact_inset {
            Some(inset) => inset,
            None => {
                let kernels = place_kernels(basis_grid.positions(), &params.kernels)
                    .map_err(|e| e.to_string())?;
                let mut radii = kernels.radii().to_vec();
                radii.sort_by(f64::total_cmp);
                1.5 * radii[radii.len() / 2]
            }
        };
    }
    let materials = vec![lame; basis_grid.len()];
    let (basis, _, _) = if args.exact {
        // Held on both point sets: the basis grid's and the simulation's points in the end.
        let region: Vec<Vector3<f64>> = basis_grid
            .positions()
            .iter()
            .chain(points.positions())
            .filter(|x| x.x <= 0.5 - inset)
            .copied()
            .collect();
        build_basis_with_regions(
            &basis_grid,
            &materials,
            &params,
            &[region],
            &RegionConstraintParams::default(),
            &[],
        )
    } else {
        build_basis(&basis_grid, &materials, &params)
    }
    .map_err(|e| e.to_string())?;
    Ok(BeamBasis {
        basis_grid,
        points,
        basis,
        inset,
    })
}

/// Gravity, and the clamped end x ≤ 0.5 pinned by the penalty, or held exactly on x ≤ 0.5 −
/// inset with the band up to 0.5 pinned.
fn beam_scene(model: &ReducedModel<StableNeoHookean>, exact: bool, inset: f64) -> Scene {
    let region = |keep: &dyn Fn(f64) -> bool| PinnedRegion {
        points: model.points_where(|x| keep(x.x)),
        target: PinTarget::Rest,
    };
    Scene {
        gravity: Some(Vector3::new(0.0, -9.8, 0.0)),
        pins: if !exact {
            vec![region(&|x| x <= 0.5)]
        } else if inset > 0.0 {
            vec![region(&|x| x > 0.5 - inset && x <= 0.5)]
        } else {
            Vec::new()
        },
        held: if exact {
            vec![region(&|x| x <= 0.5 - inset)]
        } else {
            Vec::new()
        },
        floor: None,
        colliders: Vec::new(),
    }
}

/// The simulator's options the flags ask for.
fn simulation_params(args: &Args) -> SimulationParams {
    let pin_modulus = match args.pin_modulus {
        None => PenaltyParams::default().pin_modulus,
        Some(PinModulusChoice::Young) => PinModulus::Young,
        Some(PinModulusChoice::PWave) => PinModulus::PWave,
    };
    let base = if args.fresh_hessians {
        SimulationParams::paper_setting()
    } else {
        SimulationParams::default()
    };
    SimulationParams {
        time_step: 0.01,
        newton: NewtonParams {
            tolerance: args.tolerance,
            ..base.newton
        },
        penalty: PenaltyParams {
            pin_factor: args.pin_factor,
            pin_modulus,
            ..Default::default()
        },
        tangent: if args.exact_tangent {
            HessianTangent::Exact
        } else {
            HessianTangent::ProjectedPsd
        },
        ..base
    }
}

/// What the steps measured.
#[derive(Default)]
struct Measured {
    timings: NewtonTimings,
    /// Seconds in `step` alone.
    stepping: f64,
    iterations: usize,
    unconverged: usize,
    /// (t in s, mean y displacement of the end face in m) at t = 0.5 and 1.0 s.
    tip_y: Vec<(&'static str, f64)>,
    pin_deviation: f64,
    held_deviation: f64,
    /// Drift of every point of the clamped end x ≤ 0.5 (held, band or penalized) from rest.
    end_drift: f64,
}

/// Runs `steps` steps, timing only the steps (as the library's runner does) and measuring the
/// tip at `lattice` and the clamped end's drift.
fn step_through(
    sim: &mut Simulator<StableNeoHookean>,
    basis: &skin_eigen::SkinningBasis,
    lattice: &[Vector3<f64>],
    steps: usize,
) -> Result<Measured, String> {
    let tip = DeformationMap::new(basis, lattice).map_err(|e| e.to_string())?;
    let end_rest: Vec<Vector3<f64>> = sim
        .model()
        .rest_positions()
        .iter()
        .copied()
        .filter(|x| x.x <= 0.5)
        .collect();
    let end = DeformationMap::new(basis, &end_rest).map_err(|e| e.to_string())?;
    let mut m = Measured::default();
    for step in 1..=steps {
        let t = Instant::now();
        let report = sim.step().map_err(|e| format!("step {step} failed: {e}"))?;
        m.stepping += t.elapsed().as_secs_f64();
        m.iterations += report.iterations;
        m.unconverged += usize::from(!report.converged());
        m.timings.assembly += report.timings.assembly;
        m.timings.solve += report.timings.solve;
        m.timings.line_search += report.timings.line_search;
        m.pin_deviation = m.pin_deviation.max(sim.max_pin_deviation().unwrap_or(0.0));
        m.held_deviation = m
            .held_deviation
            .max(sim.max_held_deviation().unwrap_or(0.0));
        for (x, x0) in end.positions(&sim.state().z).iter().zip(&end_rest) {
            m.end_drift = m.end_drift.max((x - x0).norm());
        }
        if step == 50 || step == 100 {
            let x = tip.positions(&sim.state().z);
            let dy = x.iter().zip(lattice).map(|(x, r)| x.y - r.y).sum::<f64>() / 121.0;
            m.tip_y.push((if step == 50 { "0.5" } else { "1.0" }, dy));
        }
    }
    Ok(m)
}

/// The run's setup, for the report.
struct Setup<'a> {
    args: &'a Args,
    basis_points: usize,
    simulation_points: usize,
    inset: f64,
    basis_seconds: f64,
    setup_seconds: f64,
    quadrature: &'a reduced_sim::QuadratureReport,
}

fn print_json(s: &Setup, m: &Measured) {
    let Args {
        modes,
        kernels,
        steps,
        ..
    } = *s.args;
    let per_step = |t: f64| 1e3 * t / steps as f64;
    let tips: Vec<String> = m
        .tip_y
        .iter()
        .map(|(k, v)| format!("\"{k}\": {v:.8e}"))
        .collect();
    println!(
        "{{\"modes\": {modes}, \"kernels\": {kernels}, \"basis_points\": {}, \
         \"simulation_points\": {}, \"steps\": {steps}, \"tip_y\": {{{}}}, \
         \"ms_per_step\": {:.4}, \"ms_assembly\": {:.4}, \"ms_solve\": {:.4}, \
         \"ms_line_search\": {:.4}, \"newton_iterations_mean\": {:.4}, \
         \"unconverged_steps\": {}, \"max_pin_deviation\": {:.4e}, \"max_held_deviation\": {:.4e}, \"end_drift\": {:.4e}, \"exact_inset\": {:.4}, \"basis_seconds\": {:.4}, \
         \"setup_seconds\": {:.4}, \
         \"quadrature\": {{\"kind\": \"{}\", \"points\": {}}}}}",
        s.basis_points,
        s.simulation_points,
        tips.join(", "),
        per_step(m.stepping),
        per_step(m.timings.assembly),
        per_step(m.timings.solve),
        per_step(m.timings.line_search),
        m.iterations as f64 / steps as f64,
        m.unconverged,
        m.pin_deviation,
        m.held_deviation,
        m.end_drift,
        s.inset,
        s.basis_seconds,
        s.setup_seconds,
        s.quadrature.kind,
        s.quadrature.points,
    );
}

fn print_text(s: &Setup, m: &Measured) {
    let Args {
        modes,
        kernels,
        steps,
        ..
    } = *s.args;
    let per_step = |t: f64| 1e3 * t / steps as f64;
    println!(
        "beam Bend, m = {modes}, K = {kernels}, basis on {} points, simulated on {} points",
        s.basis_points, s.simulation_points
    );
    println!(
        "basis {:.2} s, model setup {:.2} s; elastic energy on {} {} points",
        s.basis_seconds, s.setup_seconds, s.quadrature.points, s.quadrature.kind
    );
    if let Some(r) = &s.quadrature.cubature {
        println!(
            "cubature: {} points from {} training poses in {:.2} s, force error {:.2e} \
             (training) / {:.2e} (unseen poses), Σw/V = {:.3}; stopped because {}",
            r.points,
            r.training_poses,
            r.seconds,
            r.training_error,
            r.validation_error,
            r.weight_over_volume,
            r.stop.describe()
        );
    }
    for (k, v) in &m.tip_y {
        println!("tip y at t = {k} s: {v:.6} m");
    }
    println!(
        "{:.2} ms/step (assembly {:.2}, solve {:.2}, line search {:.2}), \
         {:.2} Newton iterations/step, {} unconverged steps, \
         pinned points within {:.2e} m of their targets",
        per_step(m.stepping),
        per_step(m.timings.assembly),
        per_step(m.timings.solve),
        per_step(m.timings.line_search),
        m.iterations as f64 / steps as f64,
        m.unconverged,
        m.pin_deviation
    );
}

fn run() -> Result<(), String> {
    let args: Args = clap::Parser::parse();
    if args.modes == 0 || args.kernels == 0 || args.basis_points == 0 || args.sim_points == 0 {
        return Err("--modes, --kernels, --basis-points and --points must be positive".into());
    }
    let material = MaterialSample {
        youngs_modulus: 5e6,
        poisson_ratio: 0.45,
        density: 1000.0,
    };
    let lame = LameParameters::from_young_poisson(material.youngs_modulus, material.poisson_ratio)
        .map_err(|e| e.to_string())?;

    let t = Instant::now();
    let BeamBasis {
        basis_grid,
        points,
        basis,
        inset,
    } = build_beam_basis(&args, lame)?;
    let basis_seconds = t.elapsed().as_secs_f64();

    let t = Instant::now();
    let model = ReducedModel::new(
        &basis,
        &points,
        &vec![material; points.len()],
        StableNeoHookean,
    )
    .map_err(|e| e.to_string())?;
    let rule = if args.full_quadrature {
        QuadratureRule::PAPER
    } else {
        QuadratureRule::default()
    };
    let (model, quadrature) = rule.apply(model).map_err(|e| e.to_string())?;
    let scene = beam_scene(&model, args.exact, inset);
    let mut sim =
        Simulator::new(model, &scene, simulation_params(&args)).map_err(|e| e.to_string())?;
    let lattice: Vec<Vector3<f64>> = (0..11)
        .flat_map(|a| (0..11).map(move |b| Vector3::new(5.0, a as f64 / 10.0, b as f64 / 10.0)))
        .collect();
    let setup_seconds = t.elapsed().as_secs_f64();

    let measured = step_through(&mut sim, &basis, &lattice, args.steps)?;
    let setup = Setup {
        args: &args,
        basis_points: basis_grid.len(),
        simulation_points: sim.model().rest_positions().len(),
        inset,
        basis_seconds,
        setup_seconds,
        quadrature: &quadrature,
    };
    if args.json {
        print_json(&setup, &measured);
    } else {
        print_text(&setup, &measured);
    }
    Ok(())
}

fn main() {
    if let Err(e) = run() {
        eprintln!("beam_bend: {e}");
        std::process::exit(1);
    }
}
