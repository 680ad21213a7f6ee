//! Cells of a (shape, boundary condition) row that Tables 2 and 7 print: the reference mesh in
//! words, the held nodes and points, which method is lower.

use crate::shapes::reference::FemMeshSummary;
use crate::shapes::result::FemRunSummary;

/// "N cells, V vertices, volume ±x%" of a reference's mesh, with the islands dropped.
pub(super) fn describe(mesh: Option<FemMeshSummary>) -> String {
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

/// "FEM nodes / integration points" held in each region, "+"-joined, or "—".
pub(super) fn held_cell(fem: Option<&FemRunSummary>, region_points: Option<&[usize]>) -> String {
    let join = |v: &[usize]| v.iter().map(usize::to_string).collect::<Vec<_>>().join("+");
    match (fem, region_points) {
        (Some(fem), Some(points)) if !points.is_empty() => {
            format!("{} / {}", join(&fem.region_nodes), join(points))
        }
        _ => "—".into(),
    }
}

/// Which method has the lower MSE, or why the reference cannot say.
pub(super) fn lower_cell(
    untrusted: Option<&str>,
    ours: Option<f64>,
    theirs: Option<f64>,
) -> String {
    match (untrusted, ours, theirs) {
        (Some(why), Some(_), _) => format!("no trustworthy reference: {why}"),
        (None, Some(o), Some(t)) if o < t => "FreeForm".into(),
        (None, Some(_), Some(_)) => "Simplicits".into(),
        _ => "—".into(),
    }
}
