//! The candidate points' force columns over the training poses, held as per-point factors.

use faer::{Accum, Mat, MatMut, MatRef, Par};
use hyperelastic::HyperelasticMaterial;
use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use crate::model::reduced_model::ReducedModel;

/// Candidate c's column holds, pose after pose, its weighted, normalized force density
/// `ω ⊙ g_c(z_k) / ‖f_k‖` (`3K · 4(m+1)` rows for K poses): laid out as a `4(m+1) × 3K`
/// matrix it is `s ⊙ (G_c S_c)`, with G_c the point's `4(m+1) × 3` gradient block,
/// `S_c[t, 3k + r] = P_ck[r, t]` its stresses (`3 × 3K`) and `s` the row scales `ω / ‖f_k‖`.
/// The columns are never stored: each candidate keeps G_c and S_c (the strains
/// `[F_k − I]_k = Z_allᵀ G_c`, `3K × 3`, are one small product over all poses, Z_all the
/// `4(m+1) × 3K` poses side by side), and products with columns are formed from them.
pub(super) struct CandidateForces {
    /// G of every candidate, column-major `4(m+1) × 3C` (candidate c at columns 3c … 3c + 2).
    gradients: Vec<f64>,
    /// S_c of every candidate.
    stresses: Vec<Mat<f64>>,
    /// Per row: `ω / ‖f_k‖`.
    scale: Vec<f64>,
    /// 4(m + 1).
    block_len: usize,
    /// K.
    pose_count: usize,
    /// Rest position of each candidate (m).
    positions: Vec<Vector3<f64>>,
    /// The mean distance between candidates, `(V / C)^(1/3)` (m; V the model's volume, C the
    /// candidates).
    spacing: f64,
}

impl CandidateForces {
    /// The candidates `pool` (integration points of `model`) over `poses` (each 12(m+1) long)
    /// whose targets have norms `norms`, with the force weights `omega`. On a model with a
    /// projected dilatation, `pressure_coefficients` holds the full model's p̂ at each pose
    /// (P each), and a candidate's stress is the shifted one,
    /// `P(F) + κ (p̂ · q(X) − (J − γ)) cof F`: summed with the volumes over every point, the
    /// columns are then exactly the targets (empty without a dilatation).
    pub(super) fn new<M: HyperelasticMaterial>(
        model: &ReducedModel<M>,
        pool: &[usize],
        poses: &[&[f64]],
        norms: &[f64],
        omega: &[f64],
        pressure_coefficients: &[Vec<f64>],
    ) -> Self {
        let map = model.deformation_map();
        let block_len = map.layout().block_len();
        let all_poses: Vec<f64> = poses.iter().flat_map(|p| p.iter().copied()).collect();
        let lame = model.lame_parameters();
        let material = model.material();
        let dilatation = model.dilatation();
        let stresses = pool
            .par_iter()
            .map(|&i| {
                let stress = |pose: usize, f: &Matrix3<f64>| {
                    let p = material.first_piola_kirchhoff(&lame[i], f);
                    match dilatation {
                        None => p,
                        Some(d) => d.stress_at(p, f, &pressure_coefficients[pose], i),
                    }
                };
                stresses_at(stress, map.gradient_block(i), &all_poses, poses.len())
            })
            .collect();
        CandidateForces {
            gradients: pool
                .iter()
                .flat_map(|&i| map.gradient_block(i).iter().copied())
                .collect(),
            stresses,
            scale: norms
                .iter()
                .flat_map(|&norm| omega.iter().map(move |w| w / norm))
                .collect(),
            block_len,
            pose_count: poses.len(),
            positions: pool.iter().map(|&i| model.rest_positions()[i]).collect(),
            spacing: (model.volumes().iter().sum::<f64>() / pool.len().max(1) as f64).cbrt(),
        }
    }

    /// Candidate c's rest position (m).
    pub(super) fn position(&self, c: usize) -> Vector3<f64> {
        self.positions[c]
    }

    /// The mean distance between candidates, `(V / C)^(1/3)` (m): V the model's volume, C the
    /// candidates.
    pub(super) fn spacing(&self) -> f64 {
        self.spacing
    }

    /// The scale of each row of a column: `ω / ‖f_k‖` (`3K · 4(m+1)`).
    pub(super) fn scales(&self) -> &[f64] {
        &self.scale
    }

    /// Rows of a column: `3K · 4(m+1)`.
    pub(super) fn rows(&self) -> usize {
        self.scale.len()
    }

    /// Number of candidates.
    pub(super) fn len(&self) -> usize {
        self.stresses.len()
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
        let n = 3 * self.block_len;
        &self.gradients[c * n..(c + 1) * n]
    }

