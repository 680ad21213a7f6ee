//! One (shape, boundary condition) row of Table 2: its typed fields (the JSON) and its Markdown
//! line.

use serde::Serialize;

use super::preamble::row_error;
use super::shape_cells::{describe, held_cell, lower_cell};
use crate::report::table::{not_run_or, sci};
use crate::shapes::boundary::ShapeBoundary;
use crate::shapes::reference::FemMeshSummary;
use crate::shapes::result::{FemRunSummary, ShapeResult, ShapeStudy};
use rkpm_core::CoverageReport;

/// One (shape, boundary condition) of Table 2. Errors are normalized by L = 1 m (design §4.3).
#[derive(Clone, Debug, Serialize)]
pub struct Table2Row {
    /// The shape's name (file stem).
    pub name: String,
    /// The shape's title ("Spot", "Thingi10K 32770").
    pub title: String,
    /// The boundary condition's name ("fix_side", …).
    pub bc: &'static str,
    /// The boundary condition.
    #[serde(skip)]
    pub boundary: ShapeBoundary,
    /// E (Pa).
    pub youngs_modulus: f64,
    /// The shape's collection ("Thingi10K", "classic", "other").
    pub collection: &'static str,
    /// Ours: normalized MSE.
    pub ours_mse: Option<f64>,
    /// Ours: normalized max error.
    pub ours_max: Option<f64>,
    /// Simplicits: normalized MSE.
    pub simplicits_mse: Option<f64>,
    /// Simplicits: normalized max error.
    pub simplicits_max: Option<f64>,
    /// Ours: fitting residual of the FEM trajectory.
    pub ours_fitting_residual: Option<f64>,
    /// Simplicits: fitting residual of the FEM trajectory.
    pub simplicits_fitting_residual: Option<f64>,
    /// Ours: steps whose Newton solve did not converge.
    pub ours_unconverged_steps: Option<usize>,
    /// Simplicits: steps whose Newton solve did not converge.
    pub simplicits_unconverged_steps: Option<usize>,
    /// Ours: largest distance of a held point from its target (m).
    pub ours_max_pin_deviation: Option<f64>,
    /// Ours: wall time per step (ms).
    pub ours_ms_per_step: Option<f64>,
    /// Simplicits: wall time per step (ms).
    pub simplicits_ms_per_step: Option<f64>,
    /// Ours: quadrature points.
    pub ours_quadrature_points: Option<usize>,
    /// Simplicits: quadrature points.
    pub simplicits_quadrature_points: Option<usize>,
    /// The reference mesh's relative volume error.
    pub fem_volume_error: Option<f64>,
    /// Whether the row's reference passes the quality gate.
    pub trusted: bool,
    /// Why it does not.
    pub why_untrusted: Option<String>,
    /// How much the finer check changes the reference (relative).
    pub reference_change: Option<f64>,
    /// The finer convergence check's run.
    pub reference_check: Option<FemRunSummary>,
    /// Why the check did not run.
    pub reference_check_error: Option<String>,
    /// Exact pins: normalized MSE.
    pub exact_mse: Option<f64>,
    /// Exact pins: normalized max error.
    pub exact_max: Option<f64>,
    /// Exact pins: largest distance of a held point from its target (m).
    pub exact_max_pin_deviation: Option<f64>,
    /// Why the exact-pin run failed.
    pub exact_error: Option<String>,
    /// The exact-pin basis's kernel coverage.
    pub exact_kernel_coverage: Option<CoverageReport>,
    /// Simplicits: largest distance of a held point from its target (m).
    pub simplicits_max_pin_deviation: Option<f64>,
    /// The reference's run.
    pub fem: Option<FemRunSummary>,
    /// Integration points held in each region.
    pub region_points: Option<Vec<usize>>,
    /// The shape's basis build (s).
    pub basis_seconds: Option<f64>,
    /// The shape's Simplicits training (s).
    pub training_seconds: Option<f64>,
    /// The shape's FEM references (s).
    pub fem_seconds: Option<f64>,
    /// The mesh this row's reference ran on.
    pub fem_mesh: Option<FemMeshSummary>,
    /// The row's error, if it failed.
    pub error: Option<String>,
}

