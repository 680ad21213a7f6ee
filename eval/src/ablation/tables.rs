//! Tables 3 and 4 (the training and sampling ablations on the beam) as typed rows rendered to
//! Markdown beside the paper's numbers, JSON and CSV.

use std::fmt::Write as _;

use serde::Serialize;

use crate::ablation::study::{AblationStudy, AblationStudyConfig, TestScore};
use crate::beam_protocol::evaluation::FemSummary;
use crate::beam_protocol::preamble::{score_or_why, settings_lines};
use crate::beam_scenario::BeamTest;
use crate::report::paper;
use crate::report::table::{PaperTable, RenderedTable, csv_number, csv_text, sci};

/// How the trained rows were trained.
fn training_line(config: &AblationStudyConfig) -> String {
    let t = config.training();
    format!(
        "Trained rows: {} Adam steps (lr {:e}) on the same grid and kernels as our basis; \
         Simplicits and random-z: {} points × {} random handle sets per step, loss {} · \
         elastic + {:e} · orthogonality; Hessian: tr(cᵀH_w c)/max(λ+4μ) + {:e} · \
         mean((cᵀ𝓜c − I)²), m + 1 columns trained and the lowest Ritz pair dropped (the \
         constant). Random points: {} fresh uniform points per step; grid points: draws from the \
         grid (random-z) or the full grid quadrature (Hessian). Training times are wall time on \
         this machine ({} threads; the paper's are on a GPU), from the run that produced the \
         cached model.\n",
        t.steps,
        t.learning_rate,
        t.points_per_step,
        t.transforms_per_step,
        t.elastic_weight,
        t.ortho_weight,
        t.ortho_weight,
        t.points_per_step,
        rayon::current_num_threads()
    )
}

/// What an ablation table ran with: the study's configuration and its FEM references.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct AblationTableSettings<'a> {
    /// The study's configuration.
    pub config: &'a AblationStudyConfig,
    /// One summary per test's FEM reference.
    pub fem: &'a [FemSummary],
}

/// Table 3 as data: each way of finding the weights, simulated on the Drop (Bend) and Twist.
#[derive(Clone, Debug, Serialize)]
pub struct Table3<'a> {
    /// Always 3.
    pub table: u32,
    /// Modes m.
    pub m: usize,
    /// One row per method.
    pub rows: Vec<Table3Row>,
    /// What the study ran with.
    pub settings: AblationTableSettings<'a>,
}

/// One method of Table 3. Errors are normalized by L = 5 m (design §4.3).
#[derive(Clone, Debug, Serialize)]
pub struct Table3Row {
    /// The method ("FreeForm (ours)", "Simplicits", …).
    pub method: String,
    /// Normalized MSE on the Drop (the Bend), if scored.
    pub drop_mse: Option<f64>,
    /// Normalized MSE on the Twist, if scored.
    pub twist_mse: Option<f64>,
    /// Every test's scores.
    pub scores: Vec<TestScore>,
    /// Training wall time (s), from the run that produced the cached model.
    pub training_seconds: f64,
    /// Whether the model was read from the cache.
    pub cached: bool,
    /// The training loss at the first and last step, for trained rows.
    pub loss_first_last: Option<(f64, f64)>,
    /// The paper's Drop MSE for this method.
    pub paper_drop_mse: Option<f64>,
    /// The paper's Twist MSE for this method.
    pub paper_twist_mse: Option<f64>,
    /// The paper's training time for this method (s, GPU).
    pub paper_seconds: Option<f64>,
}

/// Table 4 as data: each method simulated on grid and on random integration points.
#[derive(Clone, Debug, Serialize)]
pub struct Table4<'a> {
    /// Always 4.
    pub table: u32,
    /// Modes m.
    pub m: usize,
    /// One row per (method, test).
    pub rows: Vec<Table4Row>,
    /// What the study ran with.
    pub settings: AblationTableSettings<'a>,
}

/// One (method, test) of Table 4.
#[derive(Clone, Debug, Serialize)]
pub struct Table4Row {
    /// The method.
    pub method: String,
    /// "bend" (the Drop) or "twist".
    pub test: &'static str,
    /// Normalized MSE simulated on the grid (v = h³).
    pub grid_mse: f64,
    /// Normalized MSE simulated on uniform random points (v = V / N).
    pub random_mse: f64,
    /// The paper's grid MSE.
    pub paper_grid_mse: Option<f64>,
    /// The paper's random-point MSE.
    pub paper_random_mse: Option<f64>,
}

impl<'a> AblationTableSettings<'a> {
    fn of(study: &'a AblationStudy) -> Self {
        AblationTableSettings {
            config: &study.config,
            fem: &study.fem,
        }
    }
}

impl<'a> Table3<'a> {
    /// Table 3 of `study`.
    pub fn new(study: &'a AblationStudy) -> Self {
        let rows = study
            .table3
            .iter()
            .map(|r| {
                let p = paper::table3(&r.method);
                Table3Row {
                    method: r.method.clone(),
                    drop_mse: r.mse(BeamTest::Bend),
                    twist_mse: r.mse(BeamTest::Twist),
                    scores: r.scores.clone(),
                    training_seconds: r.training_seconds,
                    cached: r.cached,
                    loss_first_last: r.loss,
                    paper_drop_mse: p.map(|p| p.0),
                    paper_twist_mse: p.map(|p| p.1),
                    paper_seconds: p.map(|p| p.2),
                }
            })
            .collect();
        Table3 {
            table: 3,
            m: study.config.modes(),
            rows,
            settings: AblationTableSettings::of(study),
        }
    }
}

