//! The Newton solver on objectives whose minimizers and behaviour are known in closed form.

use faer::linalg::solvers::{Llt, Solve};
use faer::{Mat, Side};
use optimize::{
    HessianReuse, NewtonError, NewtonObjective, NewtonParams, NewtonStop, minimize,
    minimize_reusing,
};

/// A dense objective from closures; the factorization is faer's Cholesky, shifted by `shift · I`
/// (doubling from `shift`) until it succeeds when `shift > 0`, refused otherwise.
type Energy = Box<dyn Fn(&[f64]) -> f64>;
type Gradient = Box<dyn Fn(&[f64]) -> Vec<f64>>;
type Hessian = Box<dyn Fn(&[f64]) -> Mat<f64>>;

struct Dense {
    energy: Energy,
    gradient: Gradient,
    hessian: Hessian,
    shift: f64,
}

impl NewtonObjective for Dense {
    type Hessian = Mat<f64>;
    type Factor = Llt<f64>;

    fn energy(&self, x: &[f64]) -> f64 {
        (self.energy)(x)
    }

    fn gradient(&self, x: &[f64]) -> Vec<f64> {
        (self.gradient)(x)
    }

    fn gradient_and_hessian(&self, x: &[f64], gradient: Option<Vec<f64>>) -> (Vec<f64>, Mat<f64>) {
        (
            gradient.unwrap_or_else(|| self.gradient(x)),
            (self.hessian)(x),
        )
    }

    fn factor(&self, hessian: Mat<f64>) -> Option<Llt<f64>> {
        if let Ok(llt) = hessian.llt(Side::Lower) {
            return Some(llt);
        }
        let mut shift = self.shift;
        while shift > 0.0 && shift < 1e12 {
            let shifted = Mat::from_fn(hessian.nrows(), hessian.ncols(), |i, j| {
                hessian[(i, j)] + if i == j { shift } else { 0.0 }
            });
            if let Ok(llt) = shifted.llt(Side::Lower) {
                return Some(llt);
            }
            shift *= 2.0;
        }
        None
    }

    fn solve(&self, factor: &Llt<f64>, gradient: &[f64]) -> Vec<f64> {
        let mut rhs = Mat::from_fn(gradient.len(), 1, |i, _| -gradient[i]);
        factor.solve_in_place(rhs.as_mut());
        (0..gradient.len()).map(|i| rhs[(i, 0)]).collect()
    }

    fn step_norm(&self, step: &[f64]) -> f64 {
        step.iter().map(|s| s * s).sum::<f64>().sqrt()
    }
}

/// E = ½ xᵀAx − bᵀx with A = [[4, 1], [1, 3]], b = (1, 2): minimizer A⁻¹b = (1/11, 7/11).
fn quadratic() -> Dense {
    let a = [[4.0, 1.0], [1.0, 3.0]];
    let b = [1.0, 2.0];
    let ax = move |x: &[f64]| {
        [
            a[0][0] * x[0] + a[0][1] * x[1],
            a[1][0] * x[0] + a[1][1] * x[1],
        ]
    };
    Dense {
        energy: Box::new(move |x: &[f64]| {
            let y = ax(x);
            0.5 * (x[0] * y[0] + x[1] * y[1]) - b[0] * x[0] - b[1] * x[1]
        }),
        gradient: Box::new(move |x: &[f64]| {
            let y = ax(x);
            vec![y[0] - b[0], y[1] - b[1]]
        }),
        hessian: Box::new(move |_: &[f64]| Mat::from_fn(2, 2, |i, j| a[i][j])),
        shift: 0.0,
    }
}

/// Rosenbrock E = (1 − x)² + 100 (y − x²)², minimum 0 at (1, 1); its Hessian is indefinite
/// where y > x² + 1/200, so the factorization shifts it there.
fn rosenbrock() -> Dense {
    Dense {
        energy: Box::new(|x: &[f64]| (1.0 - x[0]).powi(2) + 100.0 * (x[1] - x[0] * x[0]).powi(2)),
        gradient: Box::new(|x: &[f64]| {
            let r = x[1] - x[0] * x[0];
            vec![-2.0 * (1.0 - x[0]) - 400.0 * x[0] * r, 200.0 * r]
        }),
        hessian: Box::new(|x: &[f64]| {
            let h = [
                [2.0 - 400.0 * x[1] + 1200.0 * x[0] * x[0], -400.0 * x[0]],
                [-400.0 * x[0], 200.0],
            ];
            Mat::from_fn(2, 2, |i, j| h[i][j])
        }),
        shift: 1.0,
    }
}

