//! Tables 2 (MSE and max error on the shapes, training time) and 7 (basis fitting residual on
//! the shapes) as Markdown with the paper's averages beside ours, JSON (`"shapes"`: one row per
//! (shape, boundary condition); `"averages"`) and CSV.
//!
//! Averages are means over the shapes where every method in the row finished the boundary
//! condition and the FEM reference passed the quality gate
//! ([`ShapeResult::untrusted_reference`]: volume kept within
//! `ShapeStudyConfig::max_reference_volume_error`, every step converged; `n` says how many);
//! "improvement" is `(S − F) / S` of those averages, and "wins" counts the shapes where our
//! value is the lower one.

use fem_ref::LatticeRefinement;
use hyperelastic::HessianTangent;
use std::fmt::Write as _;

use serde::Serialize;
use serde_json::{Value, json};

use crate::beam::reduced::quadrature_rule_label;
use crate::report::paper;
use crate::report::table::{RenderedTable, not_run_or, sci};
use crate::shapes::boundary::ShapeBoundary;
use crate::shapes::catalog::{SHAPE_DENSITY, SHAPE_POISSON_RATIO, ShapeCollection};
use crate::shapes::reference::{
    FemMeshSummary, ReferenceFactorReuse, STIFF_YOUNGS_MODULUS, ShapeFemParams,
};
use crate::shapes::study::{MethodScores, ShapeResult, ShapeRow, ShapeStudy};

/// Which number of a method's scores a table reports.
#[derive(Clone, Copy)]
enum Measure {
    Mse,
    Max,
    Fit,
}

impl Measure {
    fn of(self, s: &MethodScores) -> f64 {
        match self {
            Measure::Mse => s.mse,
            Measure::Max => s.max,
            Measure::Fit => s.fitting_residual,
        }
    }
}

/// The average of one measure over one group of shapes and one boundary condition.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ShapeAverage {
    /// "all", "Thingi10K", "classic", "other".
    pub collection: String,
    /// The boundary condition.
    pub boundary: ShapeBoundary,
    /// Shapes averaged (those where both methods finished, or ours alone without Simplicits).
    pub shapes: usize,
    /// Our mean.
    pub ours: Option<f64>,
    /// Simplicits' mean over the same shapes.
    pub simplicits: Option<f64>,
    /// `(S − F) / S` of the means, in percent.
    pub improvement_percent: Option<f64>,
    /// Shapes where ours is lower.
    pub wins: usize,
}

/// Mean and standard deviation (population) of `values`, if any.
fn mean_std(values: &[f64]) -> Option<(f64, f64)> {
    if values.is_empty() {
        return None;
    }
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
    Some((mean, var.sqrt()))
}

/// The groups a study's shapes fall in: "all", then each collection present.
fn groups(study: &ShapeStudy) -> Vec<(String, Vec<&ShapeResult>)> {
    let mut out = vec![("all".to_string(), study.shapes.iter().collect::<Vec<_>>())];
    for c in [
        ShapeCollection::Thingi10k,
        ShapeCollection::Classic,
        ShapeCollection::Other,
    ] {
        let members: Vec<&ShapeResult> =
            study.shapes.iter().filter(|s| s.collection == c).collect();
        if !members.is_empty() && members.len() < study.shapes.len() {
            out.push((c.name().to_string(), members));
        }
    }
    out
}

fn average(
    collection: &str,
    shapes: &[&ShapeResult],
    boundary: ShapeBoundary,
    measure: Measure,
    with_simplicits: bool,
    gate: f64,
) -> ShapeAverage {
    let pairs: Vec<(f64, Option<f64>)> = trusted_rows(shapes, boundary, gate)
        .filter_map(|r| {
            let ours = measure.of(r.ours.as_ref()?);
            let theirs = r.simplicits.as_ref().map(|s| measure.of(s));
            (!with_simplicits || theirs.is_some()).then_some((ours, theirs))
        })
        .collect();
    let n = pairs.len();
    let ours = (n > 0).then(|| pairs.iter().map(|p| p.0).sum::<f64>() / n as f64);
    let simplicits = (with_simplicits && n > 0)
        .then(|| pairs.iter().filter_map(|p| p.1).sum::<f64>() / n as f64);
    ShapeAverage {
        collection: collection.into(),
        boundary,
        shapes: n,
        ours,
        simplicits,
        improvement_percent: match (ours, simplicits) {
            (Some(o), Some(s)) if s > 0.0 => Some(100.0 * (s - o) / s),
            _ => None,
        },
        wins: pairs
            .iter()
            .filter(|(o, s)| s.is_some_and(|s| *o < s))
            .count(),
    }
}

