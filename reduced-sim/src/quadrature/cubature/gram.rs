//! The Gram matrix of the cubature's force columns from small per-point factors, without the
//! columns themselves (the Gram updates were the largest part of the cubature's
//! preparation at m = 32).
//!
//! Column i of the cubature's matrix A stacks, pose after pose, point i's weighted force
//! density `ω ∘ g_i(z_k) / ‖ω ∘ f_k‖`, whose entry `(k, r, a)` is
//! `ω_{ra} Σ_s G_i[a, s] P_{ik}[r, s] / ‖ω ∘ f_k‖` (G_i the point's `4(m+1) × 3` gradient
//! block, `P_{ik}` its first Piola–Kirchhoff stress at pose k). Summing over a and k apart,
//!
//! ```text
//! A_iᵀ A_j = Σ_r Σ_{s,t} M^r_ij[s, t] N^r_ij[s, t],
//! M^r_ij = (Ω_r G_i)ᵀ (Ω_r G_j)     (3 × 3, inner dimension 4(m+1), Ω_r = diag(ω_{r·}))
//! N^r_ij = Q^r_iᵀ Q^r_j             (3 × 3, inner dimension K, Q^r_i[k, s] = P_{ik}[r, s] / ‖ω ∘ f_k‖)
//! ```
//!
//! so a block of new Gram columns costs `54 (4(m+1) + K)` flops per pair, all in matrix
//! products, instead of `2 · 12(m+1) K` (K poses): 4.6× fewer at m = 32 with 60 poses.

use faer::{Accum, Mat, MatRef, Par};
use rayon::prelude::*;

/// Per point of a growing set, the factors `Ω_r G_i` and `Q^r_i` of the module docs, from
/// which [`ForceGramFactors::cross`] forms Gram columns.
pub(crate) struct ForceGramFactors {
    /// `4(m+1)`.
    block_len: usize,
    /// K.
    poses: usize,
    /// Per r: the columns `ω_{r·} ∘ G_i[:, s]`, column-major `4(m+1) × 3n` (point i's three
    /// columns at 3i).
    scaled_gradients: [Vec<f64>; 3],
    /// Per r: the columns `Q^r_i[:, s]`, column-major `K × 3n`.
    scaled_stresses: [Vec<f64>; 3],
}

impl ForceGramFactors {
    /// An empty set for gradient blocks of `block_len = 4(m+1)` rows and `poses` poses.
    pub(crate) fn new(block_len: usize, poses: usize) -> Self {
        ForceGramFactors {
            block_len,
            poses,
            scaled_gradients: Default::default(),
            scaled_stresses: Default::default(),
        }
    }

    /// Number of points held.
    pub(crate) fn len(&self) -> usize {
        self.scaled_gradients[0].len() / (3 * self.block_len)
    }

    /// Adds a point: its gradient block `gradient` (column-major `4(m+1) × 3`), the force
    /// weights `omega` (length `12(m+1)`, z's layout), its stresses `stresses` (`3 × 3K`,
    /// `stresses[(s, 3k + r)] = P_k[r, s]`) and the per-pose scales `pose_scales`
    /// (`1 / ‖ω ∘ f_k‖`, length K).
    ///
    /// # Panics
    /// If a length does not match.
    pub(crate) fn push(
        &mut self,
        gradient: &[f64],
        omega: &[f64],
        stresses: MatRef<'_, f64>,
        pose_scales: &[f64],
    ) {
        let n4 = self.block_len;
        assert_eq!(gradient.len(), 3 * n4, "a 4(m+1) × 3 gradient block");
        assert_eq!(omega.len(), 3 * n4, "one force weight per component of z");
        assert_eq!(pose_scales.len(), self.poses, "one scale per pose");
        assert_eq!(
            (stresses.nrows(), stresses.ncols()),
            (3, 3 * self.poses),
            "3 × 3K stresses"
        );
        for r in 0..3 {
            let w = &omega[r * n4..(r + 1) * n4];
            for s in 0..3 {
                self.scaled_gradients[r].extend(
                    gradient[s * n4..(s + 1) * n4]
                        .iter()
                        .zip(w)
                        .map(|(g, w)| g * w),
                );
            }
            for s in 0..3 {
                self.scaled_stresses[r].extend(
                    pose_scales
                        .iter()
                        .enumerate()
                        .map(|(k, scale)| stresses[(s, 3 * k + r)] * scale),
                );
            }
        }
    }

    /// Keeps the points `keep` (ascending indices into the set), in that order.
    pub(crate) fn retain(&mut self, keep: &[usize]) {
        for (factors, len) in [
            (&mut self.scaled_gradients, 3 * self.block_len),
            (&mut self.scaled_stresses, 3 * self.poses),
        ] {
            for columns in factors.iter_mut() {
                for (to, &from) in keep.iter().enumerate() {
                    if to != from {
                        columns.copy_within(from * len..(from + 1) * len, to * len);
                    }
                }
                columns.truncate(keep.len() * len);
            }
        }
    }

