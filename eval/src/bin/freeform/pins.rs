//! `freeform pins`: the pin sweep of issue 25.

use std::path::{Path, PathBuf};

use anyhow::Result;
use artifact::write_atomically;
use eval::pins::{PinSweepConfig, exact_sweep_table, pin_sweep_table, run_pin_sweep};
use eval::progress::Progress;

/// Runs the sweep, prints its table (or JSON) and writes `pins.md` and `pins.json` under `out`.
pub(crate) fn run(
    quick: bool,
    json: bool,
    exact_only: bool,
    cache: PathBuf,
    out: &Path,
    progress: &Progress,
) -> Result<()> {
    let mut config = if quick {
        PinSweepConfig::quick(cache)
    } else {
        PinSweepConfig::full(cache)
    };
    if exact_only {
        config.factors.clear();
    }
    let sweep = run_pin_sweep(&config, progress)?;
    let mut md = pin_sweep_table(&config, &sweep);
    md += &exact_sweep_table(&config, &sweep);
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
