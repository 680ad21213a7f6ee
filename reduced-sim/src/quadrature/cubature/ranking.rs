//! The candidates' correlations with the residual, `Aᵀr`, from small per-point factors
//! instead of the force columns.
//!
//! Candidate c's column holds, at row `(3k + r) · 4(m+1) + a`, the entry
//! `s_{kra} Σ_t G_c[a, t] P_ck[r, t]` (`s` the row scales `ω_{ra} / ‖f_k‖`, G_c the point's
//! `4(m+1) × 3` gradient block, `P_ck` its first Piola–Kirchhoff stress at pose k). With the
//! scaled residual laid out as the `4(m+1) × 3K` matrix `R[a, 3k + r] = s_{kra} r_{kra}`,
//!
//! ```text
//! A_cᵀ r = Σ_{t, j} T[3c + t, j] S[3c + t, j],   T = G_allᵀ R  (3C × 3K),
//! S[3c + t, 3k + r] = P_ck[r, t],
//! ```
//!
//! one matrix product over all C candidates (inner dimension 4(m+1)) and an elementwise
//! contraction. The factors take `4 (12(m+1) + 18K)` bytes per candidate (6 KB at m = 32 with
//! 60 poses) where the columns took `4 · 12(m+1) K` (95 KB). Ranking only: the products are
//! f32; the weights, the residual and the errors stay f64.

use faer::{Accum, MatMut, MatRef, Par};
use rayon::prelude::*;

use super::candidates::CandidateForces;

/// Rows of S and T one task contracts.
const ROWS_PER_TASK: usize = 3 * 128;

/// The factors of every candidate's column and the products they rank with.
pub(super) struct ResidualCorrelation {
    /// 4(m + 1).
    block_len: usize,
    /// G_all in f32, column-major `4(m+1) × 3C` (candidate c at columns 3c … 3c + 2).
    gradients: Vec<f32>,
    /// S in f32, column-major `3C × 3K`.
    stresses: Vec<f32>,
    /// The row scales `s` of a column (`3K · 4(m+1)`).
    scale: Vec<f64>,
    /// `‖A_c‖` in f64, by candidate.
    norms: Vec<f64>,
    /// The candidates the factors hold, in their order (those retired leave).
    members: Vec<usize>,
}

impl ResidualCorrelation {
    /// The factors of every candidate of `candidates`, whose column rows are scaled by
    /// `omega` (the force weights, `12(m+1)`) and `pose_scales` (`1 / ‖f_k‖`, K).
    pub(super) fn new(candidates: &CandidateForces, omega: &[f64], pose_scales: &[f64]) -> Self {
        let (n4, poses, count) = (
            candidates.block_len(),
            candidates.pose_count(),
            candidates.len(),
        );
        let rows = 3 * count;
        let gradients: Vec<f32> = (0..count)
            .flat_map(|c| candidates.gradient_block(c).iter().map(|&g| g as f32))
            .collect();
        // Per candidate, its column's norm from the factors:
        // ‖A_c‖² = Σ_r Σ_{t,u} (Σ_a ω_ra² G[a,t] G[a,u]) (Σ_k P_k[r,t] P_k[r,u] / ‖f_k‖²).
        let squared_scales: Vec<f64> = pose_scales.iter().map(|p| p * p).collect();
        let norms: Vec<f64> = (0..count)
            .into_par_iter()
            .map(|c| {
                let stresses = candidates.stresses(c);
                let g = candidates.gradient_block(c);
                let mut squared = 0.0;
                for r in 0..3 {
                    let w = &omega[r * n4..(r + 1) * n4];
                    let column = |t: usize| &g[t * n4..(t + 1) * n4];
                    let mut gradient_part = [[0.0; 3]; 3];
                    let mut stress_part = [[0.0; 3]; 3];
                    for t in 0..3 {
                        for u in t..3 {
                            let x: f64 = w
                                .iter()
                                .zip(column(t))
                                .zip(column(u))
                                .map(|((w, a), b)| w * w * a * b)
                                .sum();
                            let y: f64 = squared_scales
                                .iter()
                                .enumerate()
                                .map(|(k, p)| {
                                    p * stresses[(t, 3 * k + r)] * stresses[(u, 3 * k + r)]
                                })
                                .sum();
                            (gradient_part[t][u], gradient_part[u][t]) = (x, x);
                            (stress_part[t][u], stress_part[u][t]) = (y, y);
                        }
                    }
                    for t in 0..3 {
                        for u in 0..3 {
                            squared += gradient_part[t][u] * stress_part[t][u];
                        }
                    }
                }
                squared.max(0.0).sqrt()
            })
            .collect();
        // S in f32, a column (pose and row r) at a time: each task writes contiguous memory.
        let mut stresses = vec![0.0_f32; rows * 3 * poses];
        stresses
            .par_chunks_mut(rows)
            .enumerate()
            .for_each(|(j, column)| {
                for (c, out) in column.chunks_exact_mut(3).enumerate() {
                    let s = candidates.stresses(c);
                    for (t, out) in out.iter_mut().enumerate() {
                        *out = s[(t, j)] as f32;
                    }
                }
            });
        ResidualCorrelation {
            block_len: n4,
            gradients,
            stresses,
            scale: candidates.scales().to_vec(),
            norms,
            members: (0..count).collect(),
        }
    }

    /// `‖A_c‖` of every candidate (retired or not).
    pub(super) fn norms(&self) -> &[f64] {
        &self.norms
    }

