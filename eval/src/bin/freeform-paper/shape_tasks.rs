//! `table 2 7` as tasks of a workflow engine: the plan, one stage of some shapes, a shard of
//! raw rows and a receipt written last (`eval::shapes::shard`).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use eval::shapes::boundary::ShapeBoundary;
use eval::shapes::config::ShapeStudyConfig;
use eval::shapes::result::{ShapeStudy, mesh_name};
use eval::shapes::shard::{Provenance, Shard, settings_key, shard_meshes};
use eval::shapes::stage::ShapeStage;
use eval::shapes::study::{estimate_references, run_shape_stage};
use eval::shapes::tasks::{Receipt, TaskPlan};
use freeform::terminal_progress::TerminalProgress;

/// The workflow options of `table 2 7`.
#[derive(clap::Args)]
pub(crate) struct TaskOptions {
    /// Print the task plan as JSON (the shapes in table order with their files and moduli,
    /// the boundary conditions, the stages, every (shape, stage) task and what it waits for,
    /// the settings key) and run nothing.
    #[arg(long)]
    pub(crate) plan: bool,
    /// With --plan: add each reference's and check's DOFs and factor memory (its mesh built and
    /// its system analysed, nothing run: seconds to minutes a shape), the largest of them, and
    /// the tasks that would not fit in this machine's available memory.
    #[arg(long, requires = "plan")]
    estimate: bool,
    /// Run one stage of the shapes' work: `train` (the baseline's network), `reference` (the
    /// FEM references), `check` (their finer references), or `row` (score from the cache alone
    /// and write a shard; needs --shard-out). Every stage but `row` only fills the cache.
    #[arg(long, value_enum)]
    pub(crate) stage: Option<ShapeStage>,
    /// Only these boundary conditions (comma-separated: fix_side, pull_farthest,
    /// pull_boundary). A shard of fewer conditions has other settings than the study's.
    #[arg(long, value_delimiter = ',')]
    boundaries: Vec<String>,
    /// The shapes with indices I, I + N, I + 2N, … of the folder's (`--shard 0/4`): one task
    /// of a Slurm array or GNU parallel.
    #[arg(long, value_name = "I/N")]
    shard: Option<String>,
    /// Write the raw rows with the settings and provenance to FILE, for `merge`.
    #[arg(long, value_name = "FILE")]
    shard_out: Option<PathBuf>,
    /// When done, write a receipt to FILE (the shapes, the stage, what was written, the
    /// settings key, host, threads, start and end): last, so it means the task finished.
    #[arg(long, value_name = "FILE")]
    receipt: Option<PathBuf>,
}

impl TaskOptions {
    /// Narrows `config` to `--shard` and `--boundaries`.
    pub(crate) fn select(&self, config: &mut ShapeStudyConfig) -> Result<()> {
        if let Some(shard) = &self.shard {
            let (i, n) = shard
                .split_once('/')
                .and_then(|(i, n)| Some((i.parse::<usize>().ok()?, n.parse::<usize>().ok()?)))
                .filter(|(i, n)| i < n)
                .with_context(|| format!("--shard {shard}: expected I/N with 0 ≤ I < N"))?;
            config.meshes = shard_meshes(&config.meshes, i, n);
            if config.meshes.is_empty() {
                bail!("--shard {shard}: no shape has an index I + kN");
            }
        }
        if !self.boundaries.is_empty() {
            let chosen: Vec<ShapeBoundary> = self
                .boundaries
                .iter()
                .map(|b| {
                    serde_json::from_value(serde_json::Value::String(b.clone())).with_context(
                        || format!("--boundaries: no condition `{b}` (fix_side, pull_farthest, pull_boundary)"),
                    )
                })
                .collect::<Result<_>>()?;
            config.boundaries.retain(|b| chosen.contains(b));
        }
        if self.stage == Some(ShapeStage::Row) && self.shard_out.is_none() {
            bail!("--stage row writes a shard: give --shard-out FILE");
        }
        Ok(())
    }

    /// `--plan` or `--stage`: prints the plan, or runs the stage and writes its shard and
    /// receipt.
    pub(crate) fn run(
        &self,
        config: &ShapeStudyConfig,
        every_mesh: &[PathBuf],
        started: f64,
        progress: &TerminalProgress,
    ) -> Result<()> {
        if self.plan {
            let mut plan = TaskPlan::new(config);
            if self.estimate {
                plan = plan.with_estimates(&estimate_references(config, progress)?);
            }
            println!("{}", serde_json::to_string_pretty(&plan)?);
            return Ok(());
        }
        let Some(stage) = self.stage else {
            return Ok(());
        };
        let study = run_shape_stage(config, stage, progress)?;
        let failed: Vec<String> = study
            .shapes
            .iter()
            .filter_map(|s| s.error.as_ref().map(|e| format!("{}: {e}", s.name)))
            .chain(study.shapes.iter().flat_map(|s| {
                s.rows.iter().filter_map(move |r| {
                    r.error
                        .as_ref()
                        .map(|e| format!("{} {}: {e}", s.name, r.boundary.title()))
                })
            }))
            .collect();
        progress.status(format!(
            "stage {}: {} shape(s) in {:.0} s{}",
            stage.name(),
            study.shapes.len(),
            study.seconds,
            if failed.is_empty() {
                String::new()
            } else {
                format!("; failed: {}", failed.join("; "))
            }
        ));
        self.finish(&study, every_mesh, started)?;
        if stage != ShapeStage::Row && !failed.is_empty() {
            bail!("stage {} failed: {}", stage.name(), failed.join("; "));
        }
        Ok(())
    }

    /// Writes the shard (with `--shard-out`) and then the receipt (with `--receipt`) of
    /// `study`, one part of the study over `every_mesh`.
    pub(crate) fn finish(
        &self,
        study: &ShapeStudy,
        every_mesh: &[PathBuf],
        started: f64,
    ) -> Result<()> {
        let mut wrote = Vec::new();
        if let Some(path) = &self.shard_out {
            let names = every_mesh.iter().map(|p| mesh_name(p)).collect();
            Shard::new(study, names, started).write(path)?;
            println!("wrote {}", path.display());
            wrote.push(path.clone());
        }
        if let Some(path) = &self.receipt {
            write_receipt(path, study, self.stage, wrote, started)?;
        }
        Ok(())
    }
}

fn write_receipt(
    path: &Path,
    study: &ShapeStudy,
    stage: Option<ShapeStage>,
    wrote: Vec<PathBuf>,
    started: f64,
) -> Result<()> {
    let receipt = Receipt {
        shapes: study.shapes.iter().map(|s| s.name.clone()).collect(),
        stage,
        boundaries: study.config.boundaries.clone(),
        wrote,
        cache_dir: study.config.cache_dir.clone(),
        settings_key: settings_key(&study.config),
        provenance: Provenance::since(started),
    };
    artifact::write_atomically(path, &serde_json::to_vec_pretty(&receipt)?)?;
    Ok(())
}
