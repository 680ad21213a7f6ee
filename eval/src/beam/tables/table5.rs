//! Table 5: wall time per step on this machine for each m (Bend), the FEM step, and FEM/ours.

use std::fmt::Write as _;

use serde::Serialize;

use super::BeamTableSettings;
use crate::beam::study::BeamStudy;
use crate::beam_protocol::preamble::settings_lines;
use crate::beam_scenario::BeamTest;
use crate::particle_baselines::particle_baseline::ParticleMethod;
use crate::report::paper;
use crate::report::table::{PaperTable, csv_text};

/// Table 5 as data.
#[derive(Clone, Debug, Serialize)]
pub struct Table5<'a> {
    /// Always 5.
    pub table: u32,
    /// One row per m (Bend).
    pub rows: Vec<Table5Row>,
    /// The FEM reference's step (ms), timed in this run.
    pub fem_ms_per_step: Option<f64>,
    /// The FEM reference's resolution ("P2 res 4").
    pub fem_resolution: Option<String>,
    /// The paper's FEM step (ms).
    pub paper_fem_ms: f64,
    /// One row per particle method and spacing on the Bend.
    pub particle_baselines: Vec<Table5ParticleRow>,
    /// The paper's MPM step (ms).
    pub paper_mpm_ms: f64,
    /// The paper's SPH step (ms).
    pub paper_sph_ms: f64,
    /// CPU threads the run had (rayon).
    pub threads: usize,
    /// What the study ran with.
    pub settings: BeamTableSettings<'a>,
}

/// One m of Table 5 (the Bend).
#[derive(Clone, Debug, Serialize)]
pub struct Table5Row {
    /// Modes m.
    pub m: usize,
    /// Ours: wall time per 0.01 s step (ms).
    pub ours_ms_per_step: f64,
    /// The FEM's step over ours.
    pub fem_over_ours: Option<f64>,
    /// Where the elastic energy was integrated, and at how many points.
    pub quadrature: Option<Table5Quadrature>,
    /// Newton iterations per step.
    pub iterations_per_step: f64,
    /// Hessians assembled per step.
    pub hessians_per_step: f64,
    /// Simplicits (ours): wall time per step (ms), if run.
    pub simplicits_ms_per_step: Option<f64>,
    /// The paper's FreeForm step (ms), if it has this m.
    pub paper_ours_ms: Option<f64>,
    /// The paper's Simplicits step (ms), if it has this m.
    pub paper_simplicits_ms: Option<f64>,
}

/// A quadrature's kind and size.
#[derive(Clone, Debug, Serialize)]
pub struct Table5Quadrature {
    /// "full", "random_subset" or "cubature".
    pub kind: String,
    /// Points the elastic energy is evaluated at.
    pub points: usize,
}

/// One particle method and spacing of Table 5 (the Bend).
#[derive(Clone, Debug, Serialize)]
pub struct Table5ParticleRow {
    /// MPM or SPH.
    pub method: ParticleMethod,
    /// Grid cell (MPM) or particle spacing (SPH) (m).
    pub spacing: f64,
    /// Wall time per 0.01 s of simulated time (ms).
    pub ms_per_step: f64,
    /// Particles.
    pub particles: usize,
    /// Substeps per 0.01 s step.
    pub substeps_per_step: usize,
    /// Where the time went: (phase, ms per step).
    pub split: Vec<(String, f64)>,
    /// Solver iterations per step (SPH).
    pub iterations_per_step: Option<f64>,
    /// Setup time (s).
    pub setup_seconds: f64,
    /// The FEM's step over this method's.
    pub fem_over_baseline: Option<f64>,
    /// The paper's step for this method (ms).
    pub paper_ms: f64,
}

