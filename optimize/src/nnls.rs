//! Non-negative least squares: `min ‖A x − b‖²  subject to  x ≥ 0`, by the active-set method
//! of Lawson and Hanson (1974, ch. 23) in the normal-equation form of Bro and de Jong (1997),
//! which needs only `AᵀA` and `Aᵀb` (so a caller that grows A column by column, as greedy
//! cubature does, updates them instead of refactoring A).
//!
//! With `P` the passive set (free variables) and `R` the active set (held at 0):
//!
//! 1. `w = Aᵀb − AᵀA x` (the negative gradient). If `w_j ≤ tol` for every `j ∈ R`, x is optimal
//!    (the KKT conditions hold); stop.
//! 2. Move `j = argmax_{R} w_j` into P.
//! 3. Solve the unconstrained problem on P: `(AᵀA)_PP s_P = (Aᵀb)_P`, `s_R = 0`. If some
//!    `s_i ≤ 0` on P, step from x toward s as far as feasibility allows
//!    (`α = min_{s_i ≤ 0} x_i / (x_i − s_i)`), move the variables that reached 0 back to R and
//!    solve again; otherwise `x = s` and go to 1.
//!
//! A warm start (a feasible x, e.g. the solution before new columns were added) starts P at its
//! support.

use faer::MatRef;
use thiserror::Error;

use crate::subset_cholesky::SubsetCholesky;

/// Options of [`nnls`] and [`nnls_normal`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NnlsParams {
    /// Optimality tolerance on the negative gradient (default 1e-10), relative to the larger
    /// of `max |Aᵀb|` and the size of the terms that cancel in `w_j`, bounded by
    /// `‖a_j‖ Σ_k ‖a_k‖ x_k` (Cauchy–Schwarz on `AᵀA`): the solve stops when
    /// `w_j ≤ tolerance · max(max|Aᵀb|, ‖a_j‖ Σ_k ‖a_k‖ x_k)` on every variable held at 0. The
    /// second term keeps round-off in `w` (large when a nearly dependent support needs
    /// large x) from freeing a variable whose column the support already spans.
    pub tolerance: f64,
    /// Cap on outer iterations (default: 3 × the number of variables).
    pub max_iterations: Option<usize>,
    /// Variables moved into the passive set per outer iteration, those of largest gradient
    /// (default 1: Lawson–Hanson). More cut the number of factorizations on large problems;
    /// the stopping test (KKT) is the same.
    pub block: usize,
}

impl Default for NnlsParams {
    fn default() -> Self {
        NnlsParams {
            tolerance: 1e-10,
            max_iterations: None,
            block: 1,
        }
    }
}

/// The solution of an NNLS problem.
#[derive(Clone, Debug, PartialEq)]
pub struct NnlsSolution {
    /// x ≥ 0 (length n).
    pub x: Vec<f64>,
    /// Outer iterations (moves of variables into the passive set).
    pub iterations: usize,
}

/// An NNLS problem that cannot be solved.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum NnlsError {
    /// The matrices' sizes do not agree.
    #[error("NNLS sizes disagree: {what}")]
    Dimension {
        /// Which sizes.
        what: String,
    },
    /// A NaN or infinity in the input.
    #[error("NNLS input contains a non-finite value")]
    NonFinite,
    /// The iteration cap was reached before the KKT conditions held.
    #[error(
        "NNLS did not converge in {iterations} iterations (largest free gradient {gradient:e})"
    )]
    NotConverged {
        /// Outer iterations taken.
        iterations: usize,
        /// The largest `w_j` left on the active set.
        gradient: f64,
    },
}

/// Solves `min ‖A x − b‖², x ≥ 0` (A is `rows × n`, b has `rows` entries).
///
/// # Errors
/// [`NnlsError`]: mismatched sizes, non-finite input, or no convergence within the cap.
pub fn nnls(a: MatRef<'_, f64>, b: &[f64], params: &NnlsParams) -> Result<NnlsSolution, NnlsError> {
    if a.nrows() != b.len() {
        return Err(NnlsError::Dimension {
            what: format!("A has {} rows, b has {} entries", a.nrows(), b.len()),
        });
    }
    let gram = a.transpose() * a;
    let b_col = MatRef::from_column_major_slice(b, b.len(), 1);
    let atb_col = a.transpose() * b_col;
    let atb: Vec<f64> = (0..a.ncols()).map(|j| atb_col[(j, 0)]).collect();
    nnls_normal(gram.as_ref(), &atb, None, params)
}

