//! What the elastic energy, gradient and Hessian at one z share: the elastic points'
//! deformation gradients `F_i(z) = I + Zᵀ G_i` and, with a projected dilatation, its state
//! there (its energy, each point's dilatation `J − γ` and the pressure coefficients `p̂`).

use hyperelastic::HyperelasticMaterial;
use nalgebra::Matrix3;

use crate::model::projected_dilatation::DilatationState;
use crate::model::reduced_model::ReducedModel;

/// `F_i(z)` at every elastic point (one per point of [`ReducedModel::elastic_map`]) and the
/// projected dilatation's state at them, formed once and read by
/// [`ReducedModel::elastic_energy_at`], [`ReducedModel::elastic_gradient_at`] and
/// [`ReducedModel::add_elastic_hessian_at`].
#[derive(Debug)]
pub(crate) struct ElasticDeformation {
    /// `F_i`, one per elastic point.
    pub(crate) gradients: Vec<Matrix3<f64>>,
    /// The projected dilatation's state at `gradients`; `None` without one.
    pub(crate) dilatation: Option<DilatationState>,
}

impl<M: HyperelasticMaterial> ReducedModel<M> {
    /// The elastic points' deformation at z (length 12(m + 1)).
    ///
    /// # Panics
    /// If `z.len() != 12(m + 1)`.
    pub(crate) fn elastic_deformation(&self, z: &[f64]) -> ElasticDeformation {
        self.elastic_deformation_of(self.elastic_map().deformation_gradients(z))
    }

    /// The elastic points' deformation at the gradients `f` (one per elastic point).
    ///
    /// # Panics
    /// If `f.len()` is not the number of elastic points.
    pub(crate) fn elastic_deformation_of(&self, f: Vec<Matrix3<f64>>) -> ElasticDeformation {
        assert_eq!(f.len(), self.elastic_map().len(), "one F per elastic point");
        ElasticDeformation {
            dilatation: self.dilatation().map(|d| d.state(&f)),
            gradients: f,
        }
    }
}
