//! `freeform-paper merge`: Tables 2 and 7 from shards of the shapes study;
//! `freeform-paper import-tables`: shards from tables rendered before shards existed.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use eval::report::table::write_table;
use eval::shapes::merge::merge_shards;
use eval::shapes::rendered_import::shards_from_rendered_tables;
use eval::shapes::shard::Shard;
use eval::shapes::tables::{table2, table7};

/// Merges `files` (shards written by `table 2 7 … --shard-out`) and writes Tables 2 and 7
/// (Markdown, JSON, CSV) under `out`, headed **Partial** when shapes are missing; prints them.
pub(crate) fn run(files: &[PathBuf], json: bool, out: &Path) -> Result<()> {
    let shards = files
        .iter()
        .map(|path| Ok((path.clone(), Shard::read(path)?)))
        .collect::<Result<Vec<_>>>()?;
    let study = merge_shards(&shards)?;
    let missing: Vec<String> = study
        .unfinished()
        .into_iter()
        .chain(study.unfinished_rows())
        .collect();
    eprintln!(
        "{} shard(s), {} of {} shapes{}",
        shards.len(),
        study.shapes.len(),
        study.config.meshes.len(),
        if missing.is_empty() {
            String::new()
        } else {
            format!("; missing: {}", missing.join(", "))
        }
    );
    let mut rendered_json = Vec::new();
    for table in [table2(&study), table7(&study)] {
        let files = write_table(&table, out)?;
        if json {
            rendered_json.push(table.json);
        } else {
            println!("{}", table.markdown);
            for f in files {
                println!("wrote {}", f.display());
            }
            println!();
        }
    }
    if json {
        println!("{}", serde_json::to_string_pretty(&rendered_json)?);
    }
    Ok(())
}

/// Reads the rendered `tables` and writes their shards to `dir`, each named after its table's
/// folder; prints the files written.
pub(crate) fn import_tables(tables: &[PathBuf], dir: &Path) -> Result<()> {
    let read = tables
        .iter()
        .map(|path| {
            let text =
                std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
            let value = serde_json::from_slice(&text)
                .with_context(|| format!("{} is not JSON", path.display()))?;
            Ok((path.clone(), value))
        })
        .collect::<Result<Vec<_>>>()?;
    let shards = shards_from_rendered_tables(&read)?;
    for (path, shard) in tables.iter().zip(shards) {
        let Some(shard) = shard else {
            println!("{}: every row replaced by a later table", path.display());
            continue;
        };
        let folder = path
            .parent()
            .and_then(Path::file_name)
            .map_or_else(|| "table".into(), |n| n.to_string_lossy().into_owned());
        let out = dir.join(format!("{folder}.json"));
        shard.write(&out)?;
        let rows: usize = shard.shapes.iter().map(|s| s.rows.len()).sum();
        println!("wrote {} ({rows} rows)", out.display());
    }
    Ok(())
}
