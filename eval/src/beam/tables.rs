//! The beam tables (1, 5, 6; 3 and 4 in [`crate::ablation::tables`]) as Markdown (ours beside
//! the paper's), JSON and CSV, and the Twist error-per-frame plot.

use std::fmt::Write as _;

use serde_json::{Value, json};

use crate::beam::study::{BeamRow, BeamStudy};
use crate::beam_protocol::preamble::settings_lines;
use crate::beam_scenario::{BEAM_TIME_STEP, BeamTest};
use crate::particle_baselines::particle_baseline::ParticleMethod;
use crate::report::paper;
use crate::report::plot::{AxisScale, PlotSpec, Series};
use crate::report::table::{RenderedTable, not_run_or, sci};

fn optional(v: Option<f64>) -> String {
    v.map_or(String::new(), |v| format!("{v:e}"))
}

/// How the Simplicits column was produced (or that it was not).
fn simplicits_line(study: &BeamStudy) -> String {
    match &study.config.simplicits {
        None => "\nSimplicits (ours) was not run (`--skip-simplicits`).\n".into(),
        Some(p) => {
            let seconds: Vec<String> = study
                .rows
                .iter()
                .filter(|r| r.test.name() == "bend")
                .filter_map(|r| {
                    r.simplicits
                        .as_ref()
                        .map(|s| format!("m={}: {:.0} s", r.m, s.training_seconds))
                })
                .collect();
            format!(
                "\nSimplicits (ours): the baseline of design §3.9 trained on the same grid as our basis \
                 ({} Adam steps of {} points × {} transforms; training time {}), simulated by the same \
                 reduced simulator and scene.\n",
                p.steps,
                p.points_per_step,
                p.transforms_per_step,
                seconds.join(", ")
            )
        }
    }
}

/// A particle method's cell of `r`: the particle methods do not depend on m, so each one's
/// finest scored spacing goes beside the paper's m = 9 value (empty on other rows, or when the
/// study did not run the method).
fn particle_cell(
    study: &BeamStudy,
    r: &BeamRow,
    method: ParticleMethod,
    configured: bool,
) -> String {
    if r.m != 9 || !configured {
        return String::new();
    }
    study
        .particle_baselines
        .iter()
        .filter(|p| p.method == method && p.test == r.test && p.mse.is_some())
        .min_by(|a, b| a.spacing.total_cmp(&b.spacing))
        .map_or("not scored".into(), |p| {
            format!(
                "{:.2e} ({} {} m)",
                p.mse.unwrap_or(f64::NAN),
                method.spacing_name(),
                p.spacing
            )
        })
}

