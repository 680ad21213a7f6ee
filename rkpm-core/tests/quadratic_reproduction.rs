//! Quadratic reproduction ([`Reproduction::Quadratic`]): quadratic fields and their gradients
//! interpolated exactly, gradients against central differences, smooth fields approximated
//! more closely than by the paper's linear functions, and too few kernels refused.

use nalgebra::{Matrix3, Vector3};
use rkpm_core::{
    KernelParams, Kernels, Reproduction, ShapeFunctionError, ShapeFunctionParams, ShapeFunctions,
    evaluate_shape_functions, place_kernels, sample_box_grid,
};

fn quadratic() -> ShapeFunctionParams {
    ShapeFunctionParams {
        reproduction: Reproduction::Quadratic,
        ..Default::default()
    }
}

/// Grid points in the box [0, sides] and `count` kernels placed on them.
fn box_layout(sides: [f64; 3], spacing: f64, count: usize) -> (Vec<Vector3<f64>>, Kernels) {
    let points = sample_box_grid(Vector3::zeros(), Vector3::from(sides), spacing).unwrap();
    let kernels = place_kernels(
        points.positions(),
        &KernelParams {
            count,
            ..Default::default()
        },
    )
    .unwrap();
    (points.positions().to_vec(), kernels)
}

/// `Σ_k ϕ_k(X_i) f(p_k)` and its gradient at every point.
fn interpolated(
    shape: &ShapeFunctions,
    kernels: &Kernels,
    f: impl Fn(&Vector3<f64>) -> f64,
) -> Vec<(f64, Vector3<f64>)> {
    let nodal: Vec<f64> = kernels.centers().iter().map(f).collect();
    (0..shape.point_count())
        .map(|i| shape.interpolate(i, &nodal))
        .collect()
}

#[test]
fn quadratic_fields_and_their_gradients_are_reproduced_to_round_off() {
    let (points, kernels) = box_layout([2.0, 1.0, 1.0], 0.1, 150);
    let shape = evaluate_shape_functions(&kernels, &points, &quadratic()).unwrap();
    // q(X) = c + g·X + Xᵀ A X with a full symmetric A.
    let a = Matrix3::new(0.7, -0.3, 0.2, -0.3, 1.1, 0.5, 0.2, 0.5, -0.9);
    let g = Vector3::new(0.4, -1.2, 0.8);
    let q = |x: &Vector3<f64>| 0.25 + g.dot(x) + x.dot(&(a * x));
    let grad_q = |x: &Vector3<f64>| g + 2.0 * a * x;
    let mut worst: f64 = 0.0;
    for ((value, gradient), x) in interpolated(&shape, &kernels, q).iter().zip(&points) {
        worst = worst
            .max((value - q(x)).abs())
            .max((gradient - grad_q(x)).norm());
    }
    assert!(worst < 1e-8, "quadratic field reproduced to {worst:e}");
    // The paper's linear functions do not reproduce it.
    let linear =
        evaluate_shape_functions(&kernels, &points, &ShapeFunctionParams::default()).unwrap();
    let linear_worst = interpolated(&linear, &kernels, q)
        .iter()
        .zip(&points)
        .map(|((value, _), x)| (value - q(x)).abs())
        .fold(0.0, f64::max);
    assert!(linear_worst > 1e-3, "linear error {linear_worst:e}");
}

#[test]
fn quadratic_gradients_match_central_differences() {
    let (_, kernels) = box_layout([2.0, 1.0, 1.0], 0.1, 120);
    let h = 1e-6;
    for q in [
        Vector3::new(0.31, 0.52, 0.47),
        Vector3::new(1.73, 0.11, 0.9),
        Vector3::new(0.05, 0.95, 0.02),
    ] {
        let at = |x: Vector3<f64>| evaluate_shape_functions(&kernels, &[x], &quadratic()).unwrap();
        let base = at(q);
        let scale = base
            .gradients(0)
            .iter()
            .map(|g| g.norm())
            .fold(0.0, f64::max);
        for d in 0..3 {
            let e = Vector3::ith(d, h);
            let (plus, minus) = (at(q + e), at(q - e));
            assert_eq!(plus.kernels(0), base.kernels(0), "same kernels in reach");
            assert_eq!(minus.kernels(0), base.kernels(0), "same kernels in reach");
            for (j, gradient) in base.gradients(0).iter().enumerate() {
                let fd = (plus.values(0)[j] - minus.values(0)[j]) / (2.0 * h);
                let error = (fd - gradient[d]).abs() / scale;
                assert!(error < 1e-6, "kernel {j}, axis {d} at {q:?}: {error:e}");
            }
        }
    }
}

/// Largest error of the interpolated smooth field `sin(2x) cos(3y) e^z` over the points.
fn smooth_field_error(
    kernels: &Kernels,
    points: &[Vector3<f64>],
    params: &ShapeFunctionParams,
) -> f64 {
    let f = |x: &Vector3<f64>| (2.0 * x.x).sin() * (3.0 * x.y).cos() * x.z.exp();
    let shape = evaluate_shape_functions(kernels, points, params).unwrap();
    interpolated(&shape, kernels, f)
        .iter()
        .zip(points)
        .map(|((value, _), x)| (value - f(x)).abs())
        .fold(0.0, f64::max)
}

#[test]
fn quadratic_reproduction_approximates_a_smooth_field_more_closely_and_converges_faster() {
    let mut errors = Vec::new();
    for count in [150, 1200] {
        let (points, kernels) = box_layout([2.0, 1.0, 1.0], 0.05, count);
        let linear = smooth_field_error(&kernels, &points, &ShapeFunctionParams::default());
        let quadratic = smooth_field_error(&kernels, &points, &quadratic());
        assert!(
            quadratic < 0.5 * linear,
            "{count} kernels: quadratic {quadratic:e} against linear {linear:e}"
        );
        errors.push((linear, quadratic));
    }
    // Eight times the kernels halve the spacing: linear error falls about 4×, quadratic 8×.
    let (linear_rate, quadratic_rate) = (errors[0].0 / errors[1].0, errors[0].1 / errors[1].1);
    assert!(
        quadratic_rate > linear_rate,
        "error ratios: linear {linear_rate}, quadratic {quadratic_rate}"
    );
}

#[test]
fn fewer_than_ten_kernels_in_reach_is_a_singular_moment_matrix() {
    // Nine kernels: enough for linear functions, not for quadratic ones.
    let centers: Vec<Vector3<f64>> = (0..9)
        .map(|i| {
            let t = i as f64;
            Vector3::new(0.3 * (t * 1.3).cos(), 0.3 * (t * 2.1).sin(), 0.1 * t - 0.4)
        })
        .collect();
    let kernels = Kernels::new(centers, vec![0.5; 9]).unwrap();
    let x = [Vector3::new(0.01, -0.02, 0.03)];
    assert!(evaluate_shape_functions(&kernels, &x, &ShapeFunctionParams::default()).is_ok());
    match evaluate_shape_functions(&kernels, &x, &quadratic()) {
        Err(ShapeFunctionError::SingularMomentMatrix {
            kernels_in_reach, ..
        }) => assert_eq!(kernels_in_reach, 9),
        other => panic!("expected a singular moment matrix, got {other:?}"),
    }
}
