//! `freeform-paper merge`: Tables 2 and 7 from shards of the shapes study.

use std::path::{Path, PathBuf};

use anyhow::Result;
use eval::report::table::write_table;
use eval::shapes::shard::{Shard, merge_shards};
use eval::shapes::tables::{table2, table7};

/// Merges `files` (shards written by `table 2 7 … --shard-out`) and writes Tables 2 and 7
/// (Markdown, JSON, CSV) under `out`, headed **Partial** when shapes are missing; prints them.
pub(crate) fn run(files: &[PathBuf], json: bool, out: &Path) -> Result<()> {
    let shards = files
        .iter()
        .map(|path| Ok((path.clone(), Shard::read(path)?)))
        .collect::<Result<Vec<_>>>()?;
    let study = merge_shards(&shards)?;
    let missing = study.unfinished();
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
