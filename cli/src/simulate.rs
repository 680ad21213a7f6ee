//! `freeform simulate`: a scene file through the library.

use std::path::Path;

use anyhow::Result;
use freeform::terminal_progress::{BarProgress, TerminalProgress};
use freeform::{
    Geometry, ObjectsFile, SceneFile, SimulateReport, points_preview, simulate_objects,
    simulate_scene_file,
};
use nalgebra::Vector3;

use crate::render::write_png;

/// Runs `scene` and writes its frames under `<out>/<scene stem>/`, with the stress when
/// `stress` (or the file) asks for it.
pub(crate) fn run(
    scene: &Path,
    stress: bool,
    out: &Path,
    cache: &Path,
    progress: TerminalProgress,
) -> Result<()> {
    let stem = scene.file_stem().unwrap_or_default().to_string_lossy();
    let out = out.join(stem.as_ref());
    if ObjectsFile::describes(scene) {
        if stress {
            anyhow::bail!("--stress: stress output is not written for several objects yet");
        }
        return run_objects(&ObjectsFile::load(scene)?, &out, cache, progress);
    }
    let mut file = SceneFile::load(scene)?;
    file.simulation.stress |= stress;
    let report = simulate_scene_file(&file, &out, Some(cache), &BarProgress::new(progress))?;
    println!(
        "{} frames written to {}; basis {:.2} s, {:.2} ms/step (assembly {:.2}, solve {:.2}, \
         line search {:.2}), {:.1} Newton iterations ({:.2} Hessians) per step, {} unconverged \
         steps, final max displacement {:.4} m, deepest penetration {:.2e} m",
        report.frames_written,
        out.display(),
        report.basis_seconds,
        report.ms_per_step,
        report.ms_split_per_step[0],
        report.ms_split_per_step[1],
        report.ms_split_per_step[2],
        report.iterations_per_step,
        report.hessians_per_step,
        report.unconverged_steps,
        report.final_max_displacement,
        report.max_penetration
    );
    println!(
        "mechanical energy {:.4e} J at the start, {:.4e} J at the end; largest rise over a step \
         {:.2e} J",
        report.energy[0], report.energy[1], report.max_energy_rise
    );
    if let Some(q) = &report.quadrature {
        match &q.cubature {
            Some(c) => {
                println!(
                    "elastic quadrature: cubature of {} of {} points, {} to force error {:.1e} \
                     (unseen poses {:.1e})",
                    q.points,
                    report.simulation_points,
                    if c.cached {
                        "loaded from the cache".to_string()
                    } else {
                        format!("optimized in {:.2} s", c.seconds)
                    },
                    c.training_error,
                    c.validation_error
                );
                if let Some(warning) = &c.cache_warning {
                    eprintln!("warning: the cubature was not cached: {warning}");
                }
            }
            None => println!("elastic quadrature: {} ({} points)", q.kind, q.points),
        }
        if let Some(choice) = &q.choice
            && !choice.chose_cubature
        {
            let why = if choice.noted_over_budget {
                format!(
                    "an earlier run's cubature training ran out of its budget on a run predicted \
                     at least half as long; this run's elastic work on every point is predicted \
                     at {:.2} s",
                    choice.predicted_full_seconds
                )
            } else {
                format!(
                    "the run's elastic work on every point was predicted at {:.2} s, and \
                     training stopped after {:.2} s, past the {:.2} s a cubature of its size \
                     could still save",
                    choice.predicted_full_seconds, choice.spent_seconds, choice.budget_seconds
                )
            };
            println!("  (automatic quadrature: every point, since {why})");
        }
    }
    if !report.final_positions.is_empty() {
        let png = out.join("preview.png");
        write_preview(&report, &file, &png)?;
        println!(
            "preview of the last frame{}: {}",
            if report.final_von_mises.is_some() {
                " coloured by von Mises stress (blue 0, white half, red the 98th percentile)"
            } else {
                ""
            },
            png.display()
        );
    }
    if let Some(stress) = &report.stress {
        println!(
            "stress written: largest von Mises {:.4e} Pa (output points {:.4e} Pa); {} inverted \
             points (stress written as 0, flagged `inverted`)",
            stress.max_von_mises, stress.max_von_mises_output, stress.most_inverted
        );
    }
    Ok(())
}

