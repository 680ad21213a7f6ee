//! The paper's tables as typed data and their three renderings: a table is a struct of typed
//! rows ([`PaperTable`]) whose serde form is its JSON file; its CSV and Markdown are rendered
//! from the same rows. Also the cell formats every table shares and the files they go to.

use std::path::{Path, PathBuf};

use serde::Serialize;
use serde_json::Value;

use crate::EvalError;

/// A table as data: typed rows (`Serialize`: the JSON file) from which the Markdown (with its
/// settings preamble) and the CSV (header and one line per row) are rendered.
pub trait PaperTable: Serialize {
    /// The paper's table number (1–7).
    fn number(&self) -> u32;

    /// The Markdown: title, settings preamble, sections and rows.
    fn markdown(&self) -> String;

    /// The CSV: a header line and one line per row.
    fn csv(&self) -> String;

    /// The three renderings together, for [`write_table`].
    fn render(&self) -> RenderedTable {
        RenderedTable {
            number: self.number(),
            markdown: self.markdown(),
            // A struct of numbers, strings, options and maps always serializes.
            json: serde_json::to_value(self).unwrap_or(Value::Null),
            csv: self.csv(),
        }
    }
}

/// A rendered table.
#[derive(Clone, Debug)]
pub struct RenderedTable {
    /// Table number (1–7).
    pub number: u32,
    /// Markdown with a settings preamble.
    pub markdown: String,
    /// Machine-readable form: the table's typed rows.
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

/// A CSV cell: the value in full in `1.2345e-4` form, or empty.
pub fn csv_number(v: Option<f64>) -> String {
    v.map_or(String::new(), |v| format!("{v:e}"))
}

/// CSV text: the header, then one line per row of cells (already formatted and quoted).
pub fn csv_text(header: &[&str], rows: impl IntoIterator<Item = Vec<String>>) -> String {
    let mut csv = header.join(",");
    csv.push('\n');
    for row in rows {
        csv += &row.join(",");
        csv.push('\n');
    }
    csv
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

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Serialize)]
    struct Tiny {
        table: u32,
        rows: Vec<(String, Option<f64>)>,
    }

    impl PaperTable for Tiny {
        fn number(&self) -> u32 {
            self.table
        }
        fn markdown(&self) -> String {
            self.rows
                .iter()
                .map(|(name, v)| format!("| {name} | {} |\n", sci(*v)))
                .collect()
        }
        fn csv(&self) -> String {
            csv_text(
                &["name", "value"],
                self.rows
                    .iter()
                    .map(|(name, v)| vec![name.clone(), csv_number(*v)]),
            )
        }
    }

    #[test]
    fn the_three_renderings_come_from_the_same_typed_rows() {
        let tiny = Tiny {
            table: 9,
            rows: vec![("a".into(), Some(1.25e-4)), ("b".into(), None)],
        };
        let rendered = tiny.render();
        assert_eq!(rendered.number, 9);
        assert_eq!(rendered.markdown, "| a | 1.25e-4 |\n| b | — |\n");
        assert_eq!(rendered.csv, "name,value\na,1.25e-4\nb,\n");
        assert_eq!(rendered.json["rows"][0][1], 1.25e-4);
        assert!(rendered.json["rows"][1][1].is_null());
    }
}