/// A feasible starting point for [`nnls_normal`]: `x ≥ 0` (length n) and the variables to
/// start free (`free[i]`, length n; the support of x is free whatever it says). Freeing
/// variables that are likely positive (e.g. columns a greedy method just added) saves one
/// outer iteration, and one factorization, per variable.
#[derive(Clone, Copy, Debug)]
pub struct NnlsWarmStart<'a> {
    /// The start, `x ≥ 0`.
    pub x: &'a [f64],
    /// Variables in the first passive set besides the support of x.
    pub free: &'a [bool],
}

/// The Cholesky factor of a solve's final passive set, carried into the next solve of a
/// problem that only gained variables (columns of A) or lost variables at zero, as greedy
/// cubature's are: the next solve factors only the variables that joined instead of the whole
/// warm-start support (`O(k² b)` instead of `O(k³)`).
///
/// Contract: between two solves with the same `NnlsFactor`, the entries of `AᵀA` among the
/// previous solution's positive variables are unchanged (new variables may be appended and
/// variables renumbered with [`NnlsFactor::renumber`]).
#[derive(Clone, Debug, Default)]
pub struct NnlsFactor {
    factor: Option<SubsetCholesky>,
}

impl NnlsFactor {
    /// No factor yet: the first solve factors its warm start.
    pub fn new() -> Self {
        NnlsFactor::default()
    }

    /// Follows a renumbering of the variables: variable i is now `new_index[i]`, or left the
    /// problem (`None`), which only variables at zero in the last solution may.
    ///
    /// # Panics
    /// If a variable positive in the last solution has no new index.
    pub fn renumber(&mut self, new_index: &[Option<usize>]) {
        if let Some(factor) = &mut self.factor {
            factor.renumber(new_index);
        }
    }
}

/// Solves the NNLS problem given its normal equations: `gram = AᵀA` (`n × n`, symmetric
/// positive semidefinite) and `atb = Aᵀb` (length n), optionally from a warm start.
///
/// # Errors
/// [`NnlsError`]: mismatched sizes, non-finite input, or no convergence within the cap.
pub fn nnls_normal(
    gram: MatRef<'_, f64>,
    atb: &[f64],
    warm: Option<NnlsWarmStart<'_>>,
    params: &NnlsParams,
) -> Result<NnlsSolution, NnlsError> {
    nnls_normal_carried(gram, atb, warm, params, &mut NnlsFactor::new())
}

