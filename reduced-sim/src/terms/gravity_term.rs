//! Gravity's potential on one body.

use faer::Mat;
use hyperelastic::{HyperelasticMaterial, Tangent};
use nalgebra::Vector3;

use crate::model::reduced_model::ReducedModel;
use crate::terms::step_term::{StepTerm, TermPoint};

/// `E_grav(z) = −Σ_i ρ_i v_i gᵀ x_i(z)` (J, up to a constant; design §3.7): linear in z, so
/// its gradient `∂E/∂z_r = −g_r Σ_i ρ_i v_i B_i` is constant and its Hessian zero.
pub(crate) struct GravityTerm {
    /// `∂E_grav/∂z`, length 12(m + 1).
    gradient: Vec<f64>,
}

impl GravityTerm {
    /// Gravity `g` (m/s², finite) on `model`'s integration points.
    pub(crate) fn new<M: HyperelasticMaterial>(model: &ReducedModel<M>, g: Vector3<f64>) -> Self {
        let map = model.deformation_map();
        let mut weighted_sum = vec![0.0; map.layout().block_len()];
        for i in 0..map.len() {
            let w = model.densities()[i] * model.volumes()[i];
            for (s, b) in weighted_sum.iter_mut().zip(map.position_row(i)) {
                *s += w * b;
            }
        }
        GravityTerm {
            gradient: (0..3)
                .flat_map(|r| weighted_sum.iter().map(move |s| -g[r] * s))
                .collect(),
        }
    }
}

impl StepTerm for GravityTerm {
    fn name(&self) -> &str {
        "gravity"
    }

    fn add_energy(&self, at: &TermPoint<'_>, energy: &mut f64) {
        *energy += self
            .gradient
            .iter()
            .zip(at.z)
            .map(|(a, b)| a * b)
            .sum::<f64>();
    }

    fn add_derivatives(
        &self,
        _at: &TermPoint<'_>,
        _tangent: Tangent,
        gradient: &mut [f64],
        _hessian: Option<&mut Mat<f64>>,
    ) {
        for (a, b) in gradient.iter_mut().zip(&self.gradient) {
            *a += b;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::analytic_field::{analytic_model, probe_z};
    use crate::terms::scene_terms::term_point;
    use crate::terms::term_check::{TermCheckParams, check_term};

    #[test]
    fn gravity_passes_the_term_check_and_is_the_weight_times_the_drop() {
        let (model, _) = analytic_model();
        let g = Vector3::new(0.3, -9.8, 0.1);
        let term = GravityTerm::new(&model, g);
        let z = probe_z(model.deformation_map().layout().len(), 0.02);
        let at = term_point(&model, &z, 0.0);
        check_term(&term, &at, &TermCheckParams::default()).unwrap();
        // E(z) − E(0) = −Σ ρ v g·(x_i(z) − X_i), summed point by point.
        let map = model.deformation_map();
        let expected: f64 = (0..map.len())
            .map(|i| {
                let drop = map.position(i, &z) - map.rest_positions()[i];
                -model.densities()[i] * model.volumes()[i] * g.dot(&drop)
            })
            .sum();
        let energy = term.energy(&at) - term.energy(&term_point(&model, &vec![0.0; z.len()], 0.0));
        assert!(
            (energy - expected).abs() < 1e-9 * expected.abs(),
            "{energy} vs {expected}"
        );
    }
}
