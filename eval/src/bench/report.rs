//! The bench's results: one [`BenchResult`] per run, the Pareto front, the CSV and Markdown, and
//! the headline plot.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::EvalError;
use crate::bench::config::BenchConfig;
use crate::particle_baselines::particle_baseline::ParticleMethod;
use crate::report::plot::{AxisScale, PlotSpec, Series};
use artifact::write_atomically;

/// The bench's knob names with their plot labels, in plot order.
const FREEFORM_SERIES: [(&str, &str); 11] = [
    ("m", "FreeForm, varying m"),
    ("K", "FreeForm, varying K"),
    ("points", "FreeForm, varying points"),
    ("tolerance", "FreeForm, varying tolerance"),
    ("pin factor", "FreeForm, varying pin factor"),
    ("Hessian reuse", "FreeForm with Hessian reuse, varying m"),
    ("cubature", "FreeForm on a cubature, varying m"),
    (
        "cubature + reuse",
        "FreeForm on a cubature with Hessian reuse, varying m",
    ),
    (
        "quadrature points",
        "FreeForm m=16 on fewer points (cubature tolerance, random subsets)",
    ),
    (
        "exact pins",
        "FreeForm, exact pins, cubature with Hessian reuse, varying m",
    ),
    (
        "basis grid",
        "FreeForm on a cubature of the basis grid with Hessian reuse, varying m",
    ),
];

/// One timed configuration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BenchResult {
    /// "freeform", "simplicits" or "fem".
    pub method: String,
    /// The knob varied ("m", "K", "points", "tolerance", "pin factor", "FEM").
    pub knob: String,
    /// Human-readable settings.
    pub label: String,
    /// Wall time per step (ms).
    pub ms_per_step: f64,
    /// Of which Hessian/gradient assembly, factorization and solve, line search (ms; 0 for the
    /// FEM, whose split is not recorded here).
    pub ms_split: [f64; 3],
    /// Hessians assembled per step (1 for the FEM, which assembles every iteration's).
    pub hessians_per_step: f64,
    /// Points the elastic energy is evaluated at (FreeForm and Simplicits; 0 for the FEM).
    pub quadrature_points: usize,
    /// One-off cost before stepping: basis build and quadrature for FreeForm, training for
    /// Simplicits (from the run that produced the cached network) (s); 0 for FEM.
    pub setup_seconds: f64,
    /// Normalized MSE against the ground truth.
    pub normalized_mse: f64,
    /// Normalized max error.
    pub normalized_max: f64,
    /// Largest distance (m) of a ground-truth vertex in the clamped end from its rest position
    /// over the run (0 for the FEM, which holds them).
    #[serde(default)]
    pub region_drift: f64,
    /// On the Pareto front of (ms per step, MSE).
    pub pareto: bool,
}

/// Indices of the results no other result beats in both time and error.
pub fn pareto_front(points: &[(f64, f64)]) -> Vec<usize> {
    (0..points.len())
        .filter(|&i| {
            !(0..points.len()).any(|j| {
                j != i
                    && points[j].0 <= points[i].0
                    && points[j].1 <= points[i].1
                    && (points[j].0 < points[i].0 || points[j].1 < points[i].1)
            })
        })
        .collect()
}

/// Writes `bench.csv` and `bench.md` under `dir`; returns the Markdown and the paths.
///
/// # Errors
/// [`EvalError`] for a file that cannot be written.
pub fn write_bench(
    results: &[BenchResult],
    config: &BenchConfig,
    dir: &Path,
) -> Result<(String, Vec<PathBuf>), EvalError> {
    let mut csv = String::from(
        "method,knob,label,ms_per_step,ms_assembly,ms_solve,ms_line_search,hessians_per_step,quadrature_points,setup_seconds,normalized_mse,normalized_max,region_drift,pareto\n",
    );
    let mut md = format!(
        "## Error vs time, beam Bend ({} steps; ground truth FEM {}; {} threads)\n\n\
         | method | knob | settings | ms/step | assembly / solve / line search | Hessians/step | setup s | MSE | max | clamp drift (mm) | Pareto |\n|---|---|---|---|---|---|---|---|---|---|---|\n",
        config.steps,
        config.ground_truth.label(),
        rayon::current_num_threads()
    );
    for r in results {
        let _ = writeln!(
            csv,
            "{},{},\"{}\",{},{},{},{},{},{},{},{:e},{:e},{:e},{}",
            r.method,
            r.knob,
            r.label,
            r.ms_per_step,
            r.ms_split[0],
            r.ms_split[1],
            r.ms_split[2],
            r.hessians_per_step,
            r.quadrature_points,
            r.setup_seconds,
            r.normalized_mse,
            r.normalized_max,
            r.region_drift,
            r.pareto
        );
        let _ = writeln!(
            md,
            "| {} | {} | {} | {:.2} | {:.2} / {:.2} / {:.2} | {:.2} | {:.1} | {:.2e} | {:.2e} | {:.1} | {} |",
            r.method,
            r.knob,
            r.label,
            r.ms_per_step,
            r.ms_split[0],
            r.ms_split[1],
            r.ms_split[2],
            r.hessians_per_step,
            r.setup_seconds,
            r.normalized_mse,
            r.normalized_max,
            1e3 * r.region_drift,
            if r.pareto { "★" } else { "" }
        );
    }
    let mut written = Vec::new();
    for (name, text) in [("bench.csv", &csv), ("bench.md", &md)] {
        let path = dir.join(name);
        write_atomically(&path, text.as_bytes())?;
        written.push(path);
    }
    Ok((md, written))
}

