//! `freeform-paper pins`: the pin sweep.

use crate::preset_args::PresetArgs;
use std::path::Path;

use anyhow::Result;
use artifact::write_atomically;
use eval::pins::table::{held_sweep_table, pin_sweep_table};
use eval::pins::{PinSweepConfig, run_pin_sweep};
use eval::presets::{StudyKind, set_folder};
use freeform::terminal_progress::TerminalProgress;

/// Runs the sweep, prints its table (or JSON) and writes `pins.md` and `pins.json` under `out`.
pub(crate) fn run(
    preset: &PresetArgs,
    json: bool,
    cache: &Path,
    out: &Path,
    progress: &TerminalProgress,
) -> Result<()> {
    let config: PinSweepConfig = preset.load("pins")?.config(StudyKind::Pins, |table| {
        set_folder(table, "cache_dir", cache)
    })?;
    let sweep = run_pin_sweep(&config, progress)?;
    let mut md = pin_sweep_table(&config, &sweep);
    md += &held_sweep_table(&config, &sweep);
    let data =
        serde_json::to_string_pretty(&serde_json::json!({"config": config, "sweep": sweep}))?;
    std::fs::create_dir_all(out)?;
    write_atomically(&out.join("pins.md"), md.as_bytes())?;
    write_atomically(&out.join("pins.json"), data.as_bytes())?;
    if json {
        println!("{data}");
    } else {
        println!("{md}");
    }
    Ok(())
}
