//! Table 2: averages per boundary condition and collection with the paper's beside them,
//! training and step times, and one row per (shape, boundary condition).

use std::fmt::Write as _;

use serde::Serialize;

use super::averages::{Measure, ShapeAverage, average, exact_average, groups, mean_std};
use super::preamble::{percent, settings_lines, step_time};
pub use super::table2_row::Table2Row;
use crate::report::paper;
use crate::report::table::{PaperTable, RenderedTable, csv_number, csv_text, sci};
use crate::shapes::boundary::ShapeBoundary;
use crate::shapes::config::ShapeStudyConfig;
use crate::shapes::result::ShapeStudy;

/// Table 2 as data.
#[derive(Clone, Debug, Serialize)]
pub struct Table2<'a> {
    /// Always 2.
    pub table: u32,
    /// Shapes of the study not yet in it.
    pub unfinished: Vec<String>,
    /// (shape, condition) rows of finished shapes not yet in it.
    pub unfinished_rows: Vec<String>,
    /// One row per (shape, boundary condition).
    pub shapes: Vec<Table2Row>,
    /// One row per (collection, boundary condition).
    pub averages: Vec<Table2Average>,
    /// Mean and standard deviation of the basis build (`ours`) and Simplicits training times.
    pub training_seconds: TrainingSeconds,
    /// The paper's Table 2 averages.
    pub paper: Vec<Table2PaperRow>,
    /// Wall time of the study (s).
    pub wall_seconds: f64,
    /// What the study ran with.
    pub settings: &'a ShapeStudyConfig,
    /// The settings, reference, gate, baseline and metrics preamble (Markdown).
    #[serde(skip)]
    preamble: String,
    /// The Markdown lines of step times over every row ("mean ± sd ms …"), ours then
    /// Simplicits.
    #[serde(skip)]
    step_times: [String; 2],
    /// Per shape with a convergence check: the checks' seconds.
    #[serde(skip)]
    check_seconds: Vec<f64>,
    /// Per shape: the FEM references' seconds.
    #[serde(skip)]
    fem_seconds: Vec<f64>,
}

/// One (collection, boundary condition) of Table 2's averages, over the trusted rows where
/// every method finished.
#[derive(Clone, Debug, Serialize)]
pub struct Table2Average {
    /// "all", "Thingi10K", "classic", "other".
    pub collection: String,
    /// The boundary condition's name.
    pub bc: &'static str,
    /// Shapes averaged.
    pub shapes: usize,
    /// Our mean MSE.
    pub ours_mse: Option<f64>,
    /// Our mean max error.
    pub ours_max: Option<f64>,
    /// Simplicits' mean MSE.
    pub simplicits_mse: Option<f64>,
    /// Simplicits' mean max error.
    pub simplicits_max: Option<f64>,
    /// `(S − F) / S` of the mean MSEs (%).
    pub improvement_mse_percent: Option<f64>,
    /// `(S − F) / S` of the mean max errors (%).
    pub improvement_max_percent: Option<f64>,
    /// Shapes where our MSE is lower.
    pub wins_mse: usize,
    /// Shapes where our max error is lower.
    pub wins_max: usize,
    /// Mean exact-pin MSE over mean penalty MSE, where the study ran exact pins.
    pub exact_over_penalty_mse: Option<f64>,
    /// Mean exact-pin max error over mean penalty max error.
    pub exact_over_penalty_max: Option<f64>,
}

/// Mean, standard deviation and count of per-shape times.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct MeanStd {
    /// Mean (s).
    pub mean: f64,
    /// Standard deviation (population, s).
    pub std: f64,
    /// Shapes.
    pub n: usize,
}

impl MeanStd {
    fn of(values: &[f64]) -> Option<Self> {
        mean_std(values).map(|(mean, std)| MeanStd {
            mean,
            std,
            n: values.len(),
        })
    }
}

/// The per-shape setup times of Table 2.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct TrainingSeconds {
    /// Our basis (sampling and eigensolve).
    pub ours: Option<MeanStd>,
    /// Simplicits' training.
    pub simplicits: Option<MeanStd>,
}

/// One of the paper's Table 2 averages.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Table2PaperRow {
    /// "Thingi10K" or "SimReady".
    pub dataset: &'static str,
    /// The boundary condition's name.
    pub bc: &'static str,
    /// Simplicits MSE.
    pub simplicits_mse: f64,
    /// Simplicits max error.
    pub simplicits_max: f64,
    /// FreeForm MSE.
    pub ours_mse: f64,
    /// FreeForm max error.
    pub ours_max: f64,
}

