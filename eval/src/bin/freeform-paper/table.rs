//! `freeform-paper table`: the paper's tables, each group of tables from its preset.

use crate::plot_or_warn;
use crate::preset_args::PresetArgs;
use crate::shape_tasks;
use std::path::{Path, PathBuf};

use anyhow::{Result, bail};
use eval::ablation::study::{AblationStudyConfig, run_ablation_study};
use eval::ablation::tables::{table3, table4};
use eval::beam::study::run_beam_study;
use eval::beam::tables::{table1, table5, table6, twist_error_plot};
use eval::beam_protocol::study_config::BeamStudyConfig;
use eval::beam_scenario::BeamTest;
use eval::presets::{StudyKind, set_folder};
use eval::report::table::{RenderedTable, write_table};
use eval::shapes::config::ShapeStudyConfig;
use eval::shapes::result::ShapeStudy;
use eval::shapes::shard::unix_seconds;
use eval::shapes::study::{mesh_files, run_shape_study};
use eval::shapes::tables::{table2, table7};
use freeform::terminal_progress::TerminalProgress;

/// Options of `freeform-paper table`.
#[derive(clap::Args)]
pub(crate) struct TableOptions {
    /// The configuration: tables 1, 5, 6 default to the `beam` preset, 3 and 4 to `ablation`,
    /// 2 and 7 to `shapes` (the trusted setting). `--preset`, `--config` and `--set` need the
    /// tables of one group.
    #[command(flatten)]
    preset: PresetArgs,
    /// Print JSON instead of Markdown.
    #[arg(long)]
    json: bool,
    /// Tables 2 and 7: the folder of closed meshes (OBJ/STL/PLY), e.g. `data/meshes`.
    #[arg(long)]
    meshes: Option<PathBuf>,
    /// Tables 2 and 7: only the mesh with this file name or stem.
    #[arg(long)]
    only: Option<String>,
    /// Tables 2 and 7: shapes run at the same time (the preset's `jobs`).
    #[arg(long)]
    jobs: Option<usize>,
    /// Tables 2 and 7: compute nothing and score what the cache holds (a row whose reference
    /// or check is not cached says so and is not scored), for work spread over several runs.
    #[arg(long)]
    cached_only: bool,
    /// Tables 2 and 7, for a workflow engine: the shapes, their stages and the settings key as
    /// JSON; runs nothing.
    #[command(flatten)]
    tasks: shape_tasks::TaskOptions,
}

/// The groups of tables that share one run, and their presets.
const GROUPS: [(&[u32], &str); 3] = [
    (&[1, 5, 6], "beam"),
    (&[3, 4], "ablation"),
    (&[2, 7], "shapes"),
];

