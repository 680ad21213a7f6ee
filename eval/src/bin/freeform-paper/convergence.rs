//! `freeform-paper convergence`: the convergence study in m.

use crate::plot_or_warn;
use crate::preset_args::PresetArgs;
use std::path::Path;

use anyhow::Result;
use artifact::write_atomically;
use eval::convergence::{
    ConvergenceConfig, ConvergenceStudy, ConvergenceTest, convergence_table, run_convergence,
};
use eval::presets::{StudyKind, set_folder};
use eval::report::plot::{AxisScale, PlotSpec, Series};
use freeform::terminal_progress::TerminalProgress;

/// Runs the study, prints its table (or one JSON row per run) and writes `convergence.md`,
/// `convergence.json` and a plot of error against m per test under `out`.
pub(crate) fn run(
    preset: &PresetArgs,
    json: bool,
    cache: &Path,
    out: &Path,
    progress: &TerminalProgress,
) -> Result<()> {
    let config: ConvergenceConfig = preset
        .load("convergence")?
        .config(StudyKind::Convergence, |table| {
            set_folder(table, "cache_dir", cache)
        })?;
    let study = run_convergence(&config, progress)?;
    let md = convergence_table(&config, &study);
    let data =
        serde_json::to_string_pretty(&serde_json::json!({"config": config, "study": study}))?;
    std::fs::create_dir_all(out)?;
    write_atomically(&out.join("convergence.md"), md.as_bytes())?;
    write_atomically(&out.join("convergence.json"), data.as_bytes())?;
    for &test in &config.tests {
        plot_or_warn(
            &error_against_m(&config, &study, test),
            &out.join(format!("convergence_{}", test.name())),
        );
    }
    if json {
        for row in &study.rows {
            println!("{}", serde_json::to_string(row)?);
        }
    } else {
        println!("{md}");
    }
    Ok(())
}

/// Normalized MSE against m, one series per (treatment, ν, K), and the static test's energy
/// projections.
fn error_against_m(
    config: &ConvergenceConfig,
    study: &ConvergenceStudy,
    test: ConvergenceTest,
) -> PlotSpec {
    let mut series = Vec::new();
    for &treatment in &config.treatments {
        for &volumetric in &config.volumetric {
            for &nu in &config.poisson_ratios {
                for &kernels in &config.kernels {
                    let rows = || {
                        study.rows.iter().filter(move |r| {
                            r.test == test
                                && r.treatment == treatment
                                && r.volumetric == volumetric
                                && r.nu == nu
                                && r.kernels == kernels
                                && r.failure.is_none()
                        })
                    };
                    let color = series.len();
                    series.push(Series {
                        label: format!(
                            "{} {} ν={nu} K={kernels}",
                            treatment.name(),
                            volumetric.name()
                        ),
                        points: rows().map(|r| (r.m as f64, r.mse)).collect(),
                        line: true,
                        color,
                    });
                    if test == ConvergenceTest::StaticBend {
                        series.push(Series {
                            label: format!(
                                "{} {} ν={nu} K={kernels}: energy projection",
                                treatment.name(),
                                volumetric.name()
                            ),
                            points: rows()
                                .filter_map(|r| r.best_energy.map(|e| (r.m as f64, e)))
                                .collect(),
                            line: false,
                            color,
                        });
                    }
                }
            }
        }
    }
    PlotSpec {
        title: format!("{}: error against m", test.name()),
        x_label: "modes m".into(),
        y_label: "normalized MSE".into(),
        scale: AxisScale::LogLog,
        series,
    }
}