/// Table 1: normalized MSE of ours against FEM for each (test, m), beside the paper's columns,
/// with both pin treatments (penalty, and exact when the study ran it) and their drifts.
pub fn table1(study: &BeamStudy) -> RenderedTable {
    let mut md = String::from("## Table 1: normalized MSE against FEM (beam)\n\n");
    md += &settings_lines(&study.config, &study.fem);
    md += &exact_line(study);
    md += "\n| test | m | ours MSE | ours max | pin drift held / region (mm) | exact MSE | exact max | exact drift held / region (mm) | paper FreeForm | paper Simplicits | Simplicits (ours) | MPM (ours, m = 9 rows) | MPM (paper) | SPH (ours, m = 9 rows) | SPH (paper) |\n";
    md += "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
    let mut csv = String::from(
        "test,m,ours_mse,ours_max,exact_mse,exact_max,exact_max_pin_deviation,simplicits_mse,simplicits_max,paper_ours_mse,paper_simplicits_mse\n",
    );
    let mut rows = Vec::new();
    for r in &study.rows {
        let name = r.test.name();
        let paper_ours = paper::table1_ours(name, r.m);
        let paper_simplicits = paper::table1_simplicits(name, r.m);
        let particle = paper::TABLE1_PARTICLE
            .iter()
            .find(|p| p.0 == name && r.m == 9);
        let exact = r.exact.as_ref();
        let mpm = particle_cell(study, r, ParticleMethod::Mpm, study.config.mpm.is_some());
        let sph = particle_cell(study, r, ParticleMethod::Sph, study.config.sph.is_some());
        let _ = writeln!(
            md,
            "| {name} | {} | {:.2e} | {:.2e} | {:.1} / {:.1} | {} | {} | {} | {} | {} | {} | {mpm} | {} | {sph} | {} |",
            r.m,
            r.ours_mse,
            r.ours_max,
            1e3 * r.max_pin_deviation,
            1e3 * r.region_drift,
            not_run_or(exact.map(|e| e.mse)),
            not_run_or(exact.map(|e| e.max)),
            exact.map_or("not run".into(), |e| format!(
                "{:.1e} / {:.1}",
                1e3 * e.max_pin_deviation,
                1e3 * e.region_drift
            )),
            sci(paper_ours),
            sci(paper_simplicits),
            not_run_or(r.simplicits.as_ref().map(|s| s.mse)),
            sci(particle.map(|p| p.1)),
            sci(particle.map(|p| p.2)),
        );
        let _ = writeln!(
            csv,
            "{name},{},{:e},{:e},{},{},{},{},{},{},{}",
            r.m,
            r.ours_mse,
            r.ours_max,
            optional(exact.map(|e| e.mse)),
            optional(exact.map(|e| e.max)),
            optional(exact.map(|e| e.max_pin_deviation)),
            optional(r.simplicits.as_ref().map(|s| s.mse)),
            optional(r.simplicits.as_ref().map(|s| s.max)),
            paper_ours.map_or(String::new(), |v| format!("{v:e}")),
            paper_simplicits.map_or(String::new(), |v| format!("{v:e}"))
        );
        rows.push(json!({
            "test": name,
            "m": r.m,
            "ours_mse": r.ours_mse,
            "ours_max": r.ours_max,
            "paper_ours_mse": paper_ours,
            "paper_simplicits_mse": paper_simplicits,
            "simplicits_mse": r.simplicits.as_ref().map(|s| s.mse),
            "simplicits_max": r.simplicits.as_ref().map(|s| s.max),
            "simplicits_training_seconds": r.simplicits.as_ref().map(|s| s.training_seconds),
            "unconverged_steps": r.unconverged_steps,
            "max_pin_deviation": r.max_pin_deviation,
            "region_drift": r.region_drift,
            "exact_mse": exact.map(|e| e.mse),
            "exact_max": exact.map(|e| e.max),
            "exact_max_pin_deviation": exact.map(|e| e.max_pin_deviation),
            "exact_region_drift": exact.map(|e| e.region_drift),
            "exact_inset": exact.map(|e| e.inset),
            "exact_ms_per_step": exact.map(|e| e.ms_per_step),
            "exact_unconverged_steps": exact.map(|e| e.unconverged_steps),
        }));
    }
    md += &simplicits_line(study);
    md += &particle_baselines_section(study);
    let particle_baselines: Vec<Value> = study
        .particle_baselines
        .iter()
        .map(|p| {
            json!({"method": p.method, "test": p.test.name(), "spacing": p.spacing,
                "mse": p.mse, "max": p.max, "ms_per_step": p.ms_per_step,
                "failure": p.failure, "steps_completed": p.steps_completed,
                "particles": p.particles, "substeps_per_step": p.substeps_per_step,
                "max_pin_deviation": p.max_pin_deviation,
                "iterations_per_step": p.iterations_per_step,
                "setup_seconds": p.setup_seconds,
                "paper_mse": p.method.paper_mse(p.test.name())})
        })
        .collect();
    RenderedTable {
        number: 1,
        markdown: md,
        json: json!({"table": 1, "rows": rows, "particle_baselines": particle_baselines,
            "settings": settings_json(study)}),
        csv,
    }
}

