//! Shards gathered into one study, row by row ([`merge_shards`]): the study Tables 2 and 7
//! render.
//!
//! A row is one (shape, boundary condition). Shards merge when the settings that change a row
//! agree: every setting of [`crate::shapes::shard::row_settings`] except the list of
//! conditions (a shard may hold some conditions' rows of a shape, another the rest) and the
//! FEM's factor reuse, which changes a row only through whether it covers that row's reference
//! and is compared row by row. One row in two shards must agree outside its timing fields, and
//! so must the shape-level fields of one shape. Shapes no shard holds and rows of a held shape
//! no shard holds stay unfinished, so the tables are headed **Partial** and name them.

use std::path::PathBuf;

use serde_json::Value;
use thiserror::Error;

use crate::shapes::boundary::ShapeBoundary;
use crate::shapes::config::ShapeStudyConfig;
use crate::shapes::result::{ShapeResult, ShapeRow, ShapeStudy};
use crate::shapes::shard::Shard;

/// Shards could not be merged.
#[derive(Debug, Error)]
pub enum MergeError {
    /// No shard was given.
    #[error("no shards to merge")]
    NoShards,
    /// Two shards come from studies with different settings.
    #[error(
        "{path}: its settings differ from {first}'s at `{field}` ({theirs} there, {ours} here)"
    )]
    SettingsDiffer {
        /// The shard that differs.
        path: PathBuf,
        /// The shard whose settings head the merge.
        first: PathBuf,
        /// The first differing setting (a dotted path; a setting compared row by row names the
        /// row in brackets).
        field: String,
        /// Its value in the heading shard.
        theirs: String,
        /// Its value in this one.
        ours: String,
    },
    /// Two shards hold the same shape or row with different results.
    #[error(
        "{shape} is in {first} and {path} with different results at `{field}` (timing fields \
         aside)"
    )]
    Conflict {
        /// The shape.
        shape: String,
        /// The shard that held it first.
        first: PathBuf,
        /// The shard that disagrees.
        path: PathBuf,
        /// The first differing field (a dotted path; rows are named by their condition,
        /// `rows[fix_side].ours.mse`).
        field: String,
    },
}

/// The first dotted path where `a` and `b` differ, if any, with the two values.
pub(crate) fn first_difference(
    a: &Value,
    b: &Value,
    path: &str,
) -> Option<(String, String, String)> {
    match (a, b) {
        (Value::Object(x), Value::Object(y)) => {
            let mut keys: Vec<&String> = x.keys().chain(y.keys()).collect();
            keys.sort();
            keys.dedup();
            keys.into_iter().find_map(|k| {
                let here = if path.is_empty() {
                    k.clone()
                } else {
                    format!("{path}.{k}")
                };
                first_difference(
                    x.get(k).unwrap_or(&Value::Null),
                    y.get(k).unwrap_or(&Value::Null),
                    &here,
                )
            })
        }
        (Value::Array(x), Value::Array(y)) if x.len() == y.len() => x
            .iter()
            .zip(y)
            .enumerate()
            .find_map(|(i, (p, q))| first_difference(p, q, &format!("{path}[{i}]"))),
        _ if a == b => None,
        _ => Some((path.to_string(), a.to_string(), b.to_string())),
    }
}

/// `value` with every timing field (wall times, seconds, ms per step, whether it came from the
/// cache) left out: what must agree between two copies of one shape.
pub(crate) fn without_timing(value: &Value) -> Value {
    const TIMING: [&str; 3] = ["seconds", "ms_per_step", "cached"];
    match value {
        Value::Object(map) => Value::Object(
            map.iter()
                .filter(|(k, _)| !TIMING.iter().any(|t| k.contains(t)))
                .map(|(k, v)| (k.clone(), without_timing(v)))
                .collect(),
        ),
        Value::Array(items) => Value::Array(items.iter().map(without_timing).collect()),
        other => other.clone(),
    }
}

