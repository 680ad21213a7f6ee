//! The preamble Tables 2 and 7 share (settings, FEM reference, quality gate, baseline,
//! metrics) and the cells both print.

use fem_ref::LatticeRefinement;
use hyperelastic::HessianTangent;
use std::fmt::Write as _;

use super::averages::mean_std;
use crate::reduced_settings::quadrature_rule_label;
use crate::shapes::boundary::ShapeBoundary;
use crate::shapes::catalog::{SHAPE_DENSITY, SHAPE_POISSON_RATIO};
use crate::shapes::config::ShapeStudyConfig;
use crate::shapes::reference::{ReferenceFactorReuse, STIFF_YOUNGS_MODULUS, ShapeFemParams};
use crate::shapes::result::{MethodScores, ShapeResult, ShapeRow, ShapeStudy};

/// The settings preamble shared by Tables 2 and 7.
pub(super) fn settings_lines(study: &ShapeStudy) -> String {
    let mut out = run_lines(study);
    let c = &study.config;
    let _ = writeln!(out, "Boundary conditions: {}", c.boundary.describe());
    fem_line(&mut out, c);
    gate_line(&mut out, study);
    simplicits_line(&mut out, c);
    metrics_line(&mut out, study);
    out
}

/// "Partial" and "Cached only" notices, then the reduced settings.
fn run_lines(study: &ShapeStudy) -> String {
    let c = &study.config;
    let s = &c.settings;
    let unfinished = study.unfinished();
    let unfinished_rows = study.unfinished_rows();
    let mut out = if unfinished.is_empty() {
        String::new()
    } else {
        format!(
            "**Partial:** {} of {} shapes finished when this was written (the run went on or was \
             stopped); not yet: {}. Rows, averages and counts cover the finished shapes only.\n\n",
            c.meshes.len() - unfinished.len(),
            c.meshes.len(),
            unfinished.join(", ")
        )
    };
    if !unfinished_rows.is_empty() {
        out += &format!(
            "**Partial:** rows not yet: {}. Averages and counts cover the finished rows only.\n\n",
            unfinished_rows.join(", ")
        );
    }
    if c.cached_only {
        out += "**Cached only:** nothing was computed for this table; a row whose FEM reference or \
                convergence check the cache does not hold says so and is not scored.\n\n";
    }
    out += &format!(
        "Settings: every mesh scaled so its largest bounding-box side is L = 1 m; ν = {}, ρ = {} \
         kg/m³, E per shape (10⁵ Pa organic, 10⁸ Pa manufactured; `eval::shapes::catalog`, shown \
         per shape below). m = {}, K = {} kernels; our basis and Simplicits on the same ≈{} grid \
         points; simulation on ≈{} grid points; Newton tolerance {:e}; {}{}. Elastic \
         quadrature: {}{}; Hessians: {}.\n",
        SHAPE_POISSON_RATIO,
        SHAPE_DENSITY,
        s.modes,
        s.kernels,
        s.basis_points,
        s.simulation_points,
        s.newton_tolerance,
        s.pin_rule_label(),
        s.pressure_label(),
        s.quadrature_label(),
        match c.simplicits_quadrature {
            Some(rule) if c.simplicits.is_some() =>
                format!(" (Simplicits: {})", quadrature_rule_label(rule)),
            _ => String::new(),
        },
        s.hessian_reuse_label()
    );
    out
}

/// The FEM reference: mesh, lattices, Newton, tangents.
fn fem_line(out: &mut String, c: &ShapeStudyConfig) {
    let _ = writeln!(
        out,
        "FEM reference: {:?} tetrahedra on the lattice mesher's mesh{}, the first of {} cells \
         across (×1.5, up to {}) whose volume is within {:.0}% of the surface's, else the \
         finest; pieces the lattice cut off from the body dropped (they would fall freely); \
         Dirichlet conditions on the nodes in each region{}; Newton to {:e} in at most {} \
         iterations a step{}, {} element tangents.",
        c.fem.order,
        match c.fem.refinement {
            LatticeRefinement::Uniform => String::new(),
            LatticeRefinement::Graded {
                max_halvings,
                linearity_tolerance,
            } => format!(
                " graded near the surface (up to {max_halvings} halvings where the signed \
                 distance departs from linear by {linearity_tolerance} of an edge)"
            ),
        },
        c.fem.first_cells_across,
        c.fem.max_cells_across,
        100.0 * c.fem.volume_tolerance,
        condition_lattices(&c.fem),
        c.fem.newton.tolerance,
        c.fem.newton.max_iterations,
        match c.fem.factor_reuse {
            ReferenceFactorReuse::Never => String::new(),
            reuse => format!(
                " ({} to {:e}, the Cholesky factor carried across iterations and steps while \
                 chord steps halve)",
                match reuse {
                    ReferenceFactorReuse::Pulls => "the Pulls' references".to_string(),
                    ReferenceFactorReuse::PullsAndStiffFixSide => format!(
                        "the Pulls' references and Fix side's where E ≥ {STIFF_YOUNGS_MODULUS:e} \
                         Pa"
                    ),
                    _ => "every reference".to_string(),
                },
                fem_ref::reusing_reference_newton().tolerance
            ),
        },
        match c.fem.tangent {
            HessianTangent::ProjectedPsd => "PSD-projected",
            HessianTangent::Exact => "exact",
            HessianTangent::ExactWhenDefinite => "exact (projected when not definite)",
            HessianTangent::AbsoluteEigenvalues => "absolute-eigenvalue",
            HessianTangent::ExactElseAbsolute => "exact (absolute-eigenvalue when not definite)",
        }
    );
}