/// Table 1's particle-baseline sections (MPM, SPH): how each was run and one row per
/// (test, spacing), or that it was not run.
fn particle_baselines_section(study: &BeamStudy) -> String {
    let mut md = String::new();
    match &study.config.mpm {
        None => md += "MPM (ours): not run (`--skip-mpm`); the paper's values are shown.\n",
        Some(mpm) => {
            let _ = write!(
                md,
                "\n### MPM (ours)\n\nExplicit APIC MPM as warp-mpm runs it (quadratic \
                 B-splines, {}, Δt = {:e} s), {} particles per grid cell on the beam grid, pinned \
                 and twisted regions by particle velocity enforcement; positions read at tracers \
                 placed at the FEM vertices (moved with the grid velocity; those in a pinned or \
                 twisted region onto its target, like the region's particles), scored like every \
                 other method. The paper's MPM is its m = 9 column.\n\n",
                mpm.material.name(),
                mpm.time_step,
                mpm.particles_per_cell.pow(3)
            );
            md += &particle_rows(study, ParticleMethod::Mpm);
        }
    }
    match &study.config.sph {
        None => md += "SPH (ours): not run (`--skip-sph`); the paper's values are shown.\n",
        Some(sph) => {
            let _ = write!(
                md,
                "\n### SPH (ours)\n\nImplicit corotated SPH of Kugelstadt et al. 2021 as \
                 SPlisHSPlasH runs it (cubic spline kernel, support {} × the particle spacing, \
                 corrected gradients fixed at rest, stretching solved against a matrix factored \
                 once, volume by conjugate gradients to {:e}, zero-energy-mode control α = {}, {} \
                 step(s) of Δt = {} s per 0.01 s frame, {} rest volumes), particles on a lattice at \
                 the stated spacing, pinned \
                 and twisted regions as prescribed particle positions; the FEM vertices carried by \
                 the particles' displacements through a linearly consistent interpolant (those in a \
                 pinned or twisted region put on its target), scored like every other method. The \
                 paper's SPH is its m = 9 column.\n\n",
                sph.params.support_over_spacing,
                sph.params.volume_tolerance,
                sph.params.zero_energy_alpha,
                sph.substeps,
                sph.params.time_step,
                sph.params.rest_volume.name()
            );
            md += &particle_rows(study, ParticleMethod::Sph);
        }
    }
    md
}

/// One particle method's rows of Table 1's section.
fn particle_rows(study: &BeamStudy, method: ParticleMethod) -> String {
    let mut md = format!(
        "| test | {} (m) | particles | MSE | max | pinned particles' drift (mm) | ms per 0.01 s | \
         steps per 0.01 s | solver iterations per step | setup (s) | paper {} MSE |\n\
         |---|---|---|---|---|---|---|---|---|---|---|\n",
        method.spacing_name(),
        method.label()
    );
    for p in study
        .particle_baselines
        .iter()
        .filter(|p| p.method == method)
    {
        let (mse, max) = match (&p.failure, p.mse, p.max) {
            (None, Some(mse), Some(max)) => (format!("{mse:.2e}"), format!("{max:.2e}")),
            (why, ..) => (
                format!(
                    "not scored: stopped after {} steps ({})",
                    p.steps_completed,
                    why.as_deref().unwrap_or("no score")
                ),
                "—".into(),
            ),
        };
        let _ = writeln!(
            md,
            "| {} | {} | {} | {mse} | {max} | {:.1} | {:.0}{} | {} | {} | {:.1} | {} |",
            p.test.name(),
            p.spacing,
            p.particles,
            1e3 * p.max_pin_deviation,
            p.ms_per_step,
            if p.cached { " (cached)" } else { "" },
            p.substeps_per_step,
            p.iterations_per_step
                .map_or("—".into(), |i| format!("{i:.0}")),
            p.setup_seconds,
            sci(method.paper_mse(p.test.name())),
        );
    }
    md
}