impl Table2Row {
    pub(super) fn new(study: &ShapeStudy, shape: &ShapeResult, boundary: ShapeBoundary) -> Self {
        let gate = study.config.max_reference_volume_error;
        let row = shape.rows.iter().find(|r| r.boundary == boundary);
        // The mesh this row's reference ran on (any condition's may be its own lattice).
        let reference_mesh = row.and_then(|r| shape.reference_mesh(r)).or(shape.fem_mesh);
        let ours = row.and_then(|r| r.ours);
        let theirs = row.and_then(|r| r.simplicits);
        let exact = row.and_then(|r| r.exact);
        let untrusted = row.and_then(|r| shape.untrusted_reference(r, gate));
        Table2Row {
            name: shape.name.clone(),
            title: shape.title.clone(),
            bc: boundary.name(),
            boundary,
            youngs_modulus: shape.youngs_modulus,
            collection: shape.collection.name(),
            ours_mse: ours.map(|s| s.mse),
            ours_max: ours.map(|s| s.max),
            simplicits_mse: theirs.map(|s| s.mse),
            simplicits_max: theirs.map(|s| s.max),
            ours_fitting_residual: ours.map(|s| s.fitting_residual),
            simplicits_fitting_residual: theirs.map(|s| s.fitting_residual),
            ours_unconverged_steps: ours.map(|s| s.unconverged_steps),
            simplicits_unconverged_steps: theirs.map(|s| s.unconverged_steps),
            ours_max_pin_deviation: ours.map(|s| s.max_pin_deviation),
            ours_ms_per_step: ours.map(|s| s.ms_per_step),
            simplicits_ms_per_step: theirs.map(|s| s.ms_per_step),
            ours_quadrature_points: ours.map(|s| s.quadrature_points),
            simplicits_quadrature_points: theirs.map(|s| s.quadrature_points),
            fem_volume_error: reference_mesh.map(|m| m.relative_volume_error),
            trusted: row.is_some() && untrusted.is_none(),
            why_untrusted: untrusted,
            reference_change: row.and_then(|r| r.reference_change),
            reference_check: row.and_then(|r| r.reference_check.clone()),
            reference_check_error: row.and_then(|r| r.reference_check_error.clone()),
            exact_mse: exact.map(|s| s.mse),
            exact_max: exact.map(|s| s.max),
            exact_max_pin_deviation: exact.map(|s| s.max_pin_deviation),
            exact_error: row.and_then(|r| r.exact_error.clone()),
            exact_kernel_coverage: row.and_then(|r| r.exact_kernel_coverage),
            simplicits_max_pin_deviation: theirs.map(|s| s.max_pin_deviation),
            fem: row.and_then(|r| r.fem.clone()),
            region_points: row.map(|r| r.region_points.clone()),
            basis_seconds: shape.basis_seconds,
            training_seconds: shape.training_seconds,
            fem_seconds: shape.fem_seconds,
            fem_mesh: reference_mesh,
            error: row_error(shape, boundary),
        }
    }

    /// The row's Markdown line.
    pub(super) fn markdown(&self) -> String {
        let exact_cell = |v: Option<f64>| match (v, &self.exact_error) {
            (Some(v), _) => format!("{v:.2e}"),
            (None, Some(e)) => format!("failed: {e}"),
            (None, None) => "not run".into(),
        };
        let mm = |v: Option<f64>| v.map_or("—".into(), |v| format!("{:.2}", 1e3 * v));
        format!(
            "| {} ({}) | {:.0e} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
            self.name,
            self.title,
            self.youngs_modulus,
            describe(self.fem_mesh),
            self.boundary.title(),
            self.error
                .as_ref()
                .filter(|_| self.ours_mse.is_none())
                .map_or_else(|| sci(self.ours_mse), |e| format!("failed: {e}")),
            sci(self.ours_max),
            mm(self.ours_max_pin_deviation),
            exact_cell(self.exact_mse),
            exact_cell(self.exact_max),
            mm(self.exact_max_pin_deviation),
            not_run_or(self.simplicits_mse),
            not_run_or(self.simplicits_max),
            lower_cell(
                self.why_untrusted.as_deref(),
                self.ours_mse,
                self.simplicits_mse
            ),
            held_cell(self.fem.as_ref(), self.region_points.as_deref()),
            sci(self.fem.as_ref().map(|f| f.max_displacement)),
            self.basis_seconds.map_or("—".into(), |s| format!("{s:.1}")),
            self.training_seconds
                .map_or("—".into(), |s| format!("{s:.0}")),
            self.fem_seconds.map_or("—".into(), |s| format!("{s:.0}")),
        )
    }
}