impl<'a> Table2<'a> {
    /// Table 2 of `study`.
    pub fn new(study: &'a ShapeStudy) -> Self {
        let shapes = study
            .shapes
            .iter()
            .flat_map(|shape| {
                study
                    .config
                    .boundaries
                    .iter()
                    .map(move |&b| Table2Row::new(study, shape, b))
            })
            .collect();
        let basis: Vec<f64> = study
            .shapes
            .iter()
            .filter_map(|s| s.basis_seconds)
            .collect();
        let training: Vec<f64> = study
            .shapes
            .iter()
            .filter_map(|s| s.training_seconds)
            .collect();
        // Each shape's convergence checks, where any ran: the seconds of their runs.
        let steps = study.config.boundary.steps as f64;
        let check_seconds = study
            .shapes
            .iter()
            .filter_map(|s| {
                let runs: Vec<f64> = s
                    .rows
                    .iter()
                    .filter_map(|r| r.reference_check.as_ref())
                    .map(|check| check.seconds_per_step * steps)
                    .collect();
                (!runs.is_empty()).then(|| runs.iter().sum())
            })
            .collect();
        Table2 {
            table: 2,
            unfinished: study.unfinished(),
            unfinished_rows: study.unfinished_rows(),
            shapes,
            averages: averages(study),
            training_seconds: TrainingSeconds {
                ours: MeanStd::of(&basis),
                simplicits: MeanStd::of(&training),
            },
            paper: paper::TABLE2
                .iter()
                .map(|r| Table2PaperRow {
                    dataset: r.dataset,
                    bc: r.boundary,
                    simplicits_mse: r.simplicits[0],
                    simplicits_max: r.simplicits[1],
                    ours_mse: r.ours[0],
                    ours_max: r.ours[1],
                })
                .collect(),
            wall_seconds: study.seconds,
            settings: &study.config,
            preamble: settings_lines(study),
            step_times: [
                step_time(study, |r| r.ours),
                step_time(study, |r| r.simplicits),
            ],
            check_seconds,
            fem_seconds: study.shapes.iter().filter_map(|s| s.fem_seconds).collect(),
        }
    }

    fn with_simplicits(&self) -> bool {
        self.settings.simplicits.is_some()
    }

    /// The averages per collection and boundary condition, as Markdown.
    fn averages_markdown(&self, md: &mut String) {
        *md += "\n### Averages\n\n| shapes | method | ";
        for b in ShapeBoundary::ALL {
            let _ = write!(md, "{0} MSE | {0} max | ", b.title());
        }
        *md += "n per BC |\n|---|---|---|---|---|---|---|---|---|\n";
        let mut collections: Vec<&str> = Vec::new();
        for a in &self.averages {
            if !collections.contains(&a.collection.as_str()) {
                collections.push(&a.collection);
            }
        }
        for collection in collections {
            let group: Vec<&Table2Average> = self
                .averages
                .iter()
                .filter(|a| a.collection == collection)
                .collect();
            let counts: Vec<String> = group.iter().map(|a| a.shapes.to_string()).collect();
            let counts = counts.join("/");
            let mut line = |method: &str, cells: &dyn Fn(&Table2Average) -> [String; 2]| {
                let cells: Vec<String> = group.iter().flat_map(|a| cells(a)).collect();
                let _ = writeln!(
                    *md,
                    "| {collection} | {method} | {} | {counts} |",
                    cells.join(" | ")
                );
            };
            if self.with_simplicits() {
                line("Simplicits (ours)", &|a| {
                    [sci(a.simplicits_mse), sci(a.simplicits_max)]
                });
            }
            line("FreeForm (ours)", &|a| [sci(a.ours_mse), sci(a.ours_max)]);
            if self.with_simplicits() {
                line("improvement", &|a| {
                    [
                        percent(a.improvement_mse_percent),
                        percent(a.improvement_max_percent),
                    ]
                });
                line("wins", &|a| {
                    [
                        format!("{}/{}", a.wins_mse, a.shapes),
                        format!("{}/{}", a.wins_max, a.shapes),
                    ]
                });
            }
            if self.settings.exact_pins.is_some() {
                let ratio = |v: Option<f64>| v.map_or("—".into(), |v| format!("{v:.2}×"));
                let cells: Vec<String> = group
                    .iter()
                    .flat_map(|a| {
                        [
                            ratio(a.exact_over_penalty_mse),
                            ratio(a.exact_over_penalty_max),
                        ]
                    })
                    .collect();
                let _ = writeln!(
                    *md,
                    "| {collection} | FreeForm exact pins ÷ penalty (mean over the same shapes) | {} | |",
                    cells.join(" | ")
                );
            }
        }
    }

    /// Training and step times, as Markdown.
    fn times_markdown(&self, md: &mut String) {
        let stat = |s: Option<MeanStd>| {
            s.map_or("—".into(), |s| {
                format!("{:.2} ± {:.2} s (n = {})", s.mean, s.std, s.n)
            })
        };
        let TrainingSeconds { ours, simplicits } = self.training_seconds;
        *md += "\n### Training time per shape (this machine, 2 cores)\n\n";
        let _ = writeln!(
            md,
            "- FreeForm basis (sampling + eigen solve): {}",
            stat(ours)
        );
        let _ = writeln!(md, "- Simplicits training: {}", stat(simplicits));
        if let (Some(b), Some(t)) = (ours, simplicits) {
            let _ = writeln!(
                md,
                "- ratio of the means: {:.0}× (improvement {:.1}%)",
                t.mean / b.mean,
                100.0 * (1.0 - b.mean / t.mean)
            );
        }
        let _ = writeln!(
            md,
            "- FEM reference, three runs: {}",
            stat(MeanStd::of(&self.fem_seconds))
        );
        if !self.check_seconds.is_empty() {
            let _ = writeln!(
                md,
                "- FEM convergence checks (the 1.5× finer references): {}",
                stat(MeanStd::of(&self.check_seconds))
            );
        }
        for (dataset, sm, ss, fm, fs) in paper::TABLE2_TRAINING {
            let _ = writeln!(
                md,
                "- paper {dataset} (GPU): Simplicits {sm:.2} ± {ss:.2} s, FreeForm {fm:.2} ± {fs:.2} s"
            );
        }
        *md += "\n### Reduced step time (this machine, every row)\n\n";
        let _ = writeln!(md, "- FreeForm: {}", self.step_times[0]);
        if self.with_simplicits() {
            let _ = writeln!(md, "- Simplicits: {}", self.step_times[1]);
        }
    }
}

