//! The averages Tables 2 and 7 print: one measure over one group of shapes and one boundary
//! condition, over the rows whose reference passes the quality gate.

use serde::Serialize;

use crate::shapes::boundary::ShapeBoundary;
use crate::shapes::catalog::ShapeCollection;
use crate::shapes::result::{MethodScores, ShapeResult, ShapeRow, ShapeStudy};

/// Which number of a method's scores a table reports.
#[derive(Clone, Copy)]
pub(super) enum Measure {
    Mse,
    Max,
    Fit,
}

impl Measure {
    pub(super) fn of(self, s: &MethodScores) -> f64 {
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
pub(super) fn mean_std(values: &[f64]) -> Option<(f64, f64)> {
    if values.is_empty() {
        return None;
    }
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
    Some((mean, var.sqrt()))
}

/// The groups a study's shapes fall in: "all", then each collection present.
pub(super) fn groups(study: &ShapeStudy) -> Vec<(String, Vec<&ShapeResult>)> {
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

pub(super) fn average(
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
pub(super) fn trusted_rows<'a>(
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
pub(super) fn exact_average(
    shapes: &[&ShapeResult],
    boundary: ShapeBoundary,
    gate: f64,
) -> [Option<f64>; 2] {
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