/// How the exact columns were produced (or that they were not).
fn exact_line(study: &BeamStudy) -> String {
    let inset = study
        .rows
        .iter()
        .find_map(|r| r.exact.as_ref().map(|e| e.inset));
    match (inset, study.config.exact_pins) {
        (Some(inset), Some(radii)) => format!(
            "Exact pins: each pinned or twisted region held exactly by its own handles \
             (a basis per test, built for the regions on compact B-spline kernels, modes vanishing \
             there), on the region shrunk by {inset:.3} m ({} median kernel radii); the points \
             between are kept by the penalty. Drift: held = the held integration points (penalty \
             columns: every pinned point), region = the FEM vertices of the whole region (what \
             the FEM holds exactly). The library's default is the penalty: across `freeform-paper pins` \
             (Bend and Twist, m = 16 / 32, three ν) the exact pins are more accurate in 2 of 10 \
             runs (README).\n",
            radii
        ),
        _ => "Exact pins: not run.\n".into(),
    }
}

/// Table 5: wall time per step on this machine for each m (Bend), the FEM step, and FEM/ours.
pub fn table5(study: &BeamStudy) -> RenderedTable {
    let fem = study.fem.iter().find(|f| f.test.name() == "bend");
    let fem_ms = fem.map(|f| 1e3 * f.seconds_per_step);
    let mut md = String::from("## Table 5: ms per 0.01 s step, beam Bend\n\n");
    md += &settings_lines(&study.config, &study.fem);
    md += &format!(
        "This machine: {} CPU threads (rayon). The paper's numbers are on a GPU.\n",
        rayon::current_num_threads()
    );
    md += "\n| m | ours ms/step | Newton it./step | Hessians/step | quadrature points | FEM/ours | Simplicits ms/step | paper FreeForm | paper Simplicits |\n|---|---|---|---|---|---|---|---|---|\n";
    let mut csv = String::from(
        "m,ours_ms_per_step,fem_ms_per_step,ratio,paper_ours_ms,paper_simplicits_ms\n",
    );
    let mut rows = Vec::new();
    for r in study.rows.iter().filter(|r| r.test.name() == "bend") {
        let ratio = fem_ms.map(|f| f / r.ms_per_step);
        let p = paper::table5(r.m);
        let _ = writeln!(
            md,
            "| {} | {:.2} | {:.2} | {:.2} | {} | {} | {} | {} | {} |",
            r.m,
            r.ms_per_step,
            r.iterations_per_step,
            r.hessians_per_step,
            r.quadrature
                .as_ref()
                .map_or("—".into(), |q| format!("{} ({})", q.points, q.kind)),
            ratio.map_or("—".into(), |v| format!("{v:.0}×")),
            r.simplicits
                .as_ref()
                .map_or("not run".into(), |s| format!("{:.2}", s.ms_per_step)),
            p.map_or("—".into(), |p| format!("{:.2}", p.1)),
            p.map_or("—".into(), |p| format!("{:.2}", p.0)),
        );
        let _ = writeln!(
            csv,
            "{},{},{},{},{},{}",
            r.m,
            r.ms_per_step,
            fem_ms.unwrap_or(f64::NAN),
            ratio.unwrap_or(f64::NAN),
            p.map_or(String::new(), |p| p.1.to_string()),
            p.map_or(String::new(), |p| p.0.to_string())
        );
        rows.push(
            json!({"m": r.m, "ours_ms_per_step": r.ms_per_step, "fem_over_ours": ratio,
            "quadrature": r.quadrature.as_ref().map(|q| json!({"kind": q.kind, "points": q.points})),
            "hessians_per_step": r.hessians_per_step,
            "simplicits_ms_per_step": r.simplicits.as_ref().map(|s| s.ms_per_step),
            "paper_ours_ms": p.map(|p| p.1), "paper_simplicits_ms": p.map(|p| p.0)}),
        );
    }
    let _ = writeln!(
        md,
        "| FEM ({}) | {} | | | | {:.1} (paper FEM) | |",
        fem.map_or("—".into(), |f| f.resolution.clone()),
        fem_ms.map_or("—".into(), |v| format!("{v:.1}")),
        paper::TABLE5_FEM_MS
    );
    let mut particle_baselines = Vec::new();
    for p in study
        .particle_baselines
        .iter()
        .filter(|p| p.test == BeamTest::Bend)
    {
        let method = p.method;
        let _ = writeln!(
            md,
            "| {} {} = {} m ({} particles, {} steps per 0.01 s) | {:.1} | | | | {:.1} (paper {}) | |",
            method.label(),
            method.spacing_name(),
            p.spacing,
            p.particles,
            p.substeps_per_step,
            p.ms_per_step,
            method.paper_ms(),
            method.label()
        );
        let _ = writeln!(
            csv,
            "{} {},{},{},{},,",
            method.key(),
            p.spacing,
            p.ms_per_step,
            fem_ms.unwrap_or(f64::NAN),
            fem_ms.map_or(f64::NAN, |f| f / p.ms_per_step)
        );
        particle_baselines.push(json!({"method": method, "spacing": p.spacing,
            "ms_per_step": p.ms_per_step, "particles": p.particles,
            "substeps_per_step": p.substeps_per_step, "split": p.split,
            "iterations_per_step": p.iterations_per_step, "setup_seconds": p.setup_seconds,
            "fem_over_baseline": fem_ms.map(|f| f / p.ms_per_step),
            "paper_ms": method.paper_ms()}));
    }
    if study.config.mpm.is_some() {
        md += "MPM: ms per 0.01 s of simulated time (its substeps of the stated Δt together).\n";
    }
    if study.config.sph.is_some() {
        md += "SPH: ms per 0.01 s step (one implicit step), setup (neighbourhoods, factorization) \
               left out.\n";
    }
    RenderedTable {
        number: 5,
        markdown: md,
        json: json!({"table": 5, "rows": rows, "fem_ms_per_step": fem_ms,
            "paper_fem_ms": paper::TABLE5_FEM_MS, "particle_baselines": particle_baselines,
            "paper_mpm_ms": paper::TABLE5_MPM_MS, "paper_sph_ms": paper::TABLE5_SPH_MS,
            "settings": settings_json(study)}),
        csv,
    }
}

