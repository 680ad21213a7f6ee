//! The Twist error frame by frame against the FEM, for ours, Simplicits and the particle
//! baselines.

use crate::beam::study::BeamStudy;
use crate::beam_scenario::{BEAM_TIME_STEP, BeamTest};
use crate::report::plot::{AxisScale, PlotSpec, Series};

/// The Twist error frame by frame: normalized MSE of each frame against the FEM for ours and
/// Simplicits at every m of the study (the paper's Twist rows are averages of these curves),
/// with t = frame · h on the x axis. `None` when the study has no scored Twist row.
pub fn twist_error_plot(study: &BeamStudy) -> Option<PlotSpec> {
    let curve = |per_frame: &[f64]| -> Vec<(f64, f64)> {
        per_frame
            .iter()
            .enumerate()
            .map(|(i, &e)| ((i + 1) as f64 * BEAM_TIME_STEP, e))
            .collect()
    };
    let mut series = Vec::new();
    for (k, r) in study
        .rows
        .iter()
        .filter(|r| r.test == BeamTest::Twist)
        .enumerate()
    {
        series.push(Series {
            label: format!("FreeForm m = {}", r.m),
            points: curve(&r.ours_per_frame_mse),
            line: true,
            color: 2 * k,
        });
        if let Some(s) = &r.simplicits {
            series.push(Series {
                label: format!("Simplicits m = {}", r.m),
                points: curve(&s.per_frame_mse),
                line: true,
                color: 2 * k + 1,
            });
        }
    }
    for (k, p) in study
        .particle_baselines
        .iter()
        .filter(|p| p.test == BeamTest::Twist && !p.per_frame_mse.is_empty())
        .enumerate()
    {
        series.push(Series {
            label: format!(
                "{} {} = {} m",
                p.method.label(),
                p.method.spacing_name(),
                p.spacing
            ),
            points: curve(&p.per_frame_mse),
            line: true,
            color: 13 + k,
        });
    }
    (!series.is_empty()).then(|| PlotSpec {
        title: "Beam Twist: error per frame against the FEM".into(),
        x_label: "t (s)".into(),
        y_label: "normalized MSE of the frame".into(),
        scale: AxisScale::LogY,
        series,
    })
}
