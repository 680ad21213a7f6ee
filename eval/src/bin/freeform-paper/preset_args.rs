//! The options every experiment command shares: which preset, which file, which changes.

use std::path::PathBuf;

use anyhow::{Result, bail};
use eval::presets::{Preset, PresetChoice};

/// Which configuration an experiment runs: a committed preset (`eval/presets/`), or a file of
/// the same form, changed key by key.
#[derive(clap::Args, Debug, Default)]
pub(crate) struct PresetArgs {
    /// A committed preset by name (default: the command's own; `--quick` picks its `-quick`
    /// variant). `freeform-paper presets` lists them.
    #[arg(long, conflicts_with = "config")]
    pub(crate) preset: Option<String>,
    /// A preset file of your own (TOML: `study = "…"` and a `[config]` table).
    #[arg(long)]
    pub(crate) config: Option<PathBuf>,
    /// Change one setting of the preset: a dotted key inside `[config]` and a TOML value, e.g.
    /// `--set settings.kernels=500`, `--set modes=[16]`, `--set simplicits=none`. Repeatable.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub(crate) set: Vec<String>,
    /// The quick variant of the default preset (minutes instead of hours).
    #[arg(long)]
    pub(crate) quick: bool,
}

impl PresetArgs {
    /// The preset these options name, `default` (or `default-quick`) when none is given, with
    /// the `--set` changes applied.
    pub(crate) fn load(&self, default: &str) -> Result<Preset> {
        let choice = match (&self.preset, &self.config) {
            (Some(_), _) | (_, Some(_)) if self.quick => {
                bail!(
                    "--quick picks the quick variant of the default preset; with --preset or --config name the one you want"
                )
            }
            (Some(name), _) => PresetChoice::Named(name.clone()),
            (None, Some(path)) => PresetChoice::File(path.clone()),
            (None, None) if self.quick => PresetChoice::Named(format!("{default}-quick")),
            (None, None) => PresetChoice::Named(default.to_string()),
        };
        Ok(Preset::load(&choice)?.with_overrides(&self.set)?)
    }
}
