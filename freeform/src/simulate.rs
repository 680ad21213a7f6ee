//! A scene file, run end to end: geometry → basis → simulation → frames on disk.

use std::path::Path;

use artifact::{ArtifactError, write_atomically};
use nalgebra::Vector3;
use reduced_sim::{QuadratureReport, QuadratureRule};
use serde::{Deserialize, Serialize};

use crate::object_setup::{ObjectDescription, ObjectSetup};
use crate::progress::Progress;
use crate::runner::run;
use crate::scene_file::{SceneFile, SimulationSpec};
use crate::simulate_error::SimulateError;
use crate::stress_summary::StressSummary;

/// What [`simulate_scene_file`] did.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SimulateReport {
    /// Basis build time (s).
    pub basis_seconds: f64,
    /// Mean wall time per step (ms).
    pub ms_per_step: f64,
    /// Of which Hessian and gradient assembly, factorization and solve, line search (ms).
    #[serde(default)]
    pub ms_split_per_step: [f64; 3],
    /// Mean Newton iterations per step (every solve of a step, friction lagging included).
    #[serde(default)]
    pub iterations_per_step: f64,
    /// Mean Hessians assembled per step.
    #[serde(default)]
    pub hessians_per_step: f64,
    /// Steps that did not converge.
    pub unconverged_steps: usize,
    /// Largest distance of a constrained integration point from its target over the run (m).
    #[serde(default)]
    pub max_pin_deviation: f64,
    /// The same for the exactly held points alone (`pins = { exact = … }`; 0 otherwise).
    #[serde(default)]
    pub max_held_deviation: f64,
    /// The deepest penetration of an integration point into the floor or a collider over the
    /// run (m).
    #[serde(default)]
    pub max_penetration: f64,
    /// The mechanical energy at the start and at the end (J, kinetic, elastic and the scene's
    /// potentials; [`reduced_sim::Simulator::mechanical_energy`]).
    #[serde(default)]
    pub energy: [f64; 2],
    /// The largest rise of that energy over one step (J; 0 when it only fell).
    #[serde(default)]
    pub max_energy_rise: f64,
    /// Frames written.
    pub frames_written: usize,
    /// Integration points simulated.
    pub simulation_points: usize,
    /// Largest displacement of a surface vertex (or cloud point) at the last frame (m).
    pub final_max_displacement: f64,
    /// For a splat scene: the most splats with det F ≤ 0 in one written frame.
    #[serde(default)]
    pub inverted_splats: usize,
    /// The elastic quadrature (kind, points, cubature report).
    #[serde(default)]
    pub quadrature: Option<QuadratureReport>,
    /// The stress over the written frames, when `simulation.stress` asked for it.
    #[serde(default)]
    pub stress: Option<StressSummary>,
    /// The basis settings the run used, every default filled in (`None` in summaries written
    /// before they were recorded).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub basis: Option<crate::BasisSpec>,
    /// The simulation settings the run used, every default filled in (how the regions were
    /// held, the volumetric term, the quadrature asked for; `None` in summaries written before
    /// they were recorded).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub simulation: Option<SimulationSpec>,
    /// The output vertices (or cloud points) at the last step (m), for a preview; not in
    /// `summary.json`.
    #[serde(skip)]
    pub final_positions: Vec<Vector3<f64>>,
    /// Their von Mises stress at the last step (Pa), with `simulation.stress`; not in
    /// `summary.json`.
    #[serde(skip)]
    pub final_von_mises: Option<Vec<f64>>,
}

/// Writes `report` as `<out_dir>/summary.json` (pretty JSON, atomically).
///
/// # Errors
/// [`ArtifactError`] naming the file.
pub(crate) fn write_summary(out_dir: &Path, report: &impl Serialize) -> Result<(), ArtifactError> {
    write_atomically(
        &out_dir.join("summary.json"),
        serde_json::to_string_pretty(report)
            .unwrap_or_default()
            .as_bytes(),
    )
}