impl<'a> Table5<'a> {
    /// Table 5 of `study`.
    pub fn new(study: &'a BeamStudy) -> Self {
        let fem = study.fem.iter().find(|f| f.test == BeamTest::Bend);
        let fem_ms = fem.map(|f| 1e3 * f.seconds_per_step);
        let rows = study
            .rows
            .iter()
            .filter(|r| r.test == BeamTest::Bend)
            .map(|r| {
                let p = paper::table5(r.m);
                Table5Row {
                    m: r.m,
                    ours_ms_per_step: r.ms_per_step,
                    fem_over_ours: fem_ms.map(|f| f / r.ms_per_step),
                    quadrature: r.quadrature.as_ref().map(|q| Table5Quadrature {
                        kind: q.kind.clone(),
                        points: q.points,
                    }),
                    iterations_per_step: r.iterations_per_step,
                    hessians_per_step: r.hessians_per_step,
                    simplicits_ms_per_step: r.simplicits.as_ref().map(|s| s.ms_per_step),
                    paper_ours_ms: p.map(|p| p.1),
                    paper_simplicits_ms: p.map(|p| p.0),
                }
            })
            .collect();
        let particle_baselines = study
            .particle_baselines
            .iter()
            .filter(|p| p.test == BeamTest::Bend)
            .map(|p| Table5ParticleRow {
                method: p.method,
                spacing: p.spacing,
                ms_per_step: p.ms_per_step,
                particles: p.particles,
                substeps_per_step: p.substeps_per_step,
                split: p.split.clone(),
                iterations_per_step: p.iterations_per_step,
                setup_seconds: p.setup_seconds,
                fem_over_baseline: fem_ms.map(|f| f / p.ms_per_step),
                paper_ms: p.method.paper_ms(),
            })
            .collect();
        Table5 {
            table: 5,
            rows,
            fem_ms_per_step: fem_ms,
            fem_resolution: fem.map(|f| f.resolution.clone()),
            paper_fem_ms: paper::TABLE5_FEM_MS,
            particle_baselines,
            paper_mpm_ms: paper::TABLE5_MPM_MS,
            paper_sph_ms: paper::TABLE5_SPH_MS,
            threads: rayon::current_num_threads(),
            settings: BeamTableSettings::of(study),
        }
    }
}

impl PaperTable for Table5<'_> {
    fn number(&self) -> u32 {
        self.table
    }

    fn markdown(&self) -> String {
        let config = self.settings.config;
        let mut md = String::from("## Table 5: ms per 0.01 s step, beam Bend\n\n");
        md += &settings_lines(config, self.settings.fem, self.settings.failed_rows);
        md += &format!(
            "This machine: {} CPU threads (rayon). The paper's numbers are on a GPU.\n",
            self.threads
        );
        md += "\n| m | ours ms/step | Newton it./step | Hessians/step | quadrature points | FEM/ours | Simplicits ms/step | paper FreeForm | paper Simplicits |\n|---|---|---|---|---|---|---|---|---|\n";
        for r in &self.rows {
            let _ = writeln!(
                md,
                "| {} | {:.2} | {:.2} | {:.2} | {} | {} | {} | {} | {} |",
                r.m,
                r.ours_ms_per_step,
                r.iterations_per_step,
                r.hessians_per_step,
                r.quadrature
                    .as_ref()
                    .map_or("—".into(), |q| format!("{} ({})", q.points, q.kind)),
                r.fem_over_ours.map_or("—".into(), |v| format!("{v:.0}×")),
                r.simplicits_ms_per_step
                    .map_or("not run".into(), |s| format!("{s:.2}")),
                r.paper_ours_ms.map_or("—".into(), |p| format!("{p:.2}")),
                r.paper_simplicits_ms
                    .map_or("—".into(), |p| format!("{p:.2}")),
            );
        }
        let _ = writeln!(
            md,
            "| FEM ({}) | {} | | | | {:.1} (paper FEM) | |",
            self.fem_resolution.as_deref().unwrap_or("—"),
            self.fem_ms_per_step
                .map_or("—".into(), |v| format!("{v:.1}")),
            self.paper_fem_ms
        );
        for p in &self.particle_baselines {
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
                p.paper_ms,
                method.label()
            );
        }
        if config.mpm.is_some() {
            md +=
                "MPM: ms per 0.01 s of simulated time (its substeps of the stated Δt together).\n";
        }
        if config.sph.is_some() {
            md += "SPH: ms per 0.01 s step (one implicit step), setup (neighbourhoods, factorization) \
                   left out.\n";
        }
        md
    }

    fn csv(&self) -> String {
        let fem_ms = self.fem_ms_per_step.unwrap_or(f64::NAN);
        let optional = |v: Option<f64>| v.map_or(String::new(), |v| v.to_string());
        let ours = self.rows.iter().map(|r| {
            vec![
                r.m.to_string(),
                r.ours_ms_per_step.to_string(),
                fem_ms.to_string(),
                r.fem_over_ours.unwrap_or(f64::NAN).to_string(),
                optional(r.paper_ours_ms),
                optional(r.paper_simplicits_ms),
            ]
        });
        let particles = self.particle_baselines.iter().map(|p| {
            vec![
                format!("{} {}", p.method.key(), p.spacing),
                p.ms_per_step.to_string(),
                fem_ms.to_string(),
                p.fem_over_baseline.unwrap_or(f64::NAN).to_string(),
                String::new(),
                String::new(),
            ]
        });
        csv_text(
            &[
                "m",
                "ours_ms_per_step",
                "fem_ms_per_step",
                "ratio",
                "paper_ours_ms",
                "paper_simplicits_ms",
            ],
            ours.chain(particles),
        )
    }
}