/// Runs a scene of several objects and writes their frames under `out/<object>/`.
fn run_objects(
    file: &ObjectsFile,
    out: &Path,
    cache: &Path,
    progress: TerminalProgress,
) -> Result<()> {
    let report = simulate_objects(file, out, Some(cache), &BarProgress::new(progress))?;
    println!(
        "{} objects, {} frames each written under {}; setup {:.2} s, {:.2} ms/step \
         (assembly {:.2}, solve {:.2}, line search {:.2}, contact search {:.2}), {:.1} Newton \
         iterations ({:.1} Hessians, {:.1} line-search cuts) and {:.2} joint solves per step, \
         {} unconverged steps",
        report.objects.len(),
        report.frames_written,
        out.display(),
        report.setup_seconds,
        report.ms_per_step,
        report.ms_split_per_step[0],
        report.ms_split_per_step[1],
        report.ms_split_per_step[2],
        report.ms_split_per_step[3],
        report.iterations_per_step,
        report.hessians_per_step,
        report.line_search_cuts_per_step,
        report.joint_solves_per_step,
        report.unconverged_steps
    );
    println!(
        "deepest penetration {:.2e} m (between objects: {:.2e} m into the contact shell); \
         closest samples of different objects {}",
        report.max_penetration,
        report.max_contact_overlap,
        report
            .min_contact_gap
            .map_or("never within the contact radius".into(), |g| format!(
                "{g:.2e} m (contact radius {} m)",
                file.contact.radius
            ))
    );
    println!(
        "mechanical energy {:.4e} J at the start, {:.4e} J at the end; largest rise over a step \
         {:.2e} J",
        report.energy[0], report.energy[1], report.max_energy_rise
    );
    for o in &report.objects {
        println!(
            "  {}: {} points, {} quadrature points, {} contact samples, basis {:.2} s",
            o.name, o.simulation_points, o.quadrature.points, o.contact_samples, o.basis_seconds
        );
    }
    // The objects (red) with the surfaces of the colliders at the last frame (blue).
    let end = file.simulation.steps as f64 * file.simulation.time_step;
    let mut points = report.final_positions.clone();
    let mut values = vec![1.0; points.len()];
    let colliders = freeform::ColliderFrames::new(out, &file.scene.colliders);
    for surface in colliders.surfaces_at(end) {
        if let Ok(mesh) = rkpm_core::TriangleMesh::new(surface.vertices, surface.triangles) {
            let spacing = 0.02 * mesh.bounding_box().largest_side();
            for p in Geometry::Surface(mesh).contact_samples(spacing) {
                points.push(p);
                values.push(0.0);
            }
        }
    }
    let png = out.join("preview.png");
    // The colliders faint, so the objects inside show through.
    let opacity: Vec<f64> = values
        .iter()
        .map(|&v| if v > 0.0 { 1.0 } else { 0.06 })
        .collect();
    write_points_preview(
        &points,
        Some(&values),
        Some(&opacity),
        file.scene.gravity,
        &png,
    )?;
    println!(
        "preview of the last frame (objects red, colliders blue): {}",
        png.display()
    );
    Ok(())
}

/// Draws the last frame's output points (512² pixels) as round splats about as wide as their
/// spacing on the surface, coloured by their von Mises stress when the run computed it, seen
/// from 30° about and 20° above the scene's up (against gravity, else +y).
fn write_preview(report: &SimulateReport, file: &SceneFile, png: &Path) -> Result<()> {
    write_points_preview(
        &report.final_positions,
        report.final_von_mises.as_deref(),
        None,
        file.scene.gravity,
        png,
    )
}

/// `write_preview` of `points` (m) with their `values` (colour scale) or grey, opaque or
/// with the given opacities (0 … 1), seen about the scene's up (against gravity, else +y).
fn write_points_preview(
    points: &[Vector3<f64>],
    values: Option<&[f64]>,
    opacity: Option<&[f64]>,
    gravity: Option<Vector3<f64>>,
    png: &Path,
) -> Result<()> {
    let up = gravity
        .filter(|g| g.norm() > 0.0)
        .map_or(Vector3::y(), |g| -g.normalize());
    write_png(&points_preview(points, values, opacity, up, 512, 512)?, png)
}
