//! `freeform simulate`: a scene file through the library.

use std::path::Path;

use anyhow::Result;
use freeform::terminal_progress::{BarProgress, TerminalProgress};
use freeform::{ObjectsFile, SceneFile, simulate_objects, simulate_scene_file};

use crate::output_frames::{RunOutput, SceneInfo};
use crate::preview::write_preview;
use crate::viewer_page::{ViewerParams, ViewerReport, write_viewer};

/// What `simulate` writes besides the frames.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct SimulateOptions {
    /// Write the stress whatever the scene file says.
    pub stress: bool,
    /// The viewer page's limits.
    pub viewer: ViewerParams,
}

/// Runs `scene` and writes its frames under `<out>/<scene stem>/`, with the stress when
/// `stress` (or the file) asks for it.
pub(crate) fn run(
    scene: &Path,
    options: &SimulateOptions,
    out: &Path,
    cache: &Path,
    progress: TerminalProgress,
) -> Result<()> {
    let stem = scene.file_stem().unwrap_or_default().to_string_lossy();
    let out = out.join(stem.as_ref());
    if ObjectsFile::describes(scene) {
        let mut file = ObjectsFile::load(scene)?;
        file.simulation.stress |= options.stress;
        run_objects(&file, &out, cache, progress)?;
        let info = SceneInfo::new(&file.scene, file.simulation.time_step);
        return write_views(&out, &info, &options.viewer);
    }
    let mut file = SceneFile::load(scene)?;
    file.simulation.stress |= options.stress;
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
                if !c.reached_tolerance {
                    eprintln!(
                        "note: the cubature stopped short of its force tolerance: {}",
                        c.stop.describe()
                    );
                }
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
    if let Some(stress) = &report.stress {
        println!(
            "stress written: largest von Mises {:.4e} Pa (output points {:.4e} Pa); {} inverted \
             points (stress written as 0, flagged `inverted`)",
            stress.max_von_mises, stress.max_von_mises_output, stress.most_inverted
        );
    }
    let info = SceneInfo::new(&file.scene, file.simulation.time_step);
    write_views(&out, &info, &options.viewer)
}

/// Writes `scene.json`, `preview.png` and `view.html` beside the frames in `out`.
fn write_views(out: &Path, info: &SceneInfo, viewer: &ViewerParams) -> Result<()> {
    info.write(out)?;
    let run = RunOutput::read(out)?;
    let png = out.join("preview.png");
    let colouring = write_preview(&run, &png)?;
    println!(
        "preview (the most stressed or last frame, and five across the run; coloured by {}): {}",
        colouring.scalar.map_or_else(
            || "the splats' own colours".to_string(),
            |s| format!("{} from 0 to {:.3e} {}", s.label(), colouring.max, s.unit())
        ),
        png.display()
    );
    print_viewer(&write_viewer(&run, viewer)?);
    Ok(())
}

/// Says where the viewer page is and what it holds.
pub(crate) fn print_viewer(report: &ViewerReport) {
    let dropped = if report.frames < report.frames_written {
        format!(
            " ({} of {} frames, the rest dropped to stay under the size limit)",
            report.frames, report.frames_written
        )
    } else {
        format!(" ({} frames)", report.frames)
    };
    println!(
        "viewer: {}, {:.1} MB{dropped}; open it in a browser",
        report.path.display(),
        report.bytes as f64 / 1e6
    );
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
    Ok(())
}
