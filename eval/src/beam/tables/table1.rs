//! Table 1: normalized MSE of ours against the FEM for each (test, m), beside the paper's
//! columns, with both pin treatments and the particle baselines.

use std::fmt::Write as _;

use serde::Serialize;

use super::{BeamTableSettings, simplicits_line};
use crate::beam::study::BeamStudy;
use crate::beam_protocol::failed_row::FailedBeamRow;
use crate::beam_protocol::preamble::settings_lines;
use crate::particle_baselines::particle_baseline::ParticleMethod;
use crate::report::paper;
use crate::report::table::{PaperTable, csv_number, csv_text, not_run_or, sci};

/// Table 1 as data.
#[derive(Clone, Debug, Serialize)]
pub struct Table1<'a> {
    /// Always 1.
    pub table: u32,
    /// One row per (test, m), tests outermost.
    pub rows: Vec<Table1Row>,
    /// One row per (particle method, test, spacing) the study ran.
    pub particle_baselines: Vec<Table1ParticleRow>,
    /// The (test, m) runs that failed, with their errors.
    pub failed_rows: &'a [FailedBeamRow],
    /// What the study ran with.
    pub settings: BeamTableSettings<'a>,
}

/// One (test, m) of Table 1. Errors are normalized by L = 5 m (design §4.3); distances in m.
#[derive(Clone, Debug, Serialize)]
pub struct Table1Row {
    /// "bend" or "twist".
    pub test: &'static str,
    /// Modes m.
    pub m: usize,
    /// Ours (penalty pins): normalized MSE.
    pub ours_mse: f64,
    /// Ours: normalized max error.
    pub ours_max: f64,
    /// The paper's FreeForm MSE at this (test, m), if it has one.
    pub paper_ours_mse: Option<f64>,
    /// The paper's Simplicits MSE at this (test, m), if it has one.
    pub paper_simplicits_mse: Option<f64>,
    /// Simplicits (ours): normalized MSE, if run.
    pub simplicits_mse: Option<f64>,
    /// Simplicits (ours): normalized max error.
    pub simplicits_max: Option<f64>,
    /// Simplicits (ours): training time of the cached network (s).
    pub simplicits_training_seconds: Option<f64>,
    /// Ours: steps whose Newton solve did not converge.
    pub unconverged_steps: usize,
    /// Ours: largest distance of a held integration point from its target (m).
    pub max_pin_deviation: f64,
    /// Ours: largest distance of a FEM vertex of a held region from its target (m).
    pub region_drift: f64,
    /// Exact pins: normalized MSE, if run.
    pub exact_mse: Option<f64>,
    /// Exact pins: normalized max error.
    pub exact_max: Option<f64>,
    /// Exact pins: largest distance of a held integration point from its target (m).
    pub exact_max_pin_deviation: Option<f64>,
    /// Exact pins: largest distance of a FEM vertex of a held region from its target (m).
    pub exact_region_drift: Option<f64>,
    /// Exact pins: how far the held regions were shrunk (m).
    pub exact_inset: Option<f64>,
    /// Exact pins: wall time per step (ms).
    pub exact_ms_per_step: Option<f64>,
    /// Exact pins: steps whose Newton solve did not converge.
    pub exact_unconverged_steps: Option<usize>,
}

/// One (particle method, test, spacing) of Table 1's particle sections.
#[derive(Clone, Debug, Serialize)]
pub struct Table1ParticleRow {
    /// MPM or SPH.
    pub method: ParticleMethod,
    /// "bend" or "twist".
    pub test: &'static str,
    /// Grid cell (MPM) or particle spacing (SPH) (m).
    pub spacing: f64,
    /// Normalized MSE, when scored.
    pub mse: Option<f64>,
    /// Normalized max error, when scored.
    pub max: Option<f64>,
    /// Wall time per 0.01 s of simulated time (ms).
    pub ms_per_step: f64,
    /// Why the run stopped early, if it did.
    pub failure: Option<String>,
    /// Steps completed.
    pub steps_completed: usize,
    /// Particles.
    pub particles: usize,
    /// Substeps per 0.01 s step.
    pub substeps_per_step: usize,
    /// Largest distance of a pinned particle from its target (m).
    pub max_pin_deviation: f64,
    /// Solver iterations per step (SPH).
    pub iterations_per_step: Option<f64>,
    /// Setup time (s).
    pub setup_seconds: f64,
    /// The paper's MSE for this method and test (its m = 9 column).
    pub paper_mse: Option<f64>,
    /// Whether the run was read from the cache (its times are from the run that made it;
    /// Markdown only, so that a cached rerun's JSON equals the first run's).
    #[serde(skip)]
    pub cached: bool,
}