/// The averages per collection and boundary condition.
fn averages(study: &ShapeStudy) -> Vec<Table2Average> {
    let with_simplicits = study.config.simplicits.is_some();
    let gate = study.config.max_reference_volume_error;
    let mut averages = Vec::new();
    for (collection, shapes) in groups(study) {
        for b in ShapeBoundary::ALL {
            let mse: ShapeAverage =
                average(&collection, &shapes, b, Measure::Mse, with_simplicits, gate);
            let max: ShapeAverage =
                average(&collection, &shapes, b, Measure::Max, with_simplicits, gate);
            let [exact_mse, exact_max] = if study.config.exact_pins.is_some() {
                exact_average(&shapes, b, gate)
            } else {
                [None, None]
            };
            averages.push(Table2Average {
                collection: collection.clone(),
                bc: b.name(),
                shapes: mse.shapes,
                ours_mse: mse.ours,
                ours_max: max.ours,
                simplicits_mse: mse.simplicits,
                simplicits_max: max.simplicits,
                improvement_mse_percent: mse.improvement_percent,
                improvement_max_percent: max.improvement_percent,
                wins_mse: mse.wins,
                wins_max: max.wins,
                exact_over_penalty_mse: exact_mse,
                exact_over_penalty_max: exact_max,
            });
        }
    }
    averages
}

impl PaperTable for Table2<'_> {
    fn number(&self) -> u32 {
        self.table
    }

    fn markdown(&self) -> String {
        let mut md =
            String::from("## Table 2: shapes, normalized MSE and max error against FEM\n\n");
        md += &self.preamble;
        self.averages_markdown(&mut md);
        paper_rows(&mut md);
        self.times_markdown(&mut md);
        md += "\n### Per shape\n\n| shape | E (Pa) | FEM mesh | BC | FreeForm MSE | FreeForm max | pin drift (mm) | exact MSE | exact max | exact drift (mm) | Simplicits MSE | Simplicits max | lower MSE | held FEM nodes / points | FEM max displ. / L | basis s | training s | FEM s |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
        for row in &self.shapes {
            md += &row.markdown();
        }
        md += "\nPaper rows: the paper's Table 2 (m = 32, GPU); its datasets are 20 Thingi10K shapes \
               and 19 SimReady assets, ours the 24 shared meshes (`data/README.md`), so only the \
               ordering and rough size compare.\n";
        md
    }

    fn csv(&self) -> String {
        csv_text(
            &[
                "name",
                "bc",
                "ours_mse",
                "ours_max",
                "simplicits_mse",
                "simplicits_max",
                "ours_fit",
                "simplicits_fit",
                "error",
            ],
            self.shapes.iter().map(|r| {
                vec![
                    r.name.clone(),
                    r.bc.to_string(),
                    csv_number(r.ours_mse),
                    csv_number(r.ours_max),
                    csv_number(r.simplicits_mse),
                    csv_number(r.simplicits_max),
                    csv_number(r.ours_fitting_residual),
                    csv_number(r.simplicits_fitting_residual),
                    format!(
                        "\"{}\"",
                        r.error.clone().unwrap_or_default().replace('"', "'")
                    ),
                ]
            }),
        )
    }
}

/// Table 2 of `study`, rendered ([`Table2`]).
pub fn table2(study: &ShapeStudy) -> RenderedTable {
    Table2::new(study).render()
}

/// The paper's Table 2 averages, one row per dataset and method.
fn paper_rows(md: &mut String) {
    for dataset in ["Thingi10K", "SimReady"] {
        let rows: Vec<&paper::Table2Row> = paper::TABLE2
            .iter()
            .filter(|r| r.dataset == dataset)
            .collect();
        let cells = |pick: fn(&paper::Table2Row) -> [f64; 2]| {
            rows.iter()
                .flat_map(|r| pick(r))
                .map(|v| format!("{v:.2e}"))
                .collect::<Vec<_>>()
                .join(" | ")
        };
        let _ = writeln!(
            md,
            "| paper {dataset} | Simplicits | {} | |",
            cells(|r| r.simplicits)
        );
        let _ = writeln!(
            md,
            "| paper {dataset} | FreeForm | {} | |",
            cells(|r| r.ours)
        );
    }
}
