//! A run recorded at given rest points every frame (usually a reference's mesh vertices): the
//! library's [`run`] with a recorder, for comparing a trajectory with a reference.

use hyperelastic::HyperelasticMaterial;
use nalgebra::Vector3;
use reduced_sim::{DeformationMap, DeformationMapError, SkinningField};
use thiserror::Error;

use crate::progress::Progress;
use crate::runner::{RunError, RunReport, Simulation, run};

/// A trajectory at the output points, with the run's timings and convergence.
#[derive(Clone, Debug)]
pub struct RecordedRun {
    /// Output-point positions per frame, frame 0 = rest (m); `steps + 1` frames.
    pub frames: Vec<Vec<Vector3<f64>>>,
    /// Timings, Newton counts, pin deviation, points simulated and held.
    pub report: RunReport,
}

/// A recorded run could not start or stopped.
#[derive(Debug, Error)]
pub enum RecordError {
    /// The skinning field cannot be evaluated at the output points.
    #[error("evaluating the skinning field at the output points failed")]
    OutputMap(#[source] DeformationMapError),
    /// The run failed (setup or a step).
    #[error(transparent)]
    Run(#[from] RunError),
}

/// Simulates `steps` steps of `simulation`, recording positions at `output_points` (rest, m)
/// every frame, with a progress stage labelled `label`.
///
/// # Errors
/// [`RecordError::OutputMap`] when the field cannot be evaluated at the output points;
/// [`RecordError::Run`] for a model, scene or step that fails.
pub fn run_recorded<B: SkinningField + ?Sized, M: HyperelasticMaterial + Clone>(
    simulation: &Simulation<'_, B, M>,
    output_points: &[Vector3<f64>],
    steps: usize,
    label: &str,
    progress: &dyn Progress,
) -> Result<RecordedRun, RecordError> {
    let output =
        DeformationMap::new(simulation.field, output_points).map_err(RecordError::OutputMap)?;
    let mut frames = Vec::with_capacity(steps + 1);
    progress.begin(steps, label);
    let report = run(simulation, steps, |frame| {
        frames.push(output.positions(&frame.simulator.state().z));
        if frame.index > 0 {
            progress.advance();
        }
        Ok(())
    });
    progress.finish();
    Ok(RecordedRun {
        frames,
        report: report?,
    })
}