    /// Candidate c's stresses at every pose: `3 × 3K`, `[(t, 3k + r)] = P_k[r, t]`.
    pub(super) fn stresses(&self, c: usize) -> MatRef<'_, f64> {
        self.stresses[c].as_ref()
    }

    /// Candidate c's column (`rows` entries).
    #[cfg(test)]
    pub(super) fn column(&self, c: usize, column: &mut [f64]) {
        let n4 = self.block_len;
        faer::linalg::matmul::matmul(
            MatMut::from_column_major_slice_mut(column, n4, 3 * self.pose_count),
            Accum::Replace,
            MatRef::from_column_major_slice(self.gradient_block(c), n4, 3),
            self.stresses(c),
            1.0,
            Par::Seq,
        );
        for (x, s) in column.iter_mut().zip(&self.scale) {
            *x *= s;
        }
    }

    /// `v ⊙ s`: a vector of a column's rows scaled as the columns are, for [`Self::dot`].
    pub(super) fn scaled(&self, v: &[f64]) -> Vec<f64> {
        v.iter().zip(&self.scale).map(|(v, s)| v * s).collect()
    }

    /// `A_cᵀ v` from `scaled` = [`Self::scaled`]`(v)`: `Σ_{t,j} (G_cᵀ V)[t, j] S_c[t, j]`.
    pub(super) fn dot(&self, c: usize, scaled: &[f64]) -> f64 {
        let n4 = self.block_len;
        let (g, stresses) = (self.gradient_block(c), self.stresses(c));
        let mut sum = 0.0;
        for (j, v) in scaled.chunks_exact(n4).enumerate() {
            for t in 0..3 {
                let gv: f64 = g[t * n4..(t + 1) * n4]
                    .iter()
                    .zip(v)
                    .map(|(g, v)| g * v)
                    .sum();
                sum += gv * stresses[(t, j)];
            }
        }
        sum
    }

    /// `Σ_j weights[j] A_{members[j]}`, as one product `s ⊙ (G_S W)` with `G_S` the members'
    /// gradient blocks side by side (`4(m+1) × 3n`) and `W` their weighted stresses stacked
    /// (`3n × 3K`).
    pub(super) fn combination(&self, members: &[usize], weights: &[f64]) -> Vec<f64> {
        let (n4, columns, n) = (self.block_len, 3 * self.pose_count, members.len());
        let gradients: Vec<f64> = members
            .iter()
            .flat_map(|&c| self.gradient_block(c).iter().copied())
            .collect();
        let mut stacked = vec![0.0; 3 * n * columns];
        for (j, column) in stacked.chunks_exact_mut(3 * n).enumerate() {
            for ((to, &c), &w) in column.chunks_exact_mut(3).zip(members).zip(weights) {
                for (x, &p) in to.iter_mut().zip(self.stresses[c].col_as_slice(j)) {
                    *x = w * p;
                }
            }
        }
        let mut combination = vec![0.0; self.rows()];
        faer::linalg::matmul::matmul(
            MatMut::from_column_major_slice_mut(&mut combination, n4, columns),
            Accum::Replace,
            MatRef::from_column_major_slice(&gradients, n4, 3 * n),
            MatRef::from_column_major_slice(&stacked, 3 * n, columns),
            1.0,
            Par::rayon(0),
        );
        for (x, s) in combination.iter_mut().zip(&self.scale) {
            *x *= s;
        }
        combination
    }
}

/// A point's stresses `stress(k, F_k)` at every pose k (`3 × 3K`, `[(t, 3k + r)] = P_k[r, t]`)
/// from its gradient block `gradient` (`4(m+1) × 3`) and the `poses` side by side
/// (`4(m+1) × 3K`).
fn stresses_at(
    stress: impl Fn(usize, &Matrix3<f64>) -> Matrix3<f64>,
    gradient: &[f64],
    poses: &[f64],
    pose_count: usize,
) -> Mat<f64> {
    let n4 = gradient.len() / 3;
    let mut strain = Mat::<f64>::zeros(3 * pose_count, 3);
    faer::linalg::matmul::matmul(
        strain.as_mut(),
        Accum::Replace,
        MatRef::from_column_major_slice(poses, n4, 3 * pose_count).transpose(),
        MatRef::from_column_major_slice(gradient, n4, 3),
        1.0,
        Par::Seq,
    );
    let mut stresses = Mat::<f64>::zeros(3, 3 * pose_count);
    for pose in 0..pose_count {
        let f = Matrix3::from_fn(|r, s| strain[(3 * pose + r, s)] + f64::from(u8::from(r == s)));
        let p = stress(pose, &f);
        for r in 0..3 {
            for s in 0..3 {
                stresses[(s, 3 * pose + r)] = p[(r, s)];
            }
        }
    }
    stresses
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ProjectedDilatationParams;
    use crate::model::analytic_field::{affine_pressure, analytic_model};
    use crate::quadrature::cubature::{
        CubatureParams, force_weights, norm, training_poses, weighted_targets,
    };

    /// The full quadrature (every point at its volume) is an exact cubature of the targets,
    /// with or without a projected dilatation: the columns are split as the targets are.
    #[test]
    fn every_point_at_its_volume_sums_to_the_targets_with_a_projected_dilatation() {
        let (model, points) = analytic_model();
        let pressure = affine_pressure(&points);
        let model = model
            .with_projected_dilatation(pressure, ProjectedDilatationParams::default())
            .expect("independent functions");
        let params = CubatureParams::FEW_POSES;
        let poses = training_poses(&model, &params).expect("poses");
        let omega = force_weights(&model, params.time_step);
        // The targets and pressure coefficients as the optimization forms them.
        let (weighted, coefficients) = weighted_targets(&model, &poses, &omega);
        let coefficients: Vec<Vec<f64>> = coefficients
            .into_iter()
            .map(|c| c.expect("a dilatation"))
            .collect();
        let norms: Vec<f64> = weighted.iter().map(|f| norm(f)).collect();
        let targets: Vec<f64> = weighted
            .iter()
            .zip(&norms)
            .flat_map(|(f, n)| f.iter().map(move |x| x / n))
            .collect();
        let pose_refs: Vec<&[f64]> = poses.iter().map(Vec::as_slice).collect();
        let pool: Vec<usize> = (0..points.len()).collect();
        let candidates =
            CandidateForces::new(&model, &pool, &pose_refs, &norms, &omega, &coefficients);
        let sum = candidates.combination(&pool, model.volumes());
        let difference: Vec<f64> = sum.iter().zip(&targets).map(|(a, b)| a - b).collect();
        let error = norm(&difference) / norm(&targets);
        assert!(error < 1e-12, "relative difference {error:e}");
    }
}