/// The headline figure: normalized MSE against ms per step, log-log, one colour per knob, the
/// coarser FEM levels, and the Pareto front as a line. Draw it with
/// [`crate::report::plot::write_plot`].
pub fn bench_plot(results: &[BenchResult], config: &BenchConfig) -> PlotSpec {
    let mut series: Vec<Series> = Vec::new();
    for (i, (knob, label)) in FREEFORM_SERIES.into_iter().enumerate() {
        let mut points: Vec<(f64, f64)> = results
            .iter()
            .filter(|r| r.method == "freeform" && r.knob == knob)
            .map(|r| (r.ms_per_step, r.normalized_mse))
            .collect();
        if points.is_empty() {
            continue;
        }
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        series.push(Series {
            label: label.into(),
            points,
            line: false,
            // Colours 5-7 are the front, the coarser FEM and Simplicits; 14 and 15 MPM and
            // SPH; 13 is too pale to read (Palette99).
            color: match i {
                0..5 => i,
                5..10 => 8 + i - 5,
                _ => 18 + i - 10,
            },
        });
    }
    let mut simplicits: Vec<(f64, f64)> = results
        .iter()
        .filter(|r| r.method == "simplicits")
        .map(|r| (r.ms_per_step, r.normalized_mse))
        .collect();
    if !simplicits.is_empty() {
        simplicits.sort_by(|a, b| a.0.total_cmp(&b.0));
        series.push(Series {
            label: "Simplicits, varying m".into(),
            points: simplicits,
            line: false,
            color: 7,
        });
    }
    let fem: Vec<(f64, f64)> = results
        .iter()
        .filter(|r| r.method == "fem")
        .map(|r| (r.ms_per_step, r.normalized_mse))
        .collect();
    if !fem.is_empty() {
        series.push(Series {
            label: "coarser FEM (P1/P2)".into(),
            points: fem,
            line: false,
            color: 6,
        });
    }
    for (method, color) in [(ParticleMethod::Mpm, 14), (ParticleMethod::Sph, 15)] {
        let points: Vec<(f64, f64)> = results
            .iter()
            .filter(|r| r.method == method.key())
            .map(|r| (r.ms_per_step, r.normalized_mse))
            .collect();
        if !points.is_empty() {
            series.push(Series {
                label: format!("{}, varying {}", method.label(), method.spacing_name()),
                points,
                line: false,
                color,
            });
        }
    }
    let mut front: Vec<(f64, f64)> = results
        .iter()
        .filter(|r| r.pareto)
        .map(|r| (r.ms_per_step, r.normalized_mse))
        .collect();
    front.sort_by(|a, b| a.0.total_cmp(&b.0));
    // First, so the markers of every configuration are drawn over the front's line.
    series.insert(
        0,
        Series {
            label: "Pareto front".into(),
            points: front,
            line: true,
            color: 5,
        },
    );
    PlotSpec {
        title: format!(
            "Beam Bend: error vs time per step (truth: FEM {})",
            config.ground_truth.label()
        ),
        x_label: "ms per 0.01 s step (this machine)".into(),
        y_label: "normalized MSE vs FEM".into(),
        scale: AxisScale::LogLog,
        series,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pareto_front_keeps_exactly_the_undominated_points() {
        let points = [
            (1.0, 5.0),
            (2.0, 3.0),
            (3.0, 4.0),
            (4.0, 1.0),
            (2.0, 3.0),
            (5.0, 1.0),
        ];
        // (3,4) is beaten by (2,3); (5,1) by (4,1); the duplicate (2,3) pair dominate nothing
        // of each other.
        assert_eq!(pareto_front(&points), vec![0, 1, 3, 4]);
    }
}