/// [`nnls_normal`] with the passive set's factor carried from the previous solve of the same
/// growing problem (see [`NnlsFactor`]'s contract) and left for the next.
///
/// # Errors
/// [`NnlsError`]: mismatched sizes, non-finite input, or no convergence within the cap.
pub fn nnls_normal_carried(
    gram: MatRef<'_, f64>,
    atb: &[f64],
    warm: Option<NnlsWarmStart<'_>>,
    params: &NnlsParams,
    carried: &mut NnlsFactor,
) -> Result<NnlsSolution, NnlsError> {
    let n = atb.len();
    if gram.nrows() != n || gram.ncols() != n {
        return Err(NnlsError::Dimension {
            what: format!(
                "AᵀA is {}×{}, Aᵀb has {n} entries",
                gram.nrows(),
                gram.ncols()
            ),
        });
    }
    if let Some(w) = warm
        && (w.x.len() != n || w.free.len() != n)
    {
        return Err(NnlsError::Dimension {
            what: format!(
                "the warm start has {} values and {} flags, expected {n}",
                w.x.len(),
                w.free.len()
            ),
        });
    }
    let finite = atb.iter().all(|v| v.is_finite())
        && (0..n).all(|j| (0..n).all(|i| gram[(i, j)].is_finite()))
        && warm.is_none_or(|w| w.x.iter().all(|v| v.is_finite()));
    if !finite {
        return Err(NnlsError::NonFinite);
    }
    let scale = atb.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    if scale == 0.0 {
        return Ok(NnlsSolution {
            x: vec![0.0; n],
            iterations: 0,
        });
    }
    // ‖a_j‖ = √(AᵀA)_jj, for the round-off scale of w_j.
    let column_norms: Vec<f64> = (0..n).map(|j| gram[(j, j)].max(0.0).sqrt()).collect();
    let max_iterations = params.max_iterations.unwrap_or(3 * n.max(1));

    let mut x: Vec<f64> = warm.map_or_else(
        || vec![0.0; n],
        |w| w.x.iter().map(|v| v.max(0.0)).collect(),
    );
    let mut passive: Vec<bool> = match warm {
        Some(w) => x.iter().zip(w.free).map(|(&v, &f)| v > 0.0 || f).collect(),
        None => vec![false; n],
    };
    // The passive set's factor, updated as variables join and leave: the carried one, less
    // what is not passive now, plus what is.
    let factor = match &mut carried.factor {
        Some(factor) => {
            factor.adapt(gram);
            factor
        }
        empty => empty.insert(SubsetCholesky::new(gram)),
    };
    let mut in_factor = vec![false; n];
    for i in factor.set().to_vec() {
        if i < n && passive[i] {
            in_factor[i] = true;
        } else {
            factor.remove(i);
        }
    }
    let mut iterations = 0;
    if passive.iter().any(|&p| p) {
        let joining: Vec<usize> = (0..n).filter(|&i| passive[i] && !in_factor[i]).collect();
        factor.insert(gram, &joining);
        restore_feasibility(gram, atb, &mut x, &mut passive, factor);
    }
    loop {
        let w = negative_gradient(gram, atb, &x);
        let spread: f64 = column_norms.iter().zip(&x).map(|(a, x)| a * x).sum();
        let mut joining: Vec<usize> = (0..n)
            .filter(|&j| {
                !passive[j] && w[j] > params.tolerance * scale.max(column_norms[j] * spread)
            })
            .collect();
        if joining.is_empty() {
            return Ok(NnlsSolution { x, iterations });
        }
        joining.sort_by(|&i, &j| w[j].total_cmp(&w[i]));
        if iterations >= max_iterations {
            return Err(NnlsError::NotConverged {
                iterations,
                gradient: w[joining[0]],
            });
        }
        iterations += 1;
        let before = x.clone();
        joining.truncate(params.block.max(1));
        for &j in &joining {
            passive[j] = true;
        }
        factor.insert(gram, &joining);
        restore_feasibility(gram, atb, &mut x, &mut passive, factor);
        if x == before && params.block > 1 {
            // Every joined variable fell out again: try the best one alone.
            passive[joining[0]] = true;
            factor.insert(gram, &joining[..1]);
            restore_feasibility(gram, atb, &mut x, &mut passive, factor);
        }
        if x == before {
            // The best variable's least-squares value was not positive (round-off at the
            // tolerance): optimal to working precision.
            passive[joining[0]] = false;
            factor.remove(joining[0]);
            return Ok(NnlsSolution { x, iterations });
        }
    }
}

/// The inner loop (step 3): moves x to the least-squares solution on the passive set (whose
/// factor `factor` is), dropping variables that would turn negative, until that solution is
/// strictly positive.
fn restore_feasibility(
    gram: MatRef<'_, f64>,
    atb: &[f64],
    x: &mut [f64],
    passive: &mut [bool],
    factor: &mut SubsetCholesky,
) {
    debug_assert_eq!(gram.nrows(), x.len());
    loop {
        let set = factor.set().to_vec();
        debug_assert!(set.iter().all(|&i| passive[i]));
        if set.is_empty() {
            return;
        }
        let s = factor.solve(atb);
        if s.iter().all(|&v| v > 0.0) {
            for (&i, v) in set.iter().zip(&s) {
                x[i] = *v;
            }
            return;
        }
        let alpha = set
            .iter()
            .zip(&s)
            .filter(|&(_, &v)| v <= 0.0)
            .map(|(&i, &v)| x[i] / (x[i] - v))
            .fold(f64::INFINITY, f64::min);
        for (&i, v) in set.iter().zip(&s) {
            x[i] += alpha * (v - x[i]);
        }
        // Whatever reached zero on its way to a non-positive value leaves P (the minimizing
        // index exactly, others to round-off); a variable at zero whose solution is positive
        // stays (a freed warm-start variable).
        let floor = 1e-14 * set.iter().fold(0.0_f64, |m, &i| m.max(x[i].abs()));
        for (&i, v) in set.iter().zip(&s) {
            let reached = *v <= 0.0 && (x[i] <= floor || x[i] / (x[i] - v) <= alpha);
            if reached || (x[i] <= floor && *v <= floor) {
                x[i] = 0.0;
                passive[i] = false;
                factor.remove(i);
            }
        }
    }
}

