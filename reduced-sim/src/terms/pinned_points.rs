//! The integration points of one pinned region, with their rows of the deformation map.

use faer::{Accum, MatRef, Par};
use nalgebra::Vector3;

use crate::model::deformation_map::DeformationMap;
use crate::scene::{PinTarget, PinnedRegion};

/// One region's points: rest positions, volumes, rows `B_i` and where they must be.
pub(crate) struct PinnedPoints {
    pub(crate) rest: Vec<Vector3<f64>>,
    /// Volumes v_i (m³).
    pub(crate) volumes: Vec<f64>,
    /// B restricted to the region's points, column-major `4(m+1) × P`.
    pub(crate) b: Vec<f64>,
    target: PinTarget,
}

impl PinnedPoints {
    /// `region`'s points on `map` (indices already checked against it).
    pub(crate) fn new(map: &DeformationMap, volumes: &[f64], region: &PinnedRegion) -> Self {
        PinnedPoints {
            rest: region
                .points
                .iter()
                .map(|&i| map.rest_positions()[i])
                .collect(),
            volumes: region.points.iter().map(|&i| volumes[i]).collect(),
            b: region
                .points
                .iter()
                .flat_map(|&i| map.position_row(i).iter().copied())
                .collect(),
            target: region.target.clone(),
        }
    }

    /// The points' targets (m) at time `time` (s).
    pub(crate) fn targets(&self, time: f64) -> Vec<Vector3<f64>> {
        self.rest.iter().map(|x| self.target.at(x, time)).collect()
    }

    /// Positions `x_i(z)` (m) of the region's points.
    pub(crate) fn positions(&self, map: &DeformationMap, z: &[f64]) -> Vec<Vector3<f64>> {
        let n4 = map.layout().block_len();
        let p = self.rest.len();
        let mut u = vec![0.0; 3 * p];
        faer::linalg::matmul::matmul(
            faer::MatMut::from_column_major_slice_mut(&mut u, 3, p),
            Accum::Replace,
            map.z_matrix(z).transpose(),
            MatRef::from_column_major_slice(&self.b, n4, p),
            1.0,
            Par::Seq,
        );
        self.rest
            .iter()
            .zip(u.chunks_exact(3))
            .map(|(x, u)| x + Vector3::new(u[0], u[1], u[2]))
            .collect()
    }

    /// The largest distance (m) of a point from its target at z and time `time` (s).
    pub(crate) fn max_deviation(&self, map: &DeformationMap, z: &[f64], time: f64) -> f64 {
        self.positions(map, z)
            .iter()
            .zip(self.targets(time))
            .map(|(x, t)| (x - t).norm())
            .fold(0.0, f64::max)
    }
}
