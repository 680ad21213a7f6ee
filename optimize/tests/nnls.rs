//! Non-negative least squares against problems whose solution is known: one built from its
//! KKT conditions, and every random small problem against exhaustive enumeration of supports.

use faer::Mat;
use faer::linalg::solvers::{Solve, SolveLstsq};
use optimize::{NnlsError, NnlsParams, NnlsWarmStart, nnls, nnls_normal};
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn random_matrix(rows: usize, cols: usize, rng: &mut ChaCha8Rng) -> Mat<f64> {
    Mat::from_fn(rows, cols, |_, _| rng.random_range(-1.0..1.0))
}

/// `‖A x − b‖²`.
fn residual_squared(a: &Mat<f64>, x: &[f64], b: &[f64]) -> f64 {
    (0..a.nrows())
        .map(|i| {
            let ax: f64 = (0..a.ncols()).map(|j| a[(i, j)] * x[j]).sum();
            (ax - b[i]).powi(2)
        })
        .sum()
}

/// The exact NNLS minimizer by trying every support: the unconstrained least-squares solution
/// on each subset of columns, kept when it is non-negative; the best residual wins.
fn brute_force(a: &Mat<f64>, b: &[f64]) -> (Vec<f64>, f64) {
    let n = a.ncols();
    let mut best = (vec![0.0; n], residual_squared(a, &vec![0.0; n], b));
    for mask in 1u32..(1 << n) {
        let set: Vec<usize> = (0..n).filter(|j| mask & (1 << j) != 0).collect();
        // A minimizer with at most rank(A) ≤ rows columns in its support exists
        // (Carathéodory), so larger supports need not be tried.
        if set.len() > a.nrows() {
            continue;
        }
        let sub = Mat::from_fn(a.nrows(), set.len(), |i, k| a[(i, set[k])]);
        let rhs = Mat::from_fn(b.len(), 1, |i, _| b[i]);
        let solution = sub.qr().solve_lstsq(&rhs);
        if (0..set.len()).any(|k| solution[(k, 0)] < 0.0) {
            continue;
        }
        let mut x = vec![0.0; n];
        for (k, &j) in set.iter().enumerate() {
            x[j] = solution[(k, 0)];
        }
        let r = residual_squared(a, &x, b);
        if r < best.1 {
            best = (x, r);
        }
    }
    best
}

#[test]
fn a_problem_built_from_its_kkt_conditions_is_solved_to_its_known_solution() {
    // x* = (2, 0, 0.5, 0, 1.5, 0): b = A x* + r with Aᵀr = d, d = 0 on the support and
    // strictly negative off it, so x* is the unique minimizer (A has full column rank).
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let a = random_matrix(20, 6, &mut rng);
    let x_star = [2.0, 0.0, 0.5, 0.0, 1.5, 0.0];
    let d = [0.0, -0.3, 0.0, -1.0, 0.0, -0.05];
    let gram = a.transpose() * &a;
    let y = gram
        .llt(faer::Side::Lower)
        .unwrap()
        .solve(Mat::from_fn(6, 1, |i, _| d[i]));
    let r = &a * &y;
    let b: Vec<f64> = (0..20)
        .map(|i| (0..6).map(|j| a[(i, j)] * x_star[j]).sum::<f64>() + r[(i, 0)])
        .collect();
    let solution = nnls(a.as_ref(), &b, &NnlsParams::default()).unwrap();
    for (got, want) in solution.x.iter().zip(x_star) {
        assert!(
            (got - want).abs() < 1e-12,
            "x = {:?}, expected {x_star:?}",
            solution.x
        );
    }
}

#[test]
fn a_warm_start_reaches_the_same_solution_as_a_cold_one() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let a = random_matrix(40, 15, &mut rng);
    let b: Vec<f64> = (0..40).map(|_| rng.random_range(-1.0..1.0)).collect();
    let gram = a.transpose() * &a;
    let atb: Vec<f64> = (0..15)
        .map(|j| (0..40).map(|i| a[(i, j)] * b[i]).sum())
        .collect();
    let cold = nnls_normal(gram.as_ref(), &atb, None, &NnlsParams::default()).unwrap();
    // Warm start from the solution of the first 10 columns, padded with zeros.
    let sub_gram = Mat::from_fn(10, 10, |i, j| gram[(i, j)]);
    let partial = nnls_normal(sub_gram.as_ref(), &atb[..10], None, &NnlsParams::default()).unwrap();
    let mut warm = partial.x.clone();
    warm.resize(15, 0.0);
    // With the five new variables held at zero, and with them freed.
    for free_new in [false, true] {
        let free: Vec<bool> = (0..15).map(|i| free_new && i >= 10).collect();
        let start = NnlsWarmStart {
            x: &warm,
            free: &free,
        };
        let warmed = nnls_normal(gram.as_ref(), &atb, Some(start), &NnlsParams::default()).unwrap();
        for (c, w) in cold.x.iter().zip(&warmed.x) {
            assert!(
                (c - w).abs() < 1e-10,
                "cold {:?} vs warm {:?} (new variables freed: {free_new})",
                cold.x,
                warmed.x
            );
        }
    }
}