impl<'a> Table1<'a> {
    /// Table 1 of `study`.
    pub fn new(study: &'a BeamStudy) -> Self {
        let rows = study
            .rows
            .iter()
            .map(|r| {
                let name = r.test.name();
                let exact = r.exact.as_ref();
                let simplicits = r.simplicits.as_ref();
                Table1Row {
                    test: name,
                    m: r.m,
                    ours_mse: r.ours_mse,
                    ours_max: r.ours_max,
                    paper_ours_mse: paper::table1_ours(name, r.m),
                    paper_simplicits_mse: paper::table1_simplicits(name, r.m),
                    simplicits_mse: simplicits.map(|s| s.mse),
                    simplicits_max: simplicits.map(|s| s.max),
                    simplicits_training_seconds: simplicits.map(|s| s.training_seconds),
                    unconverged_steps: r.unconverged_steps,
                    max_pin_deviation: r.max_pin_deviation,
                    region_drift: r.region_drift,
                    exact_mse: exact.map(|e| e.mse),
                    exact_max: exact.map(|e| e.max),
                    exact_max_pin_deviation: exact.map(|e| e.max_pin_deviation),
                    exact_region_drift: exact.map(|e| e.region_drift),
                    exact_inset: exact.map(|e| e.inset),
                    exact_ms_per_step: exact.map(|e| e.ms_per_step),
                    exact_unconverged_steps: exact.map(|e| e.unconverged_steps),
                }
            })
            .collect();
        let particle_baselines = study
            .particle_baselines
            .iter()
            .map(|p| Table1ParticleRow {
                method: p.method,
                test: p.test.name(),
                spacing: p.spacing,
                mse: p.mse,
                max: p.max,
                ms_per_step: p.ms_per_step,
                failure: p.failure.clone(),
                steps_completed: p.steps_completed,
                particles: p.particles,
                substeps_per_step: p.substeps_per_step,
                max_pin_deviation: p.max_pin_deviation,
                iterations_per_step: p.iterations_per_step,
                setup_seconds: p.setup_seconds,
                paper_mse: p.method.paper_mse(p.test.name()),
                cached: p.cached,
            })
            .collect();
        Table1 {
            table: 1,
            rows,
            particle_baselines,
            failed_rows: &study.failed_rows,
            settings: BeamTableSettings::of(study),
        }
    }

    /// A particle method's cell of `r`: the particle methods do not depend on m, so each one's
    /// finest scored spacing goes beside the paper's m = 9 value (empty on other rows, or when
    /// the study did not run the method).
    fn particle_cell(&self, r: &Table1Row, method: ParticleMethod, configured: bool) -> String {
        if r.m != 9 || !configured {
            return String::new();
        }
        self.particle_baselines
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

    /// How the exact columns were produced (or that they were not).
    fn exact_line(&self) -> String {
        let inset = self.rows.iter().find_map(|r| r.exact_inset);
        match (inset, self.settings.config.exact_pins) {
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

    /// Table 1's particle-baseline sections (MPM, SPH): how each was run and one row per
    /// (test, spacing), or that it was not run.
    fn particle_baselines_section(&self) -> String {
        let config = self.settings.config;
        let mut md = String::new();
        match &config.mpm {
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
                md += &self.particle_rows(ParticleMethod::Mpm);
            }
        }
        match &config.sph {
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
                md += &self.particle_rows(ParticleMethod::Sph);
            }
        }
        md
    }

    /// One particle method's rows of Table 1's section.
    fn particle_rows(&self, method: ParticleMethod) -> String {
        let mut md = format!(
            "| test | {} (m) | particles | MSE | max | pinned particles' drift (mm) | ms per 0.01 s | \
             steps per 0.01 s | solver iterations per step | setup (s) | paper {} MSE |\n\
             |---|---|---|---|---|---|---|---|---|---|---|\n",
            method.spacing_name(),
            method.label()
        );
        for p in self
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
                p.test,
                p.spacing,
                p.particles,
                1e3 * p.max_pin_deviation,
                p.ms_per_step,
                if p.cached { " (cached)" } else { "" },
                p.substeps_per_step,
                p.iterations_per_step
                    .map_or("—".into(), |i| format!("{i:.0}")),
                p.setup_seconds,
                sci(p.paper_mse),
            );
        }
        md
    }
}

