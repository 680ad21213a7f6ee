//! The constant matrix of the stretching solve, assembled and factored once (Kugelstadt et al.
//! 2021, Eq. 29): `A = M + dt² ∇²(E_s + E_h)`, the same for each of the three coordinates.

use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::sparse::{SparseColMat, SymbolicSparseColMat};
use faer::{Mat, Side};
use nalgebra::{DMatrix, Vector3};
use rayon::prelude::*;

use crate::sph::elasticity::SphElasticity;
use crate::sph::simulator::SphError;

/// Particles per chunk whose local matrices are computed in parallel before being added.
const CHUNK: usize = 512;

/// The factored stretching matrix over the free particles (one scalar unknown per particle
/// and coordinate; the three coordinates share it).
///
/// Per particle i, with locals {i} ∪ N(i), Y = [−Σ_j ỹ_ij, ỹ_ij…] (3 × (|N|+1)) and
/// H_i = S − X Y the hourglass rows (S: +1 at j, −1 at i; X: rows (X_j − X_i)ᵀ):
///
/// ```text
/// A = M + Σ_i [ 2 dt² μ_i V_i YᵀY + dt² H_iᵀ diag(c_ij) H_i ]
/// ```
///
/// restricted to the free particles (constrained ones are moved by their targets and sit in
/// the right-hand side). Symmetric positive definite for positive masses.
pub struct StretchingSystem {
    free_index: Vec<usize>,
    free: Vec<usize>,
    llt: Llt<usize, f64>,
    nonzeros: usize,
}

impl StretchingSystem {
    /// Assembles and factors A for masses `masses` (kg), time step `dt` (s), with the
    /// particles flagged in `constrained` left out.
    ///
    /// # Errors
    /// [`SphError::Factorization`] when the sparse Cholesky fails (out of memory, or a matrix
    /// that is not positive definite).
    pub fn new(
        elasticity: &SphElasticity,
        masses: &[f64],
        constrained: &[bool],
        dt: f64,
    ) -> Result<Self, SphError> {
        let g = elasticity.gradients();
        let n = g.len();
        let mut free_index = vec![usize::MAX; n];
        let free: Vec<usize> = (0..n).filter(|&i| !constrained[i]).collect();
        for (f, &i) in free.iter().enumerate() {
            free_index[i] = f;
        }
        // Lower-triangle pattern of the free block: column b holds the free rows a ≥ b that
        // share a neighbourhood {i} ∪ N(i) with b.
        let locals = |i: usize| std::iter::once(i).chain(g.neighbours(i).iter().copied());
        let columns: Vec<Vec<usize>> = free
            .par_iter()
            .map(|&b| {
                let fb = free_index[b];
                let mut rows: Vec<usize> = locals(b)
                    .flat_map(&locals)
                    .map(|a| free_index[a])
                    .filter(|&fa| fa != usize::MAX && fa >= fb)
                    .collect();
                rows.sort_unstable();
                rows.dedup();
                rows
            })
            .collect();
        let mut col_ptr = Vec::with_capacity(free.len() + 1);
        col_ptr.push(0usize);
        for c in &columns {
            col_ptr.push(col_ptr.last().copied().unwrap_or(0) + c.len());
        }
        let row_idx: Vec<usize> = columns.into_iter().flatten().collect();
        let mut values = vec![0.0; row_idx.len()];
        let position = |fa: usize, fb: usize| -> usize {
            let rows = &row_idx[col_ptr[fb]..col_ptr[fb + 1]];
            col_ptr[fb] + rows.binary_search(&fa).expect("entry in the pattern")
        };
        for (f, &i) in free.iter().enumerate() {
            values[position(f, f)] += masses[i];
        }
        let rest = elasticity.rest_positions();
        let dt2 = dt * dt;
        let starts: Vec<usize> = (0..n).step_by(CHUNK).collect();
        for start in starts {
            let end = (start + CHUNK).min(n);
            let local: Vec<DMatrix<f64>> = (start..end)
                .into_par_iter()
                .map(|i| {
                    let weights = g.weights(i);
                    let nn = weights.len();
                    let mut y = DMatrix::<f64>::zeros(3, nn + 1);
                    for (k, w) in weights.iter().enumerate() {
                        for r in 0..3 {
                            y[(r, k + 1)] = w[r];
                            y[(r, 0)] -= w[r];
                        }
                    }
                    let stretch = 2.0 * dt2 * elasticity.lame()[i].mu() * elasticity.volumes()[i];
                    let mut q = y.tr_mul(&y) * stretch;
                    if nn > 0 {
                        let mut x = DMatrix::<f64>::zeros(nn, 3);
                        for (k, &j) in g.neighbours(i).iter().enumerate() {
                            let d: Vector3<f64> = rest[j] - rest[i];
                            for r in 0..3 {
                                x[(k, r)] = d[r];
                            }
                        }
                        let mut h = -(x * &y);
                        for k in 0..nn {
                            h[(k, k + 1)] += 1.0;
                            h[(k, 0)] -= 1.0;
                        }
                        let mut ch = h.clone();
                        for (k, e) in g.entries(i).enumerate() {
                            let c = dt2 * elasticity.hourglass_stiffness(e);
                            ch.row_mut(k).scale_mut(c);
                        }
                        q += h.tr_mul(&ch);
                    }
                    q
                })
                .collect();
            for (i, q) in (start..end).zip(local) {
                let ids: Vec<usize> = locals(i).map(|a| free_index[a]).collect();
                for (lb, &fb) in ids.iter().enumerate() {
                    if fb == usize::MAX {
                        continue;
                    }
                    for (la, &fa) in ids.iter().enumerate() {
                        if fa != usize::MAX && fa >= fb {
                            values[position(fa, fb)] += q[(la, lb)];
                        }
                    }
                }
            }
        }
        let nonzeros = row_idx.len();
        let m = free.len();
        let symbolic = SymbolicSparseColMat::new_checked(m, m, col_ptr, None, row_idx);
        let matrix = SparseColMat::new(symbolic, values);
        let factorization = |e: String| SphError::Factorization(e);
        let analysis = SymbolicLlt::try_new(matrix.symbolic(), Side::Lower)
            .map_err(|e| factorization(format!("{e:?}")))?;
        let llt = Llt::try_new_with_symbolic(analysis, matrix.as_ref(), Side::Lower)
            .map_err(|e| factorization(format!("{e:?}")))?;
        Ok(StretchingSystem {
            free_index,
            free,
            llt,
            nonzeros,
        })
    }

    /// Solves A Δ = r for the free particles (three right-hand sides at once); entries of
    /// constrained particles in `rhs` are ignored and zero in the result (m).
    pub fn solve(&self, rhs: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
        let mut b = Mat::<f64>::from_fn(self.free.len(), 3, |f, c| rhs[self.free[f]][c]);
        self.llt.solve_in_place(b.as_mut());
        (0..rhs.len())
            .map(|i| match self.free_index[i] {
                usize::MAX => Vector3::zeros(),
                f => Vector3::new(b[(f, 0)], b[(f, 1)], b[(f, 2)]),
            })
            .collect()
    }

    /// Stored entries of the matrix's lower triangle.
    pub fn nonzeros(&self) -> usize {
        self.nonzeros
    }
}