/// The `boundary` rows of `shapes` whose FEM reference passes the quality gate.
fn trusted_rows<'a>(
    shapes: &'a [&'a ShapeResult],
    boundary: ShapeBoundary,
    gate: f64,
) -> impl Iterator<Item = &'a ShapeRow> {
    shapes.iter().flat_map(move |s| {
        s.rows
            .iter()
            .filter(move |r| r.boundary == boundary && s.untrusted_reference(r, gate).is_none())
    })
}

/// Over the (shape, `boundary`) rows where both our penalty and exact-pin runs finished: the
/// ratio of the mean exact MSE (and max) to the mean penalty MSE (and max).
fn exact_average(shapes: &[&ShapeResult], boundary: ShapeBoundary, gate: f64) -> [Option<f64>; 2] {
    let pairs: Vec<(MethodScores, MethodScores)> = trusted_rows(shapes, boundary, gate)
        .filter_map(|r| Some((r.ours?, r.exact?)))
        .collect();
    let ratio = |pick: fn(&MethodScores) -> f64| {
        let penalty: f64 = pairs.iter().map(|p| pick(&p.0)).sum();
        let exact: f64 = pairs.iter().map(|p| pick(&p.1)).sum();
        (!pairs.is_empty() && penalty > 0.0).then(|| exact / penalty)
    };
    [ratio(|s| s.mse), ratio(|s| s.max)]
}

/// The settings preamble shared by Tables 2 and 7.
fn settings_lines(study: &ShapeStudy) -> String {
    let c = &study.config;
    let s = &c.settings;
    let unfinished = study.unfinished();
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
    if c.cached_only {
        out += "**Cached only:** nothing was computed for this table; a row whose FEM reference or \
                convergence check the cache does not hold says so and is not scored.\n\n";
    }
    out += &format!(
        "Settings: every mesh scaled so its largest bounding-box side is L = 1 m; ν = {}, ρ = {} \
         kg/m³, E per shape (10⁵ Pa organic, 10⁸ Pa manufactured; `eval::shapes::catalog`, shown \
         per shape below). m = {}, K = {} kernels; our basis and Simplicits on the same ≈{} grid \
         points; simulation on ≈{} grid points; Newton tolerance {:e}; pin penalty {}. Elastic \
         quadrature: {}{}; Hessians: {}.\n",
        SHAPE_POISSON_RATIO,
        SHAPE_DENSITY,
        s.modes,
        s.kernels,
        s.basis_points,
        s.simulation_points,
        s.tolerance,
        s.pin_rule_label(),
        s.quadrature_label(),
        match c.simplicits_quadrature {
            Some(rule) if c.simplicits.is_some() =>
                format!(" (Simplicits: {})", quadrature_rule_label(rule)),
            _ => String::new(),
        },
        s.hessian_reuse_label()
    );
    let _ = writeln!(out, "Boundary conditions: {}", c.boundary.describe());
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
    out
}

fn percent(v: Option<f64>) -> String {
    v.map_or("—".into(), |v| format!("{v:+.1}%"))
}