/// The quality gate and how many rows pass it.
fn gate_line(out: &mut String, study: &ShapeStudy) {
    let c = &study.config;
    let gate = c.max_reference_volume_error;
    let rows: Vec<(&ShapeResult, &ShapeRow)> = study
        .shapes
        .iter()
        .flat_map(|s| s.rows.iter().map(move |r| (s, r)))
        .collect();
    let trusted = rows
        .iter()
        .filter(|(s, r)| s.untrusted_reference(r, gate).is_none())
        .count();
    let _ = writeln!(
        out,
        "Quality gate: a (shape, BC) row is scored, and averaged, only if its FEM mesh \
         keeps the surface's volume within ±{:.0}%, every FEM step converged{}: {trusted} of {} \
         rows pass.",
        100.0 * gate,
        if c.check_convergence {
            ", and the 1.5× finer reference changes it by less than a tenth of the smaller method \
             MSE"
        } else {
            " (convergence under refinement not checked: `--check-convergence`)"
        },
        rows.len()
    );
}

/// How Simplicits was trained, or that it was not run.
fn simplicits_line(out: &mut String, c: &ShapeStudyConfig) {
    let _ = writeln!(
        out,
        "{}",
        match &c.simplicits {
            Some(p) => format!(
                "Simplicits (ours): design §3.9's network trained for {} Adam steps{} of {} points × \
                 {} transforms, simulated by the same reduced simulator and scene.",
                p.steps,
                if p.steps < baselines::SimplicitsParams::default().steps {
                    " (fewer than the paper's 10 000)"
                } else {
                    ""
                },
                p.points_per_step,
                p.transforms_per_step
            ),
            None => "Simplicits was not run (`--skip-simplicits`).".into(),
        }
    );
}

/// The metrics and the study's wall time.
fn metrics_line(out: &mut String, study: &ShapeStudy) {
    let c = &study.config;
    let _ = writeln!(
        out,
        "Metrics (design §4.3) at the FEM mesh's vertices over frames 1..T: MSE = mean |x − x*|² / \
         L², max = max |x − x*| / L, fitting residual = mean |x(z*) − x*| / L. Wall time of the \
         study: {:.0} s ({} job{}){}.",
        study.seconds,
        c.jobs,
        if c.jobs == 1 { "" } else { "s" },
        if c.jobs > 1 {
            "; shapes shared the cores, so per-shape times (basis, training, FEM) are inflated \
             against a run of one shape at a time"
        } else {
            ""
        }
    );
}

pub(super) fn percent(v: Option<f64>) -> String {
    v.map_or("—".into(), |v| format!("{v:+.1}%"))
}

/// The per-shape error text of a row, if any (the shape's own error first).
pub(super) fn row_error(shape: &ShapeResult, boundary: ShapeBoundary) -> Option<String> {
    shape.error.clone().or_else(|| {
        shape
            .rows
            .iter()
            .find(|r| r.boundary == boundary)
            .and_then(|r| r.error.clone())
    })
}

/// A method's reduced step time over every row it ran: "mean ± sd ms on a median of N
/// quadrature points (n = rows)".
pub(super) fn step_time(
    study: &ShapeStudy,
    scores: fn(&ShapeRow) -> Option<MethodScores>,
) -> String {
    let runs: Vec<MethodScores> = study
        .shapes
        .iter()
        .flat_map(|s| &s.rows)
        .filter_map(scores)
        .collect();
    let ms: Vec<f64> = runs.iter().map(|r| r.ms_per_step).collect();
    let mut points: Vec<usize> = runs.iter().map(|r| r.quadrature_points).collect();
    points.sort_unstable();
    match mean_std(&ms) {
        Some((mean, sd)) => format!(
            "{mean:.1} ± {sd:.1} ms a step on a median of {} quadrature points (n = {})",
            points[points.len() / 2],
            ms.len()
        ),
        None => "—".into(),
    }
}

/// Where the conditions' references run on lattices of their own ("", or a clause naming
/// each: slab faces on vertex planes, pulled regions' edges refined).
fn condition_lattices(fem: &ShapeFemParams) -> String {
    let clauses: Vec<&str> = [
        (
            fem.clamp_on_lattice_plane,
            "Fix side's clamped face on a vertex plane",
        ),
        (
            fem.pull_slabs_on_lattice_planes,
            "Pull boundary's two slab faces on vertex planes",
        ),
        (
            fem.refines_region_edges(ShapeBoundary::PullFarthest),
            "the lattice refined to its finest level along Pull farthest's pulled balls' spheres",
        ),
        (
            fem.refines_region_edges(ShapeBoundary::PullBoundary),
            "the lattice refined to its finest level along Pull boundary's slab faces",
        ),
    ]
    .into_iter()
    .filter_map(|(on, clause)| on.then_some(clause))
    .collect();
    if clauses.is_empty() {
        String::new()
    } else {
        format!(" ({})", clauses.join("; "))
    }
}