/// Runs a scene file with stable Neo-Hookean elasticity and writes `frame_NNNNN.ply` / `.vtk`
/// (the deformed surface or cloud, every `output_every` steps and the last) and `summary.json`
/// under `out_dir`; with `simulation.stress`, the VTK frames carry the stress at the output
/// points and `points_NNNNN.vtk` the integration points with theirs ([`crate::StressField`]); with
/// colliders, `colliders_NNNNN.ply` their surfaces at each frame ([`crate::ColliderFrames`]).
/// A cubature (`simulation.quadrature`) is cached under `cache_dir` when one is given.
///
/// # Errors
/// [`SimulateError`] naming the stage; frames already written stay valid files.
pub fn simulate_scene_file(
    file: &SceneFile,
    out_dir: &Path,
    cache_dir: Option<&Path>,
    progress: &dyn Progress,
) -> Result<SimulateReport, SimulateError> {
    let description = ObjectDescription {
        geometry: &file.geometry,
        scale: 1.0,
        material: &file.material,
        basis: &file.basis,
        simulation: &file.simulation,
        scene: &file.scene,
        label: String::new(),
    };
    let (setup, splats) = ObjectSetup::prepare(&description, progress)?;
    let basis_seconds = setup.basis_seconds;
    let collider_frames = crate::ColliderFrames::new(out_dir, &file.scene.colliders);
    let mut output = setup.output(out_dir, splats, file.simulation.stress)?;
    let steps = file.simulation.steps;
    let simulation = setup.simulation(&file.scene, &file.simulation, cache_dir);
    let mut frames_written = 0;
    let mut last_z = Vec::new();
    match &file.simulation.quadrature {
        QuadratureRule::Cubature(p) => progress.status(&format!(
            "elastic quadrature: optimizing a cubature to force error {} (at most {} points)",
            p.tolerance, p.max_points
        )),
        QuadratureRule::Automatic(p) => progress.status(&format!(
            "elastic quadrature: a cubature to force error {} (at most {} points) if it pays \
             for itself in {steps} steps, else every point",
            p.tolerance, p.max_points
        )),
        QuadratureRule::Full | QuadratureRule::RandomSubset { .. } => {}
    }
    progress.begin(steps, "simulate");
    let report = run(&simulation, steps, |frame| {
        let z = &frame.simulator.state().z;
        if frame.index % file.simulation.output_every == 0 || frame.index == steps {
            output.write(frame.index, z, frame.time)?;
            collider_frames.write(frame.index, frame.time)?;
            frames_written += 1;
        }
        if frame.index > 0 {
            progress.advance();
        }
        if frame.index == steps {
            last_z.clone_from(z);
        }
        Ok(())
    });
    progress.finish();
    let report = report?;
    let report = SimulateReport {
        basis_seconds,
        ms_per_step: report.ms_per_step,
        ms_split_per_step: [
            report.ms_assembly_per_step,
            report.ms_solve_per_step,
            report.ms_line_search_per_step,
        ],
        iterations_per_step: report.iterations_per_step,
        hessians_per_step: report.hessians_per_step,
        max_pin_deviation: report.max_pin_deviation,
        max_held_deviation: report.max_held_deviation,
        unconverged_steps: report.unconverged_steps,
        max_penetration: report.max_penetration,
        energy: report.energy,
        max_energy_rise: report.max_energy_rise,
        frames_written,
        simulation_points: setup.points.len(),
        final_max_displacement: output
            .map
            .displacements(&last_z)
            .iter()
            .map(|d| d.norm())
            .fold(0.0, f64::max),
        inverted_splats: output.inverted_splats,
        quadrature: Some(report.quadrature.clone()),
        stress: output.summary.clone(),
        basis: Some(file.basis),
        simulation: Some(file.simulation),
        final_positions: output.map.positions(&last_z),
        final_von_mises: output.last_von_mises(),
    };
    write_summary(out_dir, &report)?;
    Ok(report)
}
