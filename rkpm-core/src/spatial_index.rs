//! Nearest-neighbour and radius queries over a fixed point set (a thin wrapper over kiddo's
//! immutable k-d tree, so the rest of the crate does not depend on its query-builder API).

use std::num::NonZeroUsize;

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use nalgebra::Vector3;

/// A static k-d tree over points; queries return `(index, distance)` pairs (distance in the
/// points' units, not squared), nearest first.
pub struct SpatialIndex {
    tree: ImmutableKdTree<f64, 3>,
    len: usize,
}

impl SpatialIndex {
    /// Builds the tree.
    ///
    /// # Panics
    /// If `points` has more than `u32::MAX` entries.
    pub fn new(points: &[Vector3<f64>]) -> Self {
        assert!(
            points.len() < u32::MAX as usize,
            "too many points for the spatial index"
        );
        let coords: Vec<[f64; 3]> = points.iter().map(|p| [p.x, p.y, p.z]).collect();
        let tree = ImmutableKdTree::new_from_slice(&coords)
            .expect("a k-d tree can be built over finite points");
        SpatialIndex {
            tree,
            len: points.len(),
        }
    }

    /// Number of indexed points.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether the index is empty.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The `n` nearest points to `q` (fewer if the set is smaller), nearest first.
    pub fn nearest(&self, q: &Vector3<f64>, n: usize) -> Vec<(usize, f64)> {
        let Some(n) = NonZeroUsize::new(n.min(self.len)) else {
            return Vec::new();
        };
        self.tree
            .query(&[q.x, q.y, q.z])
            .nearest_n::<SquaredEuclidean<f64>>(n)
            .execute()
            .into_iter()
            .map(|r| (r.item as usize, r.distance.sqrt()))
            .collect()
    }

    /// All points within distance `radius` of `q` (inclusive), in no particular order.
    pub fn within(&self, q: &Vector3<f64>, radius: f64) -> Vec<(usize, f64)> {
        self.tree
            .query(&[q.x, q.y, q.z])
            .within::<SquaredEuclidean<f64>>(radius * radius)
            .unsorted()
            .execute()
            .into_iter()
            .map(|r| (r.item as usize, r.distance.sqrt()))
            .collect()
    }
}
