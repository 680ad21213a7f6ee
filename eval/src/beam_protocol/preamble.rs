//! The preamble every beam table shares: the reduced settings, each FEM reference, the metrics;
//! and a score cell that says why a score is missing.

use std::fmt::Write as _;

use crate::beam_protocol::evaluation::FemSummary;
use crate::beam_protocol::failed_row::FailedBeamRow;
use crate::beam_protocol::study_config::BeamStudyConfig;
use crate::beam_scenario::{BeamTest, beam_length_scale};

/// The settings preamble of a beam table: the reduced settings, each FEM reference and the
/// runs that failed.
pub(crate) fn settings_lines(
    config: &BeamStudyConfig,
    fem: &[FemSummary],
    failed: &[FailedBeamRow],
) -> String {
    let s = &config.settings;
    let mut out = format!(
        "Settings: beam 5×1×1 m, E = 5 MPa, ν = 0.45, ρ = 1000 kg/m³, h = 0.01 s; K = {} kernels, \
         basis on ≈{} grid points, simulation on ≈{} grid points, Newton tolerance {:e}, {}. \
         Elastic quadrature: {}; Hessians: {}{}.\n",
        s.kernels,
        s.basis_points,
        s.simulation_points,
        s.newton_tolerance,
        s.pin_rule_label(),
        s.quadrature_label(),
        s.hessian_reuse_label(),
        s.pressure_label(),
    );
    for f in fem {
        let _ = writeln!(
            out,
            "FEM ground truth ({}): {}, {} steps, {} DOFs, {} vertices, {:.3} s/step, {:.1} Newton \
             it./step (largest {}), {} unconverged steps{}.{}",
            f.test.name(),
            f.resolution,
            f.steps,
            f.dofs,
            f.vertices,
            f.seconds_per_step,
            f.iterations_per_step,
            f.max_iterations,
            f.unconverged_steps,
            if f.cached {
                format!(
                    " (cached; s/step timed over {} fresh steps in this run)",
                    f.timed_steps
                )
            } else {
                String::new()
            },
            f.not_scored.as_ref().map_or(String::new(), |why| format!(
                " **{} not scored**: {why}.",
                f.test.name()
            ))
        );
    }
    for f in failed {
        let _ = writeln!(
            out,
            "**{} m = {} failed** (no row): {}.",
            f.test.name(),
            f.m,
            f.error
        );
    }
    let _ = writeln!(
        out,
        "Metrics (design §4.3) at the FEM vertices over frames 1..T, L = {} m: MSE = mean |x − x*|² / L², \
         max = max |x − x*| / L, fitting residual = mean |x(z*) − x*| / L.",
        beam_length_scale()
    );
    out
}

/// A score, or "not scored" when `test`'s reference in `fem` was refused (a step stopped
/// unconverged), or "not run".
pub(crate) fn score_or_why(v: Option<f64>, fem: &[FemSummary], test: BeamTest) -> String {
    match v {
        Some(v) => format!("{v:.2e}"),
        None if fem.iter().any(|f| f.test == test && f.not_scored.is_some()) => "not scored".into(),
        None => "not run".into(),
    }
}
