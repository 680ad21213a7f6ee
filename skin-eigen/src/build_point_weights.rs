//! A basis's weights at the points it was built on, kept beside it so that evaluating it there
//! again (a model whose integration points are the basis's own, the library's default) does not
//! evaluate the RKPM shape functions a second time.

use std::sync::Arc;

use nalgebra::Vector3;

use crate::skinning_basis::SkinningWeights;

/// The weights W and ∇W ([`SkinningWeights`]) at the build points, or nothing.
///
/// Derived data: two bases that differ only here are equal, and it is not saved with the basis
/// (a loaded basis evaluates afresh). Memory: `32 · N · (m + 1)` bytes for N points, shared
/// between clones.
#[derive(Clone, Debug, Default)]
pub(crate) struct BuildPointWeights(Option<Arc<(Vec<Vector3<f64>>, SkinningWeights)>>);

impl BuildPointWeights {
    /// The weights `weights` at `points`.
    pub(crate) fn new(points: Vec<Vector3<f64>>, weights: SkinningWeights) -> Self {
        BuildPointWeights(Some(Arc::new((points, weights))))
    }

    /// The kept weights when `points` are the build points, element for element.
    pub(crate) fn at(&self, points: &[Vector3<f64>]) -> Option<&SkinningWeights> {
        self.0
            .as_deref()
            .filter(|(kept, _)| kept.as_slice() == points)
            .map(|(_, weights)| weights)
    }
}

impl PartialEq for BuildPointWeights {
    /// Always equal: the kept weights follow from the rest of the basis.
    fn eq(&self, _: &Self) -> bool {
        true
    }
}
