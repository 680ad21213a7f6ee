//! `freeform-paper stress`: the numerical stress suite.

use crate::preset_args::PresetArgs;
use std::path::Path;

use anyhow::{Result, bail};
use artifact::write_atomically;
use eval::presets::StudyKind;
use eval::stress::{StressConfig, run_stress, stress_markdown};
use freeform::terminal_progress::TerminalProgress;

/// Runs the suite, writes `stress/stress.{md,json}` and fails if any case is not acceptable.
pub(crate) fn run(
    preset: &PresetArgs,
    json: bool,
    out: &Path,
    progress: &TerminalProgress,
) -> Result<()> {
    let config: StressConfig = preset.load("stress")?.config(StudyKind::Stress, |_| {})?;
    let bar = progress.bar(config.cases.len(), "stress cases");
    let outcomes = run_stress(&config, |o| {
        bar.inc(1);
        bar.set_message(o.case.name.clone());
    });
    bar.finish_and_clear();
    let md = stress_markdown(&outcomes);
    let value = serde_json::to_value(&outcomes)?;
    let dir = out.join("stress");
    std::fs::create_dir_all(&dir)?;
    write_atomically(&dir.join("stress.md"), md.as_bytes())?;
    write_atomically(
        &dir.join("stress.json"),
        serde_json::to_string_pretty(&value)?.as_bytes(),
    )?;
    if json {
        println!("{}", serde_json::to_string_pretty(&value)?);
    } else {
        println!("{md}\nwrote {}", dir.display());
    }
    let bad: Vec<&str> = outcomes
        .iter()
        .filter(|o| !o.acceptable())
        .map(|o| o.case.name.as_str())
        .collect();
    if !bad.is_empty() {
        bail!(
            "{} stress case(s) produced non-finite values or panicked: {}",
            bad.len(),
            bad.join(", ")
        );
    }
    Ok(())
}
