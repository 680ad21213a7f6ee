//! The beam tables (1, 5, 6; 3 and 4 in [`crate::ablation::tables`]) as typed rows rendered to
//! Markdown (ours beside the paper's), JSON and CSV, and the Twist error-per-frame plot.

pub mod table1;
pub mod table5;
pub mod table6;
pub mod twist_plot;

use serde::Serialize;

use crate::beam::study::BeamStudy;
use crate::beam_protocol::evaluation::FemSummary;
use crate::beam_protocol::failed_row::FailedBeamRow;
use crate::beam_protocol::study_config::BeamStudyConfig;
use crate::report::table::{PaperTable, RenderedTable};
pub use table1::{Table1, Table1ParticleRow, Table1Row};
pub use table5::{Table5, Table5ParticleRow, Table5Row};
pub use table6::{Table6, Table6Row};
pub use twist_plot::twist_error_plot;

/// What a beam table ran with: the study's configuration and its FEM references.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct BeamTableSettings<'a> {
    /// The study's configuration.
    pub config: &'a BeamStudyConfig,
    /// One summary per test's FEM reference.
    pub fem: &'a [FemSummary],
    /// The runs that failed (each table's preamble names them; Table 1's JSON lists them).
    #[serde(skip)]
    pub failed_rows: &'a [FailedBeamRow],
}

impl<'a> BeamTableSettings<'a> {
    /// The settings of `study`.
    pub fn of(study: &'a BeamStudy) -> Self {
        BeamTableSettings {
            config: &study.config,
            fem: &study.fem,
            failed_rows: &study.failed_rows,
        }
    }
}

/// Table 1 of `study`, rendered ([`Table1`]).
pub fn table1(study: &BeamStudy) -> RenderedTable {
    Table1::new(study).render()
}

/// Table 5 of `study`, rendered ([`Table5`]).
pub fn table5(study: &BeamStudy) -> RenderedTable {
    Table5::new(study).render()
}

/// Table 6 of `study`, rendered ([`Table6`]).
pub fn table6(study: &BeamStudy) -> RenderedTable {
    Table6::new(study).render()
}

/// How the Simplicits column was produced (or that it was not), from the rows' (test, m,
/// Simplicits training seconds): the Bend rows' times are listed.
fn simplicits_line<'r>(
    config: &BeamStudyConfig,
    rows: impl Iterator<Item = (&'r str, usize, Option<f64>)>,
) -> String {
    match &config.simplicits {
        None => "\nSimplicits (ours) was not run (`--skip-simplicits`).\n".into(),
        Some(p) => {
            let seconds: Vec<String> = rows
                .filter(|(test, ..)| *test == "bend")
                .filter_map(|(_, m, s)| s.map(|s| format!("m={m}: {s:.0} s")))
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