impl PaperTable for Table1<'_> {
    fn number(&self) -> u32 {
        self.table
    }

    fn markdown(&self) -> String {
        let config = self.settings.config;
        let mut md = String::from("## Table 1: normalized MSE against FEM (beam)\n\n");
        md += &settings_lines(config, self.settings.fem, self.settings.failed_rows);
        md += &self.exact_line();
        md += "\n| test | m | ours MSE | ours max | pin drift held / region (mm) | exact MSE | exact max | exact drift held / region (mm) | paper FreeForm | paper Simplicits | Simplicits (ours) | MPM (ours, m = 9 rows) | MPM (paper) | SPH (ours, m = 9 rows) | SPH (paper) |\n";
        md += "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
        for r in &self.rows {
            let particle = paper::TABLE1_PARTICLE
                .iter()
                .find(|p| p.0 == r.test && r.m == 9);
            let mpm = self.particle_cell(r, ParticleMethod::Mpm, config.mpm.is_some());
            let sph = self.particle_cell(r, ParticleMethod::Sph, config.sph.is_some());
            let _ = writeln!(
                md,
                "| {} | {} | {:.2e} | {:.2e} | {:.1} / {:.1} | {} | {} | {} | {} | {} | {} | {mpm} | {} | {sph} | {} |",
                r.test,
                r.m,
                r.ours_mse,
                r.ours_max,
                1e3 * r.max_pin_deviation,
                1e3 * r.region_drift,
                not_run_or(r.exact_mse),
                not_run_or(r.exact_max),
                match (r.exact_max_pin_deviation, r.exact_region_drift) {
                    (Some(held), Some(region)) => {
                        format!("{:.1e} / {:.1}", 1e3 * held, 1e3 * region)
                    }
                    _ => "not run".into(),
                },
                sci(r.paper_ours_mse),
                sci(r.paper_simplicits_mse),
                not_run_or(r.simplicits_mse),
                sci(particle.map(|p| p.1)),
                sci(particle.map(|p| p.2)),
            );
        }
        md += &simplicits_line(
            config,
            self.rows
                .iter()
                .map(|r| (r.test, r.m, r.simplicits_training_seconds)),
        );
        md += &self.particle_baselines_section();
        md
    }

    fn csv(&self) -> String {
        csv_text(
            &[
                "test",
                "m",
                "ours_mse",
                "ours_max",
                "exact_mse",
                "exact_max",
                "exact_max_pin_deviation",
                "simplicits_mse",
                "simplicits_max",
                "paper_ours_mse",
                "paper_simplicits_mse",
            ],
            self.rows.iter().map(|r| {
                vec![
                    r.test.to_string(),
                    r.m.to_string(),
                    format!("{:e}", r.ours_mse),
                    format!("{:e}", r.ours_max),
                    csv_number(r.exact_mse),
                    csv_number(r.exact_max),
                    csv_number(r.exact_max_pin_deviation),
                    csv_number(r.simplicits_mse),
                    csv_number(r.simplicits_max),
                    csv_number(r.paper_ours_mse),
                    csv_number(r.paper_simplicits_mse),
                ]
            }),
        )
    }
}
