//! The elastic points' deformation at the last z a step's potential was evaluated at.
//!
//! Newton's line search evaluates the energy at the point it then accepts, and the next
//! iteration asks for the gradient (and perhaps the Hessian) at that same point. Keeping the
//! [`ElasticDeformation`] of the last evaluation lets the gradient skip forming the `F_i`
//! and the projected dilatation's state again: one pass over the points' `G_i` instead of two
//! where the energy needs every `F_i` before any point's share, and fewer products where it
//! does not.

use std::sync::{Arc, Mutex, MutexGuard, PoisonError};

use hyperelastic::HyperelasticMaterial;

use crate::model::elastic_deformation::ElasticDeformation;
use crate::model::reduced_model::ReducedModel;

/// The last z asked for and the elastic deformation there, of the one model the potential
/// belongs to. Results do not depend on it: a z that is not the stored one to the bit is
/// formed again.
#[derive(Debug, Default)]
pub(crate) struct DeformationCache {
    last: Mutex<Option<(Vec<f64>, Arc<ElasticDeformation>)>>,
}

impl DeformationCache {
    /// The elastic deformation of `model` at `z`: the stored one when `z` is the stored z to
    /// the bit, else formed by [`ReducedModel::elastic_deformation`] and stored.
    pub(crate) fn at<M: HyperelasticMaterial>(
        &self,
        model: &ReducedModel<M>,
        z: &[f64],
    ) -> Arc<ElasticDeformation> {
        if let Some(deformation) = self.stored(z) {
            return deformation;
        }
        let deformation = Arc::new(model.elastic_deformation(z));
        *self.lock() = Some((z.to_vec(), Arc::clone(&deformation)));
        deformation
    }

    /// The stored deformation when `z` is the stored z to the bit.
    pub(crate) fn stored(&self, z: &[f64]) -> Option<Arc<ElasticDeformation>> {
        let last = self.lock();
        let (at, deformation) = last.as_ref()?;
        let same = at.len() == z.len() && at.iter().zip(z).all(|(a, b)| a.to_bits() == b.to_bits());
        same.then(|| Arc::clone(deformation))
    }

    /// The stored pair; it is replaced whole, so a lock poisoned by a panic elsewhere still
    /// holds a complete value.
    fn lock(&self) -> MutexGuard<'_, Option<(Vec<f64>, Arc<ElasticDeformation>)>> {
        self.last.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::analytic_field::{analytic_model, probe_z};

    #[test]
    fn the_stored_deformation_is_returned_only_for_the_same_z_to_the_bit() {
        let (model, _) = analytic_model();
        let map = model.elastic_map();
        let cache = DeformationCache::default();
        let z = probe_z(map.layout().len(), 0.01);
        assert!(cache.stored(&z).is_none());
        let first = cache.at(&model, &z);
        assert_eq!(first.gradients, map.deformation_gradients(&z));
        assert!(Arc::ptr_eq(&first, &cache.stored(&z).unwrap()));
        let mut nudged = z.clone();
        nudged[0] = f64::from_bits(nudged[0].to_bits() + 1);
        assert!(cache.stored(&nudged).is_none());
        let second = cache.at(&model, &nudged);
        assert_eq!(second.gradients, map.deformation_gradients(&nudged));
        assert!(cache.stored(&z).is_none(), "only the last z is kept");
    }
}
