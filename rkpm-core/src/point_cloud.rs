//! Point clouds and 3D Gaussian Splatting objects as simulation input.

use nalgebra::{UnitQuaternion, Vector3};

use crate::aabb::Aabb;

/// Per-Gaussian attributes of a 3D Gaussian Splatting file, as stored there.
#[derive(Clone, Debug, PartialEq)]
pub struct GaussianSplatAttributes {
    /// Opacity as a logit (`sigmoid(opacity)` is the alpha in `[0, 1]`).
    pub opacity_logits: Vec<f64>,
    /// Per-axis scale as a natural log (`exp(scale)` is the standard deviation, file units).
    pub log_scales: Vec<[f64; 3]>,
    /// Orientation, normalized from the file's `(w, x, y, z)` quaternion.
    pub rotations: Vec<UnitQuaternion<f64>>,
}

/// A set of points sampling a solid (file units), with 3DGS attributes where the source had
/// them.
#[derive(Clone, Debug, PartialEq)]
pub struct PointCloud {
    positions: Vec<Vector3<f64>>,
    splats: Option<GaussianSplatAttributes>,
}

impl PointCloud {
    /// A cloud from positions and optional splat attributes.
    ///
    /// # Panics
    /// If the splat attribute arrays do not have one entry per position.
    pub fn new(positions: Vec<Vector3<f64>>, splats: Option<GaussianSplatAttributes>) -> Self {
        if let Some(s) = &splats {
            let n = positions.len();
            assert!(
                s.opacity_logits.len() == n && s.log_scales.len() == n && s.rotations.len() == n,
                "splat attributes must have one entry per point"
            );
        }
        PointCloud { positions, splats }
    }

    /// Point positions.
    pub fn positions(&self) -> &[Vector3<f64>] {
        &self.positions
    }

    /// The 3DGS attributes, if the file had them.
    pub fn splats(&self) -> Option<&GaussianSplatAttributes> {
        self.splats.as_ref()
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Whether the cloud has no points.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Bounding box of the points (`None` when empty).
    pub fn bounding_box(&self) -> Option<Aabb> {
        Aabb::from_points(&self.positions)
    }
}
