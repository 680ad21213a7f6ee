//! `freeform-paper presets`: the committed presets, listed or printed.

use anyhow::Result;
use eval::presets::{PRESETS, Preset};

/// Lists every preset with its first comment line, or prints `name` with `set` applied.
pub(crate) fn run(name: Option<&str>, set: &[String]) -> Result<()> {
    let Some(name) = name else {
        for (name, text) in PRESETS {
            // The leading comment up to its first colon or full stop.
            let comment: Vec<&str> = text
                .lines()
                .map_while(|line| line.strip_prefix("# "))
                .collect();
            let comment = comment.join(" ");
            let end = comment.find([':', '.']).unwrap_or(comment.len());
            println!("{name:<20} {}", &comment[..end]);
        }
        return Ok(());
    };
    let preset = Preset::named(name)?.with_overrides(set)?;
    let mut table = toml::Table::new();
    table.insert(
        "study".into(),
        toml::Value::String(preset.study.name().into()),
    );
    table.insert("config".into(), toml::Value::Table(preset.config));
    print!("{}", toml::to_string(&table)?);
    Ok(())
}
