//! A rendered table (Markdown with its settings preamble, JSON, CSV), its files, and the cell
//! formats every table shares.

use std::path::{Path, PathBuf};

use serde_json::Value;

use crate::EvalError;

/// A rendered table.
#[derive(Clone, Debug)]
pub struct RenderedTable {
    /// Table number (1, 3, 4, 5, 6).
    pub number: u32,
    /// Markdown with a settings preamble.
    pub markdown: String,
    /// Machine-readable form.
    pub json: Value,
    /// Header and rows.
    pub csv: String,
}

/// A value in `1.23e-4` form, or "—".
pub fn sci(v: Option<f64>) -> String {
    v.map_or("—".into(), |v| format!("{v:.2e}"))
}

/// A value in `1.23e-4` form, or "not run".
pub fn not_run_or(v: Option<f64>) -> String {
    v.map_or("not run".into(), |v| format!("{v:.2e}"))
}

/// Writes `table<N>.md`, `.json` and `.csv` under `dir`; returns the paths.
///
/// # Errors
/// [`EvalError::Io`] naming the file.
pub fn write_table(table: &RenderedTable, dir: &Path) -> Result<Vec<PathBuf>, EvalError> {
    std::fs::create_dir_all(dir).map_err(|e| EvalError::io(dir, e))?;
    let base = dir.join(format!("table{}", table.number));
    let mut written = Vec::new();
    for (ext, text) in [
        ("md", table.markdown.clone()),
        (
            "json",
            serde_json::to_string_pretty(&table.json).unwrap_or_default(),
        ),
        ("csv", table.csv.clone()),
    ] {
        let path = base.with_extension(ext);
        artifact::write_atomically(&path, text.as_bytes())?;
        written.push(path);
    }
    Ok(written)
}
