//! `freeform demo`: the beam Bend against the FEM ground truth.

use crate::plot_or_warn;
use optimize::{HessianReuse, NewtonParams};
use std::path::Path;
use std::time::Instant;

use anyhow::Result;
use artifact::write_atomically;
use eval::beam::reduced::{
    ReducedSettings, build_beam_basis, run_reduced_beam, run_reduced_beam_with,
};
use eval::beam::study::beam_length_scale;
use eval::beam::{BEAM_MAX, BeamTest, beam_material};
use eval::fem_reference::{FemResolution, run_fem_beam};
use eval::metrics::trajectory_errors;
use eval::progress::Progress;
use eval::report::plot::{AxisScale, PlotSpec, Series};
use fem_ref::ElementOrder;
use freeform::frames::unstructured_grid_vtk;
use nalgebra::Vector3;
use reduced_sim::QuadratureRule;

/// Runs the demo and prints (or writes as JSON) its result.
pub(crate) fn run(
    quick: bool,
    json: bool,
    out: &Path,
    cache: &Path,
    progress: &Progress,
) -> Result<()> {
    let start = Instant::now();
    // The library's defaults (cubature, Hessian reuse); the paper's setting is run beside them.
    let (settings, steps, fem) = if quick {
        (
            ReducedSettings {
                modes: 6,
                kernels: 200,
                basis_points: 3000,
                simulation_points: 1000,
                ..ReducedSettings::library_default()
            },
            20,
            FemResolution {
                order: ElementOrder::Quadratic,
                cells_per_metre: 2,
            },
        )
    } else {
        (
            ReducedSettings::library_default(),
            100,
            FemResolution::GROUND_TRUTH,
        )
    };
    let paper_settings = ReducedSettings {
        quadrature: QuadratureRule::PAPER,
        hessian_reuse: HessianReuse::Never,
        ..settings
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
    let run = run_reduced_beam_with(
        test,
        &basis.basis,
        &settings,
        beam_material(),
        Some(cache),
        &vertices,
        steps,
        progress,
    )?;
    let paper = run_reduced_beam(
        test,
        &basis.basis,
        &paper_settings,
        &vertices,
        steps,
        progress,
    )?;
    let fem_frames = reference.vertex_frames();
    let errors = trajectory_errors(&run.frames[1..], &fem_frames[1..], beam_length_scale())?;
    let paper_errors =
        trajectory_errors(&paper.frames[1..], &fem_frames[1..], beam_length_scale())?;
    let quadrature = &run.report.quadrature;

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
                unstructured_grid_vtk(&frames[step], &vertices, tets, times[step], None).as_bytes(),
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
        "simulation_points": run.report.simulation_points,
        "fem": fem.label(),
        "fem_dofs": reference.dofs,
        "fem_cached": reference.cached,
        "normalized_mse": errors.normalized_mse,
        "normalized_max": errors.normalized_max,
        "ours_ms_per_step": run.report.ms_per_step,
        "fem_ms_per_step": 1e3 * reference.seconds_per_step,
        "basis_seconds": basis.seconds,
        "tip_y_final": {"ours": ours_tip.last().map(|p| p.1), "fem": fem_tip.last().map(|p| p.1)},
        "tip_y_half_time": {"ours": ours_tip[steps / 2].1, "fem": fem_tip[steps / 2].1},
        "unconverged_steps": run.report.unconverged_steps,
        "quadrature": {"kind": quadrature.kind, "points": quadrature.points},
        "hessians_per_step": run.report.hessians_per_step,
        "paper_setting": {
            "normalized_mse": paper_errors.normalized_mse,
            "normalized_max": paper_errors.normalized_max,
            "ours_ms_per_step": paper.report.ms_per_step,
            "hessians_per_step": paper.report.hessians_per_step,
            "unconverged_steps": paper.report.unconverged_steps,
        },
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
            "FreeForm beam Bend, {steps} steps of 0.01 s: m = {}, K = {}, {} simulation points; \
             elastic energy on {} {} points, {:.2} Hessians per step",
            settings.modes,
            settings.kernels,
            run.report.simulation_points,
            quadrature.points,
            quadrature.kind,
            run.report.hessians_per_step
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
            run.report.ms_per_step,
            1e3 * reference.seconds_per_step,
            1e3 * reference.seconds_per_step / run.report.ms_per_step,
            run.report.unconverged_steps
        );
        println!(
            "the paper's setting (every point, a fresh Hessian every iteration): normalized MSE \
             {:.3e}, max {:.3e}, {:.2} ms/step ({:.0}× slower than the default step)",
            paper_errors.normalized_mse,
            paper_errors.normalized_max,
            paper.report.ms_per_step,
            paper.report.ms_per_step / run.report.ms_per_step
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