/// The settings every shard of a merge shares: `settings` without the conditions and the
/// factor reuse (compared row by row).
fn shared_settings(settings: &ShapeStudyConfig) -> Value {
    let mut value = serde_json::to_value(settings).unwrap_or(Value::Null);
    if let Value::Object(map) = &mut value {
        map.remove("boundaries");
        if let Some(Value::Object(fem)) = map.get_mut("fem") {
            fem.remove("factor_reuse");
        }
    }
    value
}

/// One merged shape and the shard each of its rows came from.
struct MergedShape<'a> {
    result: ShapeResult,
    first: &'a PathBuf,
    row_sources: Vec<&'a PathBuf>,
}

impl<'a> MergedShape<'a> {
    /// Adds `shape` from the shard at `path`: its new rows join, a row already held must agree
    /// outside timing, and so must the shape-level fields. The FEM seconds of a shard that
    /// brings only new rows add up (each shard ran its own references).
    fn absorb(&mut self, path: &'a PathBuf, shape: &ShapeResult) -> Result<(), MergeError> {
        let conflict = |first: &PathBuf, field: String| MergeError::Conflict {
            shape: shape.name.clone(),
            first: first.clone(),
            path: path.clone(),
            field,
        };
        let shape_level = |s: &ShapeResult| {
            without_timing(
                &serde_json::to_value(ShapeResult {
                    rows: Vec::new(),
                    ..s.clone()
                })
                .unwrap_or(Value::Null),
            )
        };
        if let Some((field, _, _)) =
            first_difference(&shape_level(&self.result), &shape_level(shape), "")
        {
            return Err(conflict(self.first, field));
        }
        let row_value =
            |r: &ShapeRow| without_timing(&serde_json::to_value(r).unwrap_or(Value::Null));
        let mut all_new = true;
        for row in &shape.rows {
            let held = self
                .result
                .rows
                .iter()
                .position(|r| r.boundary == row.boundary);
            match held {
                Some(i) => {
                    all_new = false;
                    let prefix = format!("rows[{}]", row.boundary.name());
                    if let Some((field, _, _)) =
                        first_difference(&row_value(&self.result.rows[i]), &row_value(row), &prefix)
                    {
                        return Err(conflict(self.row_sources[i], field));
                    }
                }
                None => {
                    self.result.rows.push(row.clone());
                    self.row_sources.push(path);
                }
            }
        }
        if all_new {
            self.result.fem_seconds = match (self.result.fem_seconds, shape.fem_seconds) {
                (Some(a), Some(b)) => Some(a + b),
                (a, b) => a.or(b),
            };
        }
        Ok(())
    }
}

/// The number of rows `shard` holds.
fn row_count(shard: &Shard) -> usize {
    shard.shapes.iter().map(|s| s.rows.len().max(1)).sum()
}

