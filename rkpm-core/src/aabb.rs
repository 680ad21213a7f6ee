//! Axis-aligned bounding boxes.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// An axis-aligned box `[min, max]` (metres, or file units before normalization).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Aabb {
    /// Componentwise minimum corner.
    pub min: Vector3<f64>,
    /// Componentwise maximum corner.
    pub max: Vector3<f64>,
}

impl Aabb {
    /// The smallest box holding every point, or `None` for an empty set.
    pub fn from_points<'a>(points: impl IntoIterator<Item = &'a Vector3<f64>>) -> Option<Self> {
        let mut iter = points.into_iter();
        let first = *iter.next()?;
        Some(iter.fold(
            Aabb {
                min: first,
                max: first,
            },
            |b, p| Aabb {
                min: b.min.inf(p),
                max: b.max.sup(p),
            },
        ))
    }

    /// Side lengths `max - min`.
    pub fn extent(&self) -> Vector3<f64> {
        self.max - self.min
    }

    /// Largest side length `L = max_i (max_i - min_i)` (the normalization length of design §4.3).
    pub fn largest_side(&self) -> f64 {
        self.extent().max()
    }

    /// Box volume `Π extent_i`.
    pub fn volume(&self) -> f64 {
        self.extent().product()
    }

    /// Centre `(min + max) / 2`.
    pub fn center(&self) -> Vector3<f64> {
        (self.min + self.max) * 0.5
    }

    /// Whether `p` lies in the closed box.
    pub fn contains(&self, p: &Vector3<f64>) -> bool {
        (0..3).all(|d| p[d] >= self.min[d] && p[d] <= self.max[d])
    }
}
