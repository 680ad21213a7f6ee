//! The candidate points' force columns over the training poses.

use faer::{Accum, Mat, MatRef, Par};
use hyperelastic::{HyperelasticMaterial, LameParameters};
use nalgebra::Matrix3;
use rayon::prelude::*;

use crate::model::deformation_map::DeformationMap;
use crate::model::reduced_model::ReducedModel;

use super::norm;

/// Candidate c's column holds, pose after pose, its weighted, normalized force density
/// `ω ⊙ g_c(z_k) / ‖f_k‖` (`3K · 4(m+1)` rows for K poses). Per candidate, two small products
/// over all poses at once: the strains `[F_k − I]_k = Z_allᵀ G_c` (`3K × 3`, Z_all the
/// `4(m+1) × 3K` poses side by side), then the force densities `[g_k]_k = G_c S`
/// (`4(m+1) × 3K`, `S[s, 3k + r] = P_k[r, s]`), which is the column's layout.
pub(super) struct CandidateForces<'a, M: HyperelasticMaterial> {
    material: &'a M,
    /// The deformation map at the candidates.
    map: DeformationMap,
    lame: Vec<LameParameters>,
    /// The poses side by side, column-major `4(m+1) × 3K`.
    poses: Vec<f64>,
    /// Per row: `ω / ‖f_k‖`.
    scale: Vec<f64>,
    /// 4(m + 1).
    block_len: usize,
    /// K.
    pose_count: usize,
}

impl<'a, M: HyperelasticMaterial> CandidateForces<'a, M> {
    /// The candidates `pool` (integration points of `model`) over `poses` (each 12(m+1) long)
    /// whose targets have norms `norms`, with the force weights `omega`.
    pub(super) fn new(
        model: &'a ReducedModel<M>,
        pool: &[usize],
        poses: &[&[f64]],
        norms: &[f64],
        omega: &[f64],
    ) -> Self {
        CandidateForces {
            material: model.material(),
            map: model.deformation_map().subset(pool),
            lame: pool.iter().map(|&i| model.lame_parameters()[i]).collect(),
            poses: poses.iter().flat_map(|p| p.iter().copied()).collect(),
            scale: norms
                .iter()
                .flat_map(|&norm| omega.iter().map(move |w| w / norm))
                .collect(),
            block_len: model.deformation_map().layout().block_len(),
            pose_count: poses.len(),
        }
    }

    /// Rows of a column: `3K · 4(m+1)`.
    pub(super) fn rows(&self) -> usize {
        self.scale.len()
    }

    /// Number of candidates.
    pub(super) fn len(&self) -> usize {
        self.lame.len()
    }

    /// 4(m + 1).
    pub(super) fn block_len(&self) -> usize {
        self.block_len
    }

    /// K.
    pub(super) fn pose_count(&self) -> usize {
        self.pose_count
    }

    /// Candidate c's G block (`4(m+1) × 3`, column-major).
    pub(super) fn gradient_block(&self, c: usize) -> &[f64] {
        self.map.gradient_block(c)
    }

    /// Candidate c's stresses at every pose: `3 × 3K`, `[(s, 3k + r)] = P_k[r, s]`.
    pub(super) fn stresses(&self, c: usize) -> Mat<f64> {
        let (n4, k) = (self.block_len, self.pose_count);
        let g_c = MatRef::from_column_major_slice(self.map.gradient_block(c), n4, 3);
        let mut strain = Mat::<f64>::zeros(3 * k, 3);
        faer::linalg::matmul::matmul(
            strain.as_mut(),
            Accum::Replace,
            MatRef::from_column_major_slice(&self.poses, n4, 3 * k).transpose(),
            g_c,
            1.0,
            Par::Seq,
        );
        let mut stresses = Mat::<f64>::zeros(3, 3 * k);
        for pose in 0..k {
            let f =
                Matrix3::from_fn(|r, s| strain[(3 * pose + r, s)] + f64::from(u8::from(r == s)));
            let p = self.material.first_piola_kirchhoff(&self.lame[c], &f);
            for r in 0..3 {
                for s in 0..3 {
                    stresses[(s, 3 * pose + r)] = p[(r, s)];
                }
            }
        }
        stresses
    }

    /// Candidate c's column, in f64 (`rows` entries), from its `stresses`.
    pub(super) fn column(&self, c: usize, stresses: MatRef<'_, f64>, column: &mut [f64]) {
        let n4 = self.block_len;
        faer::linalg::matmul::matmul(
            faer::MatMut::from_column_major_slice_mut(column, n4, 3 * self.pose_count),
            Accum::Replace,
            MatRef::from_column_major_slice(self.map.gradient_block(c), n4, 3),
            stresses,
            1.0,
            Par::Seq,
        );
        for (x, s) in column.iter_mut().zip(&self.scale) {
            *x *= s;
        }
    }

    /// Every candidate's column in f32 (only to rank candidates by their correlation with the
    /// residual: half the memory and memory traffic of f64), column-major `rows × len`, and
    /// its norm in f64; the columns that join the cubature are formed again in f64.
    pub(super) fn ranking_columns(&self) -> (Vec<f32>, Vec<f64>) {
        let rows = self.rows();
        let mut columns = vec![0.0_f32; rows * self.len()];
        let norms: Vec<f64> = columns
            .par_chunks_mut(rows)
            .enumerate()
            .map_init(
                || vec![0.0; rows],
                |scratch, (c, column)| {
                    self.column(c, self.stresses(c).as_ref(), scratch);
                    for (x, &y) in column.iter_mut().zip(scratch.iter()) {
                        *x = y as f32;
                    }
                    norm(scratch)
                },
            )
            .collect();
        (columns, norms)
    }
}
