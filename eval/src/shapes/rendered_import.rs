//! Shards from Tables 2 rendered before shards existed ([`shards_from_rendered_tables`]): each
//! `table2.json` row read back into the study's results, so that results committed as rendered
//! tables merge with [`crate::shapes::merge::merge_shards`] like any task's shards.
//!
//! A rendered row holds everything Tables 2 and 7 print and most of what a shard holds; what it
//! does not hold is listed in the shard's [`ImportedTable::unknown_fields`] and left zero or
//! `None` there.

use std::path::{Path, PathBuf};

use serde::de::DeserializeOwned;
use serde_json::Value;
use thiserror::Error;

use crate::shapes::boundary::ShapeBoundary;
use crate::shapes::catalog::{ShapeCollection, catalog_entry};
use crate::shapes::config::ShapeStudyConfig;
use crate::shapes::result::{MethodScores, ShapeResult, ShapeRow, ShapeStudy, mesh_name};
use crate::shapes::shard::{ImportedTable, Shard, unix_seconds};

/// The fields of an imported shard's results that a rendered Table 2 does not hold.
pub const UNKNOWN_FIELDS: [&str; 6] = [
    "basis_points",
    "fem_mesh (each row holds the mesh its reference ran on)",
    "rows[].exact.fitting_residual",
    "rows[].exact.ms_per_step",
    "rows[].exact.quadrature_points",
    "rows[].exact.unconverged_steps",
];

/// A rendered table could not be read back.
#[derive(Debug, Error)]
#[error("{path}: {problem}")]
pub struct ImportError {
    /// The table.
    pub path: PathBuf,
    /// What is wrong with it.
    pub problem: String,
}

/// One rendered row: its table's index and its row as read back.
struct ImportedRow {
    table: usize,
    shape: ShapeResult,
}

/// The shards of the rendered `tables` (each a `table2.json` file and its contents), one per
/// table in their order, `None` for a table none of whose rows survive.
///
/// A row (shape, condition) that a later table scored (its FreeForm MSE is there) replaces an
/// earlier table's copy; a row the table did not attempt (no run at all) is left out. Every
/// shard's `study_shapes` are the shapes of all tables (their meshes, then any other shape a
/// row names) in order of first appearance, so give the whole-table run first.
///
/// # Errors
/// [`ImportError`] naming the table, for one that is not a rendered Table 2 or whose settings
/// or rows this build cannot read.
pub fn shards_from_rendered_tables(
    tables: &[(PathBuf, Value)],
) -> Result<Vec<Option<Shard>>, ImportError> {
    let started = unix_seconds();
    let mut rows: Vec<ImportedRow> = Vec::new();
    let mut configs = Vec::new();
    let mut study_shapes: Vec<String> = Vec::new();
    for (table, (path, value)) in tables.iter().enumerate() {
        let fail = |problem: String| ImportError {
            path: path.clone(),
            problem,
        };
        if value["table"] != 2 {
            return Err(fail("not a rendered Table 2 (no \"table\": 2)".into()));
        }
        let config = field::<ShapeStudyConfig>(value, "settings").map_err(fail)?;
        for name in config.meshes.iter().map(|m| mesh_name(m)) {
            if !study_shapes.contains(&name) {
                study_shapes.push(name);
            }
        }
        configs.push(config);
        let rendered = value["shapes"]
            .as_array()
            .ok_or_else(|| fail("no \"shapes\" array".into()))?;
        for row in rendered {
            let Some(shape) = shape_of(row).map_err(|e| fail(format!("a row: {e}")))? else {
                continue;
            };
            if !study_shapes.contains(&shape.name) {
                study_shapes.push(shape.name.clone());
            }
            let boundary = shape.rows[0].boundary;
            let scored = shape.rows[0].ours.is_some();
            let earlier = rows
                .iter()
                .position(|r| r.shape.name == shape.name && r.shape.rows[0].boundary == boundary);
            match earlier {
                Some(i) if scored => rows[i] = ImportedRow { table, shape },
                Some(_) => {}
                None => rows.push(ImportedRow { table, shape }),
            }
        }
    }
    Ok(tables
        .iter()
        .zip(configs)
        .enumerate()
        .map(|(table, ((path, _), config))| {
            let mut shapes: Vec<ShapeResult> = Vec::new();
            for row in rows.iter().filter(|r| r.table == table) {
                match shapes.iter_mut().find(|s| s.name == row.shape.name) {
                    Some(shape) => shape.rows.extend(row.shape.rows.iter().cloned()),
                    None => shapes.push(row.shape.clone()),
                }
            }
            (!shapes.is_empty())
                .then(|| imported_shard(path, config, &study_shapes, shapes, started))
        })
        .collect())
}