/// `Aᵀb − AᵀA x`.
fn negative_gradient(gram: MatRef<'_, f64>, atb: &[f64], x: &[f64]) -> Vec<f64> {
    let mut w = atb.to_vec();
    for (j, &xj) in x.iter().enumerate() {
        if xj != 0.0 {
            let col = gram.col(j);
            for (wi, g) in w.iter_mut().zip(col.iter()) {
                *wi -= g * xj;
            }
        }
    }
    w
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::Mat;

    #[test]
    fn a_solution_with_an_active_bound_is_found_exactly() {
        // min ‖x − (1, −2, 3)‖², x ≥ 0: x = (1, 0, 3).
        let a = Mat::<f64>::identity(3, 3);
        let solution = nnls(a.as_ref(), &[1.0, -2.0, 3.0], &NnlsParams::default()).unwrap();
        assert_eq!(solution.x, vec![1.0, 0.0, 3.0]);
    }

    #[test]
    fn a_carried_factor_solves_a_growing_and_renumbered_problem_like_a_fresh_solve() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let (rows, n) = (80, 60);
        let a = Mat::from_fn(rows, n, |_, _| rng.random_range(-1.0..1.0));
        let b: Vec<f64> = (0..rows).map(|_| rng.random_range(-1.0..1.0)).collect();
        let b_col = Mat::from_fn(rows, 1, |i, _| b[i]);
        let params = NnlsParams::default();
        let mut carried = NnlsFactor::new();
        // The columns in play, grown 10 at a time; zero-weight ones leave after each solve.
        let mut columns: Vec<usize> = Vec::new();
        let mut x: Vec<f64> = Vec::new();
        for batch in 0..6 {
            let old = columns.len();
            columns.extend(10 * batch..10 * (batch + 1));
            let sub = Mat::from_fn(rows, columns.len(), |i, j| a[(i, columns[j])]);
            let gram = sub.transpose() * &sub;
            let atb_col = sub.transpose() * &b_col;
            let atb: Vec<f64> = (0..columns.len()).map(|j| atb_col[(j, 0)]).collect();
            x.resize(columns.len(), 0.0);
            let free: Vec<bool> = (0..columns.len()).map(|i| i >= old).collect();
            let warm = NnlsWarmStart { x: &x, free: &free };
            let got = nnls_normal_carried(gram.as_ref(), &atb, Some(warm), &params, &mut carried)
                .unwrap()
                .x;
            let want = nnls_normal(gram.as_ref(), &atb, None, &params).unwrap().x;
            for (g, w) in got.iter().zip(&want) {
                assert!(
                    (g - w).abs() <= 1e-9 * w.abs().max(1.0),
                    "batch {batch}: {g} vs {w}"
                );
            }
            let mut new_index = vec![None; columns.len()];
            let mut kept = 0;
            for (i, &v) in got.iter().enumerate() {
                if v > 0.0 {
                    new_index[i] = Some(kept);
                    kept += 1;
                }
            }
            carried.renumber(&new_index);
            columns = (0..columns.len())
                .filter(|&i| got[i] > 0.0)
                .map(|i| columns[i])
                .collect();
            x = got.into_iter().filter(|&v| v > 0.0).collect();
        }
        assert!(columns.len() > 10, "the support grew: {}", columns.len());
    }
}
