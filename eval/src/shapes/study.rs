//! The shapes study behind Tables 2 and 7 (design §4.2): for every closed mesh, normalized so its
//! largest bounding-box side is L = 1 m, our basis and the Simplicits network (m = 32) on the
//! same grid of integration points, a tetrahedralization for the FEM reference, and the three
//! boundary conditions of [`crate::shapes::boundary`] run by all three solvers. Reduced runs are
//! scored at the FEM mesh's vertices.
//!
//! A shape that cannot be read, sampled, meshed or given a basis is reported with the reason,
//! as is a boundary condition that fails on a shape (e.g. a region that selects no FEM node);
//! the study goes on. FEM trajectories and trained networks are cached, so a rerun (or a run
//! after an interruption) only computes what is missing; a cached-only study
//! ([`ShapeStudyConfig::cached_only`]) computes none of it and scores what the cache holds.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, PoisonError};
use std::time::Instant;

use crate::EvalError;
use crate::shapes::catalog::MaterialClass;
use crate::shapes::config::ShapeStudyConfig;
use crate::shapes::result::{ShapeResult, ShapeStudy};
use crate::shapes::shape_run::run_shape_into;
use crate::shapes::stage::{ShapeStage, ShapeWork};
use freeform::failure_chain;
use freeform::terminal_progress::TerminalProgress;

/// The closed meshes (`.obj`, `.stl`, `.ply`) directly in `dir`, sorted by name; with `only`,
/// just the one whose file name or stem is `only`.
///
/// # Errors
/// [`EvalError::Io`] if `dir` cannot be read; [`EvalError::InvalidInput`] if it holds no mesh or
/// nothing matches `only`.
pub fn mesh_files(dir: &Path, only: Option<&str>) -> Result<Vec<PathBuf>, EvalError> {
    let entries = std::fs::read_dir(dir).map_err(|e| EvalError::io(dir, e))?;
    let mut files: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.is_file()
                && p.extension().is_some_and(|x| {
                    matches!(x.to_ascii_lowercase().to_str(), Some("obj" | "stl" | "ply"))
                })
        })
        .collect();
    files.sort();
    if files.is_empty() {
        return Err(EvalError::InvalidInput(format!(
            "{}: no .obj, .stl or .ply file in this folder",
            dir.display()
        )));
    }
    let Some(only) = only else {
        return Ok(files);
    };
    let matching: Vec<PathBuf> = files
        .iter()
        .filter(|p| {
            p.file_name().is_some_and(|n| n == only) || p.file_stem().is_some_and(|s| s == only)
        })
        .cloned()
        .collect();
    if matching.is_empty() {
        let names: Vec<String> = files
            .iter()
            .filter_map(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
            .collect();
        return Err(EvalError::InvalidInput(format!(
            "--only {only}: no such mesh in {} (there are: {})",
            dir.display(),
            names.join(", ")
        )));
    }
    Ok(matching)
}

/// Runs the study, `config.jobs` shapes at a time. As each shape finishes, `on_shape` sees it
/// and the study so far (every finished shape, in table order; [`ShapeStudy::unfinished`] names
/// the rest), one call at a time, so it may write the tables of a long run as it goes.
///
/// # Errors
/// None from a shape (those are reported in its [`ShapeResult`]); [`EvalError::InvalidInput`] for
/// `jobs = 0` or no meshes.
pub fn run_shape_study(
    config: &ShapeStudyConfig,
    progress: &TerminalProgress,
    on_shape: impl Fn(&ShapeResult, &ShapeStudy) + Sync,
) -> Result<ShapeStudy, EvalError> {
    run_shapes(config, ShapeWork::Everything, progress, on_shape)
}

/// The FEM references of every shape and condition of `config`, and their convergence checks
/// when the study makes them, estimated: each one's mesh is built and its system analysed
/// symbolically (DOFs, factor nonzeros and bytes in each row's `reference_estimate` and
/// `check_estimate`, [`crate::shapes::result::ShapeRow`]), nothing trained, run or scored. Seconds to minutes a shape:
/// the meshing and the fill-reducing ordering of the finest references take the longest.
///
/// # Errors
/// As [`run_shape_study`].
pub fn estimate_references(
    config: &ShapeStudyConfig,
    progress: &TerminalProgress,
) -> Result<ShapeStudy, EvalError> {
    run_shapes(config, ShapeWork::Estimate, progress, |_, _| {})
}

