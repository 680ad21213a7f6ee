//! Table 2: averages per boundary condition and collection with the paper's beside them,
//! training and step times, and one row per (shape, boundary condition).

use std::fmt::Write as _;

use serde_json::{Value, json};

use super::averages::{Measure, ShapeAverage, average, exact_average, groups, mean_std};
use super::preamble::{percent, row_error, settings_lines, step_time};
use crate::report::paper;
use crate::report::table::{RenderedTable, not_run_or, sci};
use crate::shapes::boundary::ShapeBoundary;
use crate::shapes::reference::FemMeshSummary;
use crate::shapes::result::{MethodScores, ShapeResult, ShapeRow, ShapeStudy};

/// Table 2: averages per boundary condition and collection, training times, per-shape rows.
pub fn table2(study: &ShapeStudy) -> RenderedTable {
    let mut md = String::from("## Table 2: shapes, normalized MSE and max error against FEM\n\n");
    md += &settings_lines(study);
    let averages = averages_section(study, &mut md);
    paper_rows(&mut md);
    let training_seconds = times_section(study, &mut md);
    md += "\n### Per shape\n\n| shape | E (Pa) | FEM mesh | BC | FreeForm MSE | FreeForm max | pin drift (mm) | exact MSE | exact max | exact drift (mm) | Simplicits MSE | Simplicits max | lower MSE | held FEM nodes / points | FEM max displ. / L | basis s | training s | FEM s |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
    let mut csv = String::from(
        "name,bc,ours_mse,ours_max,simplicits_mse,simplicits_max,ours_fit,simplicits_fit,error\n",
    );
    let mut rows = Vec::new();
    for shape in &study.shapes {
        for &boundary in &study.config.boundaries {
            rows.push(shape_row(study, shape, boundary, &mut md, &mut csv));
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
            "unfinished_rows": study.unfinished_rows(),
            "shapes": rows,
            "averages": averages,
            "training_seconds": training_seconds,
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

/// The averages per collection and boundary condition (Markdown into `md`), as JSON rows.
fn averages_section(study: &ShapeStudy, md: &mut String) -> Vec<Value> {
    let with_simplicits = study.config.simplicits.is_some();
    let gate = study.config.max_reference_volume_error;
    *md += "\n### Averages\n\n| shapes | method | ";
    for b in ShapeBoundary::ALL {
        let _ = write!(md, "{0} MSE | {0} max | ", b.title());
    }
    *md += "n per BC |\n|---|---|---|---|---|---|---|---|---|\n";
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
                *md,
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
                *md,
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
    averages
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

/// Training and step times (Markdown into `md`); the training times as JSON.
fn times_section(study: &ShapeStudy, md: &mut String) -> Value {
    let with_simplicits = study.config.simplicits.is_some();
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
    *md += "\n### Training time per shape (this machine, 2 cores)\n\n";
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
    *md += "\n### Reduced step time (this machine, every row)\n\n";
    let _ = writeln!(md, "- FreeForm: {}", step_time(study, |r| r.ours));
    if with_simplicits {
        let _ = writeln!(md, "- Simplicits: {}", step_time(study, |r| r.simplicits));
    }

    json!({
        "ours": mean_std(&basis).map(|(m, s)| json!({"mean": m, "std": s, "n": basis.len()})),
        "simplicits": mean_std(&training).map(|(m, s)| json!({"mean": m, "std": s, "n": training.len()})),
    })
}

/// "N cells, V vertices, volume ±x%" of a reference's mesh, with the islands dropped.
fn describe(mesh: Option<FemMeshSummary>) -> String {
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
}

/// One (shape, boundary condition): its Markdown row into `md`, CSV row into `csv`, and JSON.
fn shape_row(
    study: &ShapeStudy,
    shape: &ShapeResult,
    boundary: ShapeBoundary,
    md: &mut String,
    csv: &mut String,
) -> Value {
    let gate = study.config.max_reference_volume_error;
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
    let held = held_cell(row);
    let lower = lower_cell(untrusted.as_deref(), ours, theirs);
    let _ = writeln!(
        *md,
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
        *csv,
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
    json!({
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
    })
}

/// "FEM nodes / integration points" held in each region, "+"-joined, or "—".
fn held_cell(row: Option<&ShapeRow>) -> String {
    let join = |v: &[usize]| v.iter().map(usize::to_string).collect::<Vec<_>>().join("+");
    match row {
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
    }
}

/// Which method has the lower MSE, or why the reference cannot say.
fn lower_cell(
    untrusted: Option<&str>,
    ours: Option<MethodScores>,
    theirs: Option<MethodScores>,
) -> String {
    match (untrusted, ours, theirs) {
        (Some(why), Some(_), _) => format!("no trustworthy reference: {why}"),
        (None, Some(o), Some(t)) if o.mse < t.mse => "FreeForm".into(),
        (None, Some(_), Some(_)) => "Simplicits".into(),
        _ => "—".into(),
    }
}