/// The shard of `shapes`, rows of the table at `path` run with `config`.
fn imported_shard(
    path: &Path,
    config: ShapeStudyConfig,
    study_shapes: &[String],
    shapes: Vec<ShapeResult>,
    started: f64,
) -> Shard {
    let study = ShapeStudy {
        config,
        shapes,
        seconds: 0.0,
    };
    Shard {
        imported_from: Some(ImportedTable {
            file: path.to_path_buf(),
            unknown_fields: UNKNOWN_FIELDS.iter().map(|f| f.to_string()).collect(),
        }),
        ..Shard::new(&study, study_shapes.to_vec(), started)
    }
}

/// `value[key]` read as a `T`.
fn field<T: DeserializeOwned>(value: &Value, key: &str) -> Result<T, String> {
    serde_json::from_value(value[key].clone()).map_err(|e| format!("`{key}`: {e}"))
}

/// A method's scores from the row's `{prefix}_…` fields, `None` without an MSE.
fn scores(row: &Value, prefix: &str) -> Result<Option<MethodScores>, String> {
    let get = |name: &str| field::<f64>(row, &format!("{prefix}_{name}"));
    let count = |name: &str| field::<usize>(row, &format!("{prefix}_{name}"));
    if row[format!("{prefix}_mse")].is_null() {
        return Ok(None);
    }
    Ok(Some(MethodScores {
        mse: get("mse")?,
        max: get("max")?,
        fitting_residual: get("fitting_residual")?,
        ms_per_step: get("ms_per_step")?,
        quadrature_points: count("quadrature_points")?,
        unconverged_steps: count("unconverged_steps")?,
        max_pin_deviation: get("max_pin_deviation")?,
    }))
}

/// The exact-pin scores a row prints (MSE, max, drift); the rest is unknown and zero.
fn exact_scores(row: &Value) -> Result<Option<MethodScores>, String> {
    if row["exact_mse"].is_null() {
        return Ok(None);
    }
    Ok(Some(MethodScores {
        mse: field(row, "exact_mse")?,
        max: field(row, "exact_max")?,
        max_pin_deviation: field(row, "exact_max_pin_deviation")?,
        fitting_residual: 0.0,
        ms_per_step: 0.0,
        quadrature_points: 0,
        unconverged_steps: 0,
    }))
}

/// The shape of one rendered row with that row alone, or `None` for a row no run attempted.
fn shape_of(row: &Value) -> Result<Option<ShapeResult>, String> {
    // A row the run did not attempt has no region points at all (an attempted one has a list).
    if row["region_points"].is_null() {
        return Ok(None);
    }
    let name: String = field(row, "name")?;
    let boundary: ShapeBoundary = field(row, "bc")?;
    let entry = catalog_entry(&name);
    let title = entry.map_or_else(
        || {
            Path::new(&name)
                .file_stem()
                .map_or(name.clone(), |s| s.to_string_lossy().into())
        },
        |e| e.title.into(),
    );
    let shape_row = ShapeRow {
        fem: field(row, "fem")?,
        ours: scores(row, "ours")?,
        simplicits: scores(row, "simplicits")?,
        exact: exact_scores(row)?,
        exact_error: field(row, "exact_error")?,
        exact_kernel_coverage: field(row, "exact_kernel_coverage")?,
        reference_change: field(row, "reference_change")?,
        reference_check: field(row, "reference_check")?,
        reference_check_error: field(row, "reference_check_error")?,
        fem_mesh: field(row, "fem_mesh")?,
        region_points: field(row, "region_points")?,
        error: field(row, "error")?,
        ..ShapeRow::new(boundary)
    };
    Ok(Some(ShapeResult {
        title,
        collection: entry.map_or(ShapeCollection::Other, |e| e.collection),
        class: entry.map(|e| e.class),
        youngs_modulus: field(row, "youngs_modulus")?,
        basis_points: 0,
        basis_seconds: field(row, "basis_seconds")?,
        training_seconds: field(row, "training_seconds")?,
        fem_mesh: None,
        fem_seconds: field(row, "fem_seconds")?,
        rows: vec![shape_row],
        error: None,
        name,
    }))
}