/// One stage of every shape of `config` ([`ShapeStage`]): for a workflow engine that runs the
/// stages as separate tasks. `Train`, `Reference` and `Check` fill the cache and return results
/// with only what they ran; `Row` scores the rows from the cache alone (as
/// [`ShapeStudyConfig::cached_only`]), the results a shard holds.
///
/// # Errors
/// As [`run_shape_study`].
pub fn run_shape_stage(
    config: &ShapeStudyConfig,
    stage: ShapeStage,
    progress: &TerminalProgress,
) -> Result<ShapeStudy, EvalError> {
    let config = ShapeStudyConfig {
        cached_only: config.cached_only || stage == ShapeStage::Row,
        ..config.clone()
    };
    run_shapes(&config, ShapeWork::Stage(stage), progress, |_, _| {})
}

/// [`run_shape_study`], one stage of it, or its estimates.
fn run_shapes(
    config: &ShapeStudyConfig,
    work: ShapeWork,
    progress: &TerminalProgress,
    on_shape: impl Fn(&ShapeResult, &ShapeStudy) + Sync,
) -> Result<ShapeStudy, EvalError> {
    if config.jobs == 0 || config.meshes.is_empty() {
        return Err(EvalError::InvalidInput(format!(
            "the shape study needs at least one job and one mesh (jobs = {}, {} meshes)",
            config.jobs,
            config.meshes.len()
        )));
    }
    let start = Instant::now();
    // Parallel shapes print status lines only: their bars would draw over each other.
    let progress = if config.jobs > 1 {
        progress.without_bars()
    } else {
        *progress
    };
    let progress = &progress;
    let next = AtomicUsize::new(0);
    let results: Mutex<Vec<Option<ShapeResult>>> = Mutex::new(vec![None; config.meshes.len()]);
    std::thread::scope(|scope| {
        for _ in 0..config.jobs.min(config.meshes.len()) {
            scope.spawn(|| {
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    let Some(path) = config.meshes.get(i) else {
                        break;
                    };
                    let result = run_shape(path, config, work, progress);
                    // Held through `on_shape`: one call at a time, each seeing its own shape.
                    let mut slots = results.lock().unwrap_or_else(PoisonError::into_inner);
                    let so_far = ShapeStudy {
                        config: config.clone(),
                        shapes: slots
                            .iter()
                            .enumerate()
                            .filter_map(
                                |(j, slot)| if j == i { Some(&result) } else { slot.as_ref() },
                            )
                            .cloned()
                            .collect(),
                        seconds: start.elapsed().as_secs_f64(),
                    };
                    on_shape(&result, &so_far);
                    slots[i] = Some(result);
                }
            });
        }
    });
    let shapes = results
        .into_inner()
        .unwrap_or_else(PoisonError::into_inner)
        .into_iter()
        .zip(&config.meshes)
        .map(|(slot, path)| {
            slot.unwrap_or_else(|| {
                let mut r = ShapeResult::new(path, config);
                r.error = Some("the worker running this shape stopped (a bug)".into());
                r
            })
        })
        .collect();
    Ok(ShapeStudy {
        config: config.clone(),
        shapes,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// Runs one shape; every failure ends up in the result.
fn run_shape(
    path: &Path,
    config: &ShapeStudyConfig,
    work: ShapeWork,
    progress: &TerminalProgress,
) -> ShapeResult {
    let mut result = ShapeResult::new(path, config);
    let start = Instant::now();
    progress.status(format!(
        "{}: E = {:e} Pa ({})",
        result.name,
        result.youngs_modulus,
        result.class.map_or("not catalogued", MaterialClass::name)
    ));
    if let Err(e) = run_shape_into(path, config, work, progress, &mut result) {
        result.error = Some(failure_chain(&e));
    }
    progress.status(format!(
        "{}: done in {:.1} s{}",
        result.name,
        start.elapsed().as_secs_f64(),
        result
            .error
            .as_ref()
            .map_or(String::new(), |e| format!(" ({e})"))
    ));
    result
}