/// The study the `shards` (with their files) hold together, row by row.
///
/// The shard holding the most rows (the earliest of equals) heads the merge: its settings are
/// the study's, with the conditions every shard ran together; its `study_shapes` are the
/// table's shapes, each shape once in table order, its rows in the conditions' order. Shapes no
/// shard holds are the study's [`ShapeStudy::unfinished`], rows of held shapes no shard holds
/// its [`ShapeStudy::unfinished_rows`]. Its `seconds` is the sum of the shards' wall times.
///
/// # Errors
/// [`MergeError`] for no shards; shards whose settings differ outside the conditions, or whose
/// factor reuse differs on a row they hold, or whose shape lists differ (naming the first
/// differing setting); one shape or row with two different results.
pub fn merge_shards(shards: &[(PathBuf, Shard)]) -> Result<ShapeStudy, MergeError> {
    let lead = shards
        .iter()
        .enumerate()
        .max_by_key(|(i, (_, shard))| (row_count(shard), std::cmp::Reverse(*i)))
        .map(|(_, s)| s);
    let Some((lead_path, lead)) = lead else {
        return Err(MergeError::NoShards);
    };
    let lead_settings = shared_settings(&lead.settings);
    let lead_reuse = lead.settings.fem.factor_reuse;
    let mut merged: Vec<MergedShape> = Vec::new();
    let mut boundaries: Vec<ShapeBoundary> = Vec::new();
    let mut seconds = 0.0;
    for (path, shard) in shards {
        let differs = |field: String, theirs: String, ours: String| MergeError::SettingsDiffer {
            path: path.clone(),
            first: lead_path.clone(),
            field,
            theirs,
            ours,
        };
        if let Some((field, theirs, ours)) =
            first_difference(&lead_settings, &shared_settings(&shard.settings), "")
        {
            return Err(differs(field, theirs, ours));
        }
        if shard.study_shapes != lead.study_shapes {
            return Err(differs(
                "study_shapes".into(),
                lead.study_shapes.join(", "),
                shard.study_shapes.join(", "),
            ));
        }
        let reuse = shard.settings.fem.factor_reuse;
        for shape in &shard.shapes {
            for row in &shape.rows {
                let (theirs, ours) = (
                    lead_reuse.covers(row.boundary, shape.youngs_modulus),
                    reuse.covers(row.boundary, shape.youngs_modulus),
                );
                if theirs != ours {
                    return Err(differs(
                        format!("fem.factor_reuse[{} {}]", shape.name, row.boundary.name()),
                        format!("{lead_reuse:?} (reused: {theirs})"),
                        format!("{reuse:?} (reused: {ours})"),
                    ));
                }
            }
            match merged.iter_mut().find(|m| m.result.name == shape.name) {
                Some(held) => held.absorb(path, shape)?,
                None => merged.push(MergedShape {
                    result: shape.clone(),
                    first: path,
                    row_sources: vec![path; shape.rows.len()],
                }),
            }
        }
        boundaries.extend(&shard.settings.boundaries);
        seconds += shard.provenance.finished - shard.provenance.started;
    }
    let boundaries: Vec<ShapeBoundary> = ShapeBoundary::ALL
        .into_iter()
        .filter(|b| boundaries.contains(b))
        .collect();
    let order = |b: ShapeBoundary| boundaries.iter().position(|&x| x == b);
    let shapes = lead
        .study_shapes
        .iter()
        .filter_map(|name| merged.iter().find(|m| &m.result.name == name))
        .map(|m| {
            let mut result = m.result.clone();
            result.rows.sort_by_key(|r| order(r.boundary));
            result
        })
        .collect();
    Ok(ShapeStudy {
        config: ShapeStudyConfig {
            meshes: lead.study_shapes.iter().map(PathBuf::from).collect(),
            boundaries,
            ..lead.settings.clone()
        },
        shapes,
        seconds,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn the_first_difference_is_named_by_its_dotted_path() {
        let a = json!({"settings": {"modes": 32, "kernels": 1000}, "list": [1, 2]});
        let b = json!({"settings": {"modes": 16, "kernels": 1000}, "list": [1, 2]});
        let (field, x, y) = first_difference(&a, &b, "").unwrap();
        assert_eq!(
            (field.as_str(), x.as_str(), y.as_str()),
            ("settings.modes", "32", "16")
        );
        assert!(first_difference(&a, &a, "").is_none());
        let c = json!({"list": [1, 3]});
        assert_eq!(
            first_difference(&json!({"list": [1, 2]}), &c, "")
                .unwrap()
                .0,
            "list[1]"
        );
    }

    #[test]
    fn timing_fields_are_left_out_at_every_depth() {
        let v = json!({"basis_seconds": 1.0, "rows": [{"ours": {"mse": 1e-3, "ms_per_step": 4.0}, "fem": {"cached": true, "dofs": 10}}]});
        assert_eq!(
            without_timing(&v),
            json!({"rows": [{"ours": {"mse": 1e-3}, "fem": {"dofs": 10}}]})
        );
    }
}