pub(crate) fn run(
    numbers: &[u32],
    options: TableOptions,
    out: &Path,
    cache: &Path,
    progress: &TerminalProgress,
) -> Result<()> {
    if let Some(n) = numbers.iter().find(|n| !matches!(n, 1..=7)) {
        bail!("there is no table {n}: the paper's tables are 1 to 7");
    }
    let wants = |group: &[u32]| numbers.iter().any(|n| group.contains(n));
    let groups = GROUPS.iter().filter(|(tables, _)| wants(tables)).count();
    let chosen = &options.preset;
    if groups > 1 && (chosen.preset.is_some() || chosen.config.is_some() || !chosen.set.is_empty())
    {
        bail!(
            "--preset, --config and --set configure one group of tables (1 5 6, 3 4 or 2 7); \
             run the groups one at a time"
        );
    }
    let cache_dir = |table: &mut toml::Table| set_folder(table, "cache_dir", cache);
    let mut rendered = Vec::new();
    if wants(&[2, 7]) {
        rendered.extend(shape_study_tables(numbers, &options, out, cache, progress)?);
    }
    if wants(&[3, 4]) {
        let mut ablation: AblationStudyConfig = chosen
            .load("ablation")?
            .config(StudyKind::Ablation, |table| {
                set_folder(table, "base.cache_dir", cache)
            })?;
        ablation.coefficient_ablations = wants(&[3]);
        ablation.sampling_ablation = wants(&[4]);
        let study = run_ablation_study(&ablation, progress)?;
        for &number in numbers.iter().filter(|n| matches!(n, 3 | 4)) {
            rendered.push(if number == 3 {
                table3(&study)
            } else {
                table4(&study)
            });
        }
    }
    if wants(&[1, 5, 6]) {
        let mut config: BeamStudyConfig =
            chosen.load("beam")?.config(StudyKind::Beam, cache_dir)?;
        if numbers.iter().all(|&n| n == 5) {
            // Timing only needs the Bend.
            config.tests = vec![BeamTest::Bend];
        }
        // Only Table 1 prints the exact pins, only Tables 1 and 5 the particle baselines.
        if !wants(&[1]) {
            config.exact_pins = None;
        }
        if !wants(&[1, 5]) {
            config.mpm = None;
            config.sph = None;
        }
        let study = run_beam_study(&config, progress)?;
        if wants(&[1])
            && let Some(spec) = twist_error_plot(&study)
        {
            for f in plot_or_warn(&spec, &out.join("twist_error_per_frame")) {
                progress.status(format!("wrote {}", f.display()));
            }
        }
        for &number in numbers.iter().filter(|n| matches!(n, 1 | 5 | 6)) {
            rendered.push(match number {
                1 => table1(&study),
                5 => table5(&study),
                _ => table6(&study),
            });
        }
    }
    let mut rendered_json = Vec::new();
    for table in rendered {
        let files = write_table(&table, out)?;
        if options.json {
            rendered_json.push(table.json);
        } else {
            println!("{}", table.markdown);
            for f in files {
                println!("wrote {}", f.display());
            }
            println!();
        }
    }
    if options.json {
        let value = if rendered_json.len() == 1 {
            rendered_json.remove(0)
        } else {
            serde_json::Value::Array(rendered_json)
        };
        println!("{}", serde_json::to_string_pretty(&value)?);
    }
    Ok(())
}

/// Runs the shapes study for Tables 2 and 7 (writing the tables so far after each shape) and
/// returns those of them `numbers` asks for.
fn shape_study_tables(
    numbers: &[u32],
    options: &TableOptions,
    out: &Path,
    cache: &Path,
    progress: &TerminalProgress,
) -> Result<Vec<RenderedTable>> {
    let chosen = &options.preset;
    let cache_dir = |table: &mut toml::Table| set_folder(table, "cache_dir", cache);
    let Some(dir) = &options.meshes else {
        bail!("tables 2 and 7 need --meshes DIR (e.g. data/meshes)");
    };
    let mut shapes: ShapeStudyConfig =
        chosen.load("shapes")?.config(StudyKind::Shapes, |table| {
            cache_dir(table);
            table.insert("meshes".into(), toml::Value::Array(Vec::new()));
        })?;
    let every_mesh = mesh_files(dir, None)?;
    shapes.meshes = mesh_files(dir, options.only.as_deref())?;
    shapes.jobs = options.jobs.unwrap_or(shapes.jobs);
    shapes.cached_only |= options.cached_only;
    let started = unix_seconds();
    let tasks = &options.tasks;
    tasks.select(&mut shapes)?;
    if tasks.plan || tasks.stage.is_some() {
        tasks.run(&shapes, &every_mesh, started, progress)?;
        return Ok(Vec::new());
    }
    let total = shapes.meshes.len();
    let study = run_shape_study(&shapes, progress, |shape, so_far| {
        let mut line = format!(
            "[{}/{total} shapes] {} finished",
            so_far.shapes.len(),
            shape.name
        );
        // A long run leaves the tables of the shapes it finished, should it be stopped (or
        // should a later table fail).
        let written = shape_tables(numbers, so_far)
            .iter()
            .map(|table| write_table(table, out))
            .collect::<Result<Vec<_>, _>>();
        line += &match written {
            Ok(_) => format!("; the tables so far are in {}", out.display()),
            Err(e) => format!("; the tables so far could not be written: {e}"),
        };
        progress.status(line);
    })?;
    progress.status(format!(
        "shape study: {total} shape(s) in {:.0} s",
        study.seconds
    ));
    tasks.finish(&study, &every_mesh, started)?;
    Ok(shape_tables(numbers, &study))
}

/// Tables 2 and 7 of `study`, those of them `numbers` asks for, in its order.
fn shape_tables(numbers: &[u32], study: &ShapeStudy) -> Vec<RenderedTable> {
    numbers
        .iter()
        .filter_map(|n| match n {
            2 => Some(table2(study)),
            7 => Some(table7(study)),
            _ => None,
        })
        .collect()
}