#[test]
fn a_nearly_dependent_support_spanning_the_rows_is_not_grown_past_them() {
    // b lies in the cone of four nearly dependent columns of this 4 × 6 problem (x ~ 10²–10³,
    // smallest singular value of the four 1.4e-4): the round-off left in w after that solve
    // must not free a fifth column, whose normal matrix would be singular.
    let mut rng = ChaCha8Rng::seed_from_u64(968_300);
    let a = random_matrix(4, 6, &mut rng);
    let b: Vec<f64> = (0..4).map(|_| rng.random_range(-1.0..1.0)).collect();
    for block in [1, 3] {
        let params = NnlsParams {
            block,
            ..NnlsParams::default()
        };
        let solution = nnls(a.as_ref(), &b, &params).unwrap();
        let support = solution.x.iter().filter(|&&v| v > 0.0).count();
        assert!(
            support <= 4,
            "block {block}: support of {support} in 4 rows, x = {:?}",
            solution.x
        );
        let (_, best) = brute_force(&a, &b);
        let got = residual_squared(&a, &solution.x, &b);
        assert!(
            got <= best + 1e-12,
            "block {block}: residual² {got:e}, best {best:e}"
        );
    }
}

#[test]
fn bad_input_is_refused_with_the_problem_named() {
    let a = Mat::<f64>::identity(3, 3);
    assert!(matches!(
        nnls(a.as_ref(), &[1.0, 2.0], &NnlsParams::default()),
        Err(NnlsError::Dimension { .. })
    ));
    assert_eq!(
        nnls(a.as_ref(), &[1.0, f64::NAN, 2.0], &NnlsParams::default()),
        Err(NnlsError::NonFinite)
    );
    let capped = NnlsParams {
        max_iterations: Some(1),
        ..NnlsParams::default()
    };
    assert!(matches!(
        nnls(a.as_ref(), &[1.0, 2.0, 3.0], &capped),
        Err(NnlsError::NotConverged { iterations: 1, .. })
    ));
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, rng_seed: proptest::test_runner::RngSeed::Fixed(13), ..ProptestConfig::default() })]

    /// On random problems (over- and under-determined) the solution is non-negative, meets
    /// the KKT conditions, and its residual equals the best over all supports.
    #[test]
    fn random_problems_match_exhaustive_enumeration(seed in 0u64..1_000_000, rows in 3usize..12, cols in 2usize..7) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let a = random_matrix(rows, cols, &mut rng);
        let b: Vec<f64> = (0..rows).map(|_| rng.random_range(-1.0..1.0)).collect();
        let solution = nnls(a.as_ref(), &b, &NnlsParams::default()).unwrap();
        prop_assert!(solution.x.iter().all(|&v| v >= 0.0));
        // Moving variables in blocks reaches an optimum too (the minimizer need not be unique
        // when A has dependent columns, so the residuals are compared, not the x).
        let blocked = nnls(a.as_ref(), &b, &NnlsParams { block: 3, ..NnlsParams::default() }).unwrap();
        prop_assert!(blocked.x.iter().all(|&v| v >= 0.0));
        let (_, best) = brute_force(&a, &b);
        for x in [&solution.x, &blocked.x] {
            let got = residual_squared(&a, x, &b);
            prop_assert!(got <= best * (1.0 + 1e-9) + 1e-12, "residual² {got:e} > best {best:e}");
        }
        // KKT: w = Aᵀ(b − Ax) is ≤ 0 where x = 0 and 0 where x > 0, to the round-off of the
        // terms that cancel in w_j (of size up to ‖a_j‖ Σ_k ‖a_k‖ x_k: large when a nearly
        // dependent support needs large x, as b = Ax with |x| ~ 10³ on a 4 × 6 problem did).
        let column_norm = |j: usize| (0..rows).map(|i| a[(i, j)].powi(2)).sum::<f64>().sqrt();
        let spread: f64 = (0..cols).map(|k| column_norm(k) * solution.x[k]).sum();
        for j in 0..cols {
            let w: f64 = (0..rows)
                .map(|i| a[(i, j)] * (b[i] - (0..cols).map(|k| a[(i, k)] * solution.x[k]).sum::<f64>()))
                .sum();
            let bound = 1e-9 * (column_norm(j) * spread).max(1.0);
            if solution.x[j] > 0.0 {
                prop_assert!(w.abs() < bound, "w[{j}] = {w:e} on the support (bound {bound:e})");
            } else {
                prop_assert!(w < bound, "w[{j}] = {w:e} > 0 off the support (bound {bound:e})");
            }
        }
    }
}
