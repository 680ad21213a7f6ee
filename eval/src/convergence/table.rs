//! The convergence study as Markdown.

use std::fmt::Write as _;

use crate::convergence::POOL_TOLERANCE;
use crate::convergence::config::ConvergenceConfig;
use crate::convergence::options::{BoundaryTreatment, ConvergenceTest, VolumetricTerm};
use crate::convergence::result::{ConvergenceRow, ConvergenceStudy};

/// The study as Markdown: per (test, ν, K), MSE against m for every treatment (and the static
/// projections), then the coarse FEM points.
pub fn convergence_table(config: &ConvergenceConfig, study: &ConvergenceStudy) -> String {
    let mut md = format!(
        "## Convergence in m: beam against the FEM ({}; static Bend against {})\n\n\
         E = 5 MPa, ρ = 1000 kg/m³, {} simulation points, {}; static Bend at {} g. Cells: \
         normalized MSE (static: tip error in %, + too soft; and the MSE of the energy \
         projection of the FEM field onto the same subspace).\n\n",
        config.fem.label(),
        config.static_reference_resolution().label(),
        config.settings.simulation_points,
        config.settings.quadrature_label(),
        config.static_gravity_scale
    );
    for why in &study.refused_references {
        let _ = writeln!(md, "Not scored: {why}.\n");
    }
    for &test in &config.tests {
        for &nu in &config.poisson_ratios {
            for &kernels in &config.kernels {
                let _ = write!(md, "### {} ν = {nu} K = {kernels}\n\n| m |", test.name());
                let columns: Vec<(BoundaryTreatment, VolumetricTerm)> = config
                    .treatments
                    .iter()
                    .flat_map(|&t| config.volumetric.iter().map(move |&v| (t, v)))
                    .collect();
                for (t, v) in &columns {
                    let _ = write!(md, " {} {} |", t.name(), v.name());
                }
                md += "\n|---|";
                for _ in &columns {
                    md += "---|";
                }
                md += "\n";
                for &m in &config.modes {
                    let _ = write!(md, "| {m} |");
                    for &(t, v) in &columns {
                        let row = study.rows.iter().find(|r| {
                            r.test == test
                                && r.nu == nu
                                && r.kernels == kernels
                                && r.m == m
                                && r.treatment == t
                                && r.volumetric == v
                        });
                        md += &cell(row);
                    }
                    md += "\n";
                }
                md += "\n";
            }
        }
    }
    if !study.static_reference_checks.is_empty() {
        md += "### The static reference's own error\n\nThe static reference against a finer FEM \
               interpolated at its nodes: a static row whose MSE is below the reference's is \
               within the reference's own error.\n\n| ν | reference | finer | MSE | tip change \
               |\n|---|---|---|---|---|\n";
        for c in &study.static_reference_checks {
            let _ = writeln!(
                md,
                "| {} | {} | {} | {:.3e} | {:+.2}% |",
                c.nu,
                c.resolution,
                c.finer,
                c.mse,
                100.0 * c.tip_change
            );
        }
        md += "\n";
    }
    if !study.pool_checks.is_empty() {
        let _ = write!(
            md,
            "### Integration pool\n\nThe first 2m weight-space eigenvalues with the same kernels \
             on the basis grid and on one of twice the points; converged when none moves by more \
             than {POOL_TOLERANCE:e}.\n\n| K | points | finer points | eigenvalues | largest \
             relative change | converged |\n|---|---|---|---|---|---|\n"
        );
        for p in &study.pool_checks {
            let _ = writeln!(
                md,
                "| {} | {} | {} | {} | {:.2e} | {} |",
                p.check.kernels,
                p.check.points,
                p.check.finer_points,
                p.eigenvalues,
                p.check.max_relative_change,
                if p.converged { "yes" } else { "no" }
            );
        }
        md += "\n";
    }
    if !study.coarse_fem.is_empty() {
        md += "### Coarse FEM, dynamic Bend ν = 0.45\n\n| FEM | MSE | ms/step |\n|---|---|---|\n";
        for c in &study.coarse_fem {
            let _ = writeln!(
                md,
                "| {} | {:.3e} | {:.1} |",
                c.resolution, c.mse, c.ms_per_step
            );
        }
    }
    md
}

/// A row's cell: its MSE, and for the static test its tip error and the energy projection's
/// MSE; "failed" or "—" (not run).
fn cell(row: Option<&ConvergenceRow>) -> String {
    match row {
        Some(r) if r.failure.is_none() => {
            if r.test == ConvergenceTest::StaticBend {
                let best = r
                    .best_energy
                    .map_or("not computed".to_string(), |e| format!("{e:.2e}"));
                format!(
                    " {:.3e} ({:+.2}%; best E {best}) |",
                    r.mse,
                    100.0 * r.tip_ratio
                )
            } else {
                format!(" {:.3e} |", r.mse)
            }
        }
        Some(_) => " failed |".to_string(),
        None => " — |".to_string(),
    }
}
