//! Table 6: the basis fitting residual of our basis for each (test, m).

use std::fmt::Write as _;

use serde::Serialize;

use super::{BeamTableSettings, simplicits_line};
use crate::beam::study::BeamStudy;
use crate::beam_protocol::preamble::settings_lines;
use crate::report::table::{PaperTable, csv_number, csv_text, not_run_or};

/// Table 6 as data.
#[derive(Clone, Debug, Serialize)]
pub struct Table6<'a> {
    /// Always 6.
    pub table: u32,
    /// One row per (test, m), tests outermost.
    pub rows: Vec<Table6Row>,
    /// What the study ran with.
    pub settings: BeamTableSettings<'a>,
}

/// One (test, m) of Table 6: mean |x(z*) − x*| / L of the FEM trajectory through the basis.
#[derive(Clone, Debug, Serialize)]
pub struct Table6Row {
    /// "bend" or "twist".
    pub test: &'static str,
    /// Modes m.
    pub m: usize,
    /// Our basis's fitting residual.
    pub ours_fitting_residual: f64,
    /// Simplicits (ours): its network's fitting residual, if run.
    pub simplicits_fitting_residual: Option<f64>,
    /// Simplicits (ours): training time of the cached network (s).
    pub simplicits_training_seconds: Option<f64>,
}

impl<'a> Table6<'a> {
    /// Table 6 of `study`.
    pub fn new(study: &'a BeamStudy) -> Self {
        Table6 {
            table: 6,
            rows: study
                .rows
                .iter()
                .map(|r| Table6Row {
                    test: r.test.name(),
                    m: r.m,
                    ours_fitting_residual: r.fitting_residual,
                    simplicits_fitting_residual: r.simplicits.as_ref().map(|s| s.fitting_residual),
                    simplicits_training_seconds: r.simplicits.as_ref().map(|s| s.training_seconds),
                })
                .collect(),
            settings: BeamTableSettings::of(study),
        }
    }
}

impl PaperTable for Table6<'_> {
    fn number(&self) -> u32 {
        self.table
    }

    fn markdown(&self) -> String {
        let config = self.settings.config;
        let mut md = String::from("## Table 6: basis fitting residual (beam)\n\n");
        md += &settings_lines(config, self.settings.fem, self.settings.failed_rows);
        md += "The paper's Table 6 values did not survive either text rendering, so none are shown.\n";
        md += &simplicits_line(
            config,
            self.rows
                .iter()
                .map(|r| (r.test, r.m, r.simplicits_training_seconds)),
        );
        md += "\n| test | m | ours residual | Simplicits (ours) |\n|---|---|---|---|\n";
        for r in &self.rows {
            let _ = writeln!(
                md,
                "| {} | {} | {:.2e} | {} |",
                r.test,
                r.m,
                r.ours_fitting_residual,
                not_run_or(r.simplicits_fitting_residual)
            );
        }
        md
    }

    fn csv(&self) -> String {
        csv_text(
            &[
                "test",
                "m",
                "ours_fitting_residual",
                "simplicits_fitting_residual",
            ],
            self.rows.iter().map(|r| {
                vec![
                    r.test.to_string(),
                    r.m.to_string(),
                    format!("{:e}", r.ours_fitting_residual),
                    csv_number(r.simplicits_fitting_residual),
                ]
            }),
        )
    }
}