#[test]
fn a_quadratic_is_solved_by_one_hessian_and_confirmed_by_the_lagged_factor() {
    let objective = quadratic();
    let mut x = vec![3.0, -5.0];
    let report = minimize(&objective, &mut x, &NewtonParams::default()).unwrap();
    assert_eq!(report.stop, NewtonStop::Converged);
    // Iteration 1: one Hessian, the exact step, accepted at α = 1. Iteration 2: the lagged
    // factor's step is zero to rounding, so no second Hessian.
    assert_eq!(report.hessian_assemblies, 1);
    assert_eq!(report.iterations, 2);
    assert_eq!(report.line_search_cuts, 0);
    assert!(
        (x[0] - 1.0 / 11.0).abs() < 1e-14 && (x[1] - 7.0 / 11.0).abs() < 1e-14,
        "{x:?}"
    );
    let minimum = -0.5 * (1.0 / 11.0 + 2.0 * 7.0 / 11.0);
    assert!((report.energy - minimum).abs() < 1e-14);
}

#[test]
fn rosenbrock_converges_to_its_minimum_from_the_classic_start() {
    let objective = rosenbrock();
    let mut x = vec![-1.2, 1.0];
    let params = NewtonParams {
        max_iterations: 100,
        tolerance: 1e-10,
        ..NewtonParams::default()
    };
    let report = minimize(&objective, &mut x, &params).unwrap();
    assert!(report.converged(), "{report:?}");
    assert!(
        (x[0] - 1.0).abs() < 1e-8 && (x[1] - 1.0).abs() < 1e-8,
        "{x:?}"
    );
    assert!(report.energy < 1e-16, "{}", report.energy);
    // The curved valley needs backtracking on the way.
    assert!(
        report.line_search_cuts > 0 && report.iterations > 5,
        "{report:?}"
    );
}

#[test]
fn the_iteration_cap_stops_with_the_last_iterate_and_says_so() {
    let objective = rosenbrock();
    let mut x = vec![-1.2, 1.0];
    let e0 = objective.energy(&x);
    let params = NewtonParams {
        max_iterations: 2,
        ..NewtonParams::default()
    };
    let report = minimize(&objective, &mut x, &params).unwrap();
    assert_eq!(report.stop, NewtonStop::IterationLimit);
    assert_eq!(report.iterations, 2);
    assert!(!report.converged());
    assert!(report.energy < e0 && report.energy == objective.energy(&x));
}

#[test]
fn an_uphill_direction_stalls_the_line_search_after_its_cut_budget() {
    // E = x², but the gradient handed to the solver has the wrong sign, so every Newton step
    // points uphill and no α decreases E.
    let objective = Dense {
        energy: Box::new(|x: &[f64]| x[0] * x[0]),
        gradient: Box::new(|x: &[f64]| vec![-2.0 * x[0]]),
        hessian: Box::new(|_: &[f64]| Mat::from_fn(1, 1, |_, _| 2.0)),
        shift: 0.0,
    };
    let mut x = vec![1.0];
    let params = NewtonParams {
        max_line_search_cuts: 7,
        ..NewtonParams::default()
    };
    let report = minimize(&objective, &mut x, &params).unwrap();
    assert_eq!(report.stop, NewtonStop::LineSearchStalled);
    assert_eq!(report.line_search_cuts, 7, "halvings tried, not passes");
    assert_eq!(report.iterations, 1);
    assert_eq!(x, vec![1.0], "x keeps the last accepted iterate");
}

#[test]
fn nan_energy_gradient_and_indefinite_hessians_are_named_errors() {
    let mut x = vec![1.0];
    let nan_energy = Dense {
        energy: Box::new(|_: &[f64]| f64::NAN),
        gradient: Box::new(|x: &[f64]| vec![x[0]]),
        hessian: Box::new(|_: &[f64]| Mat::from_fn(1, 1, |_, _| 1.0)),
        shift: 0.0,
    };
    assert_eq!(
        minimize(&nan_energy, &mut x, &NewtonParams::default()),
        Err(NewtonError::NonFinite {
            iteration: 0,
            quantity: "energy"
        })
    );
    let nan_gradient = Dense {
        energy: Box::new(|x: &[f64]| x[0] * x[0]),
        gradient: Box::new(|_: &[f64]| vec![f64::NAN]),
        hessian: Box::new(|_: &[f64]| Mat::from_fn(1, 1, |_, _| 1.0)),
        shift: 0.0,
    };
    assert_eq!(
        minimize(&nan_gradient, &mut x, &NewtonParams::default()),
        Err(NewtonError::NonFinite {
            iteration: 1,
            quantity: "gradient"
        })
    );
    let concave = Dense {
        energy: Box::new(|x: &[f64]| -x[0] * x[0]),
        gradient: Box::new(|x: &[f64]| vec![-2.0 * x[0]]),
        hessian: Box::new(|_: &[f64]| Mat::from_fn(1, 1, |_, _| -2.0)),
        shift: 0.0,
    };
    assert_eq!(
        minimize(&concave, &mut x, &NewtonParams::default()),
        Err(NewtonError::NotPositiveDefinite { iteration: 1 })
    );
    assert_eq!(x, vec![1.0], "a failed solve leaves x where it was");
}

