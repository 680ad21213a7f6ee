//! How a method's trajectory scores against a FEM run (design §4.3), and what makes a run no
//! reference: its unconverged frames.

use fem_ref::PointInterpolation;
use nalgebra::Vector3;
use reduced_sim::{DeformationMap, SkinningField};
use serde::{Deserialize, Serialize};

use super::{FemReferenceError, FemRun};
use crate::metrics::{TrajectoryErrors, basis_fitting_residual, per_frame_mse, trajectory_errors};

/// How well a method's trajectory matches a FEM run (design §4.3).
#[derive(Clone, Debug, PartialEq)]
pub struct FieldScores {
    /// Normalized MSE and max error.
    pub errors: TrajectoryErrors,
    /// Normalized MSE of each frame 1..T (their mean is `errors.normalized_mse`).
    pub per_frame_mse: Vec<f64>,
    /// Basis fitting residual of the FEM trajectory through the method's deformation map.
    pub fitting_residual: f64,
}

/// A FEM run some of whose Newton solves stopped unconverged: its frames are not a reference,
/// and no table scores against it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize, thiserror::Error)]
#[error(
    "the FEM reference's Newton solve did not converge at frame(s) {} of {steps} (cap {iteration_cap} \
     iterations{}): not a reference, not scored",
    list(frames),
    match step_halvings {
        0 => String::new(),
        n => format!(", steps split into halves {n} deep"),
    }
)]
pub struct UnconvergedReference {
    /// The frames (= 1-based steps) whose Newton solve did not converge.
    pub frames: Vec<usize>,
    /// Steps in the run.
    pub steps: usize,
    /// The Newton iteration cap the run used.
    pub iteration_cap: usize,
    /// How deep the run split a step that did not converge whole (0: not at all).
    #[serde(default)]
    pub step_halvings: usize,
}

fn list(frames: &[usize]) -> String {
    frames
        .iter()
        .map(usize::to_string)
        .collect::<Vec<_>>()
        .join(", ")
}

impl FemRun {
    /// The largest Newton iteration count of any step (0 for a run of no steps).
    pub fn max_iterations(&self) -> usize {
        self.step_iterations.iter().copied().max().unwrap_or(0)
    }

    /// The frames (1-based steps) whose Newton solve did not converge.
    pub fn unconverged_frames(&self) -> Vec<usize> {
        self.step_converged
            .iter()
            .enumerate()
            .filter(|(_, c)| !**c)
            .map(|(i, _)| i + 1)
            .collect()
    }

    /// `Ok` when every step converged, so the run may serve as a reference; otherwise which
    /// frames did not (`iteration_cap` is the cap the run used, for the message).
    ///
    /// # Errors
    /// [`UnconvergedReference`] naming the unconverged frames.
    pub fn check_converged(&self, iteration_cap: usize) -> Result<(), UnconvergedReference> {
        let frames = self.unconverged_frames();
        if frames.is_empty() {
            Ok(())
        } else {
            Err(UnconvergedReference {
                frames,
                steps: self.step_converged.len(),
                iteration_cap,
                step_halvings: self.failed_step_halvings,
            })
        }
    }

    /// Rest positions of the tet mesh's vertices (m).
    pub fn vertices(&self) -> &[Vector3<f64>] {
        self.mesh.tet_mesh().vertices()
    }

    /// The largest vertex displacement `|x_t − x_0|` over all frames (m).
    pub fn max_vertex_displacement(&self) -> f64 {
        let n = self.vertices().len();
        self.frames
            .iter()
            .flat_map(|f| {
                f[..n]
                    .iter()
                    .zip(&self.frames[0])
                    .map(|(x, x0)| (x - x0).norm())
            })
            .fold(0.0, f64::max)
    }

    /// Vertex positions per frame (frame 0 = rest).
    pub fn vertex_frames(&self) -> Vec<Vec<Vector3<f64>>> {
        let n = self.vertices().len();
        self.frames.iter().map(|f| f[..n].to_vec()).collect()
    }

    /// Scores `frames` (positions at this run's vertices, frame 0 = rest, as many frames as this
    /// run) of a method whose deformation map is `field`, over frames 1..T with length scale
    /// `length` (design §4.3): normalized MSE and max error, and the basis fitting residual of
    /// this trajectory through `field`.
    ///
    /// # Errors
    /// [`FemReferenceError::Metrics`] for mismatched or non-finite frames or a singular fit,
    /// [`FemReferenceError::OutputMap`] if `field` cannot be evaluated at the vertices.
    pub fn score<B: SkinningField + ?Sized>(
        &self,
        field: &B,
        frames: &[Vec<Vector3<f64>>],
        length: f64,
    ) -> Result<FieldScores, FemReferenceError> {
        let reference = self.vertex_frames();
        let errors = trajectory_errors(&frames[1..], &reference[1..], length)?;
        let per_frame_mse = per_frame_mse(&frames[1..], &reference[1..], length)?;
        let map =
            DeformationMap::new(field, self.vertices()).map_err(FemReferenceError::OutputMap)?;
        let fitting_residual = basis_fitting_residual(&map, &reference[1..], length)?;
        Ok(FieldScores {
            errors,
            per_frame_mse,
            fitting_residual,
        })
    }

    /// Positions per frame of arbitrary rest points inside the mesh, interpolated from the
    /// elements.
    ///
    /// # Errors
    /// [`FemReferenceError::PointLocation`] if a point lies outside the mesh.
    pub fn frames_at(
        &self,
        points: &[Vector3<f64>],
    ) -> Result<Vec<Vec<Vector3<f64>>>, FemReferenceError> {
        let interpolation = PointInterpolation::new(&self.mesh, points)?;
        Ok(self
            .frames
            .iter()
            .map(|f| interpolation.interpolate(f))
            .collect())
    }

    /// This run's frames interpolated at those of `points` (rest positions, m) that lie inside
    /// its mesh, with their indices (points outside are skipped, e.g. the vertices of a coarser
    /// mesh of the same shape whose boundary sticks out).
    pub fn frames_inside(&self, points: &[Vector3<f64>]) -> (Vec<usize>, Vec<Vec<Vector3<f64>>>) {
        let (interpolation, inside) = PointInterpolation::inside(&self.mesh, points);
        let frames = self
            .frames
            .iter()
            .map(|f| interpolation.interpolate(f))
            .collect();
        (inside, frames)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_unconverged_reference_names_its_frames_cap_and_split_depth() {
        let why = |step_halvings| {
            UnconvergedReference {
                frames: vec![28, 31],
                steps: 40,
                iteration_cap: 60,
                step_halvings,
            }
            .to_string()
        };
        assert!(
            why(0).contains("frame(s) 28, 31 of 40 (cap 60 iterations): not a reference"),
            "{}",
            why(0)
        );
        assert!(
            why(2).contains("(cap 60 iterations, steps split into halves 2 deep)"),
            "{}",
            why(2)
        );
    }
}
