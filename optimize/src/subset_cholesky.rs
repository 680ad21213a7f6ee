//! A Cholesky factor `L Lᵀ = G_SS` of the principal submatrix of a symmetric positive
//! semidefinite matrix G on an index set S that changes one or a few indices at a time, as the
//! passive set of an active-set NNLS does: joining indices cost `O(k² b)` (a triangular solve
//! and a `b × b` factor), leaving ones `O(k²)` (Givens rotations), against `O(k³)` to refactor.

use faer::linalg::triangular_solve::{
    solve_lower_triangular_in_place, solve_upper_triangular_in_place,
};
use faer::{Mat, MatRef, Par, Side};

/// The factor of `G_SS` (S in the order indices joined), stored column-major in the leading
/// `k × k` block of a `capacity × capacity` buffer, so a column is one slice. The buffer grows
/// when S outgrows it, so one factor can follow a matrix G that gains rows and columns.
#[derive(Clone, Debug)]
pub(crate) struct SubsetCholesky {
    set: Vec<usize>,
    capacity: usize,
    l: Vec<f64>,
    /// Diagonal shift of a block whose Schur complement is not numerically positive definite
    /// (dependent columns): `1e-12 · max diag G`, grown ×100 until the block factors.
    shift: f64,
}

impl SubsetCholesky {
    /// The factor of the empty set for a matrix G of order `gram.nrows()`.
    pub(crate) fn new(gram: MatRef<'_, f64>) -> Self {
        let mut factor = SubsetCholesky {
            set: Vec::new(),
            capacity: 0,
            l: Vec::new(),
            shift: 0.0,
        };
        factor.adapt(gram);
        factor
    }

    /// Makes the factor ready for G = `gram`, of which its set's block is unchanged (G may
    /// have grown): room for every index of G and the shift from G's diagonal.
    pub(crate) fn adapt(&mut self, gram: MatRef<'_, f64>) {
        let n = gram.nrows();
        let max_diag = (0..n).fold(0.0_f64, |m, i| m.max(gram[(i, i)]));
        self.shift = 1e-12 * max_diag.max(f64::MIN_POSITIVE);
        self.reserve(n);
    }

    /// Renumbers S after G lost rows and columns: index i becomes `new_index[i]`, which must
    /// be `Some` for every member of S.
    ///
    /// # Panics
    /// If a member of S has no new index.
    pub(crate) fn renumber(&mut self, new_index: &[Option<usize>]) {
        for i in &mut self.set {
            *i = new_index[*i].expect("a member of the factor's set left G");
        }
    }

    /// Grows the buffer to hold a factor of order `order`.
    fn reserve(&mut self, order: usize) {
        if order <= self.capacity {
            return;
        }
        let capacity = order.max(self.capacity + self.capacity / 2);
        let k = self.set.len();
        let mut l = vec![0.0; capacity * capacity];
        for j in 0..k {
            l[j * capacity..j * capacity + k]
                .copy_from_slice(&self.l[j * self.capacity..j * self.capacity + k]);
        }
        self.l = l;
        self.capacity = capacity;
    }

    /// S, in factor order.
    pub(crate) fn set(&self) -> &[usize] {
        &self.set
    }

