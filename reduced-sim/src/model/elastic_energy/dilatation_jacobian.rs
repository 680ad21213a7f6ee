//! The projected dilatation's part of the reduced elastic Hessian: its Jacobian
//! `∂r/∂z` and the rank update `(∂r/∂z)ᵀ G⁻¹ (∂r/∂z)`
//! ([`crate::model::projected_dilatation`]).

use faer::linalg::matmul::triangular::{self, BlockStructure};
use faer::{Accum, Mat, Par};
use hyperelastic::HyperelasticMaterial;
use nalgebra::Matrix3;
use rayon::prelude::*;

use crate::model::projected_dilatation::ProjectedDilatation;
use crate::model::reduced_model::ReducedModel;

impl<M: HyperelasticMaterial> ReducedModel<M> {
    /// Adds `(∂r/∂z)ᵀ G⁻¹ (∂r/∂z)` of the projected dilatation to `h`
    /// ([`crate::model::projected_dilatation`]): `X = (∂r/∂z)ᵀ G⁻¹`, then the lower triangle
    /// of `X (∂r/∂z)`, mirrored.
    pub(super) fn add_dilatation_rank_update(
        &self,
        d: &ProjectedDilatation,
        f: &[Matrix3<f64>],
        h: &mut Mat<f64>,
    ) {
        let functions = d.functions();
        let len = h.nrows();
        let jacobian_t = self.dilatation_jacobian_transpose(d, f);
        let g = d.gram_inverse();
        let g = Mat::from_fn(functions, functions, |a, b| g[(a, b)]);
        let mut x = Mat::<f64>::zeros(len, functions);
        faer::linalg::matmul::matmul(
            x.as_mut(),
            Accum::Replace,
            jacobian_t.as_ref(),
            g.as_ref(),
            1.0,
            Par::Seq,
        );
        let mut update = Mat::<f64>::zeros(len, len);
        triangular::matmul(
            update.as_mut(),
            BlockStructure::TriangularLower,
            Accum::Replace,
            x.as_ref(),
            BlockStructure::Rectangular,
            jacobian_t.transpose(),
            BlockStructure::Rectangular,
            1.0,
            Par::rayon(0),
        );
        for j in 0..len {
            for i in j..len {
                let v = update[(i, j)];
                h[(i, j)] += v;
                if i != j {
                    h[(j, i)] += v;
                }
            }
        }
    }

    /// `(∂r/∂z)ᵀ` of the projected dilatation (12(m + 1) × P) at the elastic points'
    /// deformation gradients `f`: column b is `Σ_q w_q κ_q q_b(X_q) ∂J_q/∂z`, formed as
    /// products `V Q` over blocks of points, with column q of V `w_q κ_q ∂J_q/∂z` (entry
    /// `r·4(m+1) + a` is `w_q κ_q Σ_s G_q[a, s] cof F_q[r, s]`) and Q the pressure values
    /// (N × P); the blocks' products are added in block order.
    pub(super) fn dilatation_jacobian_transpose(
        &self,
        d: &ProjectedDilatation,
        f: &[Matrix3<f64>],
    ) -> Mat<f64> {
        const POINTS_PER_BLOCK: usize = 1024;
        let map = self.elastic_map();
        let n4 = map.layout().block_len();
        let pressure = d.elastic_pressure();
        let blocks: Vec<Mat<f64>> = (0..f.len().div_ceil(POINTS_PER_BLOCK))
            .into_par_iter()
            .map(|block| {
                let start = block * POINTS_PER_BLOCK;
                let end = (start + POINTS_PER_BLOCK).min(f.len());
                let mut v = Mat::<f64>::zeros(3 * n4, end - start);
                for (k, fq) in f[start..end].iter().enumerate() {
                    let q = start + k;
                    let c = hyperelastic::cofactor(fq) * d.weighted_modulus(q);
                    let (g0, rest) = map.gradient_block(q).split_at(n4);
                    let (g1, g2) = rest.split_at(n4);
                    let column = v
                        .col_mut(k)
                        .try_as_col_major_mut()
                        .expect("a column of an owned matrix is contiguous")
                        .as_slice_mut();
                    for (r, out) in column.chunks_exact_mut(n4).enumerate() {
                        let [c0, c1, c2] = [c[(r, 0)], c[(r, 1)], c[(r, 2)]];
                        for (((o, x), y), w) in out.iter_mut().zip(g0).zip(g1).zip(g2) {
                            *o = x * c0 + y * c1 + w * c2;
                        }
                    }
                }
                let mut product = Mat::<f64>::zeros(3 * n4, d.functions());
                faer::linalg::matmul::matmul(
                    product.as_mut(),
                    Accum::Replace,
                    v.as_ref(),
                    pressure.subrows(start, end - start),
                    1.0,
                    Par::Seq,
                );
                product
            })
            .collect();
        let mut jacobian_t = Mat::<f64>::zeros(3 * n4, d.functions());
        for block in &blocks {
            jacobian_t += block;
        }
        jacobian_t
    }
}