    /// Stops ranking the candidates `retired` says (by candidate), which can never be chosen
    /// again: their factors leave once they are an eighth of those held, so later products
    /// are smaller.
    pub(super) fn retire(&mut self, retired: &[bool]) {
        let leaving = self.members.iter().filter(|&&c| retired[c]).count();
        if leaving == 0 || 8 * leaving < self.members.len() {
            return;
        }
        let (n4, rows) = (self.block_len, 3 * self.members.len());
        let columns = self.scale.len() / n4;
        let keep: Vec<usize> = (0..self.members.len())
            .filter(|&i| !retired[self.members[i]])
            .collect();
        let kept_rows = 3 * keep.len();
        let mut gradients = Vec::with_capacity(n4 * kept_rows);
        for &i in &keep {
            gradients.extend_from_slice(&self.gradients[3 * n4 * i..3 * n4 * (i + 1)]);
        }
        let mut stresses = Vec::with_capacity(kept_rows * columns);
        for j in 0..columns {
            let column = &self.stresses[j * rows..(j + 1) * rows];
            for &i in &keep {
                stresses.extend_from_slice(&column[3 * i..3 * i + 3]);
            }
        }
        self.members = keep.iter().map(|&i| self.members[i]).collect();
        self.gradients = gradients;
        self.stresses = stresses;
    }

    /// `(c, A_cᵀ r)` for every candidate c not retired (to f32 precision) for the residual `r`
    /// (a column's rows).
    pub(super) fn correlations(&mut self, residual: &[f64]) -> Vec<(usize, f64)> {
        let n4 = self.block_len;
        let rows = self.members.len() * 3;
        let columns = self.scale.len() / n4;
        let scaled: Vec<f32> = residual
            .iter()
            .zip(&self.scale)
            .map(|(r, s)| (r * s) as f32)
            .collect();
        // T a block of rows at a time, contracted with S while it is in cache.
        let gradients = MatRef::from_column_major_slice(&self.gradients, n4, rows);
        let scaled = MatRef::from_column_major_slice(&scaled, n4, columns);
        let stresses = &self.stresses;
        let mut sums = vec![0.0_f32; rows];
        sums.par_chunks_mut(ROWS_PER_TASK)
            .enumerate()
            .for_each_init(
                || vec![0.0_f32; ROWS_PER_TASK * columns],
                |block, (task, sums)| {
                    let (first, len) = (task * ROWS_PER_TASK, sums.len());
                    faer::linalg::matmul::matmul(
                        MatMut::from_column_major_slice_mut(
                            &mut block[..len * columns],
                            len,
                            columns,
                        ),
                        Accum::Replace,
                        gradients.subcols(first, len).transpose(),
                        scaled,
                        1.0,
                        Par::Seq,
                    );
                    for (j, t) in block[..len * columns].chunks_exact(len).enumerate() {
                        let s = &stresses[j * rows + first..j * rows + first + len];
                        for ((sum, t), s) in sums.iter_mut().zip(t).zip(s) {
                            *sum += t * s;
                        }
                    }
                },
            );
        sums.chunks_exact(3)
            .zip(&self.members)
            .map(|(c, &member)| (member, f64::from(c[0]) + f64::from(c[1]) + f64::from(c[2])))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::analytic_field::analytic_model;
    use crate::quadrature::cubature::{CubatureParams, dot, force_weights, norm, training_poses};

    #[test]
    fn correlations_and_norms_equal_those_of_the_force_columns() {
        let (model, _) = analytic_model();
        let params = CubatureParams::FEW_POSES;
        let poses = training_poses(&model, &params).expect("poses");
        let pose_refs: Vec<&[f64]> = poses.iter().map(Vec::as_slice).collect();
        let pose_norms: Vec<f64> = (0..poses.len()).map(|k| 1.0 + k as f64).collect();
        let pose_scales: Vec<f64> = pose_norms.iter().map(|n| 1.0 / n).collect();
        let omega = force_weights(&model, params.time_step);
        // Every point: more candidates than one task's block of rows.
        let pool: Vec<usize> = (0..model.deformation_map().len()).collect();
        assert!(3 * pool.len() > ROWS_PER_TASK);
        let candidates = CandidateForces::new(&model, &pool, &pose_refs, &pose_norms, &omega, &[]);
        let mut ranking = ResidualCorrelation::new(&candidates, &omega, &pose_scales);
        let rows = candidates.rows();
        let residual: Vec<f64> = (0..rows).map(|i| ((i * 7919) % 13) as f64 - 6.0).collect();
        let correlations = ranking.correlations(&residual);
        assert_eq!(correlations.len(), candidates.len());
        let mut column = vec![0.0; rows];
        for (c, &(member, got_correlation)) in correlations.iter().enumerate() {
            assert_eq!(member, c);
            candidates.column(c, &mut column);
            let want = norm(&column);
            assert!(want > 0.0, "candidate {c} has a zero column");
            let got = ranking.norms()[c];
            assert!(
                (got - want).abs() <= 1e-10 * want,
                "norm {c}: {got} vs {want}"
            );
            let want = dot(&column, &residual);
            assert!(
                (got_correlation - want).abs() <= 1e-5 * norm(&column) * norm(&residual),
                "correlation {c}: {got_correlation} vs {want}"
            );
        }
        // Retiring every fourth candidate leaves the others' correlations as they were.
        let retired: Vec<bool> = (0..candidates.len()).map(|c| c % 4 == 1).collect();
        ranking.retire(&retired);
        let after = ranking.correlations(&residual);
        let kept: Vec<(usize, f64)> = correlations
            .iter()
            .copied()
            .filter(|&(c, _)| !retired[c])
            .collect();
        assert_eq!(after.len(), kept.len());
        for ((c, got), (d, want)) in after.iter().zip(&kept) {
            assert_eq!(c, d);
            assert!(
                (got - want).abs() <= 1e-6 * want.abs().max(1.0),
                "{c}: {got} vs {want}"
            );
        }
    }
}
