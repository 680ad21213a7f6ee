//! `freeform simulate`: a scene file through the library.

use std::path::Path;

use anyhow::Result;
use eval::progress::{BarProgress, Progress};
use freeform::{SceneFile, simulate_scene_file};

/// Runs `scene` and writes its frames under `<out>/<scene stem>/`, with the stress when
/// `stress` (or the file) asks for it.
pub(crate) fn run(
    scene: &Path,
    stress: bool,
    out: &Path,
    cache: &Path,
    progress: Progress,
) -> Result<()> {
    let mut file = SceneFile::load(scene)?;
    file.simulation.stress |= stress;
    let stem = scene.file_stem().unwrap_or_default().to_string_lossy();
    let out = out.join(stem.as_ref());
    let report = simulate_scene_file(&file, &out, Some(cache), &BarProgress::new(progress))?;
    println!(
        "{} frames written to {}; basis {:.2} s, {:.2} ms/step, {} unconverged \
         steps, final max displacement {:.4} m, deepest penetration {:.2e} m",
        report.frames_written,
        out.display(),
        report.basis_seconds,
        report.ms_per_step,
        report.unconverged_steps,
        report.final_max_displacement,
        report.max_penetration
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