/// The per-shape error text of a row, if any (the shape's own error first).
fn row_error(shape: &ShapeResult, boundary: ShapeBoundary) -> Option<String> {
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
fn step_time(study: &ShapeStudy, scores: fn(&ShapeRow) -> Option<MethodScores>) -> String {
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

/// Table 2: averages per boundary condition and collection, training times, per-shape rows.
pub fn table2(study: &ShapeStudy) -> RenderedTable {
    let with_simplicits = study.config.simplicits.is_some();
    let gate = study.config.max_reference_volume_error;
    let mut md = String::from("## Table 2: shapes, normalized MSE and max error against FEM\n\n");
    md += &settings_lines(study);
    md += "\n### Averages\n\n| shapes | method | ";
    for b in ShapeBoundary::ALL {
        let _ = write!(md, "{0} MSE | {0} max | ", b.title());
    }
    md += "n per BC |\n|---|---|---|---|---|---|---|---|---|\n";
    let mut averages = Vec::new();
    for (collection, shapes) in groups(study) {
        let mse: Vec<ShapeAverage> = ShapeBoundary::ALL
            .iter()
            .map(|&b| average(&collection, &shapes, b, Measure::Mse, with_simplicits, gate))
            .collect();
        let max: Vec<ShapeAverage> = ShapeBoundary::ALL
            .iter()
            .map(|&b| average(&collection, &shapes, b, Measure::Max, with_simplicits, gate))
            .collect();
        let counts: Vec<String> = mse.iter().map(|a| a.shapes.to_string()).collect();
        let counts = counts.join("/");
        let mut line = |method: &str, cell: &dyn Fn(&ShapeAverage) -> String| {
            let cells: Vec<String> = mse
                .iter()
                .zip(&max)
                .flat_map(|(a, b)| [cell(a), cell(b)])
                .collect();
            let _ = writeln!(
                md,
                "| {collection} | {method} | {} | {counts} |",
                cells.join(" | ")
            );
        };
        if with_simplicits {
            line("Simplicits (ours)", &|a| sci(a.simplicits));
        }
        line("FreeForm (ours)", &|a| sci(a.ours));
        if with_simplicits {
            line("improvement", &|a| percent(a.improvement_percent));
            line("wins", &|a| format!("{}/{}", a.wins, a.shapes));
        }
        if study.config.exact_pins.is_some() {
            let exact: Vec<[Option<f64>; 2]> = ShapeBoundary::ALL
                .iter()
                .map(|&b| exact_average(&shapes, b, gate))
                .collect();
            let cells: Vec<String> = exact
                .iter()
                .flat_map(|r| r.map(|v| v.map_or("—".into(), |v| format!("{v:.2}×"))))
                .collect();
            let _ = writeln!(
                md,
                "| {collection} | FreeForm exact pins ÷ penalty (mean over the same shapes) | {} | |",
                cells.join(" | ")
            );
        }
        for (m, x) in mse.into_iter().zip(max) {
            averages.push(json!({
                "collection": collection,
                "bc": m.boundary.name(),
                "shapes": m.shapes,
                "ours_mse": m.ours,
                "ours_max": x.ours,
                "simplicits_mse": m.simplicits,
                "simplicits_max": x.simplicits,
                "improvement_mse_percent": m.improvement_percent,
                "improvement_max_percent": x.improvement_percent,
                "wins_mse": m.wins,
                "wins_max": x.wins,
            }));
        }
    }
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
    let fem: Vec<f64> = study.shapes.iter().filter_map(|s| s.fem_seconds).collect();
    // Each shape's convergence checks, where any ran: the seconds of their runs.
    let steps = study.config.boundary.steps as f64;
    let checks: Vec<f64> = study
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
    let stat = |v: &[f64]| {
        mean_std(v).map_or("—".into(), |(m, s)| {
            format!("{m:.2} ± {s:.2} s (n = {})", v.len())
        })
    };
    md += "\n### Training time per shape (this machine, 2 cores)\n\n";
    let _ = writeln!(
        md,
        "- FreeForm basis (sampling + eigen solve): {}",
        stat(&basis)
    );
    let _ = writeln!(md, "- Simplicits training: {}", stat(&training));
    if let (Some((b, _)), Some((t, _))) = (mean_std(&basis), mean_std(&training)) {
        let _ = writeln!(
            md,
            "- ratio of the means: {:.0}× (improvement {:.1}%)",
            t / b,
            100.0 * (1.0 - b / t)
        );
    }
    let _ = writeln!(md, "- FEM reference, three runs: {}", stat(&fem));
    if !checks.is_empty() {
        let _ = writeln!(
            md,
            "- FEM convergence checks (the 1.5× finer references): {}",
            stat(&checks)
        );
    }
    for (dataset, sm, ss, fm, fs) in paper::TABLE2_TRAINING {
        let _ = writeln!(
            md,
            "- paper {dataset} (GPU): Simplicits {sm:.2} ± {ss:.2} s, FreeForm {fm:.2} ± {fs:.2} s"
        );
    }
    md += "\n### Reduced step time (this machine, every row)\n\n";
    let _ = writeln!(md, "- FreeForm: {}", step_time(study, |r| r.ours));
    if with_simplicits {
        let _ = writeln!(md, "- Simplicits: {}", step_time(study, |r| r.simplicits));
    }

    md += "\n### Per shape\n\n| shape | E (Pa) | FEM mesh | BC | FreeForm MSE | FreeForm max | pin drift (mm) | exact MSE | exact max | exact drift (mm) | Simplicits MSE | Simplicits max | lower MSE | held FEM nodes / points | FEM max displ. / L | basis s | training s | FEM s |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
    let mut csv = String::from(
        "name,bc,ours_mse,ours_max,simplicits_mse,simplicits_max,ours_fit,simplicits_fit,error\n",
    );
    let mut rows = Vec::new();
    let describe = |mesh: Option<FemMeshSummary>| {
        mesh.map_or("—".into(), |m| {
            format!(
                "{} cells, {} vertices, volume {:+.1}%{}",
                m.cells_across,
                m.vertices,
                100.0 * m.relative_volume_error,
                if m.dropped_pieces > 0 {
                    format!(
                        " ({} island(s) of {:.1}% dropped)",
                        m.dropped_pieces,
                        100.0 * m.dropped_volume_fraction
                    )
                } else {
                    String::new()
                }
            )
        })
    };
    for shape in &study.shapes {
        for &boundary in &study.config.boundaries {
            let row = shape.rows.iter().find(|r| r.boundary == boundary);
            // The mesh this row's reference ran on (any condition's may be its own lattice).
            let reference_mesh = row.and_then(|r| shape.reference_mesh(r)).or(shape.fem_mesh);
            let mesh = describe(reference_mesh);
            let ours = row.and_then(|r| r.ours);
            let theirs = row.and_then(|r| r.simplicits);
            let exact = row.and_then(|r| r.exact);
            let untrusted = row.and_then(|r| shape.untrusted_reference(r, gate));
            let exact_cell = |v: Option<f64>| match (v, row.and_then(|r| r.exact_error.as_ref())) {
                (Some(v), _) => format!("{v:.2e}"),
                (None, Some(e)) => format!("failed: {e}"),
                (None, None) => "not run".into(),
            };
            let mm = |v: Option<f64>| v.map_or("—".into(), |v| format!("{:.2}", 1e3 * v));
            let error = row_error(shape, boundary);
            let join = |v: &[usize]| v.iter().map(usize::to_string).collect::<Vec<_>>().join("+");
            let held = match row {
                Some(r) if r.fem.is_some() && !r.region_points.is_empty() => format!(
                    "{} / {}",
                    join(
                        &r.fem
                            .as_ref()
                            .map_or(Vec::new(), |f| f.region_nodes.clone())
                    ),
                    join(&r.region_points)
                ),
                _ => "—".into(),
            };
            let lower = match (&untrusted, ours, theirs) {
                (Some(why), Some(_), _) => format!("no trustworthy reference: {why}"),
                (None, Some(o), Some(t)) if o.mse < t.mse => "FreeForm".into(),
                (None, Some(_), Some(_)) => "Simplicits".into(),
                _ => "—".into(),
            };
            let _ = writeln!(
                md,
                "| {} ({}) | {:.0e} | {mesh} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {lower} | {held} | {} | {} | {} | {} |",
                shape.name,
                shape.title,
                shape.youngs_modulus,
                boundary.title(),
                error
                    .as_ref()
                    .filter(|_| ours.is_none())
                    .map_or_else(|| sci(ours.map(|s| s.mse)), |e| format!("failed: {e}")),
                sci(ours.map(|s| s.max)),
                mm(ours.map(|s| s.max_pin_deviation)),
                exact_cell(exact.map(|s| s.mse)),
                exact_cell(exact.map(|s| s.max)),
                mm(exact.map(|s| s.max_pin_deviation)),
                not_run_or(theirs.map(|s| s.mse)),
                not_run_or(theirs.map(|s| s.max)),
                sci(row.and_then(|r| r.fem.as_ref()).map(|f| f.max_displacement)),
                shape
                    .basis_seconds
                    .map_or("—".into(), |s| format!("{s:.1}")),
                shape
                    .training_seconds
                    .map_or("—".into(), |s| format!("{s:.0}")),
                shape.fem_seconds.map_or("—".into(), |s| format!("{s:.0}")),
            );
            let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:e}"));
            let _ = writeln!(
                csv,
                "{},{},{},{},{},{},{},{},\"{}\"",
                shape.name,
                boundary.name(),
                opt(ours.map(|s| s.mse)),
                opt(ours.map(|s| s.max)),
                opt(theirs.map(|s| s.mse)),
                opt(theirs.map(|s| s.max)),
                opt(ours.map(|s| s.fitting_residual)),
                opt(theirs.map(|s| s.fitting_residual)),
                error.clone().unwrap_or_default().replace('"', "'"),
            );
            rows.push(json!({
                "name": shape.name,
                "bc": boundary.name(),
                "youngs_modulus": shape.youngs_modulus,
                "collection": shape.collection.name(),
                "ours_mse": ours.map(|s| s.mse),
                "ours_max": ours.map(|s| s.max),
                "simplicits_mse": theirs.map(|s| s.mse),
                "simplicits_max": theirs.map(|s| s.max),
                "ours_fitting_residual": ours.map(|s| s.fitting_residual),
                "simplicits_fitting_residual": theirs.map(|s| s.fitting_residual),
                "ours_unconverged_steps": ours.map(|s| s.unconverged_steps),
                "simplicits_unconverged_steps": theirs.map(|s| s.unconverged_steps),
                "ours_max_pin_deviation": ours.map(|s| s.max_pin_deviation),
                "ours_ms_per_step": ours.map(|s| s.ms_per_step),
                "simplicits_ms_per_step": theirs.map(|s| s.ms_per_step),
                "ours_quadrature_points": ours.map(|s| s.quadrature_points),
                "simplicits_quadrature_points": theirs.map(|s| s.quadrature_points),
                "fem_volume_error": reference_mesh.map(|m| m.relative_volume_error),
                "trusted": row.is_some() && untrusted.is_none(),
                "why_untrusted": untrusted,
                "reference_change": row.and_then(|r| r.reference_change),
                "reference_check": row.and_then(|r| r.reference_check.clone()),
                "reference_check_error": row.and_then(|r| r.reference_check_error.clone()),
                "exact_mse": exact.map(|s| s.mse),
                "exact_max": exact.map(|s| s.max),
                "exact_max_pin_deviation": exact.map(|s| s.max_pin_deviation),
                "exact_error": row.and_then(|r| r.exact_error.clone()),
                "exact_kernel_coverage": row.and_then(|r| r.exact_kernel_coverage),
                "simplicits_max_pin_deviation": theirs.map(|s| s.max_pin_deviation),
                "fem": row.and_then(|r| r.fem.clone()),
                "region_points": row.map(|r| r.region_points.clone()),
                "basis_seconds": shape.basis_seconds,
                "training_seconds": shape.training_seconds,
                "fem_seconds": shape.fem_seconds,
                "fem_mesh": reference_mesh,
                "error": error,
            }));
        }
    }
    md += "\nPaper rows: the paper's Table 2 (m = 32, GPU); its datasets are 20 Thingi10K shapes \
           and 19 SimReady assets, ours the 24 shared meshes (`data/README.md`), so only the \
           ordering and rough size compare.\n";
    RenderedTable {
        number: 2,
        markdown: md,
        json: json!({
            "table": 2,
            "unfinished": study.unfinished(),
            "shapes": rows,
            "averages": averages,
            "training_seconds": {
                "ours": mean_std(&basis).map(|(m, s)| json!({"mean": m, "std": s, "n": basis.len()})),
                "simplicits": mean_std(&training).map(|(m, s)| json!({"mean": m, "std": s, "n": training.len()})),
            },
            "paper": paper::TABLE2.iter().map(|r| json!({
                "dataset": r.dataset, "bc": r.boundary,
                "simplicits_mse": r.simplicits[0], "simplicits_max": r.simplicits[1],
                "ours_mse": r.ours[0], "ours_max": r.ours[1],
            })).collect::<Vec<Value>>(),
            "wall_seconds": study.seconds,
            "settings": serde_json::to_value(&study.config).unwrap_or(Value::Null),
        }),
        csv,
    }
}

/// Table 7: the basis fitting residual of each FEM trajectory through each method's
/// deformation map, averaged per boundary condition and per shape.
pub fn table7(study: &ShapeStudy) -> RenderedTable {
    let with_simplicits = study.config.simplicits.is_some();
    let gate = study.config.max_reference_volume_error;
    let mut md =
        String::from("## Table 7: shapes, basis fitting residual of the FEM trajectory\n\n");
    md += &settings_lines(study);
    md += "The paper's Table 7 values are not in either text rendering of the paper (only its \
           caption: ours lower than Simplicits throughout), so none are printed.\n\n";
    md += "| shapes | BC | FreeForm | Simplicits (ours) | improvement | wins | n |\n|---|---|---|---|---|---|---|\n";
    let mut averages = Vec::new();
    for (collection, shapes) in groups(study) {
        for b in ShapeBoundary::ALL {
            let a = average(&collection, &shapes, b, Measure::Fit, with_simplicits, gate);
            let _ = writeln!(
                md,
                "| {collection} | {} | {} | {} | {} | {}/{} | {} |",
                b.title(),
                sci(a.ours),
                not_run_or(a.simplicits),
                percent(a.improvement_percent),
                a.wins,
                a.shapes,
                a.shapes
            );
            averages.push(a);
        }
    }
    md += "\n| shape | BC | FreeForm | Simplicits (ours) |\n|---|---|---|---|\n";
    let mut csv = String::from("name,bc,ours_fit,simplicits_fit\n");
    let mut rows = Vec::new();
    for shape in &study.shapes {
        for &boundary in &study.config.boundaries {
            let row = shape.rows.iter().find(|r| r.boundary == boundary);
            let ours = row.and_then(|r| r.ours).map(|s| s.fitting_residual);
            let theirs = row.and_then(|r| r.simplicits).map(|s| s.fitting_residual);
            let error = row_error(shape, boundary);
            let _ = writeln!(
                md,
                "| {} | {} | {} | {} |",
                shape.name,
                boundary.title(),
                error
                    .as_ref()
                    .filter(|_| ours.is_none())
                    .map_or_else(|| sci(ours), |e| format!("failed: {e}")),
                not_run_or(theirs)
            );
            let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:e}"));
            let _ = writeln!(
                csv,
                "{},{},{},{}",
                shape.name,
                boundary.name(),
                opt(ours),
                opt(theirs)
            );
            rows.push(json!({
                "name": shape.name,
                "bc": boundary.name(),
                "ours_fitting_residual": ours,
                "simplicits_fitting_residual": theirs,
                "error": error,
            }));
        }
    }
    RenderedTable {
        number: 7,
        markdown: md,
        json: json!({
            "table": 7,
            "unfinished": study.unfinished(),
            "shapes": rows,
            "averages": averages,
            "wall_seconds": study.seconds,
            "settings": serde_json::to_value(&study.config).unwrap_or(Value::Null),
        }),
        csv,
    }
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    use super::*;
    use crate::shapes::study::{FemRunSummary, ShapeStudyConfig};

    fn scores(mse: f64) -> MethodScores {
        MethodScores {
            mse,
            max: mse.sqrt(),
            fitting_residual: 0.1 * mse,
            ms_per_step: 1.0,
            quadrature_points: 100,
            unconverged_steps: 0,
            max_pin_deviation: 0.0,
        }
    }

    /// A shape with one row per boundary condition, its FEM mesh off by `volume_error` and its
    /// FEM runs leaving `unconverged` steps, our MSE `mse` everywhere.
    fn shape(name: &str, volume_error: f64, unconverged: usize, mse: f64) -> ShapeResult {
        ShapeResult {
            name: name.into(),
            title: name.into(),
            collection: ShapeCollection::Other,
            class: None,
            youngs_modulus: 1e5,
            basis_points: 1000,
            basis_seconds: Some(1.0),
            training_seconds: None,
            fem_mesh: Some(FemMeshSummary {
                cells_across: 8,
                vertices: 100,
                tets: 300,
                relative_volume_error: volume_error,
                dropped_pieces: 0,
                dropped_volume_fraction: 0.0,
            }),
            fem_seconds: Some(1.0),
            rows: ShapeBoundary::ALL
                .iter()
                .map(|&boundary| ShapeRow {
                    boundary,
                    fem: Some(FemRunSummary {
                        region_nodes: vec![10],
                        max_displacement: 0.1,
                        dofs: 300,
                        seconds_per_step: 0.01,
                        iterations_per_step: 2.0,
                        unconverged_steps: unconverged,
                        cached: false,
                    }),
                    ours: Some(scores(mse)),
                    simplicits: None,
                    exact: None,
                    exact_error: None,
                    exact_kernel_coverage: None,
                    reference_change: None,
                    reference_check: None,
                    reference_check_error: None,
                    fem_mesh: None,
                    region_points: vec![5],
                    error: None,
                })
                .collect(),
            error: None,
        }
    }

    #[test]
    fn a_partial_study_says_which_shapes_are_not_finished_and_a_complete_one_says_nothing() {
        let mut config = ShapeStudyConfig::full(
            vec![
                PathBuf::from("meshes/done.obj"),
                PathBuf::from("meshes/later.stl"),
            ],
            PathBuf::from("unused"),
        );
        config.simplicits = None;
        let partial = ShapeStudy {
            config,
            shapes: vec![shape("done.obj", 0.0, 0, 1e-3)],
            seconds: 1.0,
        };
        let complete = ShapeStudy {
            shapes: vec![
                shape("done.obj", 0.0, 0, 1e-3),
                shape("later.stl", 0.0, 0, 2e-3),
            ],
            ..partial.clone()
        };
        for (table, complete_table) in [
            (table2(&partial), table2(&complete)),
            (table7(&partial), table7(&complete)),
        ] {
            let said = "**Partial:** 1 of 2 shapes finished";
            assert!(table.markdown.contains(said), "{}", table.markdown);
            assert!(table.markdown.contains("not yet: later.stl."));
            assert_eq!(table.json["unfinished"], json!(["later.stl"]));
            assert_eq!(table.json["shapes"].as_array().unwrap().len(), 3);
            assert!(!complete_table.markdown.contains("Partial"));
            assert_eq!(complete_table.json["unfinished"], json!([]));
            assert_eq!(complete_table.json["shapes"].as_array().unwrap().len(), 6);
        }
    }

    #[test]
    fn a_study_of_one_condition_lists_only_its_rows_and_averages_no_shape_for_the_others() {
        let mut config = ShapeStudyConfig::full(Vec::new(), PathBuf::from("unused"));
        config.simplicits = None;
        config.boundaries = vec![ShapeBoundary::PullFarthest];
        config.fem = ShapeFemParams::graded();
        let mut pulled = shape("pulled", 0.0, 0, 1e-3);
        pulled
            .rows
            .retain(|r| r.boundary == ShapeBoundary::PullFarthest);
        let study = ShapeStudy {
            config,
            shapes: vec![pulled],
            seconds: 1.0,
        };
        for table in [table2(&study), table7(&study)] {
            // The settings name the references' own lattices and the Pulls' factor reuse.
            for said in [
                "along Pull farthest's pulled balls' spheres",
                "the Pulls' references and Fix side's where E ≥ 1e7 Pa to 1e-8, the Cholesky \
                 factor carried",
            ] {
                assert!(table.markdown.contains(said), "{said}: {}", table.markdown);
            }
            let rows = table.json["shapes"].as_array().unwrap();
            assert_eq!(rows.len(), 1, "{rows:?}");
            assert_eq!(rows[0]["bc"], "pull_farthest");
            for average in table.json["averages"].as_array().unwrap() {
                // (Table 2 names the condition "bc", Table 7 "boundary".)
                let bc = average.get("bc").or_else(|| average.get("boundary"));
                let n = average["shapes"].as_u64();
                let expected = u64::from(bc.is_some_and(|bc| bc == "pull_farthest"));
                assert_eq!(n, Some(expected), "{average}");
            }
        }
    }

    #[test]
    fn the_step_time_section_averages_every_row_a_method_ran() {
        let mut config = ShapeStudyConfig::full(Vec::new(), PathBuf::from("unused"));
        config.simplicits = None;
        let fast = shape("fast", 0.0, 0, 1e-3);
        let mut slow = shape("slow", 0.0, 0, 1e-3);
        for row in &mut slow.rows {
            row.ours = Some(MethodScores {
                ms_per_step: 3.0,
                quadrature_points: 300,
                ..scores(1e-3)
            });
        }
        let study = ShapeStudy {
            config,
            shapes: vec![fast, slow],
            seconds: 1.0,
        };
        let md = table2(&study).markdown;
        // Three rows at 1 ms on 100 points, three at 3 ms on 300: mean 2, sd 1; the median of
        // six counts is the upper middle one.
        assert!(
            md.contains(
                "- FreeForm: 2.0 ± 1.0 ms a step on a median of 300 quadrature points (n = 6)"
            ),
            "{md}"
        );
        assert!(!md.contains("- Simplicits:"), "not run: {md}");
    }

    #[test]
    fn convergence_checks_report_their_finer_runs_and_their_time_per_shape() {
        let mut config = ShapeStudyConfig::full(Vec::new(), PathBuf::from("unused"));
        config.simplicits = None;
        let steps = config.boundary.steps as f64;
        // Two of "checked"'s rows ran a check of 1234 DOFs at 2 s a step; "unchecked" none.
        let mut checked = shape("checked", 0.0, 0, 1e-3);
        for row in &mut checked.rows[..2] {
            row.reference_check = row.fem.clone().map(|fem| FemRunSummary {
                dofs: 1234,
                seconds_per_step: 2.0,
                ..fem
            });
            row.reference_change = Some(1e-6);
        }
        let study = ShapeStudy {
            config,
            shapes: vec![checked, shape("unchecked", 0.0, 0, 1e-3)],
            seconds: 1.0,
        };
        let t2 = table2(&study);
        let rows = t2.json["shapes"].as_array().unwrap();
        let checks: Vec<&Value> = rows.iter().map(|r| &r["reference_check"]).collect();
        assert_eq!(checks[0]["dofs"], 1234);
        assert_eq!(checks[1]["seconds_per_step"], 2.0);
        assert!(checks[2].is_null() && checks[3].is_null(), "{checks:?}");
        let expected = format!(
            "- FEM convergence checks (the 1.5× finer references): {:.2} ± 0.00 s (n = 1)",
            2.0 * 2.0 * steps
        );
        assert!(t2.markdown.contains(&expected), "{}", t2.markdown);
    }

    #[test]
    fn references_that_lost_volume_stalled_or_change_under_refinement_are_named_and_left_out_of_the_averages()
     {
        let mut config = ShapeStudyConfig::full(Vec::new(), PathBuf::from("unused"));
        config.simplicits = None;
        // A reference 1.5× finer changes "coarse" by half its method error: not converged;
        // "good" by a hundredth of it.
        let mut coarse = shape("coarse", 0.0, 0, 1e-3);
        for row in &mut coarse.rows {
            row.reference_change = Some(5e-4);
        }
        let mut good = shape("good", -0.02, 0, 1e-4);
        for row in &mut good.rows {
            row.reference_change = Some(1e-6);
        }
        // Fix side ran on its own mesh (a shifted lattice), which lost a tenth of the volume
        // while the shape's mesh kept it: that row alone is out.
        let mut clamped = shape("clamped", 0.0, 0, 1e-2);
        for row in &mut clamped.rows {
            row.reference_change = Some(1e-6);
        }
        clamped.rows[0].fem_mesh = clamped.fem_mesh.map(|m| FemMeshSummary {
            relative_volume_error: -0.1,
            ..m
        });
        assert_eq!(clamped.rows[0].boundary, ShapeBoundary::FixSide);
        let study = ShapeStudy {
            config,
            shapes: vec![
                good,
                shape("thin", -0.40, 0, 1e-1),
                shape("stalled", 0.01, 2, 1e-2),
                coarse,
                clamped,
            ],
            seconds: 1.0,
        };
        let t2 = table2(&study);
        let rows = t2.json["shapes"].as_array().unwrap();
        let of = |name: &str| rows.iter().find(|r| r["name"] == name).unwrap();
        assert_eq!(of("good")["trusted"], true);
        assert_eq!(of("thin")["trusted"], false);
        assert!(
            of("thin")["why_untrusted"]
                .as_str()
                .unwrap()
                .contains("-40.0% of the surface's volume"),
            "{}",
            of("thin")
        );
        assert!((of("thin")["fem_volume_error"].as_f64().unwrap() + 0.4).abs() < 1e-12);
        assert!(
            of("stalled")["why_untrusted"]
                .as_str()
                .unwrap()
                .contains("2 steps unconverged")
        );
        assert!(
            of("coarse")["why_untrusted"]
                .as_str()
                .unwrap()
                .contains("finer reference changes it by 5.00e-4"),
            "{}",
            of("coarse")
        );
        assert_eq!(of("good")["reference_change"].as_f64(), Some(1e-6));
        let clamped_rows: Vec<&Value> = rows.iter().filter(|r| r["name"] == "clamped").collect();
        let (fix, pulls) = clamped_rows.split_first().unwrap();
        assert_eq!(fix["bc"], "fix_side");
        assert_eq!(fix["trusted"], false);
        assert!(
            fix["why_untrusted"]
                .as_str()
                .unwrap()
                .contains("-10.0% of the surface's volume"),
            "{fix}"
        );
        assert_eq!(fix["fem_volume_error"].as_f64(), Some(-0.1));
        for pull in pulls {
            assert_eq!(pull["trusted"], true, "{pull}");
            assert_eq!(pull["fem_volume_error"].as_f64(), Some(0.0));
        }
        // Only the trusted rows enter the averages: Fix side has "good" alone, the Pulls
        // "good" and "clamped".
        for average in t2.json["averages"].as_array().unwrap() {
            let (shapes, mse) = if average["bc"] == "fix_side" {
                (1, 1e-4)
            } else {
                (2, 0.5 * (1e-4 + 1e-2))
            };
            assert_eq!(average["shapes"], shapes, "{average}");
            let ours = average["ours_mse"].as_f64().unwrap();
            assert!((ours - mse).abs() < 1e-15, "{average}");
        }
        assert!(t2.markdown.contains("no trustworthy reference"));
        let t7 = table7(&study);
        let averages = t7.json["averages"].as_array().unwrap();
        // Per collection, in ShapeBoundary::ALL's order: Fix side, Pull farthest, Pull boundary.
        assert!(!averages.is_empty());
        for collection in averages.chunks(3) {
            let shapes: Vec<&Value> = collection.iter().map(|a| &a["shapes"]).collect();
            assert_eq!(shapes, [1, 2, 2], "{collection:?}");
        }
    }
}