    /// The leading `k × k` block: L.
    fn factor(&self) -> MatRef<'_, f64> {
        let k = self.set.len();
        MatRef::from_column_major_slice_with_stride(
            &self.l[..self.capacity * k],
            k,
            k,
            self.capacity,
        )
    }

    /// Adds `joining` (indices not in S) to S: `Y = L⁻¹ G_SJ`, then the factor of the Schur
    /// complement `G_JJ − YᵀY` as the new diagonal block.
    pub(crate) fn insert(&mut self, gram: MatRef<'_, f64>, joining: &[usize]) {
        if joining.is_empty() {
            return;
        }
        let (k, b) = (self.set.len(), joining.len());
        self.reserve(k + b);
        let mut y = Mat::from_fn(k, b, |i, j| gram[(self.set[i], joining[j])]);
        solve_lower_triangular_in_place(self.factor(), y.as_mut(), Par::Seq);
        let schur = Mat::from_fn(b, b, |i, j| gram[(joining[i], joining[j])]) - y.transpose() * &y;
        // No shift first; then 1e-12, 1e-10, … 1e-2 · max diag G; the identity if none
        // factors (a non-finite or indefinite G), which keeps the factor usable.
        let shifts = std::iter::once(0.0).chain((0..6).map(|t| self.shift * 100f64.powi(t)));
        let block = shifts
            .filter_map(|shift| {
                Mat::from_fn(b, b, |i, j| {
                    schur[(i, j)] + if i == j { shift } else { 0.0 }
                })
                .llt(Side::Lower)
                .ok()
                .map(|llt| llt.L().to_owned())
            })
            .next()
            .unwrap_or_else(|| Mat::identity(b, b));
        let n = self.capacity;
        for i in 0..k {
            let column = &mut self.l[i * n..(i + 1) * n];
            for j in 0..b {
                column[k + j] = y[(i, j)];
            }
        }
        for j in 0..b {
            let column = &mut self.l[(k + j) * n..(k + j + 1) * n];
            column[..k].fill(0.0);
            for i in 0..b {
                column[k + i] = block[(i, j)];
            }
        }
        self.set.extend_from_slice(joining);
    }

    /// Removes `index` from S: deletes its row of L and restores the triangle with Givens
    /// rotations of neighbouring columns.
    pub(crate) fn remove(&mut self, index: usize) {
        let Some(p) = self.set.iter().position(|&s| s == index) else {
            return;
        };
        let (k, n) = (self.set.len(), self.capacity);
        // Delete row p: within each column only rows from the diagonal down (and, for the
        // columns before p, from p down) hold entries.
        for j in 0..k {
            let column = &mut self.l[j * n..j * n + k];
            let first = p.max(j.saturating_sub(1));
            column.copy_within(first + 1..k, first);
            column[k - 1] = 0.0;
        }
        // Row i (≥ p) now reaches column i + 1: rotate columns i, i + 1 to zero L[i, i + 1].
        for i in p..k - 1 {
            let (left, right) = self.l[i * n..(i + 2) * n].split_at_mut(n);
            let (a, b) = (left[i], right[i]);
            let r = a.hypot(b);
            if r == 0.0 {
                continue;
            }
            let (c, s) = (a / r, b / r);
            for (x, y) in left[i..k - 1].iter_mut().zip(&mut right[i..k - 1]) {
                (*x, *y) = (c * *x + s * *y, -s * *x + c * *y);
            }
        }
        self.set.remove(p);
    }

    /// Solves `G_SS s = rhs_S` (`rhs` indexed like G); s in factor order.
    pub(crate) fn solve(&self, rhs: &[f64]) -> Vec<f64> {
        let k = self.set.len();
        let mut x = Mat::from_fn(k, 1, |i, _| rhs[self.set[i]]);
        let l = self.factor();
        solve_lower_triangular_in_place(l, x.as_mut(), Par::Seq);
        solve_upper_triangular_in_place(l.transpose(), x.as_mut(), Par::Seq);
        (0..k).map(|i| x[(i, 0)]).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// G = AᵀA for a fixed 8 × 6 A of full column rank.
    fn gram() -> Mat<f64> {
        let a = Mat::from_fn(8, 6, |i, j| {
            ((3 * i + 7 * j) % 11) as f64 - 5.0 + 0.1 * (i * j) as f64
        });
        a.transpose() * &a
    }

    /// The solution on `set` by a fresh factorization.
    fn direct(gram: &Mat<f64>, set: &[usize], rhs: &[f64]) -> Vec<f64> {
        let sub = Mat::from_fn(set.len(), set.len(), |i, j| gram[(set[i], set[j])]);
        let b = Mat::from_fn(set.len(), 1, |i, _| rhs[set[i]]);
        let x = faer::linalg::solvers::Solve::solve(&sub.llt(Side::Lower).unwrap(), b);
        (0..set.len()).map(|i| x[(i, 0)]).collect()
    }

    #[test]
    fn inserts_and_removals_solve_like_a_fresh_factorization_of_the_same_set() {
        let g = gram();
        let rhs = [1.0, -2.0, 0.5, 3.0, -1.0, 2.5];
        let mut factor = SubsetCholesky::new(g.as_ref());
        factor.insert(g.as_ref(), &[4, 1]);
        factor.insert(g.as_ref(), &[0, 5, 2]);
        factor.remove(1);
        factor.insert(g.as_ref(), &[3]);
        factor.remove(4);
        factor.remove(3);
        factor.insert(g.as_ref(), &[1, 4]);
        assert_eq!(factor.set(), &[0, 5, 2, 1, 4]);
        let got = factor.solve(&rhs);
        let want = direct(&g, factor.set(), &rhs);
        for (a, b) in got.iter().zip(&want) {
            assert!(
                (a - b).abs() <= 1e-10 * b.abs().max(1.0),
                "{got:?} vs {want:?}"
            );
        }
    }

    #[test]
    fn a_long_random_sequence_of_joins_and_leaves_keeps_solving_like_a_fresh_factorization() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let a = Mat::from_fn(60, 40, |_, _| rng.random_range(-1.0..1.0));
        let g = a.transpose() * &a;
        let rhs: Vec<f64> = (0..40).map(|_| rng.random_range(-1.0..1.0)).collect();
        let mut factor = SubsetCholesky::new(g.as_ref());
        for step in 0..200 {
            let outside: Vec<usize> = (0..40).filter(|i| !factor.set().contains(i)).collect();
            if factor.set().len() > 2 && rng.random_bool(0.5) {
                let leaving = factor.set()[rng.random_range(0..factor.set().len())];
                factor.remove(leaving);
            } else if !outside.is_empty() {
                let b = rng.random_range(1..=outside.len().min(5));
                factor.insert(g.as_ref(), &outside[..b]);
            }
            let got = factor.solve(&rhs);
            let want = direct(&g, factor.set(), &rhs);
            for (x, y) in got.iter().zip(&want) {
                assert!(
                    (x - y).abs() <= 1e-8 * y.abs().max(1.0),
                    "step {step}: {x} vs {y}"
                );
            }
        }
    }
}