/// Table 6: basis fitting residual of our basis for each (test, m).
pub fn table6(study: &BeamStudy) -> RenderedTable {
    let mut md = String::from("## Table 6: basis fitting residual (beam)\n\n");
    md += &settings_lines(&study.config, &study.fem);
    md += "The paper's Table 6 values did not survive either text rendering, so none are shown.\n";
    md += &simplicits_line(study);
    md += "\n| test | m | ours residual | Simplicits (ours) |\n|---|---|---|---|\n";
    let mut csv = String::from("test,m,ours_fitting_residual,simplicits_fitting_residual\n");
    let mut rows = Vec::new();
    for r in &study.rows {
        let simplicits = r.simplicits.as_ref().map(|s| s.fitting_residual);
        let _ = writeln!(
            md,
            "| {} | {} | {:.2e} | {} |",
            r.test.name(),
            r.m,
            r.fitting_residual,
            not_run_or(simplicits)
        );
        let _ = writeln!(
            csv,
            "{},{},{:e},{}",
            r.test.name(),
            r.m,
            r.fitting_residual,
            optional(simplicits)
        );
        rows.push(json!({"test": r.test.name(), "m": r.m,
            "ours_fitting_residual": r.fitting_residual, "simplicits_fitting_residual": simplicits}));
    }
    RenderedTable {
        number: 6,
        markdown: md,
        json: json!({"table": 6, "rows": rows, "settings": settings_json(study)}),
        csv,
    }
}

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

fn settings_json(study: &BeamStudy) -> Value {
    json!({"config": study.config, "fem": study.fem})
}
