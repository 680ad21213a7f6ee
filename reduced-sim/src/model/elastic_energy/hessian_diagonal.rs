//! The diagonal of the reduced elastic Hessian alone, without the Hessian (what the
//! cubature's force weights need: `12(m+1)` numbers where the Hessian is `(12(m+1))²`).

use hyperelastic::{HyperelasticMaterial, Matrix9, Tangent};
use rayon::prelude::*;

use crate::model::reduced_model::ReducedModel;

/// Points whose tangents are formed together.
const POINTS_PER_CHUNK: usize = 64;

impl<M: HyperelasticMaterial> ReducedModel<M> {
    /// The diagonal of [`ReducedModel::elastic_hessian`] at z (length 12(m + 1), z's layout):
    /// entry `r·4(m+1) + a` is `Σ_i Σ_{s,t} G_i[a, s] A_i^{rr}[s, t] G_i[a, t]` with
    /// `A_i^{rr}[s, t] = w_i ∂²Ψ/∂F_rs∂F_rt`, plus with a projected dilatation the diagonal of
    /// `(∂r/∂z)ᵀ G⁻¹ (∂r/∂z)`. Equal to the Hessian's diagonal up to the order of the sums.
    ///
    /// # Panics
    /// If `z.len() != 12(m + 1)`.
    pub fn elastic_hessian_diagonal(&self, z: &[f64], tangent: Tangent) -> Vec<f64> {
        let deformation = self.elastic_deformation(z);
        let f = &deformation.gradients;
        let map = self.elastic_map();
        let n4 = map.layout().block_len();
        let shift = self.pressure_shifts(&deformation);
        let chunks: Vec<Vec<f64>> = (0..f.len().div_ceil(POINTS_PER_CHUNK))
            .into_par_iter()
            .map(|chunk| {
                let start = chunk * POINTS_PER_CHUNK;
                let end = (start + POINTS_PER_CHUNK).min(f.len());
                let mut tangents = [Matrix9::zeros(); POINTS_PER_CHUNK];
                let tangents = &mut tangents[..end - start];
                self.weighted_tangents(f, start..end, tangent, shift.as_deref(), tangents);
                let mut sum = vec![0.0; 3 * n4];
                for (k, d) in tangents.iter().enumerate() {
                    let g = map.gradient_block(start + k);
                    for (r, out) in sum.chunks_exact_mut(n4).enumerate() {
                        for (a, out) in out.iter_mut().enumerate() {
                            let ga = [g[a], g[n4 + a], g[2 * n4 + a]];
                            let mut x = 0.0;
                            for s in 0..3 {
                                for t in 0..3 {
                                    x += ga[s] * d[(3 * s + r, 3 * t + r)] * ga[t];
                                }
                            }
                            *out += x;
                        }
                    }
                }
                sum
            })
            .collect();
        let mut diagonal = vec![0.0; 3 * n4];
        for chunk in &chunks {
            for (a, b) in diagonal.iter_mut().zip(chunk) {
                *a += b;
            }
        }
        if let Some(d) = self.dilatation() {
            // diag(Jᵀ G⁻¹ J) with Jᵀ = ∂r/∂zᵀ (12(m+1) × P).
            let jacobian_t = self.dilatation_jacobian_transpose(d, f);
            let g = d.gram_inverse();
            for (k, out) in diagonal.iter_mut().enumerate() {
                let row: Vec<f64> = (0..d.functions()).map(|b| jacobian_t[(k, b)]).collect();
                let mut x = 0.0;
                for (a, ra) in row.iter().enumerate() {
                    for (b, rb) in row.iter().enumerate() {
                        x += ra * g[(a, b)] * rb;
                    }
                }
                *out += x;
            }
        }
        diagonal
    }
}

#[cfg(test)]
mod tests {
    use crate::ProjectedDilatationParams;
    use crate::model::analytic_field::{affine_pressure, analytic_model, probe_z};
    use hyperelastic::Tangent;

    #[test]
    fn hessian_diagonal_equals_the_diagonal_of_the_hessian_with_and_without_a_dilatation() {
        let (model, points) = analytic_model();
        let pressure = affine_pressure(&points);
        let projected = analytic_model()
            .0
            .with_projected_dilatation(pressure, ProjectedDilatationParams::default())
            .expect("independent functions");
        let z = probe_z(model.deformation_map().layout().len(), 0.02);
        for model in [&model, &projected] {
            for tangent in [Tangent::Exact, Tangent::ProjectedPsd] {
                let hessian = model.elastic_hessian(&z, tangent);
                let diagonal = model.elastic_hessian_diagonal(&z, tangent);
                let largest = (0..diagonal.len())
                    .map(|k| hessian[(k, k)].abs())
                    .fold(0.0, f64::max);
                for (k, x) in diagonal.iter().enumerate() {
                    assert!(
                        (x - hessian[(k, k)]).abs() <= 1e-12 * largest,
                        "{tangent:?} entry {k}: {x:e} vs {:e}",
                        hessian[(k, k)]
                    );
                }
            }
        }
    }
}