impl PaperTable for Table3<'_> {
    fn number(&self) -> u32 {
        self.table
    }

    fn markdown(&self) -> String {
        let AblationTableSettings { config, fem } = self.settings;
        let mut md = format!(
            "## Table 3: how the skinning weights are found (beam, m = {})\n\n",
            self.m
        );
        md += &settings_lines(&config.base, fem, &[]);
        md += &training_line(config);
        md += "\n| method | Drop MSE | Twist MSE | training (s) | final loss | paper Drop | paper Twist | paper s |\n";
        md += "|---|---|---|---|---|---|---|---|\n";
        for r in &self.rows {
            let _ = writeln!(
                md,
                "| {} | {} | {} | {:.1}{} | {} | {} | {} | {} |",
                r.method,
                score_or_why(r.drop_mse, fem, BeamTest::Bend),
                score_or_why(r.twist_mse, fem, BeamTest::Twist),
                r.training_seconds,
                if r.cached { " (cached)" } else { "" },
                r.loss_first_last
                    .map_or("—".into(), |(a, b)| format!("{a:.2e} → {b:.2e}")),
                sci(r.paper_drop_mse),
                sci(r.paper_twist_mse),
                r.paper_seconds.map_or("—".into(), |s| format!("{s:.2}")),
            );
        }
        if !config.coefficient_ablations {
            md += "\nThe four coefficient-training rows were not run.\n";
        }
        md
    }

    fn csv(&self) -> String {
        csv_text(
            &[
                "method",
                "drop_mse",
                "twist_mse",
                "training_seconds",
                "paper_drop_mse",
                "paper_twist_mse",
                "paper_seconds",
            ],
            self.rows.iter().map(|r| {
                vec![
                    r.method.clone(),
                    csv_number(r.drop_mse),
                    csv_number(r.twist_mse),
                    r.training_seconds.to_string(),
                    csv_number(r.paper_drop_mse),
                    csv_number(r.paper_twist_mse),
                    r.paper_seconds.map_or(String::new(), |s| s.to_string()),
                ]
            }),
        )
    }
}

impl<'a> Table4<'a> {
    /// Table 4 of `study`.
    pub fn new(study: &'a AblationStudy) -> Self {
        let rows = study
            .table4
            .iter()
            .map(|r| {
                let p = paper::table4(&r.method, r.test.name());
                Table4Row {
                    method: r.method.clone(),
                    test: r.test.name(),
                    grid_mse: r.grid_mse,
                    random_mse: r.random_mse,
                    paper_grid_mse: p.map(|p| p.0),
                    paper_random_mse: p.map(|p| p.1),
                }
            })
            .collect();
        Table4 {
            table: 4,
            m: study.config.modes(),
            rows,
            settings: AblationTableSettings::of(study),
        }
    }
}

impl PaperTable for Table4<'_> {
    fn number(&self) -> u32 {
        self.table
    }

    fn markdown(&self) -> String {
        let AblationTableSettings { config, fem } = self.settings;
        let mut md = format!(
            "## Table 4: grid vs random integration points at simulation time (beam, m = {})\n\n",
            self.m
        );
        md += &settings_lines(&config.base, fem, &[]);
        let _ = writeln!(
            md,
            "Both methods' weights are built as in Table 1; only the simulation's ≈{} points change: \
             the grid (v = h³) or as many uniform random points in the beam (v = V/N, seed {}).",
            config.base.settings.simulation_points, config.random_points_seed
        );
        md += "\n| method | test | grid MSE | random MSE | random/grid | paper grid | paper random |\n";
        md += "|---|---|---|---|---|---|---|\n";
        for r in &self.rows {
            let label = if r.test == BeamTest::Bend.name() {
                "Drop"
            } else {
                "Twist"
            };
            let _ = writeln!(
                md,
                "| {} | {label} | {:.2e} | {:.2e} | {:.2} | {} | {} |",
                r.method,
                r.grid_mse,
                r.random_mse,
                r.random_mse / r.grid_mse,
                sci(r.paper_grid_mse),
                sci(r.paper_random_mse),
            );
        }
        if !config.sampling_ablation {
            md += "\nThe random-point simulations were not run.\n";
        }
        md
    }

    fn csv(&self) -> String {
        csv_text(
            &[
                "method",
                "test",
                "grid_mse",
                "random_mse",
                "paper_grid_mse",
                "paper_random_mse",
            ],
            self.rows.iter().map(|r| {
                vec![
                    r.method.clone(),
                    r.test.to_string(),
                    format!("{:e}", r.grid_mse),
                    format!("{:e}", r.random_mse),
                    csv_number(r.paper_grid_mse),
                    csv_number(r.paper_random_mse),
                ]
            }),
        )
    }
}

/// Table 3 of `study`, rendered ([`Table3`]).
pub fn table3(study: &AblationStudy) -> RenderedTable {
    Table3::new(study).render()
}

/// Table 4 of `study`, rendered ([`Table4`]).
pub fn table4(study: &AblationStudy) -> RenderedTable {
    Table4::new(study).render()
}