    /// The Gram columns of the points from `first` on against every point held:
    /// `[A_iᵀ A_j]` for i < n, first ≤ j < n (`n × (n − first)`).
    ///
    /// # Panics
    /// If `first > n`.
    pub(crate) fn cross(&self, first: usize) -> Mat<f64> {
        let n = self.len();
        assert!(first <= n, "first new point {first} of {n}");
        let new = n - first;
        if new == 0 {
            return Mat::zeros(n, 0);
        }
        let mut sums = vec![0.0; n * new];
        let mut m = Mat::<f64>::zeros(3 * n, 3 * new);
        let mut q = Mat::<f64>::zeros(3 * n, 3 * new);
        for r in 0..3 {
            for (product, columns, rows) in [
                (&mut m, &self.scaled_gradients[r], self.block_len),
                (&mut q, &self.scaled_stresses[r], self.poses),
            ] {
                let all = MatRef::from_column_major_slice(columns, rows, 3 * n);
                faer::linalg::matmul::matmul(
                    product.as_mut(),
                    Accum::Replace,
                    all.transpose(),
                    all.subcols(3 * first, 3 * new),
                    1.0,
                    Par::rayon(0),
                );
            }
            let (m, q) = (&m, &q);
            sums.par_chunks_mut(n).enumerate().for_each(|(j, sums)| {
                for t in 0..3 {
                    let (m, q) = (m.col_as_slice(3 * j + t), q.col_as_slice(3 * j + t));
                    for ((sum, m), q) in sums
                        .iter_mut()
                        .zip(m.chunks_exact(3))
                        .zip(q.chunks_exact(3))
                    {
                        *sum += m[0] * q[0] + m[1] * q[1] + m[2] * q[2];
                    }
                }
            });
        }
        Mat::from_fn(n, new, |i, j| sums[j * n + i])
    }
}

#[cfg(test)]
mod tests {
    use faer::Mat;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::ForceGramFactors;

    /// Column i of A by its definition: entry `(k, r, a)` is
    /// `ω_{ra} Σ_s G_i[a, s] P_{ik}[r, s] · scale_k`.
    fn column(
        n4: usize,
        gradient: &[f64],
        omega: &[f64],
        stresses: &Mat<f64>,
        scales: &[f64],
    ) -> Vec<f64> {
        let mut column = Vec::new();
        for (k, scale) in scales.iter().enumerate() {
            for r in 0..3 {
                for a in 0..n4 {
                    let force: f64 = (0..3)
                        .map(|s| gradient[s * n4 + a] * stresses[(s, 3 * k + r)])
                        .sum();
                    column.push(omega[r * n4 + a] * force * scale);
                }
            }
        }
        column
    }

    #[test]
    fn factored_gram_columns_are_the_products_of_the_force_columns_after_growth_and_removal() {
        let (n4, poses) = (8, 5);
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let omega: Vec<f64> = (0..3 * n4).map(|_| rng.random_range(0.1..2.0)).collect();
        let scales: Vec<f64> = (0..poses).map(|_| rng.random_range(0.5..3.0)).collect();
        let mut factors = ForceGramFactors::new(n4, poses);
        let mut columns: Vec<Vec<f64>> = Vec::new();
        let mut add = |factors: &mut ForceGramFactors, columns: &mut Vec<Vec<f64>>| {
            let gradient: Vec<f64> = (0..3 * n4).map(|_| rng.random_range(-1.0..1.0)).collect();
            let stresses = Mat::from_fn(3, 3 * poses, |_, _| rng.random_range(-1.0..1.0));
            factors.push(&gradient, &omega, stresses.as_ref(), &scales);
            columns.push(column(n4, &gradient, &omega, &stresses, &scales));
        };
        let check = |factors: &ForceGramFactors, columns: &[Vec<f64>], first: usize| {
            let cross = factors.cross(first);
            assert_eq!(
                (cross.nrows(), cross.ncols()),
                (columns.len(), columns.len() - first)
            );
            for i in 0..columns.len() {
                for j in first..columns.len() {
                    let direct: f64 = columns[i].iter().zip(&columns[j]).map(|(x, y)| x * y).sum();
                    let factored = cross[(i, j - first)];
                    assert!(
                        (factored - direct).abs() <= 1e-12 * direct.abs().max(1.0),
                        "({i}, {j}): {factored} against {direct}"
                    );
                }
            }
        };
        for _ in 0..4 {
            add(&mut factors, &mut columns);
        }
        check(&factors, &columns, 0);
        for _ in 0..3 {
            add(&mut factors, &mut columns);
        }
        check(&factors, &columns, 4);
        let keep = [0, 2, 3, 6];
        factors.retain(&keep);
        let mut kept: Vec<Vec<f64>> = keep.iter().map(|&i| columns[i].clone()).collect();
        assert_eq!(factors.len(), 4);
        check(&factors, &kept, 0);
        add(&mut factors, &mut kept);
        check(&factors, &kept, 4);
    }
}