#[test]
fn a_carried_factor_solves_the_same_quadratic_again_without_a_new_hessian_only_when_reuse_allows() {
    let objective = quadratic();
    let reuse = NewtonParams {
        hessian_reuse: HessianReuse::WhileContracting { contraction: 0.5 },
        ..Default::default()
    };
    let mut factor = None;
    let mut x = vec![3.0, -5.0];
    let first = minimize_reusing(&objective, &mut x, &reuse, &mut factor).unwrap();
    assert_eq!(first.hessian_assemblies, 1);
    assert!(factor.is_some(), "the last factorization is handed back");
    // A new start: the carried factor is the exact Hessian, so its step is the Newton step.
    let mut y = vec![-2.0, 4.0];
    let second = minimize_reusing(&objective, &mut y, &reuse, &mut factor).unwrap();
    assert!(second.converged());
    assert_eq!(second.hessian_assemblies, 0);
    assert_eq!(second.lagged_steps, 1);
    assert!((y[0] - 1.0 / 11.0).abs() < 1e-14 && (y[1] - 7.0 / 11.0).abs() < 1e-14);
    // Without reuse the carried factor only serves the convergence test: a new Hessian.
    let mut z = vec![-2.0, 4.0];
    let never =
        minimize_reusing(&objective, &mut z, &NewtonParams::default(), &mut factor).unwrap();
    assert_eq!((never.hessian_assemblies, never.lagged_steps), (1, 0));
    assert_eq!(z, y);
}

#[test]
fn chord_steps_on_rosenbrock_reach_the_same_minimum_with_fewer_hessians() {
    let objective = rosenbrock();
    let mut fresh_x = vec![-1.2, 1.0];
    let fresh = minimize(
        &objective,
        &mut fresh_x,
        &NewtonParams {
            max_iterations: 200,
            ..Default::default()
        },
    )
    .unwrap();
    let reuse = NewtonParams {
        max_iterations: 200,
        hessian_reuse: HessianReuse::WhileContracting { contraction: 0.5 },
        ..Default::default()
    };
    let mut x = vec![-1.2, 1.0];
    let reused = minimize(&objective, &mut x, &reuse).unwrap();
    assert!(fresh.converged() && reused.converged());
    assert!(
        (x[0] - 1.0).abs() < 1e-5 && (x[1] - 1.0).abs() < 1e-5,
        "{x:?}"
    );
    assert!(reused.hessian_assemblies <= fresh.hessian_assemblies);
}

/// [`quadratic`] whose every second solve (the lagged convergence test's, with the last
/// iteration's factor) cannot be had and comes back non-finite, measured by a norm that maps
/// NaN to 0 as `f64::max` does.
struct LaggedSolveFails {
    inner: Dense,
    solves: std::cell::Cell<usize>,
}

impl NewtonObjective for LaggedSolveFails {
    type Hessian = Mat<f64>;
    type Factor = Llt<f64>;

    fn energy(&self, x: &[f64]) -> f64 {
        self.inner.energy(x)
    }

    fn gradient(&self, x: &[f64]) -> Vec<f64> {
        self.inner.gradient(x)
    }

    fn gradient_and_hessian(&self, x: &[f64], gradient: Option<Vec<f64>>) -> (Vec<f64>, Mat<f64>) {
        self.inner.gradient_and_hessian(x, gradient)
    }

    fn factor(&self, hessian: Mat<f64>) -> Option<Llt<f64>> {
        self.inner.factor(hessian)
    }

    fn solve(&self, factor: &Llt<f64>, gradient: &[f64]) -> Vec<f64> {
        self.solves.set(self.solves.get() + 1);
        if self.solves.get().is_multiple_of(2) {
            return vec![f64::NAN; gradient.len()];
        }
        self.inner.solve(factor, gradient)
    }

    fn step_norm(&self, step: &[f64]) -> f64 {
        step.iter().map(|s| s * s).sum::<f64>().max(0.0).sqrt()
    }
}

#[test]
fn a_lagged_step_that_is_not_finite_is_no_convergence_and_a_new_hessian_decides() {
    let objective = LaggedSolveFails {
        inner: quadratic(),
        solves: std::cell::Cell::new(0),
    };
    let mut x = vec![0.0, 0.0];
    let report = minimize(&objective, &mut x, &NewtonParams::default()).unwrap();
    assert!(report.converged());
    assert!(
        (x[0] - 1.0 / 11.0).abs() < 1e-12 && (x[1] - 7.0 / 11.0).abs() < 1e-12,
        "{x:?}"
    );
    assert_eq!(report.hessian_assemblies, 2);
}
