//! How far a quadrature's reduced elastic forces are from the full model's: the compliance
//! weights of the force components and the relative force error over poses.

use hyperelastic::HyperelasticMaterial;

use crate::model::elastic_energy::projected_elastic_gradient;
use crate::model::elastic_quadrature::{ElasticQuadrature, QuadratureError};
use crate::model::projected_dilatation::InversionBarrier;
use crate::model::reduced_model::ReducedModel;

use super::norm;

/// The weights `ω_k = 1/sqrt(H_kk)` of the force components, with `H = M_z/h² + K₀` the
/// step system at rest (K₀ the exact elastic Hessian at z = 0, M_z the reduced mass matrix,
/// h = `time_step` in s): a force error δf moves a Newton step by about `H⁻¹ δf`, whose
/// Jacobi approximation is `diag(ω)² δf`.
pub fn force_weights<M: HyperelasticMaterial>(model: &ReducedModel<M>, time_step: f64) -> Vec<f64> {
    let layout = model.deformation_map().layout();
    let stiffness = model.elastic_hessian_diagonal(&layout.rest(), hyperelastic::Tangent::Exact);
    let mass = model.mass_block();
    let n4 = layout.block_len();
    (0..layout.len())
        .map(|k| {
            let h = stiffness[k] + mass[(k % n4, k % n4)] / (time_step * time_step);
            if h > 0.0 { 1.0 / h.sqrt() } else { 0.0 }
        })
        .collect()
}

/// The relative force error of `quadrature` on `poses` in the `weights` norm (one weight per
/// component of z, e.g. [`force_weights`]; all ones for the plain norm), each pose normalized
/// to unit force: `sqrt(Σ_p ‖ω∘(f̃_p − f_p)‖² / ‖ω∘f_p‖² / #poses)` with f the full-quadrature
/// force and f̃ the force of the model integrated by `quadrature`
/// ([`ReducedModel::with_elastic_quadrature`]; with a projected dilatation, its pressure
/// projection is formed on the quadrature's points too, and both forces leave out its
/// inversion barrier, as the training does). Poses with zero force are skipped.
///
/// # Errors
/// [`QuadratureError::OutOfRange`] for a quadrature point that is not a point of the model;
/// [`QuadratureError::Dilatation`] when the model's pressure functions are dependent at the
/// quadrature's points.
///
/// # Panics
/// If `model` already has a quadrature.
pub fn force_error<M: HyperelasticMaterial>(
    model: &ReducedModel<M>,
    quadrature: &ElasticQuadrature,
    poses: &[Vec<f64>],
    weights: &[f64],
) -> Result<f64, QuadratureError> {
    assert!(
        model.elastic_quadrature().is_none(),
        "force errors are measured against the full model"
    );
    let (subset, dilatation) = model.elastic_subset(quadrature.clone())?;
    let mut sum = 0.0;
    let mut count = 0usize;
    for (z, full) in poses.iter().zip(model.elastic_gradients(poses)) {
        let full: Vec<f64> = full.iter().zip(weights).map(|(f, w)| f * w).collect();
        let reference = norm(&full);
        if reference == 0.0 {
            continue;
        }
        let f = subset.map.deformation_gradients(z);
        let state = dilatation.as_ref().map(|d| d.state(&f));
        let approx = projected_elastic_gradient(
            model.material(),
            &subset.map,
            &subset.lame,
            subset.quadrature.weights(),
            dilatation.as_ref().zip(state.as_ref()),
            InversionBarrier::LeftOut,
            &f,
        );
        let diff: Vec<f64> = approx
            .iter()
            .zip(&full)
            .zip(weights)
            .map(|((a, f), w)| a * w - f)
            .collect();
        sum += (norm(&diff) / reference).powi(2);
        count += 1;
    }
    Ok(if count == 0 {
        0.0
    } else {
        (sum / count as f64).sqrt()
    })
}
